//! Applying a round's faults to the attempt's processes and the LAN: on time or not at all
//! (`Run::apply_on_time`), crashes, held processes let go, pauses and resumes, starved
//! links (a controller's commands late or held back, its stdin control), cuts and heals, and the
//! heartbeat-drop control. Kept apart from the observation side of [`super`].

use super::super::config::{
    APPLY_LATEST_MS, APPLY_OFFSET_MS, LAG_AFTER_TAKEOVER_MS, LET_GO_OFFSET_MS, STALL_MARGIN_MS,
    STARVED_DELAY_MS, STARVE_ONSET_MS,
};
use super::super::error::{Failure, Problem};
use super::super::lives::{self, Life};
use super::super::plan::RoundPlan;
use super::super::processes::START_VOTING;
use super::Run;
use model::Action;
use rl::procs::wall_ms;
use rl_layer::core::ControllerId;
use std::collections::BTreeSet;
use std::fmt::Write as _;

impl Run<'_> {
    /// Round `k`'s faults, at the start of real round `real`: on time or not at all. Its
    /// losses must each show a logged drop.
    pub fn apply_on_time(&mut self, k: usize, round: &RoundPlan, real: u64) -> Result<(), Failure> {
        let boundary_ms = real * self.period_ms();
        self.sleep_until(boundary_ms + APPLY_OFFSET_MS);
        let late_ms = wall_ms().saturating_sub(boundary_ms);
        if late_ms > APPLY_LATEST_MS && !round.is_empty() {
            return Err(self.failure(true, Problem::HarnessLate { real, late_ms }));
        }
        self.drops.require(k, real, &round.lost);
        self.apply(round, real)?;
        // A pause or a cut must be in force before the round's heartbeats go out.
        let done_ms = wall_ms().saturating_sub(boundary_ms);
        let heartbeats_ms = self.period_ms() / 4;
        let interrupts = round.lifecycle.iter().any(|a| {
            !matches!(
                a,
                Action::Crash { .. } | Action::Join { .. } | Action::Restart { .. }
            )
        });
        if interrupts && done_ms >= heartbeats_ms {
            let problem = Problem::HarnessLate {
                real,
                late_ms: done_ms,
            };
            return Err(self.failure(true, problem));
        }
        self.after_takeover(round, real)?;
        self.resume_within_round(round, real)
    }

    /// The starved links of the round after real round `real` begin, at [`STARVE_ONSET_MS`]
    /// into it (applying that round finds them in place).
    pub fn starve_ahead(&mut self, next: &RoundPlan, real: u64) -> Result<(), Failure> {
        let starving: Vec<ControllerId> = next
            .lifecycle
            .iter()
            .filter_map(|a| match *a {
                Action::Starve { controller } => Some(controller),
                _ => None,
            })
            .collect();
        if starving.is_empty() {
            return Ok(());
        }
        self.sleep_until(real * self.period_ms() + STARVE_ONSET_MS);
        for controller in starving {
            self.command_link(controller, Some(STARVED_DELAY_MS), real)?;
        }
        Ok(())
    }

    /// What changes a starved link in the round a peer takes over from it (a missed
    /// deadline, a late sample, a heal), in order: in the model the takeover comes with the
    /// starved link, so the late commands it is measured on go out first, and these follow
    /// from [`LAG_AFTER_TAKEOVER_MS`] into the round (the takeover writer owns the actuator
    /// then, whatever the starved one's deadline).
    fn after_takeover(&mut self, round: &RoundPlan, real: u64) -> Result<(), Failure> {
        let waiting: Vec<Action> = round
            .lifecycle
            .iter()
            .copied()
            .filter(|a| round.waits_for_takeover(*a))
            .collect();
        if waiting.is_empty() {
            return Ok(());
        }
        self.sleep_until(real * self.period_ms() + LAG_AFTER_TAKEOVER_MS);
        for action in waiting {
            match action {
                Action::Lag { controller } => self.command_link(controller, None, real)?,
                Action::CatchUp { controller } => {
                    self.command_link(controller, Some(STARVED_DELAY_MS), real)?;
                }
                Action::Heal { controller } => self.command_link(controller, Some(0), real)?,
                _ => {}
            }
        }
        Ok(())
    }

    /// Whether some process still drops heartbeats.
    pub fn dropping(&self) -> bool {
        self.lives
            .iter()
            .any(|l| l.is_running() && !l.dropping.is_empty())
    }

    /// Starts, kills, stops, continues and cuts off processes, and sets every live process's
    /// dropped peers to the round's losses.
    pub(super) fn apply(&mut self, round: &RoundPlan, real: u64) -> Result<(), Failure> {
        self.check_exits(real)?;
        // Signals first: they take microseconds, a cut's tables milliseconds, and the stall
        // a pause stands for must begin as early in its round as it can.
        let (signals, others): (Vec<Action>, Vec<Action>) = round
            .lifecycle
            .iter()
            .copied()
            .partition(|a| matches!(a, Action::Pause { .. } | Action::Resume { .. }));
        for action in signals.iter().chain(&in_force_at_round_end(&others)) {
            match *action {
                _ if round.resumes_within(*action) => {}
                Action::Crash { controller } => self.kill(controller, real)?,
                Action::Join { controller } | Action::Restart { controller } => {
                    self.admit(controller, real)?;
                }
                Action::Pause { controller } => self.pause(controller, true, real)?,
                Action::Resume { controller } => self.pause(controller, false, real)?,
                Action::Starve { controller } if self.starved.contains_key(&controller) => {}
                Action::Starve { controller } | Action::CatchUp { controller } => {
                    self.command_link(controller, Some(STARVED_DELAY_MS), real)?;
                }
                _ if round.waits_for_takeover(*action) => {}
                Action::Lag { controller } => self.command_link(controller, None, real)?,
                Action::Heal { controller } if self.starved.contains_key(&controller) => {
                    self.command_link(controller, Some(0), real)?;
                }
                Action::Isolate { .. } | Action::Unplug { .. } | Action::Heal { .. } => {
                    self.cut(*action)?;
                }
                _ => {}
            }
        }
        // The drops first: a held process obeys them, and they must be in force before the
        // round's heartbeats arrive.
        self.control_drops(round, real)?;
        self.let_go(real)
    }

    /// How controller `id`'s commands go out (its stdin control), a starved link's effect on
    /// them: late by `Some(ms)` (`Some(0)`: on time again, the link healed), or none at all
    /// (`None`: the readers miss the deadline). Kept for a later process of the same id, whose
    /// link is the same.
    fn command_link(
        &mut self,
        id: ControllerId,
        delay_ms: Option<u64>,
        real: u64,
    ) -> Result<(), Failure> {
        let line = match delay_ms {
            Some(0) => {
                self.starved.remove(&id);
                "delay-commands 0\n".to_string()
            }
            Some(ms) => format!("delay-commands {ms}\n"),
            None => "hold-commands\n".to_string(),
        };
        if delay_ms != Some(0) {
            self.starved.insert(id, line.clone());
        }
        let Some(life) = lives::current_mut(&mut self.lives, id).filter(|l| l.is_running()) else {
            return Ok(());
        };
        let source_name = life.log.source.clone();
        self.control(&source_name, &line, real)
    }

    /// Writes `line` to a process's stdin control.
    fn control(&mut self, source_name: &str, line: &str, real: u64) -> Result<(), Failure> {
        if let Err(source) = self.processes.send(source_name, line) {
            self.check_exits(real)?;
            let source_name = source_name.to_string();
            return Err(self.failure(
                false,
                Problem::Control {
                    source_name,
                    source,
                },
            ));
        }
        Ok(())
    }

    /// A cut, pulled cables or a heal on the virtual LAN.
    fn cut(&mut self, action: Action) -> Result<(), Failure> {
        let result = match self.cuts.as_mut() {
            Some(cuts) => cuts.apply(action),
            None => Err(format!("{action}: the run has no virtual LAN")),
        };
        result.map_err(|why| self.failure(false, Problem::Cut { action, why }))
    }

    /// Sets every live process's dropped peers to the round's losses (its stdin control).
    fn control_drops(&mut self, round: &RoundPlan, real: u64) -> Result<(), Failure> {
        for index in 0..self.lives.len() {
            let life = &self.lives[index];
            if !life.is_running() {
                continue;
            }
            let id = life.log.id;
            let wanted: BTreeSet<ControllerId> = round
                .lost
                .iter()
                .filter(|(_, to)| *to == id)
                .map(|(from, _)| *from)
                .collect();
            let mut commands = String::new();
            for from in wanted.difference(&life.dropping) {
                let _ = writeln!(commands, "drop-heartbeats-from {from}");
            }
            for from in life.dropping.difference(&wanted) {
                let _ = writeln!(commands, "accept-heartbeats-from {from}");
            }
            if commands.is_empty() {
                continue;
            }
            let source_name = life.log.source.clone();
            if let Err(source) = self.processes.send(&source_name, &commands) {
                self.check_exits(real)?;
                return Err(self.failure(
                    false,
                    Problem::Control {
                        source_name,
                        source,
                    },
                ));
            }
            self.drops.written(&source_name, wall_ms(), &wanted);
            self.lives[index].dropping = wanted;
        }
        Ok(())
    }

    /// SIGSTOP (`stop`) or SIGCONT in real round `real`. The model's resume starts a new
    /// incarnation (F12), which the runtime does after a stall of a peer deadline, or after a
    /// stop of a command deadline that it is continued from (impl/layer/src/stall.rs). So
    /// SIGCONT waits until the process has stood still that long: a peer deadline where the
    /// trace kept it paused across `dead_after` round ends (its peers lose it, as in the
    /// model), else the command deadline and a margin (`RunTiming::stop_noticed_ms`).
    fn pause(&mut self, id: ControllerId, stop: bool, real: u64) -> Result<(), Failure> {
        let dead_after_rounds = u64::from(self.timing.rounds.dead_after_rounds);
        let stall_ms = self.period_ms() * dead_after_rounds;
        let stopped = lives::current_mut(&mut self.lives, id)
            .and_then(|l| l.paused_wall_ms.zip(l.paused_round));
        if let (false, Some((stopped_ms, paused_round))) = (stop, stopped) {
            let still_ms = if real.saturating_sub(paused_round) >= dead_after_rounds {
                stall_ms + STALL_MARGIN_MS
            } else {
                self.timing.stop_noticed_ms
            };
            self.sleep_until(stopped_ms + still_ms);
        }
        let Some(life) = lives::current_mut(&mut self.lives, id) else {
            return Ok(());
        };
        let signal = if stop {
            life.paused_round = Some(real);
            life.resumed_round = None;
            life.paused_wall_ms = Some(wall_ms());
            libc::SIGSTOP
        } else {
            life.resumed_round = Some(real);
            libc::SIGCONT
        };
        let source_name = life.log.source.clone();
        if let Err(source) = self.processes.signal(&source_name, signal) {
            return Err(self.failure(false, Problem::Signal { id, signal, source }));
        }
        Ok(())
    }

    /// The round's resumes of controllers it paused (`RoundPlan::resumes_within`), after its
    /// other faults: each waits for a command deadline of the stop.
    pub(super) fn resume_within_round(
        &mut self,
        round: &RoundPlan,
        real: u64,
    ) -> Result<(), Failure> {
        for action in &round.lifecycle {
            if let (true, Action::Resume { controller }) = (round.resumes_within(*action), action) {
                self.pause(*controller, false, real)?;
            }
        }
        Ok(())
    }

    fn kill(&mut self, id: ControllerId, real: u64) -> Result<(), Failure> {
        let Some(life) = lives::current_mut(&mut self.lives, id) else {
            return Ok(());
        };
        life.killed_round = Some(real);
        let source_name = life.log.source.clone();
        if let Err(source) = self.processes.kill(&source_name) {
            return Err(self.failure(false, Problem::Kill { id, source }));
        }
        Ok(())
    }

    /// Starts a life for the next held process of `id` in real round `real` (a start, join
    /// or restart), to be let go at the round's [`LET_GO_OFFSET_MS`].
    pub(super) fn admit(&mut self, id: ControllerId, real: u64) -> Result<(), Failure> {
        let Some(index) = self.held.iter().position(|h| h.id == id) else {
            let what = format!("rl controller --id {id} (no held process left)");
            let source = std::io::Error::other("the plan starts more processes than it held");
            return Err(self.failure(false, Problem::Spawn { what, source }));
        };
        let held = self.held.remove(index);
        // A starved link is the controller's: a new process of it has it too.
        if let Some(line) = self.starved.get(&id).cloned() {
            self.control(&held.source, &line, real)?;
        }
        self.lives.push(Life::new(id, held.number, real, wall_ms()));
        self.letting_go.push(held.source);
        Ok(())
    }

    /// Lets one held process go now.
    pub(super) fn let_go_now(&mut self, source_name: &str, real: u64) -> Result<(), Failure> {
        self.control(source_name, START_VOTING, real)
    }

    /// Lets the processes admitted in real round `real` go, just before the round's
    /// heartbeats: a controller's first heartbeat goes out at once, and a peer with no
    /// Primary to follow takes its round phase from it (rl-core's `phase`), so it must go out
    /// on the round's phase.
    fn let_go(&mut self, real: u64) -> Result<(), Failure> {
        if self.letting_go.is_empty() {
            return Ok(());
        }
        self.sleep_until(real * self.period_ms() + LET_GO_OFFSET_MS);
        for source_name in std::mem::take(&mut self.letting_go) {
            // Restarted and crashed in the same round: it never votes.
            let killed = lives::of_process_mut(&mut self.lives, &source_name)
                .is_some_and(|l| l.killed_round.is_some());
            if !killed {
                self.let_go_now(&source_name, real)?;
            }
        }
        let late_ms = wall_ms().saturating_sub(real * self.period_ms());
        if late_ms >= self.period_ms() / 4 {
            return Err(self.failure(true, Problem::HarnessLate { real, late_ms }));
        }
        Ok(())
    }
}

/// The round's actions without a cut healed in the same round: the round's heartbeats go out
/// after all of them, so a cut with no round end in it drops nothing, and leaving it out
/// spares two nftables changes in the quarter period before they go out. A pulled cable
/// healed at once stays: its carrier still went (F16).
fn in_force_at_round_end(actions: &[Action]) -> Vec<Action> {
    let mut out: Vec<Action> = Vec::new();
    for action in actions {
        if let Action::Heal { controller } = *action {
            let cut = out
                .iter()
                .rposition(|a| *a == Action::Isolate { controller });
            if let Some(index) = cut {
                out.remove(index);
                continue;
            }
        }
        out.push(*action);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cut_healed_in_its_own_round_is_left_out_and_a_pulled_cable_is_not() {
        let isolate = Action::Isolate { controller: 2 };
        let heal = Action::Heal { controller: 2 };
        let unplug = Action::Unplug { controller: 2 };
        let pause = Action::Pause { controller: 2 };
        assert_eq!(in_force_at_round_end(&[isolate, heal, pause]), vec![pause]);
        assert_eq!(in_force_at_round_end(&[unplug, heal]), vec![unplug, heal]);
        assert_eq!(in_force_at_round_end(&[heal, isolate]), vec![heal, isolate]);
    }
}
