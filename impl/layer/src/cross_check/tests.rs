//! The cross-check's rules, input by input, with servo commands (tolerance 25 per axis).

use super::*;
use crate::vote_reader::ServoRule;
use crate::wire::ServoControl;

fn servo(pan: u16) -> ServoControl {
    ServoControl {
        pan,
        tilt: 500,
        frequency: 60,
    }
}

/// Controller 1's cross-check after input 0, answered by all three alike and aligned to. Its
/// answer to 0, the first of its life, was computed from no group position: it is never
/// judged, so it counts as late (`OddOneOut::late`) until an answer is judged not odd.
fn in_step_c1() -> CrossCheck<ServoControl, ServoRule> {
    let mut check = CrossCheck::new(1, ServoRule::default(), ODD_LIMIT_DEFAULT);
    check.all_agreed();
    round(&mut check, 0, 500, 500, 500);
    check
}

/// Controller 1 answers `input` with `own`, peers 2 and 3 with `pan2` and `pan3`; then it
/// aligns to the group's answers to it, as the tracker does when the vote accepts them.
fn round(
    check: &mut CrossCheck<ServoControl, ServoRule>,
    input: u64,
    own: u16,
    pan2: u16,
    pan3: u16,
) -> Judgement {
    let judgement = round_unaligned(check, input, own, pan2, pan3);
    check.aligned(input);
    judgement
}

/// As [`round`], without the alignment (the group's answers came too late for it).
fn round_unaligned(
    check: &mut CrossCheck<ServoControl, ServoRule>,
    input: u64,
    own: u16,
    pan2: u16,
    pan3: u16,
) -> Judgement {
    let judgement = check.answer(input, 0, RawAnswer::NONE, servo(own));
    check.peer_answer(2, input, 0, RawAnswer::NONE, servo(pan2));
    check.peer_answer(3, input, 0, RawAnswer::NONE, servo(pan3));
    judgement
}

#[test]
fn a_wrong_controller_leaves_before_answering_after_its_second_odd_input() {
    let mut check = in_step_c1();
    assert_eq!(round(&mut check, 1, 800, 500, 505), Judgement::Answer);
    assert_eq!(round(&mut check, 2, 810, 510, 512), Judgement::Answer);
    assert_eq!(check.odd_inputs(), &[1]);
    // Input 2 is judged when input 3 is answered, and that answer does not go out.
    let judgement = check.answer(3, 0, RawAnswer::NONE, servo(820));
    let expected = OddOneOut {
        on: OddOn::Output,
        inputs: vec![1, 2],
        odd_limit: 2,
        peers: vec![2, 3],
        late: 1,
    };
    assert_eq!(judgement, Judgement::Leave(expected.clone()));
    // Nothing more in this life.
    assert_eq!(
        check.answer(4, 0, RawAnswer::NONE, servo(500)),
        Judgement::Leave(expected)
    );
}

#[test]
fn odd_inputs_count_in_a_life_in_a_row_or_not() {
    let mut check = in_step_c1();
    assert_eq!(round(&mut check, 1, 800, 500, 500), Judgement::Answer);
    assert_eq!(round(&mut check, 2, 500, 500, 500), Judgement::Answer);
    assert_eq!(round(&mut check, 3, 800, 500, 500), Judgement::Answer);
    assert_eq!(check.odd_inputs(), &[1], "input 3 is judged at input 4");
    assert!(matches!(
        check.answer(4, 0, RawAnswer::NONE, servo(500)),
        Judgement::Leave(_)
    ));
    assert_eq!(check.odd_inputs(), &[1, 3]);
}

#[test]
fn nobody_is_odd_when_the_two_others_disagree() {
    // Two wrong controllers that disagree: the correct one sees no agreeing pair.
    let mut check = in_step_c1();
    for input in 1..10 {
        assert_eq!(round(&mut check, input, 500, 800, 200), Judgement::Answer);
    }
    assert!(check.odd_inputs().is_empty());
}

