//! Injected heartbeat losses, checked against the drops the controllers log: every loss the
//! model's steps need must be a logged drop, and every logged drop an injected loss.
//!
//! The `fault-injection` build logs each heartbeat its control drops (`heartbeat_dropped`,
//! from whom). Two checks, on rounds that are over:
//!
//! - **required**: in a lockstep round, each `(from, to)` the plan loses must show a drop of
//!   `from`'s heartbeat logged by `to` in that real round. Otherwise the heartbeat did not
//!   arrive at all (a real loss: on loopback, a defect) or the control came too late. Links
//!   not yet discovered are exempt: `to` must have reported `from` in `sees` since `from`'s
//!   life began (for a restarted `from`, a dead-man deadline or more after, so the old life's
//!   view does not count), else its heartbeats may simply not reach `to` yet (DDS discovery,
//!   which the plan's checks cover).
//! - **planned**: each logged drop must fall where the control had `to` drop `from` (the set
//!   written last before the drop's time, per process).

use super::config::APPLY_OFFSET_MS;
use super::error::Problem;
use super::lives::Life;
use crate::record::round_of;
use rl_layer::core::ControllerId;
use rl_layer::event::Event;
use std::collections::BTreeSet;

/// What the control told one process to drop, from when.
#[derive(Clone, Debug)]
struct Written {
    source: String,
    wall_ms: u64,
    dropping: BTreeSet<ControllerId>,
}

/// A lockstep round whose losses must each show a logged drop.
#[derive(Clone, Debug)]
struct Required {
    real: u64,
    round: usize,
    lost: BTreeSet<(ControllerId, ControllerId)>,
}

/// The injected losses of one attempt and how far they were checked.
#[derive(Clone, Debug, Default)]
pub struct DropBook {
    written: Vec<Written>,
    required: Vec<Required>,
    /// Logged drops already checked, per life (index into the lives).
    checked_events: Vec<usize>,
}

impl DropBook {
    /// The control now has `source` drop the heartbeats of `dropping` (written at `wall_ms`).
    pub fn written(&mut self, source: &str, wall_ms: u64, dropping: &BTreeSet<ControllerId>) {
        self.written.push(Written {
            source: source.to_string(),
            wall_ms,
            dropping: dropping.clone(),
        });
    }

    /// Plan round `round`, carried out in real round `real`, loses `lost`.
    pub fn require(
        &mut self,
        round: usize,
        real: u64,
        lost: &BTreeSet<(ControllerId, ControllerId)>,
    ) {
        if !lost.is_empty() {
            self.required.push(Required {
                real,
                round,
                lost: lost.clone(),
            });
        }
    }

    /// Whether the control had `source` drop `from` at `t_ms`.
    fn planned(&self, source: &str, from: ControllerId, t_ms: u64) -> bool {
        self.written
            .iter()
            .rev()
            .find(|w| w.source == source && w.wall_ms <= t_ms)
            .is_some_and(|w| w.dropping.contains(&from))
    }

    /// Checks every logged drop not yet checked, and every required round before real round
    /// `before` (rounds that are over).
    pub fn check(
        &mut self,
        lives: &[Life],
        before: u64,
        period_ms: u64,
        dead_after_rounds: u64,
    ) -> Result<(), Problem> {
        self.checked_events.resize(lives.len(), 0);
        for (index, life) in lives.iter().enumerate() {
            let events = &life.log.events;
            for event in &events[self.checked_events[index]..] {
                if let Event::HeartbeatDropped { from } = event.event {
                    if !self.planned(&life.log.source, from, event.t_ms) {
                        return Err(Problem::DropUnplanned {
                            source_name: life.log.source.clone(),
                            from,
                            t_ms: event.t_ms,
                            real: drop_round(event.t_ms, period_ms),
                        });
                    }
                }
            }
            self.checked_events[index] = events.len();
        }
        let (due, later): (Vec<Required>, Vec<Required>) =
            self.required.drain(..).partition(|r| r.real < before);
        self.required = later;
        for required in due {
            for &(from, to) in &required.lost {
                let horizon_ms = dead_after_rounds * period_ms;
                if !discovered(lives, from, to, required.real, period_ms, horizon_ms) {
                    continue;
                }
                if !dropped_in(lives, from, to, required.real, period_ms) {
                    return Err(Problem::DropMissing {
                        round: required.round,
                        real: required.real,
                        from,
                        to,
                    });
                }
            }
        }
        Ok(())
    }
}

/// The life of `id` running through real round `real`.
fn life_in(lives: &[Life], id: ControllerId, real: u64) -> Option<&Life> {
    lives.iter().rev().find(|l| {
        l.log.id == id && l.spawned_round <= real && l.killed_round.is_none_or(|k| k > real)
    })
}

