//! How each peer's commands arrive: the measurement behind the core's `Input::Commands`, by
//! which a Secondary tells a Primary whose link is starved (its commands delayed, as behind a
//! rate-limited link) from one that is merely silent (finding F17).
//!
//! Each writer's delays are taken against its own best ([`crate::delay`]: two controllers'
//! clocks need not agree). A sample later than its writer's baseline by more than the lateness
//! bound (half the command deadline) is late. A
//! controller's commands are late while the last sample of any of its writers heard within a
//! command deadline was (a writer it replaced may still have samples queued), on time while
//! none was, and unheard when no writer of its was heard for a command deadline. The core
//! decides what follows (`rl_core::rules`).
//!
//! What each verdict can cost is bounded by the model, not by this measurement: the model's
//! `Starve` may hit any controller at any time, so a verdict that is wrong (a wall clock that
//! steps back on the Primary, a burst of delay on a healthy link) costs what a starved link
//! costs there, one owner change, and never two writers at the top.

use crate::core::types::{Arrival, ControllerId};
use crate::dds::GUID;
use crate::delay::{DelayBaseline, BASELINE_MS};
use std::collections::BTreeMap;

/// How long a writer must have been heard before its samples say anything: a new writer's
/// first sample is its own baseline, so it would always be "on time" (measured: a Tertiary
/// that had just joined, whose first samples made a Secondary take over from a Primary
/// delayed by a loaded host, `lab soak --seed 14`). The model offers a starved link only
/// once the system has settled, its writers established: from the round after the one a
/// writer was created in. So this is less than a round less the writer's discovery, or a
/// Secondary could not take over where the model does (measured: at 500 ms the DDS-level
/// replay of `0242-starved-a-secondary-takes-over-from-a-starved-primary` found the
/// Tertiary's writer, created two rounds before the starved link, not yet established, and
/// no takeover); 200 ms is 20 samples at the default republish period.
pub const ESTABLISHED_MS: u64 = 200;

/// One writer's recent samples.
#[derive(Debug)]
struct WriterDelays {
    /// The controller it writes for.
    controller: ControllerId,
    /// Its delays of the last [`BASELINE_MS`] (arrivals on the loop clock).
    delays: DelayBaseline,
    /// Its last sample was late.
    late: bool,
    /// When it was first heard (the loop clock).
    first_ms: u64,
}

impl WriterDelays {
    fn last_ms(&self) -> Option<u64> {
        self.delays.last_ms()
    }
}

/// Every peer's commands, as they arrive.
#[derive(Debug)]
pub struct ArrivalWatch {
    late_after_ms: i64,
    unheard_after_ms: u64,
    writers: BTreeMap<GUID, WriterDelays>,
    /// The verdict last reported per controller.
    reported: BTreeMap<ControllerId, Arrival>,
}

impl ArrivalWatch {
    /// For a command deadline of `command_deadline_ms`: late beyond half of it, unheard after
    /// all of it.
    pub fn new(command_deadline_ms: u64) -> ArrivalWatch {
        ArrivalWatch {
            late_after_ms: i64::try_from(command_deadline_ms / 2).unwrap_or(i64::MAX),
            unheard_after_ms: command_deadline_ms,
            writers: BTreeMap::new(),
            reported: BTreeMap::new(),
        }
    }

    /// A sample of controller `from`'s writer `writer` arrived at `now_ms` (the loop clock),
    /// `delay_ms` after its source timestamp (the two wall clocks). Returns the controller's
    /// verdict when it changed, and "on time" for each sample on time while another
    /// controller's are late: that a sample arrives on time after the late one is what tells
    /// a late peer from this controller's own starved link (`rl_core`, F17).
    pub fn sample(
        &mut self,
        from: ControllerId,
        writer: GUID,
        delay_ms: i64,
        now_ms: u64,
    ) -> Option<Arrival> {
        let delays = self.writers.entry(writer).or_insert(WriterDelays {
            controller: from,
            delays: DelayBaseline::default(),
            late: false,
            first_ms: now_ms,
        });
        delays.controller = from;
        delays.late = delays.delays.lateness_ms(now_ms, delay_ms) > self.late_after_ms;
        let changed = self.report(from, now_ms);
        let another_late = self
            .reported
            .iter()
            .any(|(id, arrival)| *id != from && *arrival == Arrival::Late);
        let on_time = self.reported.get(&from) == Some(&Arrival::OnTime);
        changed.or((on_time && another_late).then_some(Arrival::OnTime))
    }

    /// The controllers whose verdict changed with time alone: every writer of theirs silent
    /// for a command deadline (unheard), or a late writer gone quiet beside one on time.
    /// Writers silent for the baseline window are forgotten (a re-created writer is a new
    /// GUID).
    pub fn silence(&mut self, now_ms: u64) -> Vec<(ControllerId, Arrival)> {
        self.writers.retain(|_, delays| {
            delays
                .last_ms()
                .is_some_and(|at_ms| now_ms.saturating_sub(at_ms) <= BASELINE_MS)
        });
        let ids: Vec<ControllerId> = self.reported.keys().copied().collect();
        ids.into_iter()
            .filter_map(|id| self.report(id, now_ms).map(|arrival| (id, arrival)))
            .collect()
    }

    /// The command deadline it was made for.
    pub fn command_deadline_ms(&self) -> u64 {
        self.unheard_after_ms
    }

    /// Measuring stops: every controller whose last verdict was not "unheard", now unheard.
    pub fn stop(self) -> Vec<(ControllerId, Arrival)> {
        self.reported
            .into_iter()
            .filter(|(_, arrival)| *arrival != Arrival::Unheard)
            .map(|(id, _)| (id, Arrival::Unheard))
            .collect()
    }

    /// Controller `id`'s verdict from its established writers heard within a command
    /// deadline: late if any of them is (samples of a writer it has since replaced may still be queued on a
    /// starved link), on time if they all are, unheard without any. Returns it when it
    /// changed.
    fn report(&mut self, id: ControllerId, now_ms: u64) -> Option<Arrival> {
        let mut arrival = Arrival::Unheard;
        let established = |d: &&WriterDelays| now_ms.saturating_sub(d.first_ms) >= ESTABLISHED_MS;
        for delays in self
            .writers
            .values()
            .filter(|d| d.controller == id)
            .filter(established)
        {
            let recent = delays
                .last_ms()
                .is_some_and(|at_ms| now_ms.saturating_sub(at_ms) <= self.unheard_after_ms);
            if recent {
                arrival = match (arrival, delays.late) {
                    (_, true) | (Arrival::Late, _) => Arrival::Late,
                    _ => Arrival::OnTime,
                };
            }
        }
        let before = self
            .reported
            .insert(id, arrival)
            .unwrap_or(Arrival::Unheard);
        (before != arrival).then_some(arrival)
    }
}

#[cfg(test)]
mod tests;