#[test]
fn agreeing_with_one_peer_is_not_odd() {
    // Within the tolerance of peer 2 (500 ~ 520), peers 2 and 3 agree (520 ~ 540), but
    // 500 and 540 do not: tolerance is not transitive, and the correct one is not odd.
    let mut check = in_step_c1();
    for input in 1..10 {
        assert_eq!(round(&mut check, input, 500, 520, 540), Judgement::Answer);
    }
    assert!(check.odd_inputs().is_empty());
}

#[test]
fn an_input_only_one_peer_answered_judges_nobody() {
    let mut check = in_step_c1();
    for input in 1..10 {
        assert_eq!(
            check.answer(input, 0, RawAnswer::NONE, servo(900)),
            Judgement::Answer
        );
        check.peer_answer(2, input, 0, RawAnswer::NONE, servo(500));
        check.aligned(input);
    }
    assert!(check.odd_inputs().is_empty());
}

#[test]
fn an_answer_not_computed_from_the_groups_position_is_not_judged() {
    let mut check = CrossCheck::new(1, ServoRule::default(), 2);
    check.all_agreed();
    // Never aligned (formation: its own start differs from the group's, and it is not wrong).
    for input in 1..5 {
        assert_eq!(
            round_unaligned(&mut check, input, 900, 500, 500),
            Judgement::Answer
        );
    }
    assert!(check.odd_inputs().is_empty());
    // Aligned at input 4: its answer to 5 is in step, and judged at 6.
    check.aligned(4);
    round_unaligned(&mut check, 5, 900, 500, 500);
    assert_eq!(check.odd_inputs(), &[] as &[u64]);
    // Not aligned at 5 (the group's answers came late): its answer to 6 is not judged.
    round(&mut check, 6, 900, 500, 500);
    assert_eq!(check.odd_inputs(), &[5]);
    round(&mut check, 7, 900, 500, 500);
    assert_eq!(check.odd_inputs(), &[5], "input 6 was not in step");
    // Aligned at 6 and 7: its answer to 7 is judged when it answers 8.
    assert!(matches!(
        check.answer(8, 0, RawAnswer::NONE, servo(900)),
        Judgement::Leave(_)
    ));
    assert_eq!(check.odd_inputs(), &[5, 7]);
}

#[test]
fn a_repeated_answer_replaces_the_one_judged() {
    let mut check = in_step_c1();
    assert_eq!(
        check.answer(1, 0, RawAnswer::NONE, servo(900)),
        Judgement::Answer
    );
    // Re-published with the value corrected before the next input: the last one is judged.
    assert_eq!(
        check.answer(1, 0, RawAnswer::NONE, servo(500)),
        Judgement::Answer
    );
    check.peer_answer(2, 1, 0, RawAnswer::NONE, servo(500));
    check.peer_answer(3, 1, 0, RawAnswer::NONE, servo(500));
    assert_eq!(
        check.answer(2, 0, RawAnswer::NONE, servo(500)),
        Judgement::Answer
    );
    assert!(check.odd_inputs().is_empty());
}

#[test]
fn a_new_life_counts_from_zero_once_in_step_again() {
    let mut check = in_step_c1();
    round(&mut check, 1, 900, 500, 500);
    round(&mut check, 2, 500, 500, 500);
    assert_eq!(check.odd_inputs(), &[1]);
    check.new_life();
    assert!(check.odd_inputs().is_empty());
    check.all_agreed();
    round_unaligned(&mut check, 3, 900, 500, 500);
    round(&mut check, 4, 900, 500, 500);
    assert!(
        check.odd_inputs().is_empty(),
        "3 not in step in the new life"
    );
    round(&mut check, 5, 900, 500, 500);
    assert_eq!(round(&mut check, 6, 900, 500, 500), Judgement::Answer);
    assert!(matches!(
        check.answer(7, 0, RawAnswer::NONE, servo(900)),
        Judgement::Leave(_)
    ));
}

