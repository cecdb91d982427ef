//! Input congruence, input by input: another value of the same input, and inputs the group
//! never had (the module's rules), with servo commands whose output agrees throughout, as a
//! controller aligned to the group's position computes it.

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

/// The digest of the group's input `input`, as every correct controller has it.
fn right(input: u64) -> u64 {
    1000 + input
}

/// Controller 1's cross-check after input 0, answered by all three alike and aligned to.
fn in_step_c1() -> CrossCheck<ServoControl, ServoRule> {
    let mut check = CrossCheck::new(1, ServoRule::default(), ODD_LIMIT_DEFAULT);
    check.all_agreed();
    check.answer(0, right(0), RawAnswer::NONE, servo(500));
    check.peer_answer(2, 0, right(0), RawAnswer::NONE, servo(500));
    check.peer_answer(3, 0, right(0), RawAnswer::NONE, servo(500));
    check.aligned(0);
    check
}

/// Peers 2 and 3 answer `input` alike, from the right input.
fn peers_answer(check: &mut CrossCheck<ServoControl, ServoRule>, input: u64) {
    check.peer_answer(2, input, right(input), RawAnswer::NONE, servo(500));
    check.peer_answer(3, input, right(input), RawAnswer::NONE, servo(500));
}

#[test]
fn another_value_of_the_same_input_leaves_at_the_second_though_the_output_agrees() {
    let mut check = in_step_c1();
    for input in 1..=2 {
        assert_eq!(
            check.answer(input, 7, RawAnswer::NONE, servo(500)),
            Judgement::Answer
        );
        peers_answer(&mut check, input);
        check.aligned(input);
    }
    assert_eq!(
        check.odd_inputs(),
        &[1],
        "odd on input, its output agreeing"
    );
    let Judgement::Leave(reason) = check.answer(3, 7, RawAnswer::NONE, servo(500)) else {
        panic!("odd on input at 1 and 2: it leaves before answering 3");
    };
    assert_eq!(reason.on, OddOn::Input);
    assert_eq!(reason.inputs, vec![1, 2]);
    assert_eq!(reason.peers, vec![2, 3]);
    let text = reason.to_string();
    assert!(text.contains("on input at 2 inputs"), "{text}");
    assert!(
        text.contains("its input disagrees with both of C2 and C3"),
        "{text}"
    );
}

#[test]
fn a_controller_that_agrees_with_one_peer_on_input_is_not_odd() {
    let mut check = in_step_c1();
    for input in 1..=6 {
        assert_eq!(
            check.answer(input, right(input), RawAnswer::NONE, servo(500)),
            Judgement::Answer
        );
        check.peer_answer(2, input, right(input), RawAnswer::NONE, servo(500));
        check.peer_answer(3, input, 7, RawAnswer::NONE, servo(500));
        check.aligned(input);
    }
}

#[test]
fn inputs_the_group_never_had_leave_at_the_fifth_in_a_row_even_out_of_step() {
    // Another camera: its frames fall between the group's, and it is never in step.
    let mut check = CrossCheck::new(1, ServoRule::default(), ODD_LIMIT_DEFAULT);
    let mut left = None;
    for k in 0..10u64 {
        peers_answer(&mut check, 2 * k);
        if let Judgement::Leave(reason) = check.answer(2 * k + 1, 9, RawAnswer::NONE, servo(500)) {
            left = Some((k, reason));
            break;
        }
    }
    let (k, reason) = left.expect("five foreign inputs in a row: it leaves");
    assert_eq!(reason.on, OddOn::Input);
    assert_eq!(reason.inputs, vec![1, 3, 5, 7, 9]);
    assert_eq!(FOREIGN_LIMIT, 5);
    assert_eq!(k, 5, "input 9 is judged when it answers 11");
}

#[test]
fn a_foreign_input_is_forgotten_at_the_next_shared_one() {
    let mut check = CrossCheck::new(1, ServoRule::default(), ODD_LIMIT_DEFAULT);
    for k in 0..20u64 {
        peers_answer(&mut check, 2 * k);
        // Every fifth input it answers is the group's (the others both peers skipped).
        let input = if k % 4 == 3 { 2 * k } else { 2 * k + 1 };
        let digest = if input % 2 == 0 { right(input) } else { 9 };
        assert_eq!(
            check.answer(input, digest, RawAnswer::NONE, servo(500)),
            Judgement::Answer
        );
    }
}

