//! The pair's rules, action by action: bugs appearing where the scope allows, each
//! controller's answer (both implementations, the comparison, then the write, or leaving),
//! crashes and restarts, and the input's close, at which each controller in service alarms a
//! partner that wrote nothing.
//!
//! The rules in words are docs/protocol.md, "Other architectures: the spec"; every function
//! here is one of them.

use super::state::{
    Answer, BugSite, Implementation, Output, PairAction, PairController, PairState,
};
use super::{BugReach, PairConfig};
use crate::architectures::ArchitectureMutation;
use crate::types::{Id, Life, Phase};

/// The initial states: both controllers in service and correct, the first input open,
/// triggering the bugs to come or not (both, when a bug may appear).
pub fn init_states(config: &PairConfig) -> Vec<PairState> {
    trigger_choices(config)
        .into_iter()
        .map(|triggers| PairState {
            controllers: [PairController::new(1), PairController::new(2)],
            triggers,
            samples: [None; 2],
            crashes: 0,
            bugs: 0,
            double_failure: false,
            closed_without_right: false,
        })
        .collect()
}

/// Whether an input triggers the bugs matters only where a bug may appear.
fn trigger_choices(config: &PairConfig) -> Vec<bool> {
    if config.max_bugs == 0 {
        vec![false]
    } else {
        vec![false, true]
    }
}

/// Every action enabled in `state`.
pub fn actions(config: &PairConfig, state: &PairState, actions: &mut Vec<PairAction>) {
    if state.input_fresh() && state.bugs < config.max_bugs {
        for site in bug_sites(config, state) {
            actions.push(PairAction::BugAppears { site });
        }
    }
    for c in &state.controllers {
        if c.in_service() && c.answer == Answer::Pending {
            actions.push(PairAction::Answer { controller: c.id });
        }
        if c.in_service() && state.crashes < config.max_crashes {
            actions.push(PairAction::Crash { controller: c.id });
        }
        if may_restart(state, c) {
            actions.push(PairAction::Restart { controller: c.id });
        }
    }
    if state.input_answered() {
        for triggers in trigger_choices(config) {
            actions.push(PairAction::NextInput { triggers });
        }
    }
}

/// Where a new bug may appear: sites of the scope's reach not already buggy.
fn bug_sites(config: &PairConfig, state: &PairState) -> Vec<BugSite> {
    let ids = state.controllers.map(|c| c.id);
    match config.bug_reach {
        BugReach::OneImplementation => ids
            .iter()
            .flat_map(|&controller| {
                Implementation::ALL.map(|implementation| BugSite::One {
                    controller,
                    implementation,
                })
            })
            .filter(|site| !already_buggy(state, *site))
            .collect(),
        BugReach::BothImplementations => ids
            .iter()
            .map(|&controller| BugSite::BothImplementations { controller })
            .filter(|site| !already_buggy(state, *site))
            .collect(),
        BugReach::BothControllers => Implementation::ALL
            .iter()
            .map(|&implementation| BugSite::BothControllers { implementation })
            .filter(|site| !already_buggy(state, *site))
            .collect(),
    }
}

/// The implementations a bug at `site` lies in: (controller, implementation) pairs.
fn places(site: BugSite) -> Vec<(Id, Implementation)> {
    match site {
        BugSite::One {
            controller,
            implementation,
        } => vec![(controller, implementation)],
        BugSite::BothImplementations { controller } => Implementation::ALL
            .iter()
            .map(|&implementation| (controller, implementation))
            .collect(),
        BugSite::BothControllers { implementation } => {
            vec![(1, implementation), (2, implementation)]
        }
    }
}

fn already_buggy(state: &PairState, site: BugSite) -> bool {
    places(site)
        .iter()
        .all(|&(id, implementation)| state.controller(id).buggy[implementation.index()])
}

/// A crashed or FAILED controller starts again between inputs.
fn may_restart(state: &PairState, c: &PairController) -> bool {
    state.input_fresh() && (c.life == Life::Down || c.phase == Phase::Failed)
}

