//! What a controller votes for, and how votes are published and delivered.
//!
//! [`compute_vote`] is the voting algorithm; `revote` publishes its result; without F5 the
//! durable copies are delivered in batches (`deliver_votes`) and decisions are taken on them.

use super::agreement::{electorate, try_agree, Source};
use super::minority::judge_minority;
use super::window_over;
use crate::config::Config;
use crate::fixes::Mutation;
use crate::state::{link_bit, Controller, State};
use crate::types::{Assignment, Holder, Id, Phase, Role, ROLE_COUNT};

/// The initialization window closes: cast the first vote (paper, "Voting Algorithm").
pub(super) fn close_window(config: &Config, next: &mut State, id: Id) {
    next.controller_mut(id).phase = Phase::Voting;
    revote(config, next, id);
}

/// Computes and publishes its vote. Without F5, a lone voter (or a matching quorum already
/// held) agrees at once; with it only a controller alone does (the rest wait for the round).
pub(super) fn revote(config: &Config, next: &mut State, id: Id) {
    let vote = compute_vote(config, next.controller(id));
    let c = next.controller_mut(id);
    if c.phase == Phase::Failed {
        return;
    }
    c.phase = Phase::Voting;
    if c.vote != Some(vote) {
        c.vote = Some(vote);
        c.self_dissent_rounds = 0;
        vote_superseded(config, next, id);
    }
    if config.rules().f5_decide_on_heartbeats {
        // Decided at the round boundary; only a controller alone decides at once.
        if electorate(config, next.controller(id), Source::Heartbeats).size == 1 {
            try_agree(config, next, id, Source::Heartbeats);
        }
    } else {
        try_agree(config, next, id, Source::DurableVotes);
    }
}

/// The voting algorithm: who should hold which role, as this controller sees it.
///
/// A function of what the controller knows, never of its own earlier votes, so controllers
/// that know the same vote the same: every live member is ranked by the best role any known
/// agreed result gives that very incarnation (its own result and, with F6, every
/// incumbent's as this round's heartbeats carry it), then by lowest id; three at most.
/// Keeping known roles is what avoids oscillation; losing a holder promotes those below it;
/// newcomers come in below by id; two results from a healed partition merge with the
/// lower id first.
pub fn compute_vote(config: &Config, c: &Controller) -> Assignment {
    let rules = config.rules();
    let members: Vec<Holder> = c
        .members()
        .map(|id| Holder {
            id,
            incarnation: if id == c.id {
                c.incarnation
            } else {
                c.peer(id).alive.unwrap_or_default()
            },
        })
        .collect();
    let known = known_results(config, c);
    // F11: a member's place in the newest result that has it comes first, a backed result
    // before a provisional one: after a merge the side that kept a majority keeps its roles.
    // Two results of one epoch (agreed concurrently while heartbeats were lost) may give one
    // role to two members: the one that holds that result itself comes first, so a
    // controller that took a role keeps it and a newcomer the other result named waits.
    let rank = |member: &Holder| -> (std::cmp::Reverse<u32>, bool, usize, bool) {
        if config.mutated(Mutation::Failback) {
            return (std::cmp::Reverse(0), true, ROLE_COUNT, true);
        }
        known
            .iter()
            .filter_map(|(result, epoch, provisional, held_by)| {
                let role = if rules.f3_incarnation_aware {
                    result.role_of_holder(*member)
                } else {
                    result.role_of(member.id)
                };
                // Paper: "Precedence should be given to any currently Active Controller";
                // the other roles are ranked by id again.
                role.filter(|r| rules.f2_keep_standby_order || *r == Role::Primary)
                    .map(|r| {
                        let not_its_own = !(rules.f11_epochs && *held_by == member.id);
                        (
                            std::cmp::Reverse(*epoch),
                            *provisional,
                            r.rank(),
                            not_its_own,
                        )
                    })
            })
            .min()
            .unwrap_or((std::cmp::Reverse(0), true, ROLE_COUNT, true))
    };
    let mut ranked = members.clone();
    ranked.sort_by_key(|member| (rank(member), member.id));
    let mut vote = Assignment::from_ranked(ranked);
    if config.mutated(Mutation::AdmitFourth) && !vote.contains(c.id) && vote.len() == ROLE_COUNT {
        vote.0[ROLE_COUNT - 1] = Some(Holder {
            id: c.id,
            incarnation: c.incarnation,
        });
    }
    vote
}

