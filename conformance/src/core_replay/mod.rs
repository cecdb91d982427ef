//! Core-level replay: a model trace driven through real `rl_layer::core::Core` instances.
//!
//! [`network::CoreNetwork`] is a simulated clock and network around one `Core` per running controller.
//! Time is in milliseconds, one round of the model is one heartbeat period
//! ([`PERIOD_MS`]): round `r` spans `[r * 250, (r + 1) * 250)`, and the cores share these
//! boundaries as controllers with agreeing clocks do (impl/core/src/lib.rs). Each model action
//! becomes core inputs:
//!
//! - `Tick`: every live core fires its timers up to its heartbeat send slot (boundary + 62 ms)
//!   and publishes its heartbeat (a core started this round published one at its start; the
//!   latest one counts); each heartbeat is delivered (boundary + 125 ms) to every other live
//!   core unless the trace lost that link this round; then every live core fires its
//!   round-end timer at the next boundary.
//! - `LoseHeartbeat { from, to }`: that link drops this round's heartbeat.
//! - `ExpireWindow { controller }`: the core fires its window timer, which must be due at the
//!   round boundary.
//! - `Crash { controller }`: the core is dropped.
//! - `Restart` / `Join { controller }`: a new core whose incarnation is the model's number
//!   starts at boundary + 10 ms, before the send slot, so its heartbeat is delivered at this
//!   round's end and it hears this round's heartbeats, as in the model.
//! - `Pause { controller }`: the core is not stepped and its heartbeats are not sent;
//!   at `Resume` the stopped core is told `Input::StartAgain` with the next incarnation, as
//!   the runtime does when it finds its loop stalled for a peer deadline
//!   (impl/layer/src/stall.rs).
//! - `Isolate` / `Heal { controller }`: every heartbeat to and from it is lost until healed.
//!   `Unplug` cuts it off from the actuator too and tells the core `Input::StartAgain` with
//!   the next incarnation, as the runtime does when every link loses its carrier
//!   (impl/layer/src/link_watch.rs).
//! - `Starve { controller }`: every live core learns that its commands arrive late, then
//!   every other live peer's on time (`Input::Commands`, what the runtime measures,
//!   impl/layer/src/runtime/arrival.rs); a takeover's writer is one every reader knows already.
//!   `Lag` / `CatchUp`: the actuator stops and starts counting its writers. A core that says
//!   `StartAgain` (deposed) is told `Input::StartAgain` with the next incarnation at the
//!   round's end, as the runtime does.
//! - `DiscoverWriter` / `TieBreak`: the actuator's events. The network runs the model's
//!   actuator rule (`model::protocol::actuator::next_owner`) over the cores' writers (the
//!   newest one once discovered, the retiring one for the round of a raise), so the owner
//!   compared is the one DDS would give the cores' strengths.
//! - `DeliverVotes`: paper variant only; not replayed.
//!
//! A crash, restart or join also forgets the round's lost links of that controller, as the
//! model does. After every step the abstracted core states ([`crate::abstraction`]) must
//! equal the trace's state, and each live core's commands must agree with its change
//! ([`commands`]). The first difference is a [`Failure`], whose `Display` is the readable
//! diff; the replay goes on after a difference where it can, so the transcript
//! ([`transcript`]) records what the core did to the end: a changed core changes its
//! transcript even where the state check alone would stop at the first step.
//!
//! Modules: [`network`] (the simulated clock and network), [`commands`] (command checks),
//! [`transcript`] (the golden transcripts), [`coverage`] (transition coverage from the cores'
//! own states).

pub mod commands;
pub mod coverage;
pub mod network;
pub mod transcript;

pub use network::{Configure, CoreNetwork};

use crate::abstraction::UnknownIncarnation;
use crate::diff::state_diff;
use crate::trace::Trace;
use coverage::CoverageClass;
use model::traces::AbstractState;
use model::{Action, Variant};
use std::collections::BTreeSet;
use std::fmt;

/// One model round: one heartbeat period.
pub const PERIOD_MS: u64 = 250;
/// A started or restarted core starts this long after the round boundary.
pub const START_OFFSET_MS: u64 = 10;
/// Heartbeats of a round arrive this long after its boundary (after every send slot).
pub const DELIVERY_OFFSET_MS: u64 = 125;

/// Why a trace is not replayed at the core level, if it is not.
pub fn skip_reason(trace: &Trace) -> Option<String> {
    if trace.variant() == Variant::Paper {
        return Some(
            "paper variant: a counterexample of the paper's literal rules, which RL corrects \
             (docs/findings.md); the core follows the default rules"
                .to_string(),
        );
    }
    if let Some(mutation) = trace.config.mutation {
        return Some(format!("generated with the model mutation {mutation:?}"));
    }
    None
}

/// What a replay did: its transcript, what it covered and its first failure, if any.
#[derive(Clone, Debug)]
pub struct Replayed {
    pub file: String,
    /// The readable transcript of what the cores did (the snapshot).
    pub transcript: String,
    /// (action kind x stage of the acting controller) pairs its steps exercised, from the
    /// cores' own states before each step.
    pub covered: BTreeSet<CoverageClass>,
    /// Steps replayed.
    pub steps: usize,
    /// The first difference from the model.
    pub failure: Option<Failure>,
}

