//! Raw answers, input by input: a law whose output agrees within the tolerance at every input
//! (aligned to the group's position) but whose raw answer differs (the module's rules), and
//! the cases that must not count: a peer that stepped from another input, no raw answer, a
//! single peer's raw answer.

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

/// The group's raw answer to `input`, stepped from `input - 1`, as every correct law gives it.
fn right(input: u64) -> RawAnswer {
    RawAnswer {
        after: input - 1,
        digest: 2000 + input,
    }
}

/// A wrong law's raw answer to `input`, from the same input before.
fn wrong(input: u64) -> RawAnswer {
    RawAnswer {
        digest: 3000 + input,
        ..right(input)
    }
}

/// Controller 1's cross-check after input 1, answered by all three alike and aligned to.
fn in_step_c1() -> CrossCheck<ServoControl, ServoRule> {
    let mut check = CrossCheck::new(1, ServoRule::default(), ODD_LIMIT_DEFAULT);
    check.all_agreed();
    check.answer(1, 1, RawAnswer::NONE, servo(500));
    check.peer_answer(2, 1, 1, RawAnswer::NONE, servo(500));
    check.peer_answer(3, 1, 1, RawAnswer::NONE, servo(500));
    check.aligned(1);
    check
}

/// Controller 1 answers `input` with its raw answer `own`, pan 503 (within the tolerance of
/// the peers' 500); peers 2 and 3 with `raw2` and `raw3`; then it aligns to the group.
fn round(
    check: &mut CrossCheck<ServoControl, ServoRule>,
    input: u64,
    own: RawAnswer,
    (raw2, raw3): (RawAnswer, RawAnswer),
) -> Judgement {
    let judgement = check.answer(input, input, own, servo(503));
    check.peer_answer(2, input, input, raw2, servo(500));
    check.peer_answer(3, input, input, raw3, servo(500));
    check.aligned(input);
    judgement
}

#[test]
fn a_wrong_law_masked_by_the_alignment_leaves_at_its_second_odd_raw_answer() {
    let mut check = in_step_c1();
    for input in 2..=3 {
        let peers = (right(input), right(input));
        assert_eq!(
            round(&mut check, input, wrong(input), peers),
            Judgement::Answer
        );
    }
    assert_eq!(
        check.odd_inputs(),
        &[2],
        "odd on its law, its output agreeing"
    );
    let Judgement::Leave(reason) = check.answer(4, 4, wrong(4), servo(503)) else {
        panic!("odd on its law at 2 and 3: it leaves before answering 4");
    };
    assert_eq!(reason.on, OddOn::Law);
    assert_eq!(reason.inputs, vec![2, 3]);
    assert_eq!(reason.peers, vec![2, 3]);
    let text = reason.to_string();
    assert!(text.contains("on its law at 2 inputs"), "{text}");
    assert!(
        text.contains("its raw answers disagree with both of C2 and C3"),
        "{text}"
    );
}

#[test]
fn a_right_law_beside_a_peer_that_stepped_from_another_input_is_not_odd() {
    // Both peers skipped the input before (their camera readers keep only the newest frame):
    // they step from the input before that, agree with each other and not with it.
    let mut check = in_step_c1();
    for input in 2..=6 {
        let skipped = RawAnswer {
            after: input - 2,
            digest: 4000 + input,
        };
        let judgement = round(&mut check, input, right(input), (skipped, skipped));
        assert_eq!(judgement, Judgement::Answer);
    }
    assert_eq!(check.odd_inputs(), &[] as &[u64]);
}

#[test]
fn raw_answers_compare_only_when_two_peers_give_one_from_the_same_input() {
    let mut check = in_step_c1();
    for input in 2..=6 {
        // One peer gives none (an application without raw answers, or its first frame), the
        // other agrees with nobody to make a pair.
        let peers = (RawAnswer::NONE, right(input));
        assert_eq!(
            round(&mut check, input, wrong(input), peers),
            Judgement::Answer
        );
    }
    assert_eq!(check.odd_inputs(), &[] as &[u64]);
    // Its own raw answer missing: nothing to compare, whatever the peers agree on.
    for input in 7..=11 {
        let peers = (right(input), right(input));
        assert_eq!(
            round(&mut check, input, RawAnswer::NONE, peers),
            Judgement::Answer
        );
    }
    assert_eq!(check.odd_inputs(), &[] as &[u64]);
}

#[test]
fn an_odd_output_is_named_on_output_and_a_right_raw_answer_leaves_no_trace() {
    // Wrong output, right law: judged on output (its raw answer is the peers').
    let mut check = in_step_c1();
    for input in 2..=3 {
        let judgement = check.answer(input, input, right(input), servo(900));
        assert_eq!(judgement, Judgement::Answer);
        check.peer_answer(2, input, input, right(input), servo(500));
        check.peer_answer(3, input, input, right(input), servo(500));
        check.aligned(input);
    }
    let Judgement::Leave(reason) = check.answer(4, 4, right(4), servo(900)) else {
        panic!("odd on output at 2 and 3");
    };
    assert_eq!(reason.on, OddOn::Output);
}

#[test]
fn a_new_life_forgets_the_law_it_was_odd_on() {
    let mut check = in_step_c1();
    assert_eq!(
        round(&mut check, 2, wrong(2), (right(2), right(2))),
        Judgement::Answer
    );
    check.new_life();
    check.all_agreed();
    check.answer(3, 3, RawAnswer::NONE, servo(500));
    check.aligned(3);
    assert_eq!(check.odd_inputs(), &[] as &[u64]);
    // Odd again once, in the new life: not yet N.
    assert_eq!(
        round(&mut check, 4, wrong(4), (right(4), right(4))),
        Judgement::Answer
    );
    assert_eq!(
        round(&mut check, 5, right(5), (right(5), right(5))),
        Judgement::Answer
    );
    assert_eq!(check.odd_inputs(), &[4]);
}