/// Every agreed result `c` knows, with its epoch and standing (F11; 0 and backed without it)
/// and the controller that holds it (who holds it matters only between results of one epoch).
fn known_results(config: &Config, c: &Controller) -> Vec<(Assignment, u32, bool, Id)> {
    let rules = config.rules();
    let mut known: Vec<(Assignment, u32, bool, Id)> = c
        .agreed
        .map(|a| (a, c.epoch, c.provisional, c.id))
        .into_iter()
        .collect();
    // F6: every incumbent's result, as heartbeats carry it. F1 alone gives that knowledge to
    // a late joiner without a result of its own (it "takes the running system's result").
    let joining = c.agreed.is_none() && c.late_joiner;
    if rules.f6_vote_from_knowledge || (rules.f1_late_join_by_heartbeat && joining) {
        known.extend(
            c.peers
                .iter()
                .enumerate()
                .filter(|(_, p)| p.incumbent())
                .filter_map(|(index, p)| {
                    let id = (index + 1) as Id;
                    p.heard_agreed
                        .map(|a| (a, p.heard_epoch, p.heard_provisional, id))
                }),
        );
    }
    if !rules.f5_decide_on_heartbeats && joining {
        // Paper: a late joiner "assesses the existing system priority" from durable votes.
        known.extend(durable_result(config, c).map(|a| (a, 0, false, 0)));
    }
    known
}

/// The running system's result from the durable votes of live peers: the assignment most of
/// them voted for (paper: a late joiner "assesses the existing system priority" from votes).
fn durable_result(config: &Config, c: &Controller) -> Option<Assignment> {
    let rules = config.rules();
    let votes = c
        .peers
        .iter()
        .filter_map(|peer| match (peer.alive, peer.vote) {
            (Some(alive), Some((incarnation, vote)))
                if !peer.failed && (!rules.f3_incarnation_aware || alive == incarnation) =>
            {
                Some(vote)
            }
            _ => None,
        });
    most_common(votes)
}

/// The most frequent assignment; ties go to the smallest, so every controller picks the same.
fn most_common(items: impl Iterator<Item = Assignment>) -> Option<Assignment> {
    let mut counts: Vec<(Assignment, usize)> = Vec::new();
    for item in items {
        match counts.iter_mut().find(|(a, _)| *a == item) {
            Some((_, count)) => *count += 1,
            None => counts.push((item, 1)),
        }
    }
    counts
        .into_iter()
        .max_by(|(a, x), (b, y)| x.cmp(y).then(b.cmp(a)))
        .map(|(a, _)| a)
}

/// `id` published a new vote (or withdrew it). With F5 no decision reads a
/// durable copy, so superseded copies are dropped: the state stays canonical. The paper's
/// rules decide on the copies, which stay until replaced.
pub(super) fn vote_superseded(config: &Config, next: &mut State, id: Id) {
    if !config.rules().f5_decide_on_heartbeats {
        return;
    }
    for c in next.controllers.iter_mut() {
        if c.id != id {
            c.peer_mut(id).vote = None;
        }
    }
}

/// The latest durable votes of `senders` reach `to` together (one reader's batch).
pub(super) fn deliver_votes(config: &Config, next: &mut State, senders: &[Id], to: Id) {
    let rules = config.rules();
    for &from in senders {
        let sender = next.controller(from);
        let vote = (sender.incarnation, sender.vote.unwrap_or_default());
        next.overdue_votes &= !link_bit(from, to);
        let receiver = next.controller_mut(to);
        receiver.peer_mut(from).vote = Some(vote);
        if !rules.f5_decide_on_heartbeats {
            // A dissent counts only while the votes it is judged on stay the same.
            receiver.peer_mut(from).dissent_rounds = 0;
            receiver.self_dissent_rounds = 0;
        }
    }
    let c = next.controller_mut(to);
    match c.phase {
        Phase::Initializing if !rules.f5_decide_on_heartbeats => {
            // Paper: a vote before our own voting means a running system ("Late Joiner").
            c.late_joiner = true;
            if window_over(config, c) {
                close_window(config, next, to);
            }
        }
        Phase::Initializing => {}
        Phase::Voting if !rules.f5_decide_on_heartbeats => {
            try_agree(config, next, to, Source::DurableVotes)
        }
        Phase::Voting | Phase::Steady | Phase::Failed => {}
    }
    if !rules.f10_minority_grace && !rules.f5_decide_on_heartbeats {
        // Paper: "any minority vote from a controller indicates the controller is faulted".
        judge_minority(config, next, to, Source::DurableVotes);
    }
}
