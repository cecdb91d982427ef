//! Applying a round's faults to the attempt's processes and the LAN: on time or not at all
//! (`Run::apply_on_time`), crashes, starts, pauses and resumes, cuts and heals, and the
//! heartbeat-drop control. Kept apart from the observation side of [`super`].

use super::super::config::{APPLY_LATEST_MS, APPLY_OFFSET_MS, STALL_MARGIN_MS};
use super::super::error::{Failure, Problem};
use super::super::lives::{self, Life};
use super::super::plan::RoundPlan;
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
                Action::Crash { controller } => self.kill(controller, real)?,
                Action::Join { controller } | Action::Restart { controller } => {
                    self.spawn(controller, real)?;
                }
                Action::Pause { controller } => self.pause(controller, true, real)?,
                Action::Resume { controller } => self.pause(controller, false, real)?,
                Action::Isolate { .. } | Action::Unplug { .. } | Action::Heal { .. } => {
                    self.cut(*action)?;
                }
                _ => {}
            }
        }
        self.control_drops(round, real)
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

    /// SIGSTOP (`stop`) or SIGCONT in real round `real`. The model's resume stands for a
    /// stall of at least a peer deadline, which is what the runtime restarts after
    /// (impl/layer/src/stall.rs), so SIGCONT waits until the process has stood still that long.
    fn pause(&mut self, id: ControllerId, stop: bool, real: u64) -> Result<(), Failure> {
        let stall_ms = self.period_ms() * u64::from(self.timing.rounds.dead_after_rounds);
        let stopped_ms = lives::current_mut(&mut self.lives, id).and_then(|l| l.paused_wall_ms);
        if let (false, Some(stopped_ms)) = (stop, stopped_ms) {
            self.sleep_until(stopped_ms + stall_ms + STALL_MARGIN_MS);
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

    pub(super) fn spawn(&mut self, id: ControllerId, real: u64) -> Result<(), Failure> {
        let life = Life::new(id, lives::lives_of(&self.lives, id), real, wall_ms());
        if let Err(source) = self.processes.start_controller(id, &life.log.source) {
            let what = format!("rl controller --id {id}");
            return Err(self.failure(false, Problem::Spawn { what, source }));
        }
        self.lives.push(life);
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
