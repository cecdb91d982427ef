//! The commands a core emitted, checked against the model's state change: a `SetOutput`
//! exactly when its role or strength changed, a `PublishVote` exactly when its vote changed,
//! `RaiseAlarm` / `ClearAlarm` exactly for the alarms added / removed.

use super::network::{commands_of, Cause, StepLog};
use crate::abstraction::{self, IncarnationNumbers, UnknownIncarnation};
use crate::diff::id_set;
use model::traces::{AbstractController, AbstractState};
use model::Life;
use rl_layer::core::{Command, ControllerId};
use std::collections::BTreeSet;

/// The commands' disagreements with the trace's state change, one line each.
pub fn command_problems(
    before: &AbstractState,
    after: &AbstractState,
    log: &StepLog,
    numbers: &IncarnationNumbers,
) -> Result<Vec<String>, UnknownIncarnation> {
    let mut problems = Vec::new();
    for (&id, emitted) in log {
        // A life that started in the step answers for its own commands only, not for those
        // its predecessor emitted before (a deposed core's last round end, F17).
        let own = emitted
            .iter()
            .rposition(|e| e.cause == Cause::Started)
            .map_or(&emitted[..], |start| &emitted[start..]);
        let emitted = &commands_of(own);
        let Some(now) = after.controllers.iter().find(|c| c.id == id) else {
            continue;
        };
        if now.life != Life::Up {
            continue;
        }
        let blank = fresh_life(now);
        // A new life starts from nothing: the commands of the old one are not its own.
        let was = before
            .controllers
            .iter()
            .find(|c| c.id == id && c.life == Life::Up && c.incarnation == now.incarnation)
            .unwrap_or(&blank);
        check_output(id, was, now, emitted, &mut problems);
        check_vote(id, was, now, emitted, numbers, &mut problems)?;
        check_alarms(id, was, now, emitted, &mut problems);
    }
    Ok(problems)
}

fn fresh_life(now: &AbstractController) -> AbstractController {
    abstraction::blank(
        now.id,
        Life::Up,
        now.incarnation,
        Some(model::Phase::Initializing),
    )
}

fn role_name(role: Option<model::Role>) -> String {
    role.map_or("no role".to_string(), |r| r.name().to_lowercase())
}

fn strength_text(strength: Option<u8>) -> String {
    strength.map_or("silent".to_string(), |s| s.to_string())
}

fn check_output(
    id: ControllerId,
    was: &AbstractController,
    now: &AbstractController,
    emitted: &[Command],
    problems: &mut Vec<String>,
) {
    let last = emitted.iter().rev().find_map(|c| match c {
        Command::SetOutput { role, strength } => Some((
            role.map(abstraction::role),
            strength.map(abstraction::strength),
        )),
        _ => None,
    });
    let changed = (was.role, was.strength) != (now.role, now.strength);
    match (changed, last) {
        (true, None) => problems.push(format!(
            "C{id}: role/strength changed ({} {} -> {} {}) but no SetOutput was emitted",
            role_name(was.role),
            strength_text(was.strength),
            role_name(now.role),
            strength_text(now.strength)
        )),
        (false, Some((role, strength))) => problems.push(format!(
            "C{id}: SetOutput {{ {}, {} }} emitted but role/strength did not change",
            role_name(role),
            strength_text(strength)
        )),
        (true, Some((role, strength))) if (role, strength) != (now.role, now.strength) => problems
            .push(format!(
                "C{id}: SetOutput {{ {}, {} }} emitted, the state says {} {}",
                role_name(role),
                strength_text(strength),
                role_name(now.role),
                strength_text(now.strength)
            )),
        _ => {}
    }
}

fn check_vote(
    id: ControllerId,
    was: &AbstractController,
    now: &AbstractController,
    emitted: &[Command],
    numbers: &IncarnationNumbers,
    problems: &mut Vec<String>,
) -> Result<(), UnknownIncarnation> {
    let last = emitted.iter().rev().find_map(|c| match c {
        Command::PublishVote(record) => Some(record.vote),
        _ => None,
    });
    let show = |v: &Option<String>| v.clone().unwrap_or_else(|| "none".to_string());
    let changed = was.vote != now.vote;
    match (changed, last) {
        (true, None) => problems.push(format!(
            "C{id}: vote changed ({} -> {}) but no PublishVote was emitted",
            show(&was.vote),
            show(&now.vote)
        )),
        (false, Some(vote)) => problems.push(format!(
            "C{id}: PublishVote [{}] emitted but the vote did not change",
            show(&abstraction::render_assignment(id, vote, numbers)?)
        )),
        (true, Some(vote)) => {
            let published = abstraction::render_assignment(id, vote, numbers)?;
            if published != now.vote {
                problems.push(format!(
                    "C{id}: PublishVote [{}] emitted, the state's vote is [{}]",
                    show(&published),
                    show(&now.vote)
                ));
            }
        }
        (false, None) => {}
    }
    Ok(())
}

fn check_alarms(
    id: ControllerId,
    was: &AbstractController,
    now: &AbstractController,
    emitted: &[Command],
    problems: &mut Vec<String>,
) {
    let before: BTreeSet<u8> = was.alarms.iter().copied().collect();
    let after: BTreeSet<u8> = now.alarms.iter().copied().collect();
    let expected_raised: BTreeSet<u8> = after.difference(&before).copied().collect();
    let expected_cleared: BTreeSet<u8> = before.difference(&after).copied().collect();
    // An alarm a controller raises about itself (`Stalled`, for a life the model calls new)
    // is not in the model's state, which the abstraction leaves out too.
    let raised: BTreeSet<u8> = emitted
        .iter()
        .filter_map(|c| match c {
            Command::RaiseAlarm { about, .. } if *about != id => Some(*about),
            _ => None,
        })
        .collect();
    let cleared: BTreeSet<u8> = emitted
        .iter()
        .filter_map(|c| match c {
            Command::ClearAlarm { about, .. } if *about != id => Some(*about),
            _ => None,
        })
        .collect();
    if raised != expected_raised {
        problems.push(format!(
            "C{id}: alarms raised for {} but the alarms added are {}",
            id_set(&raised),
            id_set(&expected_raised)
        ));
    }
    if cleared != expected_cleared {
        problems.push(format!(
            "C{id}: alarms cleared for {} but the alarms removed are {}",
            id_set(&cleared),
            id_set(&expected_cleared)
        ));
    }
}
