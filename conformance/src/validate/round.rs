//! One round's end for one controller, under every choice of lost heartbeats towards it, and
//! the search's step that keeps the outcomes agreeing with the next boundary.

use super::compare::{abstract_one, differences};
use super::search::{representatives, step_model, visible, Branch, Dead, Search};
use super::Rejection;
use model::protocol;
use model::state::{link_bit, History};
use model::traces::AbstractController;
use model::{Action, Controller, State};
use rl_layer::core::ControllerId;
use std::collections::HashSet;

/// How a branch's round ends.
pub(super) enum RoundEnd {
    /// The branches that agree with the next boundary.
    Survivors(Vec<Branch>),
    /// No state of one controller agrees with its report: the branch dies here.
    Dead(Box<Dead>),
}

impl Search<'_> {
    /// The round ends: every live controller's candidates under every choice of lost
    /// heartbeats towards it, kept if they agree with the next boundary.
    pub(super) fn end_round(
        &mut self,
        round: u64,
        branch: &Branch,
    ) -> Result<RoundEnd, Box<Rejection>> {
        let boundary = round + 1;
        let reps = representatives(branch);
        let up: Vec<ControllerId> = reps
            .controllers
            .iter()
            .filter(|c| c.is_up())
            .map(|c| c.id)
            .collect();
        let mut slots: Vec<Vec<Vec<Controller>>> = Vec::new();
        for (index, slot) in branch.slots.iter().enumerate() {
            let id = (index + 1) as ControllerId;
            if !slot[0].is_up() {
                slots.push(vec![slot.clone()]);
                continue;
            }
            let senders: Vec<ControllerId> = up.iter().copied().filter(|s| *s != id).collect();
            let mut outcomes: Vec<(Controller, u16)> = Vec::new();
            let mut seen: HashSet<Controller> = HashSet::new();
            let number = slot[0].incarnation;
            let slept = self.slept_through(id, number, boundary);
            if slept {
                // The model's `Oversleep`: its loop ran no round end of its own here.
                outcomes.extend(slot.iter().map(|candidate| (candidate.clone(), 0)));
            }
            for candidate in slot.iter().filter(|_| !slept) {
                let mut ends = round_end_of(&self.config, &reps, id, candidate, &senders);
                ends.extend(stale_deposed_ends(
                    &self.config,
                    &reps,
                    &branch.previous,
                    id,
                    candidate,
                    &senders,
                ));
                for (next, lost) in ends {
                    self.stats.states_explored += 1;
                    if seen.insert(next.clone()) {
                        outcomes.push((next, lost));
                    }
                }
            }
            let now = self.observation(id, number, boundary)?;
            let later = self.observation(id, number, boundary + 1)?;
            let views: Vec<AbstractController> = outcomes
                .iter()
                .map(|(next, _)| abstract_one(&reps, next))
                .collect();
            let agreeing = |report: &AbstractController| -> Vec<Controller> {
                outcomes
                    .iter()
                    .zip(&views)
                    .filter(|(_, view)| differences(view, report).is_empty())
                    .map(|((next, _), _)| next.clone())
                    .collect()
            };
            let mut kept = agreeing(&now);
            if kept.is_empty() && self.lag && later != now {
                // The lag tolerance, only where no state agrees on time.
                kept = agreeing(&later);
                if !kept.is_empty() && self.lagged.insert((id, boundary)) {
                    self.stats.lagged_reports += 1;
                }
            }
            if kept.is_empty() {
                return Ok(RoundEnd::Dead(Box::new(Dead {
                    id,
                    number,
                    observed: now,
                    previous: self.observation(id, number, round)?,
                    candidates: outcomes
                        .iter()
                        .zip(views)
                        .map(|((_, lost), view)| (view, *lost, senders.clone()))
                        .collect(),
                    before: slot[0].clone(),
                })));
            }
            self.stats.candidates_max = self.stats.candidates_max.max(kept.len());
            slots.push(group_by_heartbeat(kept));
        }
        Ok(RoundEnd::Survivors(combine(slots, &reps.controllers)))
    }
}

