//! Minority judgement: marking voters whose dissent outlasts the grace (F10) FAILED, and a
//! controller that is itself outvoted failing itself (paper: "Any unit that does not agree
//! with the two votes of the other controllers will take itself offline").

use super::agreement::{electorate, note_role_change, Electorate, Source};
use super::vote::{revote, vote_superseded};
use crate::config::Config;
use crate::fixes::Mutation;
use crate::state::{Controller, State};
use crate::types::{Assignment, Id, Phase};

/// Marks minority voters FAILED; a controller that is itself the minority fails itself
/// (paper: "Any unit that does not agree with the two votes of the other controllers will
/// take itself offline").
pub(super) fn judge_minority(config: &Config, next: &mut State, id: Id, source: Source) {
    let c = next.controller(id);
    if !matches!(c.phase, Phase::Voting | Phase::Steady) {
        return;
    }
    let grace = config.minority_grace_rounds();
    let ignore = config.mutated(Mutation::IgnoreMinorityVote);
    let Electorate {
        votes, counts_self, ..
    } = electorate(config, c, source);
    // F7: judging itself, it counts every live peer's vote, FAILED marks notwithstanding: two
    // sides that marked each other FAILED would otherwise each ignore being outvoted.
    let own_outvoted = counts_self && c.vote.is_some_and(|own| outvoted(config, c, own, source));
    if judge_self(config, next, id, own_outvoted, grace, ignore) {
        return;
    }
    let mut majority: Option<(Assignment, usize)> = None;
    for (_, vote) in &votes {
        let count = votes.iter().filter(|(_, v)| v == vote).count();
        if majority.is_none_or(|(_, best)| count > best) {
            majority = Some((*vote, count));
        }
    }
    let c = next.controller_mut(id);
    let winner = majority
        .filter(|(_, count)| *count >= 2 && count * 2 > votes.len())
        .map(|(vote, _)| vote);
    let mut marked = false;
    for (voter, vote) in &votes {
        if *voter == id {
            continue;
        }
        let peer = c.peer_mut(*voter);
        if winner.is_none_or(|winner| *vote == winner) {
            peer.dissent_rounds = 0;
            continue;
        }
        if source == Source::Heartbeats && peer.silent_rounds > 0 {
            // Its heartbeat was lost this round: the vote judged is last round's, which it
            // may have changed since. A dissent counts only in rounds it was heard.
            continue;
        }
        peer.dissent_rounds = peer.dissent_rounds.saturating_add(1);
        if peer.dissent_rounds > grace && !ignore {
            peer.failed = true;
            peer.alarm = true;
            marked = true;
        }
    }
    if marked {
        revote(config, next, id);
    }
}

/// Two or more other live voters agree on a result other than `own`, and they are a majority
/// of the others (paper: "does not agree with the two votes of the other controllers"). With
/// F7 every live peer counts, FAILED marks notwithstanding; with F4 newcomers never do (see
/// `electorate`).
fn outvoted(config: &Config, c: &Controller, own: Assignment, source: Source) -> bool {
    let rules = config.rules();
    let others: Vec<Assignment> = c
        .peers
        .iter()
        .enumerate()
        .filter(|(index, peer)| *index + 1 != usize::from(c.id) && peer.alive.is_some())
        .filter(|(_, peer)| rules.f7_judge_self_by_every_vote || !peer.failed)
        .filter(|(_, peer)| !rules.f4_quorum_of_view || peer.heard_agreed.is_some())
        .filter_map(|(_, peer)| source.vote_of(&rules, peer))
        .collect();
    others.iter().any(|vote| {
        let count = others.iter().filter(|v| *v == vote).count();
        *vote != own && count >= 2 && count * 2 > others.len()
    })
}

/// Counts the rounds this controller has been outvoted; past the grace it fails itself.
/// Returns whether it did.
fn judge_self(
    config: &Config,
    next: &mut State,
    id: Id,
    outvoted: bool,
    grace: u8,
    ignore: bool,
) -> bool {
    let c = next.controller_mut(id);
    if !outvoted {
        c.self_dissent_rounds = 0;
        return false;
    }
    c.self_dissent_rounds = c.self_dissent_rounds.saturating_add(1);
    if c.self_dissent_rounds > grace && !ignore {
        fail_self(config, next, id);
        return true;
    }
    false
}

fn fail_self(config: &Config, next: &mut State, id: Id) {
    vote_superseded(config, next, id);
    let c = next.controller_mut(id);
    let old_role = c.role;
    c.phase = Phase::Failed;
    c.role = None;
    c.set_output(None);
    c.vote = None;
    c.agreed = None;
    note_role_change(&mut next.history, id, old_role, None);
}