#[test]
fn an_input_is_not_foreign_before_the_peers_answered_newer_ones_agreeing() {
    let mut check = CrossCheck::new(1, ServoRule::default(), ODD_LIMIT_DEFAULT);
    peers_answer(&mut check, 0);
    // Its inputs run ahead of the peers': not one peer has passed them.
    for input in 1..=8 {
        assert_eq!(
            check.answer(input, 9, RawAnswer::NONE, servo(500)),
            Judgement::Answer
        );
    }
    // The peers pass them, but disagree with each other on every input: nobody is odd.
    for input in 9..=20 {
        check.peer_answer(2, input, right(input), RawAnswer::NONE, servo(500));
        check.peer_answer(3, input, 7, RawAnswer::NONE, servo(500));
        assert_eq!(
            check.answer(input + 100, 9, RawAnswer::NONE, servo(500)),
            Judgement::Answer
        );
    }
}

#[test]
fn answers_kept_through_a_cut_are_not_foreign_when_the_peers_come_back() {
    let mut check = in_step_c1();
    // Cut off: it answers frames 1..=6 and hears no peer's answer to them.
    for input in 1..=6 {
        assert_eq!(
            check.answer(input, right(input), RawAnswer::NONE, servo(500)),
            Judgement::Answer
        );
    }
    // Back: the peers' answers to newer frames arrive, the one to frame 8 lost as well.
    for input in 7..=20 {
        if input != 8 {
            peers_answer(&mut check, input);
        }
        assert_eq!(
            check.answer(input, right(input), RawAnswer::NONE, servo(500)),
            Judgement::Answer,
            "input {input}"
        );
    }
}

#[test]
fn a_healed_cut_and_a_lost_answer_after_it_are_not_five_foreign_inputs() {
    let mut check = in_step_c1();
    for input in 1..=10 {
        assert_eq!(
            check.answer(input, right(input), RawAnswer::NONE, servo(500)),
            Judgement::Answer
        );
    }
    // Back: the peers answered 11, which its camera reader skipped; their answer to 12 is
    // lost, the one to 13 arrives. Its 4 answers kept through the cut would look foreign, and
    // 12 too: five in a row, were the kept ones evidence.
    peers_answer(&mut check, 11);
    assert_eq!(
        check.answer(12, right(12), RawAnswer::NONE, servo(500)),
        Judgement::Answer
    );
    peers_answer(&mut check, 13);
    assert_eq!(
        check.answer(13, right(13), RawAnswer::NONE, servo(500)),
        Judgement::Answer
    );
    peers_answer(&mut check, 14);
    assert_eq!(
        check.answer(14, right(14), RawAnswer::NONE, servo(500)),
        Judgement::Answer
    );
}

#[test]
fn without_digests_nothing_is_judged_on_input() {
    let mut check = CrossCheck::new(1, ServoRule::default(), ODD_LIMIT_DEFAULT);
    for k in 0..20u64 {
        check.peer_answer(2, 2 * k, 0, RawAnswer::NONE, servo(500));
        check.peer_answer(3, 2 * k, 0, RawAnswer::NONE, servo(500));
        assert_eq!(
            check.answer(2 * k + 1, 0, RawAnswer::NONE, servo(500)),
            Judgement::Answer
        );
    }
}

#[test]
fn an_odd_output_and_an_odd_input_of_one_life_are_its_n_and_it_says_input() {
    let mut check = in_step_c1();
    // Input 1: its output odd, its input right. Input 2: its input odd, its output right.
    assert_eq!(
        check.answer(1, right(1), RawAnswer::NONE, servo(900)),
        Judgement::Answer
    );
    peers_answer(&mut check, 1);
    check.aligned(1);
    assert_eq!(
        check.answer(2, 7, RawAnswer::NONE, servo(500)),
        Judgement::Answer
    );
    peers_answer(&mut check, 2);
    check.aligned(2);
    let Judgement::Leave(reason) = check.answer(3, right(3), RawAnswer::NONE, servo(500)) else {
        panic!("two odd inputs in one life, one of each: it leaves");
    };
    assert_eq!(reason.inputs, vec![1, 2]);
    assert_eq!(reason.on, OddOn::Input);
}