impl Search<'_> {
    /// Whether life `number` of `id` slept through the round end of `boundary`.
    fn slept_through(&self, id: ControllerId, number: u8, boundary: u64) -> bool {
        self.life(id, number)
            .is_some_and(|life| life.missed_boundaries.contains(&boundary))
    }
}

/// Candidates with different heartbeat content belong to different histories.
fn group_by_heartbeat(kept: Vec<Controller>) -> Vec<Vec<Controller>> {
    let mut groups: Vec<Vec<Controller>> = Vec::new();
    for candidate in kept {
        match groups
            .iter_mut()
            .find(|g| visible(&g[0]) == visible(&candidate))
        {
            Some(group) => group.push(candidate),
            None => groups.push(vec![candidate]),
        }
    }
    groups
}

/// Every combination of one group per controller: the branches the round leaves.
fn combine(slots: Vec<Vec<Vec<Controller>>>, previous: &[Controller]) -> Vec<Branch> {
    let mut out = vec![Branch {
        slots: Vec::new(),
        previous: previous.to_vec(),
    }];
    for groups in slots {
        let mut expanded = Vec::new();
        for partial in &out {
            for group in &groups {
                let mut branch = partial.clone();
                branch.slots.push(group.clone());
                expanded.push(branch);
            }
        }
        out = expanded;
    }
    out
}

/// Every state controller `id` (as `candidate`) can end round in, with the others as in
/// `reps`: one per subset of `senders` whose heartbeat to it is lost (bit `i` = `senders[i]`),
/// through the model's own per-controller round step (`model::protocol::round_step`, the step
/// its `Tick` runs for every controller). Due initialization windows expire right after the
/// round ends.
pub fn round_end_of(
    config: &model::Config,
    reps: &State,
    id: ControllerId,
    candidate: &Controller,
    senders: &[ControllerId],
) -> Vec<(Controller, u16)> {
    let index = usize::from(id) - 1;
    let mut base = reps.clone();
    base.controllers[index] = candidate.clone();
    base.lost_links = 0;
    base.history = History::default();
    if !tick_enabled(config, &base) {
        return Vec::new();
    }
    let mut out = Vec::new();
    for lost in 0u16..(1 << senders.len()) {
        let mut before = base.clone();
        for (bit, from) in senders.iter().enumerate() {
            if lost & (1 << bit) != 0 {
                before.lost_links |= link_bit(*from, id);
            }
        }
        let mut ended = before.clone();
        // As `Tick` does for every controller before their round steps.
        ended.controllers[index].establish_writers();
        protocol::round_step(config, &before, &mut ended, id);
        ended.lost_links = 0;
        if let Some(expired) = step_model(config, &ended, Action::ExpireWindow { controller: id }) {
            ended = expired;
        }
        out.push((ended.controllers[index].clone(), lost));
    }
    out
}

/// Tolerance 4: a controller that took over from a starved Primary (F17) may hear, instead
/// of that Primary's heartbeat of this round, the one of the round before, which waited in the
/// starved link's queue (the model's heartbeats are lost, never late). Its ends of the round
/// with the deposed Primary as it was at the previous boundary, the same life still up.
fn stale_deposed_ends(
    config: &model::Config,
    reps: &State,
    previous: &[Controller],
    id: ControllerId,
    candidate: &Controller,
    senders: &[ControllerId],
) -> Vec<(Controller, u16)> {
    let Some((deposed, incarnation)) = candidate.took_over_from else {
        return Vec::new();
    };
    let index = usize::from(deposed) - 1;
    let (Some(was), Some(now)) = (previous.get(index), reps.controllers.get(index)) else {
        return Vec::new();
    };
    let same_life = was.is_up() && now.is_up() && was.incarnation == now.incarnation;
    if !same_life || was.incarnation != incarnation || was == now {
        return Vec::new();
    }
    let mut stale = reps.clone();
    stale.controllers[index] = was.clone();
    round_end_of(config, &stale, id, candidate, senders)
}

/// The model lets the round end here (no initialization window or durable vote is due first).
fn tick_enabled(config: &model::Config, state: &State) -> bool {
    let mut enabled = Vec::new();
    protocol::actions(config, state, &mut enabled);
    enabled.contains(&Action::Tick)
}
