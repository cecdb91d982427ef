//! The vote rule for servo commands and the reader's decisions, answer by answer: two agree
//! and the median is taken; a wrong one is never taken and is named; two that disagree with the
//! third silent hold; an alarm clears; stale and out-of-step answers do not count.

use super::*;

const FRESH_MS: u64 = 100;

fn servo(pan: u16, tilt: u16) -> ServoControl {
    ServoControl {
        pan,
        tilt,
        frequency: 60,
    }
}

fn answer(from: ControllerId, input: u64, pan: u16, tilt: u16) -> Voted<ServoControl> {
    Voted {
        from,
        input,
        input_digest: 0,
        raw: crate::wire::RawAnswer::NONE,
        value: servo(pan, tilt),
    }
}

/// A reader of servo commands (default tolerance 25) alarming at the first dissent.
fn reader(fallback: Fallback<ServoControl>) -> VoteReader<ServoControl, ServoRule> {
    VoteReader::new(
        ServoRule::default(),
        VoteSettings {
            freshness_ms: FRESH_MS,
            dissent_after: 1,
            fallback,
        },
    )
}

fn accepted(events: &[VoteEvent<ServoControl>]) -> Vec<(u64, ServoControl, Vec<ControllerId>)> {
    let accepted = events.iter().filter_map(|event| match event {
        VoteEvent::Accepted {
            input,
            value,
            agreeing,
        } => Some((*input, *value, agreeing.clone())),
        _ => None,
    });
    accepted.collect()
}

#[test]
fn servo_commands_agree_per_axis_within_the_tolerance_and_at_one_frequency() {
    let rule = ServoRule {
        pan_tolerance: 10,
        tilt_tolerance: 20,
    };
    assert!(rule.agree(&servo(500, 500), &servo(510, 480)));
    assert!(!rule.agree(&servo(500, 500), &servo(511, 500)));
    assert!(!rule.agree(&servo(500, 500), &servo(500, 521)));
    let other_frequency = ServoControl {
        frequency: 50,
        ..servo(500, 500)
    };
    assert!(!rule.agree(&servo(500, 500), &other_frequency));
    // Per axis: the median of three, the lower middle of two.
    let three = [servo(510, 400), servo(500, 420), servo(505, 410)];
    assert_eq!(rule.combine(&three), servo(505, 410));
    assert_eq!(rule.combine(&three[..2]), servo(500, 400));
}

#[test]
fn two_that_agree_are_accepted_as_their_median_without_waiting_for_the_third() {
    let mut votes = reader(Fallback::Hold);
    assert_eq!(votes.offer(answer(1, 7, 500, 500), 0), vec![]);
    let events = votes.offer(answer(2, 7, 510, 490), 1);
    assert_eq!(accepted(&events), vec![(7, servo(500, 490), vec![1, 2])]);
    assert_eq!(events.len(), 1, "{events:?}");
    // The third agrees later: it joins, and the value is the median of three.
    let events = votes.offer(answer(3, 7, 505, 480), 2);
    assert_eq!(accepted(&events), vec![(7, servo(505, 490), vec![1, 2, 3])]);
    assert_eq!(votes.accepted(), Some(&servo(505, 490)));
    assert!(votes.dissenting().is_empty());
}

#[test]
fn a_wrong_controller_is_named_and_its_value_never_taken() {
    let mut votes = reader(Fallback::Hold);
    for id in 1..=3 {
        votes.offer(answer(id, 6, 500, 500), 0);
    }
    // C1 answers first, wrong by 300 on pan: nothing is taken from it alone or with one other
    // while C3, fresh, has not answered.
    assert_eq!(votes.offer(answer(1, 7, 800, 500), 1), vec![]);
    assert_eq!(votes.offer(answer(2, 7, 500, 500), 1), vec![]);
    let events = votes.offer(answer(3, 7, 502, 500), 2);
    assert_eq!(
        events,
        vec![
            VoteEvent::Accepted {
                input: 7,
                value: servo(500, 500),
                agreeing: vec![2, 3],
            },
            VoteEvent::Dissent {
                source: 1,
                raised: true,
                input: 7,
                value: servo(800, 500),
            },
        ]
    );
    assert_eq!(votes.dissenting(), vec![1]);
    // Later inputs: still refused, the alarm raised once.
    for input in 8..12 {
        let t = input * 10;
        votes.offer(answer(2, input, 500, 500), t);
        votes.offer(answer(3, input, 501, 500), t);
        let events = votes.offer(answer(1, input, 800, 500), t);
        assert_eq!(events, vec![], "C1's answer to {input} changes nothing");
        assert_eq!(votes.accepted(), Some(&servo(500, 500)));
    }
}