/// The state after `action`, or `None` when the action is not enabled.
pub fn next_state(config: &PairConfig, state: &PairState, action: PairAction) -> Option<PairState> {
    let mut next = *state;
    match action {
        PairAction::BugAppears { site } => {
            let allowed = state.input_fresh()
                && state.bugs < config.max_bugs
                && bug_sites(config, state).contains(&site);
            if !allowed {
                return None;
            }
            for (id, implementation) in places(site) {
                next.controller_mut(id).buggy[implementation.index()] = true;
            }
            next.bugs += 1;
        }
        PairAction::Answer { controller } => {
            let c = state.controller(controller);
            if !c.in_service() || c.answer != Answer::Pending {
                return None;
            }
            answer(config, &mut next, controller);
        }
        PairAction::Crash { controller } => {
            if !state.controller(controller).in_service() || state.crashes >= config.max_crashes {
                return None;
            }
            crash(&mut next, controller);
        }
        PairAction::Restart { controller } => {
            if !may_restart(state, state.controller(controller)) {
                return None;
            }
            restart(&mut next, controller);
        }
        PairAction::NextInput { triggers } => {
            if !state.input_answered() || !trigger_choices(config).contains(&triggers) {
                return None;
            }
            close_input(&mut next);
            open_input(&mut next, triggers);
        }
    }
    if next.failures_present() >= 2 {
        next.double_failure = true;
    }
    Some(next)
}

/// A controller answers the input: both implementations compute; it compares them and writes
/// the first's output only if they agree, and otherwise leaves at once, writing nothing
/// (mutation `WriteBeforeCompare`: it writes first and compares after).
fn answer(config: &PairConfig, state: &mut PairState, id: Id) {
    let triggers = state.triggers;
    let c = state.controller(id);
    let outputs = Implementation::ALL.map(|implementation| {
        if c.buggy[implementation.index()] && triggers {
            Output::Wrong
        } else {
            Output::Right
        }
    });
    let agree = outputs[0] == outputs[1];
    let write_first = config.mutation == Some(ArchitectureMutation::WriteBeforeCompare);
    if agree || write_first {
        state.samples[usize::from(id) - 1] = Some(outputs[0]);
        state.controller_mut(id).answer = Answer::Wrote;
    }
    if !agree {
        leave(state, id);
    }
}

/// A mismatch: the controller writes nothing more, goes FAILED with its local-fault alarm up
/// and exits to be restarted.
fn leave(state: &mut PairState, id: Id) {
    let c = state.controller_mut(id);
    c.phase = Phase::Failed;
    c.answer = Answer::Left;
    c.loss_alarm = false;
}

/// A crash: a sample it already wrote stays with the actuator; one it did not write is
/// missing.
fn crash(state: &mut PairState, id: Id) {
    let c = state.controller_mut(id);
    c.life = Life::Down;
    c.loss_alarm = false;
    c.judged_last = false;
    if c.answer == Answer::Pending {
        c.answer = Answer::Absent;
    }
    state.crashes += 1;
}

/// A restart, between inputs: in service again with its code, and so its bugs.
fn restart(state: &mut PairState, id: Id) {
    let c = state.controller_mut(id);
    *c = PairController {
        life: Life::Up,
        phase: Phase::Steady,
        answer: Answer::Pending,
        loss_alarm: false,
        restarted: true,
        judged_last: false,
        ..*c
    };
}

/// The current input closes: each controller in service raises its alarm if its partner
/// wrote nothing for it (the heartbeat deadline, one input), and clears it otherwise.
fn close_input(state: &mut PairState) {
    state.closed_without_right = !state.samples.contains(&Some(Output::Right));
    let missed = state.samples.map(|sample| sample.is_none());
    for (index, c) in state.controllers.iter_mut().enumerate() {
        c.missed_last = missed[index];
        c.judged_last = c.in_service();
        if c.in_service() {
            c.loss_alarm = missed[1 - index];
        }
    }
}

/// The next input opens: every controller in service owes it an answer.
fn open_input(state: &mut PairState, triggers: bool) {
    state.triggers = triggers;
    state.samples = [None; 2];
    for c in state.controllers.iter_mut() {
        c.answer = if c.in_service() {
            Answer::Pending
        } else {
            Answer::Absent
        };
    }
}