#[test]
fn with_no_limit_it_counts_and_never_leaves() {
    let mut check = CrossCheck::new(1, ServoRule::default(), 0);
    check.all_agreed();
    round(&mut check, 0, 500, 500, 500);
    for input in 1..10 {
        assert_eq!(round(&mut check, input, 900, 500, 500), Judgement::Answer);
    }
    assert_eq!(check.odd_inputs().len(), 8);
}

#[test]
fn its_own_answers_read_back_are_not_a_peer() {
    let mut check = in_step_c1();
    for input in 1..10 {
        assert_eq!(
            check.answer(input, 0, RawAnswer::NONE, servo(900)),
            Judgement::Answer
        );
        check.peer_answer(1, input, 0, RawAnswer::NONE, servo(900));
        check.peer_answer(2, input, 0, RawAnswer::NONE, servo(500));
        check.aligned(input);
    }
    assert!(
        check.odd_inputs().is_empty(),
        "one peer: no full comparison"
    );
}

#[test]
fn peers_answers_to_old_inputs_are_forgotten() {
    let mut check = in_step_c1();
    assert_eq!(
        check.answer(1, 0, RawAnswer::NONE, servo(900)),
        Judgement::Answer
    );
    check.peer_answer(2, 1, 0, RawAnswer::NONE, servo(500));
    check.peer_answer(3, 1, 0, RawAnswer::NONE, servo(500));
    check.aligned(1);
    // Peers far ahead push input 1's answers out before it is judged.
    for input in 100..100 + INPUTS_KEPT as u64 {
        check.peer_answer(2, input, 0, RawAnswer::NONE, servo(500));
    }
    assert_eq!(
        check.answer(2, 0, RawAnswer::NONE, servo(900)),
        Judgement::Answer
    );
    assert!(check.odd_inputs().is_empty());
}

#[test]
fn the_reason_names_the_inputs_and_the_agreeing_peers() {
    let reason = OddOneOut {
        on: OddOn::Output,
        inputs: vec![17, 19],
        odd_limit: 2,
        peers: vec![2, 3],
        late: 0,
    };
    assert_eq!(
        reason.to_string(),
        "the odd one out of three at 2 inputs of this life (17, 19): its answers disagree \
         with both of C2 and C3, which agree"
    );
}

#[test]
fn an_input_whose_peers_answer_late_is_judged_later_and_counted_late() {
    let mut check = in_step_c1();
    assert_eq!(
        check.answer(1, 0, RawAnswer::NONE, servo(900)),
        Judgement::Answer
    );
    // The peers' answers to 1, and so the group's position at 1, come after its answer to 2
    // (a loaded host): 2 was not computed from the group's position.
    assert_eq!(
        check.answer(2, 0, RawAnswer::NONE, servo(900)),
        Judgement::Answer
    );
    for input in 1..=2 {
        check.peer_answer(2, input, 0, RawAnswer::NONE, servo(500));
        check.peer_answer(3, input, 0, RawAnswer::NONE, servo(500));
        check.aligned(input);
    }
    // At 3, input 1 is judged late (odd) and 2 never (not in step): two late answers, and 0.
    assert_eq!(
        check.answer(3, 0, RawAnswer::NONE, servo(900)),
        Judgement::Answer
    );
    assert_eq!(check.odd_inputs(), &[1]);
    check.peer_answer(2, 3, 0, RawAnswer::NONE, servo(500));
    check.peer_answer(3, 3, 0, RawAnswer::NONE, servo(500));
    check.aligned(3);
    let expected = OddOneOut {
        on: OddOn::Output,
        inputs: vec![1, 3],
        odd_limit: 2,
        peers: vec![2, 3],
        late: 3,
    };
    // Three wrong answers went out (1, 2, 3): N = 2 and one more per late answer bound it.
    assert_eq!(
        check.answer(4, 0, RawAnswer::NONE, servo(900)),
        Judgement::Leave(expected)
    );
}