/// One input answered by C1 and C2 at 500, 500 and by C3 at `c3_pan`, 500; the events of
/// C3's answer.
fn c3_answers(
    votes: &mut VoteReader<ServoControl, ServoRule>,
    input: u64,
    c3_pan: u16,
) -> Vec<VoteEvent<ServoControl>> {
    votes.offer(answer(1, input, 500, 500), input * 10);
    votes.offer(answer(2, input, 500, 500), input * 10);
    votes.offer(answer(3, input, c3_pan, 500), input * 10)
}

fn raised_or_cleared(events: &[VoteEvent<ServoControl>]) -> Option<bool> {
    events.iter().find_map(|event| match event {
        VoteEvent::Dissent {
            source: 3, raised, ..
        } => Some(*raised),
        _ => None,
    })
}

#[test]
fn a_dissent_alarm_is_raised_at_the_third_dissent_and_cleared_after_three_agreements() {
    let mut votes = VoteReader::new(ServoRule::default(), VoteSettings::holding(FRESH_MS));
    // Wrong, right, wrong, wrong: the third dissent raises it, in a row or not.
    let alarms: Vec<_> = [900, 500, 900, 900]
        .into_iter()
        .zip(1..)
        .map(|(pan, input)| raised_or_cleared(&c3_answers(&mut votes, input, pan)))
        .collect();
    assert_eq!(alarms, [None, None, None, Some(true)]);
    // Right twice, wrong once, right three times: cleared at the third agreement in a row.
    let alarms: Vec<_> = [510, 500, 900, 500, 490, 500]
        .into_iter()
        .zip(5..)
        .map(|(pan, input)| raised_or_cleared(&c3_answers(&mut votes, input, pan)))
        .collect();
    assert_eq!(alarms, [None, None, None, None, None, Some(false)]);
    assert!(votes.dissenting().is_empty());
}

#[test]
fn a_controller_wrong_at_every_other_input_is_alarmed_and_stays_so() {
    // Finding O2 of the output model: a count in a row would never name it.
    let mut votes = VoteReader::new(ServoRule::default(), VoteSettings::holding(FRESH_MS));
    let mut raised_at = None;
    for input in 1..=20 {
        let pan = if input % 2 == 1 { 900 } else { 500 };
        if raised_or_cleared(&c3_answers(&mut votes, input, pan)) == Some(true) {
            raised_at.get_or_insert(input);
        }
        assert_eq!(votes.accepted(), Some(&servo(500, 500)), "never its 900");
    }
    assert_eq!(raised_at, Some(5), "its third dissent");
    assert_eq!(
        votes.dissenting(),
        vec![3],
        "never three agreements in a row"
    );
}

#[test]
fn two_that_disagree_with_the_third_silent_hold_the_last_accepted_value() {
    let mut votes = reader(Fallback::Hold);
    votes.offer(answer(1, 1, 500, 500), 0);
    votes.offer(answer(2, 1, 500, 500), 0);
    votes.offer(answer(3, 1, 500, 500), 0);
    // C3 goes silent; C1 and C2 disagree on input 2.
    votes.offer(answer(1, 2, 300, 500), 30);
    votes.offer(answer(2, 2, 700, 500), 40);
    assert_eq!(
        votes.tick(90),
        vec![],
        "C3 is still fresh: it may yet agree"
    );
    let events = votes.tick(101);
    assert_eq!(
        events,
        vec![VoteEvent::NoMajority {
            input: Some(2),
            fresh: vec![1, 2],
            fallback: Fallback::Hold,
            value: Some(servo(500, 500)),
        }]
    );
    assert!(votes.without_majority());
    assert_eq!(
        votes.accepted(),
        Some(&servo(500, 500)),
        "held, neither taken"
    );
    assert!(votes.dissenting().is_empty(), "no majority names nobody");
    assert_eq!(votes.tick(150), vec![], "reported once");
    // They agree again: accepted.
    votes.offer(answer(1, 3, 600, 500), 160);
    let events = votes.offer(answer(2, 3, 600, 500), 161);
    assert_eq!(accepted(&events), vec![(3, servo(600, 500), vec![1, 2])]);
    assert!(!votes.without_majority());
}

#[test]
fn without_a_majority_it_goes_to_the_safe_value_when_one_is_configured() {
    let mut votes = reader(Fallback::Safe(servo(500, 1000)));
    votes.offer(answer(1, 1, 300, 500), 0);
    let events = votes.offer(answer(2, 1, 700, 500), 1);
    assert_eq!(
        events,
        vec![VoteEvent::NoMajority {
            input: Some(1),
            fresh: vec![1, 2],
            fallback: Fallback::Safe(servo(500, 1000)),
            value: Some(servo(500, 1000)),
        }]
    );
}

