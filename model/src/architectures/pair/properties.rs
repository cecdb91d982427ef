//! What the pair must always hold and must sometimes show, each explained in
//! docs/protocol.md, "Other architectures: the spec".
//!
//! "While a single failure" properties read the ghost `double_failure`: from the moment two
//! failures were present at once they say nothing more (a pair tolerates one). A bug that
//! both implementations or both controllers share is one failure: findings A2 and A3 are
//! what happens then.

use super::state::{Answer, Output, PairState};
use super::{BugReach, PairModel};
use crate::architectures::check::{always_applies, PropertyInfo};
use crate::types::{Life, Phase};
use stateright::Expectation;

pub fn catalogue() -> Vec<PropertyInfo<PairModel>> {
    use Expectation::{Always, Sometimes};
    let p = |name, expectation, meaning, condition, lacking| PropertyInfo {
        name,
        expectation,
        meaning,
        condition,
        lacking,
    };
    vec![
        p("no wrong output reaches the actuator", Always,
          "while a single failure is present, every sample the actuator receives is right",
          no_wrong_sample, always_applies),
        p("a self-detected mismatch never reaches the actuator", Always,
          "a controller that found its implementations disagree wrote nothing for that input: it compares before it writes",
          compared_before_write, always_applies),
        p("no single failure leaves the actuator without a correct writer", Always,
          "while a single failure is present, every input closes with a right sample at the actuator",
          right_sample_every_input, always_applies),
        p("the survivor alarms the loss of its partner", Always,
          "a controller in service since an input closed, whose partner wrote nothing for that input, has its alarm up",
          loss_alarmed, always_applies),
        p("a loss alarm names only a partner that missed an input", Always,
          "a controller's alarm is up only about a partner that wrote nothing for the input closed last",
          alarm_only_after_miss, always_applies),
        p("both controllers drive the actuator", Sometimes,
          "the actuator has a right sample from each controller for one input",
          both_drive, always_applies),
        p("a mismatch removes a controller", Sometimes,
          "a controller found its implementations disagree and left, FAILED",
          mismatch_removes, needs_mismatch),
        p("the survivor alarms a removed partner", Sometimes,
          "a controller in service alarms the loss of a partner that left on a mismatch",
          survivor_alarms_removed, needs_mismatch),
        p("the survivor alarms a crashed partner", Sometimes,
          "a controller in service alarms the loss of a crashed partner",
          survivor_alarms_crashed, needs_crash),
        p("one controller drives the actuator alone", Sometimes,
          "the other is out of service and the actuator still has a right sample",
          one_drives_alone, needs_crash_or_bug),
        p("a restarted controller with a bug writes again", Sometimes,
          "a restarted controller, its bug still in its code, writes a right output at an input that does not trigger it",
          returns_and_writes, needs_bug),
    ]
}

fn no_wrong_sample(_: &PairModel, state: &PairState) -> bool {
    state.double_failure || !state.samples.contains(&Some(Output::Wrong))
}

fn compared_before_write(_: &PairModel, state: &PairState) -> bool {
    state
        .controllers
        .iter()
        .zip(state.samples)
        .all(|(c, sample)| c.answer != Answer::Left || sample.is_none())
}

fn right_sample_every_input(_: &PairModel, state: &PairState) -> bool {
    state.double_failure || !state.closed_without_right
}

fn loss_alarmed(_: &PairModel, state: &PairState) -> bool {
    state.controllers.iter().all(|c| {
        let due = c.in_service() && c.judged_last && state.partner(c.id).missed_last;
        !due || c.loss_alarm
    })
}

fn alarm_only_after_miss(_: &PairModel, state: &PairState) -> bool {
    state
        .controllers
        .iter()
        .all(|c| !c.loss_alarm || state.partner(c.id).missed_last)
}

fn both_drive(_: &PairModel, state: &PairState) -> bool {
    state.samples == [Some(Output::Right); 2]
}

fn mismatch_removes(_: &PairModel, state: &PairState) -> bool {
    state.controllers.iter().any(|c| c.phase == Phase::Failed)
}

fn survivor_alarms_removed(_: &PairModel, state: &PairState) -> bool {
    state
        .controllers
        .iter()
        .any(|c| c.in_service() && c.loss_alarm && state.partner(c.id).phase == Phase::Failed)
}

fn survivor_alarms_crashed(_: &PairModel, state: &PairState) -> bool {
    state
        .controllers
        .iter()
        .any(|c| c.in_service() && c.loss_alarm && state.partner(c.id).life == Life::Down)
}

fn one_drives_alone(_: &PairModel, state: &PairState) -> bool {
    state
        .controllers
        .iter()
        .zip(state.samples)
        .any(|(c, sample)| {
            sample == Some(Output::Right)
                && !state.partner(c.id).in_service()
                && state.samples.iter().flatten().count() == 1
        })
}

fn returns_and_writes(_: &PairModel, state: &PairState) -> bool {
    state
        .controllers
        .iter()
        .zip(state.samples)
        .any(|(c, sample)| c.restarted && c.has_bug() && sample == Some(Output::Right))
}

fn needs_bug(model: &PairModel) -> Option<&'static str> {
    (model.config.max_bugs == 0).then_some("needs a bug (--bugs 1)")
}

fn needs_mismatch(model: &PairModel) -> Option<&'static str> {
    needs_bug(model).or_else(|| {
        (model.config.bug_reach == BugReach::BothImplementations).then_some(
            "a bug both implementations share never mismatches (--bug-in one-implementation)",
        )
    })
}

fn needs_crash(model: &PairModel) -> Option<&'static str> {
    (model.config.max_crashes == 0).then_some("needs a crash (--bounces 1)")
}

fn needs_crash_or_bug(model: &PairModel) -> Option<&'static str> {
    needs_crash(model)
        .and(needs_bug(model))
        .map(|_| "needs a crash or a bug (--bounces 1 or --bugs 1)")
}