#[test]
fn a_second_peer_late_by_one_input_still_counts_the_input_odd() {
    let mut check = in_step_c1();
    assert_eq!(
        check.answer(1, 0, RawAnswer::NONE, servo(900)),
        Judgement::Answer
    );
    check.peer_answer(2, 1, 0, RawAnswer::NONE, servo(500));
    check.aligned(1);
    assert_eq!(
        check.answer(2, 0, RawAnswer::NONE, servo(900)),
        Judgement::Answer
    );
    assert!(check.odd_inputs().is_empty(), "one peer: not judged yet");
    check.peer_answer(3, 1, 0, RawAnswer::NONE, servo(505));
    check.peer_answer(2, 2, 0, RawAnswer::NONE, servo(500));
    check.peer_answer(3, 2, 0, RawAnswer::NONE, servo(500));
    check.aligned(2);
    let expected = OddOneOut {
        on: OddOn::Output,
        inputs: vec![1, 2],
        odd_limit: 2,
        peers: vec![2, 3],
        late: 2,
    };
    assert_eq!(
        check.answer(3, 0, RawAnswer::NONE, servo(900)),
        Judgement::Leave(expected)
    );
}

#[test]
fn an_agreement_forgets_the_late_answers_before_it() {
    let mut check = CrossCheck::new(1, ServoRule::default(), 2);
    check.all_agreed();
    // Formation: never in step, every answer late.
    for input in 1..5 {
        round_unaligned(&mut check, input, 500, 500, 500);
    }
    check.aligned(4);
    round(&mut check, 5, 500, 500, 500);
    round(&mut check, 6, 900, 500, 500);
    round(&mut check, 7, 900, 500, 500);
    let Judgement::Leave(reason) = check.answer(8, 0, RawAnswer::NONE, servo(900)) else {
        panic!("C1 stays at its second odd input");
    };
    assert_eq!((reason.inputs, reason.late), (vec![6, 7], 0));
}

#[test]
fn the_reason_says_how_many_answers_went_out_late() {
    let reason = OddOneOut {
        on: OddOn::Output,
        inputs: vec![17, 19],
        odd_limit: 2,
        peers: vec![2, 3],
        late: 1,
    };
    assert!(reason.to_string().ends_with(
        "which agree (1 answers went out before they could be judged at their next input)"
    ));
}

#[test]
fn an_answer_after_an_input_it_never_answered_is_not_judged() {
    let mut check = in_step_c1();
    round(&mut check, 1, 500, 500, 500);
    // Input 2 was lost to it: the group answered it, and it took the group's position there.
    check.peer_answer(2, 2, 0, RawAnswer::NONE, servo(500));
    check.peer_answer(3, 2, 0, RawAnswer::NONE, servo(500));
    check.aligned(2);
    // Its answer to 3 comes from a law that last saw input 1: not the group's to compare.
    round(&mut check, 3, 900, 500, 500);
    round(&mut check, 4, 500, 500, 500);
    assert!(check.odd_inputs().is_empty(), "{:?}", check.odd_inputs());
    // Back in step, a wrong answer is judged again.
    round(&mut check, 5, 900, 500, 500);
    round(&mut check, 6, 500, 500, 500);
    assert_eq!(check.odd_inputs(), &[5]);
}

#[test]
fn nothing_is_judged_before_the_group_has_answered_an_input_alike() {
    // Formation: the peers take their position from the owner's commands until the vote
    // works, so two of them may agree on what a right controller in step does not.
    let mut check = CrossCheck::new(1, ServoRule::default(), 2);
    for input in 0..6 {
        assert_eq!(round(&mut check, input, 900, 500, 500), Judgement::Answer);
    }
    assert!(check.odd_inputs().is_empty());
    check.all_agreed();
    round(&mut check, 6, 900, 500, 500);
    round(&mut check, 7, 900, 500, 500);
    assert_eq!(check.odd_inputs(), &[6]);
}