#[test]
fn a_lone_controller_is_never_accepted_and_a_lapsed_majority_is_reported() {
    let mut votes = reader(Fallback::Hold);
    votes.offer(answer(1, 1, 500, 500), 0);
    votes.offer(answer(2, 1, 500, 500), 0);
    // C2 dies; C1 alone answers every 10 ms.
    let mut events = Vec::new();
    for step in 1..=20 {
        events.extend(votes.offer(answer(1, 1 + step, 500 + step as u16, 500), step * 10));
    }
    assert_eq!(
        accepted(&events),
        vec![],
        "one controller alone is never taken"
    );
    assert_eq!(
        events,
        vec![VoteEvent::NoMajority {
            input: None,
            fresh: vec![1],
            fallback: Fallback::Hold,
            value: Some(servo(500, 500)),
        }]
    );
}

#[test]
fn a_stale_answer_does_not_count() {
    let mut votes = reader(Fallback::Hold);
    votes.offer(answer(1, 5, 500, 500), 0);
    assert_eq!(accepted(&votes.offer(answer(2, 5, 500, 500), 101)), vec![]);
}

#[test]
fn a_controller_a_frame_behind_or_ahead_abstains() {
    let mut votes = reader(Fallback::Hold);
    votes.offer(answer(1, 5, 500, 500), 0);
    votes.offer(answer(2, 5, 500, 500), 0);
    // C1 moves to input 6 first, C3 still answers 4: nothing new, and no fallback.
    assert_eq!(votes.offer(answer(1, 6, 520, 500), 5), vec![]);
    assert_eq!(votes.offer(answer(3, 4, 100, 100), 6), vec![]);
    let events = votes.offer(answer(2, 6, 520, 500), 7);
    assert_eq!(accepted(&events), vec![(6, servo(520, 500), vec![1, 2])]);
    // A controller far ahead (a forged input tag) answers alone: it stops nothing.
    votes.offer(answer(3, u64::MAX, 900, 900), 8);
    votes.offer(answer(1, 7, 530, 500), 9);
    let events = votes.offer(answer(2, 7, 530, 500), 10);
    assert_eq!(accepted(&events), vec![(7, servo(530, 500), vec![1, 2])]);
    assert!(votes.dissenting().is_empty());
}

#[test]
fn a_late_answer_that_disagrees_with_the_accepted_set_dissents() {
    let mut votes = reader(Fallback::Hold);
    votes.offer(answer(1, 5, 500, 500), 0);
    votes.offer(answer(2, 5, 500, 500), 0);
    // C1 is on to input 6 when C3's wrong answer to 5 arrives: judged against {1, 2}.
    votes.offer(answer(1, 6, 500, 500), 3);
    let events = votes.offer(answer(3, 5, 500, 100), 4);
    assert_eq!(
        events,
        vec![VoteEvent::Dissent {
            source: 3,
            raised: true,
            input: 5,
            value: servo(500, 100),
        }]
    );
}

#[test]
fn of_three_chained_answers_the_first_agreeing_pair_wins_and_the_third_dissents() {
    // 1 ~ 2 and 2 ~ 3, but 1 and 3 are 40 apart: {1,2} is taken, 3 is named.
    let mut votes = reader(Fallback::Hold);
    votes.offer(answer(1, 5, 480, 500), 0);
    votes.offer(answer(3, 5, 520, 500), 0);
    let events = votes.offer(answer(2, 5, 500, 500), 0);
    assert_eq!(accepted(&events), vec![(5, servo(480, 500), vec![1, 2])]);
    assert_eq!(votes.dissenting(), vec![3]);
}

/// The rule broken on purpose (`RL_VOTE_MUTATION=accept-single-source`): a wrong answer is
/// taken whether it comes first or last, which the test of a wrong controller above refuses,
/// so that test (and the lab's judge) fail every time, not only when the wrong answer wins a
/// race.
#[cfg(feature = "mutation")]
#[test]
fn a_vote_that_accepts_one_source_takes_every_answer_wrong_or_not() {
    let mut votes = reader(Fallback::Hold);
    votes.mutate(VoteMutation::AcceptSingleSource);
    let first = votes.offer(answer(1, 7, 800, 500), 1);
    assert_eq!(accepted(&first), vec![(7, servo(800, 500), vec![1])]);
    votes.offer(answer(2, 8, 500, 500), 2);
    votes.offer(answer(3, 8, 502, 500), 3);
    let last = votes.offer(answer(1, 8, 800, 500), 4);
    assert_eq!(accepted(&last), vec![(8, servo(800, 500), vec![1])]);
    let stale = votes.offer(answer(2, 7, 500, 500), 5);
    assert_eq!(accepted(&stale), vec![], "an older input is still refused");
}