/// Replays one default-variant trace against real cores; `Err` on the first difference.
pub fn replay(trace: &Trace) -> Result<Replayed, Failure> {
    let mut replayed = replay_with(trace, &|config| config);
    match replayed.failure.take() {
        Some(failure) => Err(failure),
        None => Ok(replayed),
    }
}

/// Replays one trace against cores whose configuration `configure` adjusts (the mutation
/// check configures a deliberately broken rule), to the end where it can.
pub fn replay_with(trace: &Trace, configure: &Configure) -> Replayed {
    let mut run = Replayed {
        file: trace.file.clone(),
        transcript: transcript::header(trace),
        covered: BTreeSet::new(),
        steps: 0,
        failure: None,
    };
    if let Some(reason) = skip_reason(trace) {
        run.fail(trace, 0, Problem::Unsupported(reason));
        return run;
    }
    let mut network = match CoreNetwork::start(&trace.config, &trace.initial, configure) {
        Ok(network) => network,
        Err(problem) => {
            run.stop(trace, 0, problem);
            return run;
        }
    };
    let mut observed = match network.observe() {
        Ok(observed) => observed,
        Err(problem) => {
            run.stop(trace, 0, problem);
            return run;
        }
    };
    transcript::push_state(&mut run.transcript, "initial", &observed);
    run.check_state(trace, 0, &trace.initial, &observed);
    for (index, step) in trace.steps.iter().enumerate() {
        run.covered
            .extend(coverage::classes(&observed, &step.action));
        let after = network
            .apply(step.action)
            .and_then(|log| network.observe().map(|state| (log, state)));
        let (log, state) = match after {
            Ok(done) => done,
            Err(problem) => {
                run.stop(trace, step.number, problem);
                return run;
            }
        };
        run.steps += 1;
        let title = format!("step {}: {}", step.number, step.action);
        transcript::push_step(&mut run.transcript, &title, &log, &state, &network.numbers);
        run.check_state(trace, step.number, &step.state, &state);
        let before = trace.state_before(index);
        match commands::command_problems(before, &step.state, &log, &network.numbers) {
            Ok(problems) if problems.is_empty() => {}
            Ok(problems) => run.fail(trace, step.number, Problem::Commands(problems)),
            Err(error) => run.fail(trace, step.number, Problem::Abstraction(error)),
        }
        observed = state;
    }
    run
}

impl Replayed {
    /// Keeps the first failure only: what follows it is a consequence.
    fn fail(&mut self, trace: &Trace, step: usize, problem: Problem) {
        if self.failure.is_none() {
            self.failure = Some(Failure::new(trace, step, problem));
        }
    }

    /// The replay cannot go on: say so in the transcript too.
    fn stop(&mut self, trace: &Trace, step: usize, problem: Problem) {
        let failure = Failure::new(trace, step, problem);
        self.transcript
            .push_str(&format!("\nreplay stopped at step {step}:\n{failure}"));
        if self.failure.is_none() {
            self.failure = Some(failure);
        }
    }

    fn check_state(
        &mut self,
        trace: &Trace,
        step: usize,
        expected: &AbstractState,
        observed: &AbstractState,
    ) {
        if expected != observed {
            let problem = Problem::State {
                expected: expected.clone(),
                observed: observed.clone(),
            };
            self.fail(trace, step, problem);
        }
    }
}

/// What went wrong at a step.
#[derive(Clone, Debug)]
pub enum Problem {
    /// The abstracted cores differ from the trace's state.
    State {
        expected: AbstractState,
        observed: AbstractState,
    },
    /// The commands disagree with the state change (one line per disagreement).
    Commands(Vec<String>),
    /// A timer was not due when the model's action says it fires (or was due when the model
    /// says it is not).
    Timing(String),
    /// The abstraction could not map the cores' state.
    Abstraction(UnknownIncarnation),
    /// The trace uses something the core-level replay does not map.
    Unsupported(String),
}

/// A trace that does not conform: where, and the readable difference.
#[derive(Clone, Debug)]
pub struct Failure {
    pub file: String,
    pub purpose: String,
    /// The step (1-based); 0 = the initial state.
    pub step: usize,
    pub steps_total: usize,
    pub action: Option<Action>,
    /// The actions before it, for reproducing by hand.
    pub earlier_actions: Vec<Action>,
    pub problem: Box<Problem>,
}

impl Failure {
    fn new(trace: &Trace, step: usize, problem: Problem) -> Failure {
        let index = step.checked_sub(1);
        Failure {
            file: trace.file.clone(),
            purpose: trace.purpose.clone(),
            step,
            steps_total: trace.steps.len(),
            action: index.and_then(|i| trace.steps.get(i)).map(|s| s.action),
            earlier_actions: trace
                .steps
                .iter()
                .take(index.unwrap_or(0))
                .map(|s| s.action)
                .collect(),
            problem: Box::new(problem),
        }
    }
}