/// Whether `to`'s life reported `from` in `sees` by the boundary of real round `real` (its
/// reports there reflect the heartbeats of the round before), since `from`'s life started;
/// for a restarted `from`, only from a dead-man deadline (`horizon_ms`) after its start, when
/// the old life's view is gone.
fn discovered(
    lives: &[Life],
    from: ControllerId,
    to: ControllerId,
    real: u64,
    period_ms: u64,
    horizon_ms: u64,
) -> bool {
    let (Some(sender), Some(receiver)) = (life_in(lives, from, real), life_in(lives, to, real))
    else {
        return false;
    };
    let restarted = lives
        .iter()
        .any(|l| l.log.id == from && l.started_wall_ms < sender.started_wall_ms);
    let since_ms = sender.started_wall_ms + if restarted { horizon_ms } else { 0 };
    let until_ms = real * period_ms + APPLY_OFFSET_MS;
    receiver.log.events.iter().any(|e| {
        (since_ms..until_ms).contains(&e.t_ms) && e.status().is_some_and(|s| s.sees.contains(&from))
    })
}

/// The round a logged drop belongs to. A heartbeat taken at a boundary is stamped there but
/// belongs to the round that ends (the voting loop takes samples before it ends the round);
/// a round's own heartbeats go out a quarter period in, so a drop stamped in the first
/// [`APPLY_OFFSET_MS`] of a round is the round before's.
fn drop_round(t_ms: u64, period_ms: u64) -> u64 {
    round_of(t_ms.saturating_sub(APPLY_OFFSET_MS), period_ms)
}

/// Whether `to`'s life logged a drop of `from`'s heartbeat in real round `real`.
fn dropped_in(
    lives: &[Life],
    from: ControllerId,
    to: ControllerId,
    real: u64,
    period_ms: u64,
) -> bool {
    life_in(lives, to, real).is_some_and(|life| {
        life.log.events.iter().any(|e| {
            e.event == Event::HeartbeatDropped { from } && drop_round(e.t_ms, period_ms) == real
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rl_layer::core::Status;
    use rl_layer::event::EventLine;

    const PERIOD_MS: u64 = 250;

    fn event(life: &Life, t_ms: u64, event: Event) -> EventLine {
        EventLine {
            t_ms,
            id: life.log.id,
            incarnation: life.log.incarnation,
            event,
        }
    }

    /// C1 and C2 started in round 10; C2 reported C1 in its view at boundary 12.
    fn lives() -> Vec<Life> {
        let c1 = Life::new(1, 0, 10, 10 * PERIOD_MS + 10);
        let mut c2 = Life::new(2, 0, 10, 10 * PERIOD_MS + 10);
        let mut status = Status::initial(2, c2.log.incarnation);
        status.sees = vec![1];
        let seen = event(
            &c2,
            12 * PERIOD_MS + 1,
            Event::Status {
                status: Box::new(status),
            },
        );
        c2.log.events.push(seen);
        vec![c1, c2]
    }

    fn lost() -> BTreeSet<(ControllerId, ControllerId)> {
        BTreeSet::from([(1, 2)])
    }

    #[test]
    fn a_required_loss_needs_a_logged_drop_in_its_round() {
        let mut lives = lives();
        let mut book = DropBook::default();
        book.written("C2", 13 * PERIOD_MS + 20, &BTreeSet::from([1]));
        book.require(3, 13, &lost());
        assert!(
            book.check(&lives, 13, PERIOD_MS, 2).is_ok(),
            "round 13 not over"
        );
        let missing = book.clone().check(&lives, 14, PERIOD_MS, 2);
        assert!(
            matches!(
                missing,
                Err(Problem::DropMissing {
                    round: 3,
                    real: 13,
                    from: 1,
                    to: 2
                })
            ),
            "{missing:?}"
        );
        // Taken at the next boundary: still round 13's heartbeat.
        let dropped = event(
            &lives[1],
            14 * PERIOD_MS,
            Event::HeartbeatDropped { from: 1 },
        );
        lives[1].log.events.push(dropped);
        assert!(book.check(&lives, 14, PERIOD_MS, 2).is_ok());
    }

    #[test]
    fn a_link_not_yet_discovered_is_exempt() {
        let lives = lives();
        let mut book = DropBook::default();
        // Round 11: C2 has not reported C1 yet (DDS discovery).
        book.require(1, 11, &lost());
        assert!(book.check(&lives, 12, PERIOD_MS, 2).is_ok());
    }

    #[test]
    fn a_drop_the_control_did_not_ask_for_is_unplanned() {
        let mut lives = lives();
        let mut book = DropBook::default();
        book.written("C2", 13 * PERIOD_MS + 20, &BTreeSet::from([1]));
        book.written("C2", 14 * PERIOD_MS + 20, &BTreeSet::new());
        let planned = event(
            &lives[1],
            13 * PERIOD_MS + 62,
            Event::HeartbeatDropped { from: 1 },
        );
        let late = event(
            &lives[1],
            14 * PERIOD_MS + 62,
            Event::HeartbeatDropped { from: 1 },
        );
        lives[1].log.events.extend([planned, late]);
        let unplanned = book.check(&lives, 15, PERIOD_MS, 2);
        assert!(
            matches!(
                unplanned,
                Err(Problem::DropUnplanned {
                    from: 1,
                    real: 14,
                    ..
                })
            ),
            "{unplanned:?}"
        );
    }
}