impl fmt::Display for Failure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.action {
            Some(action) => writeln!(
                f,
                "traces/{}, step {} of {}: {action}",
                self.file, self.step, self.steps_total
            )?,
            None => writeln!(f, "traces/{}, initial state", self.file)?,
        }
        writeln!(f, "  trace purpose: {}", self.purpose)?;
        if !self.earlier_actions.is_empty() {
            let list: Vec<String> = self
                .earlier_actions
                .iter()
                .enumerate()
                .map(|(i, a)| format!("{}. {a}", i + 1))
                .collect();
            writeln!(f, "  after: {}", list.join("; "))?;
        }
        match self.problem.as_ref() {
            Problem::State { expected, observed } => {
                f.write_str(&state_diff("core", "the core's", expected, observed))
            }
            Problem::Commands(lines) => {
                writeln!(f, "  the commands disagree with the state change:")?;
                for line in lines {
                    writeln!(f, "    {line}")?;
                }
                Ok(())
            }
            Problem::Timing(message) => writeln!(f, "  timing: {message}"),
            Problem::Abstraction(error) => writeln!(f, "  abstraction: {error}"),
            Problem::Unsupported(message) => writeln!(f, "  not replayable: {message}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::commands::command_problems;
    use super::network::{Cause, Emitted, StepLog};
    use super::*;
    use crate::abstraction::IncarnationNumbers;
    use model::traces::AbstractController;
    use model::Life;
    use rl_layer::core::Strength;
    use rl_layer::core::{AlarmReason, Command, Role};

    fn controller(id: u8) -> AbstractController {
        AbstractController {
            id,
            life: Life::Up,
            incarnation: 0,
            phase: Some(model::Phase::Steady),
            role: Some(model::Role::Secondary),
            strength: Some(20),
            sees: vec![1, 3],
            failed: vec![],
            alarms: vec![],
            agreed: None,
            vote: None,
        }
    }

    fn state(c: AbstractController) -> AbstractState {
        AbstractState {
            controllers: vec![controller(1), c],
            actuator_owner: Some(1),
        }
    }

    fn problems(
        before: AbstractController,
        after: AbstractController,
        emitted: Vec<Command>,
    ) -> Vec<String> {
        let log: StepLog = [(
            2,
            vec![Emitted {
                cause: Cause::Timer(rl_layer::core::Timer::RoundEnd),
                commands: emitted,
            }],
        )]
        .into_iter()
        .collect();
        command_problems(
            &state(before),
            &state(after),
            &log,
            &IncarnationNumbers::new(),
        )
        .expect("no holders to number")
    }

    #[test]
    fn a_role_change_needs_its_set_output_and_nothing_else_does() {
        let before = controller(2);
        let promoted = AbstractController {
            role: Some(model::Role::Primary),
            strength: Some(30),
            ..controller(2)
        };
        let set_output = Command::SetOutput {
            role: Some(Role::Primary),
            strength: Some(Strength(30)),
        };
        assert_eq!(
            problems(before.clone(), promoted.clone(), vec![set_output.clone()]),
            Vec::<String>::new()
        );
        assert_eq!(
            problems(before.clone(), promoted, vec![]),
            vec!["C2: role/strength changed (secondary 20 -> primary 30) but no SetOutput was emitted"]
        );
        assert_eq!(
            problems(before.clone(), before, vec![set_output]),
            vec!["C2: SetOutput { primary, 30 } emitted but role/strength did not change"]
        );
    }

    #[test]
    fn alarms_raised_and_cleared_must_match_the_alarm_set() {
        let before = AbstractController {
            alarms: vec![3],
            ..controller(2)
        };
        let after = AbstractController {
            alarms: vec![1],
            ..controller(2)
        };
        let raise = Command::RaiseAlarm {
            about: 1,
            reason: AlarmReason::Lost,
        };
        let clear = Command::ClearAlarm {
            about: 3,
            reason: AlarmReason::Lost,
        };
        assert!(problems(before.clone(), after.clone(), vec![raise.clone(), clear]).is_empty());
        assert_eq!(
            problems(before, after, vec![raise]),
            vec!["C2: alarms cleared for {} but the alarms removed are {3}"]
        );
    }

    #[test]
    fn a_window_that_is_not_due_cannot_expire() {
        let config = model::Config::default();
        let initial = AbstractState {
            controllers: vec![AbstractController {
                phase: Some(model::Phase::Initializing),
                role: None,
                strength: None,
                sees: vec![],
                ..controller(1)
            }],
            actuator_owner: None,
        };
        let mut network = CoreNetwork::start(&config, &initial, &|c| c).expect("one controller");
        assert_eq!(network.observe().expect("known lives"), initial);
        match network.apply(Action::ExpireWindow { controller: 1 }) {
            Err(Problem::Timing(message)) => {
                assert!(message.contains("window is not due"), "{message}")
            }
            other => panic!("expected a timing failure, got {other:?}"),
        }
    }
}
