//! The output model's rules, action by action: what each controller may publish, how the
//! voting receiver accepts and alarms, how the exclusive-ownership receiver follows the
//! strongest writer, and the controllers' cross-check that makes the odd one out leave.
//!
//! The rules in words are docs/protocol.md, "Output voting"; every function here is one of
//! them. Delivery is perfect within an input (the timing assumption: every command of an
//! input reaches every reader before the next input), so every controller judges the same
//! three commands.

use super::config::{CrossCheck, OutputConfig, OutputMutation};
use super::state::{
    Command, Controller, ExclusiveReceiver, Fault, OutputAction, OutputState, Value,
    VotingReceiver, CONTROLLERS,
};
use crate::types::{Id, Phase, Role};

/// The one initial state: C1 Primary, C2 Secondary, C3 Tertiary, all correct, the first
/// input open (right command v0; v0 and v1 are interchangeable).
pub fn init_states(_config: &OutputConfig) -> Vec<OutputState> {
    vec![OutputState {
        right: Value(0),
        controllers: [
            Controller::new(1, Role::Primary),
            Controller::new(2, Role::Secondary),
            Controller::new(3, Role::Tertiary),
        ],
        voting: VotingReceiver::default(),
        exclusive: ExclusiveReceiver {
            owner: Some(1),
            taken: None,
        },
        faults_begun: 0,
        two_wrong_at_once: false,
        closed_without_pair: false,
    }]
}

/// Every action enabled in `state`.
pub fn actions(config: &OutputConfig, state: &OutputState, actions: &mut Vec<OutputAction>) {
    if state.input_fresh() {
        for c in state
            .controllers
            .iter()
            .filter(|c| c.phase == Phase::Failed)
        {
            actions.push(OutputAction::Restart {
                controller: c.id,
                still_wrong: false,
            });
            if c.fault.is_some() {
                actions.push(OutputAction::Restart {
                    controller: c.id,
                    still_wrong: true,
                });
            }
        }
        if state.faults_begun < config.max_wrong {
            for c in state
                .controllers
                .iter()
                .filter(|c| c.has_role() && c.fault.is_none())
            {
                for fault in fault_choices(config, state, c.id) {
                    actions.push(OutputAction::GoWrong {
                        controller: c.id,
                        fault,
                    });
                }
            }
        }
    }
    for c in state
        .controllers
        .iter()
        .filter(|c| c.command == Command::Pending)
    {
        for command in command_choices(config, state, c.id) {
            actions.push(match command {
                Command::Sent(value) => OutputAction::Publish {
                    controller: c.id,
                    value,
                },
                _ => OutputAction::Omit { controller: c.id },
            });
        }
    }
    if state.input_answered() {
        for right in Value::RIGHT {
            actions.push(OutputAction::NextInput { right });
        }
    }
}

/// The state after `action`, or `None` when the action is not enabled.
pub fn next_state(
    config: &OutputConfig,
    state: &OutputState,
    action: OutputAction,
) -> Option<OutputState> {
    let mut next = *state;
    match action {
        OutputAction::GoWrong { controller, fault } => {
            let c = state.controller(controller);
            if !state.input_fresh() || !c.has_role() || c.fault.is_some() {
                return None;
            }
            go_wrong(&mut next, controller, fault);
        }
        OutputAction::Publish { controller, value } => {
            let command = Command::Sent(value);
            if !command_choices(config, state, controller).contains(&command) {
                return None;
            }
            publish(config, &mut next, controller, command);
        }
        OutputAction::Omit { controller } => {
            if !command_choices(config, state, controller).contains(&Command::Missing) {
                return None;
            }
            publish(config, &mut next, controller, Command::Missing);
        }
        OutputAction::NextInput { right } => {
            if !state.input_answered() {
                return None;
            }
            close_input(config, &mut next);
            open_input(&mut next, right);
        }
        OutputAction::Restart {
            controller,
            still_wrong,
        } => {
            let c = state.controller(controller);
            if !state.input_fresh()
                || c.phase != Phase::Failed
                || (still_wrong && c.fault.is_none())
            {
                return None;
            }
            restart(&mut next, controller, still_wrong);
        }
    }
    if next.two_wrong_at_once {
        forget_bounded_counts(&mut next);
    }
    Some(next)
}

/// Once two controllers were wrong together, the properties that read the per-life counts
/// say nothing more ("while at most one is wrong"): the counts are dropped, so states that
/// differ only in counts nobody reads are one state.
fn forget_bounded_counts(state: &mut OutputState) {
    for c in state.controllers.iter_mut() {
        c.wrong_in_life = 0;
        c.exclusive_wrong = 0;
        c.exclusive_missed = 0;
        c.wrong_input_in_life = 0;
        c.wrong_law_in_life = 0;
    }
}

/// The ways controller `id`'s output may go wrong. With `wrong_values_differ`, a frozen
/// value another wrong controller is frozen at is left out (the two would agree).
fn fault_choices(config: &OutputConfig, state: &OutputState, id: Id) -> Vec<Fault> {
    let mut faults = vec![
        Fault::WrongValue,
        Fault::Omitted,
        Fault::Erratic,
        Fault::WrongInput,
        Fault::WrongLaw,
    ];
    for value in Value::ALL {
        let frozen_by_another = state
            .controllers
            .iter()
            .any(|other| other.id != id && other.fault == Some(Fault::Frozen(value)));
        if !(config.wrong_values_differ && frozen_by_another) {
            faults.push(Fault::Frozen(value));
        }
    }
    faults
}

/// What controller `id` may publish for the current input: a correct one the right command;
/// a wrong one what its fault allows.
pub fn command_choices(config: &OutputConfig, state: &OutputState, id: Id) -> Vec<Command> {
    let c = state.controller(id);
    if c.command != Command::Pending {
        return Vec::new();
    }
    let excluded = values_taken_by_another_wrong(config, state, id);
    let wrong = Value::ALL
        .into_iter()
        .filter(|value| *value != state.right && !excluded.contains(value))
        .map(Command::Sent);
    match c.fault {
        // Aligned to the group's position, a wrong input or a wrong law (wrong by less than
        // the tolerance) yields the right command.
        None | Some(Fault::WrongInput | Fault::WrongLaw) => vec![Command::Sent(state.right)],
        Some(Fault::WrongValue) => wrong.collect(),
        Some(Fault::Frozen(value)) => vec![Command::Sent(value)],
        Some(Fault::Omitted) => vec![Command::Missing],
        Some(Fault::Erratic) => std::iter::once(Command::Sent(state.right))
            .chain(wrong)
            .chain(std::iter::once(Command::Missing))
            .collect(),
    }
}

/// With `wrong_values_differ`: the wrong values another wrong controller has sent, or (frozen)
/// will send, for the current input. Never more than one value is left out, and two wrong
/// values exist, so a wrong controller always has a value to send.
fn values_taken_by_another_wrong(config: &OutputConfig, state: &OutputState, id: Id) -> Vec<Value> {
    if !config.wrong_values_differ {
        return Vec::new();
    }
    let mut taken = Vec::new();
    for other in state
        .controllers
        .iter()
        .filter(|o| o.id != id && o.has_role())
    {
        let value = match (other.fault, other.command) {
            (Some(_), Command::Sent(value)) => Some(value),
            (Some(Fault::Frozen(value)), Command::Pending) => Some(value),
            _ => None,
        };
        if let Some(value) = value.filter(|value| *value != state.right) {
            taken.push(value);
        }
    }
    taken
}

fn go_wrong(state: &mut OutputState, id: Id, fault: Fault) {
    state.controller_mut(id).fault = Some(fault);
    state.faults_begun += 1;
    note_wrong_controllers(state);
}

fn note_wrong_controllers(state: &mut OutputState) {
    if state.wrong_now() >= 2 {
        state.two_wrong_at_once = true;
    }
}

/// Counters saturate one past the limit, which is all a property needs to see.
fn count_up(counter: u8, cap: u8) -> u8 {
    counter.saturating_add(1).min(cap)
}

/// Controller `id` publishes (or misses) its command for the current input: the exclusive
/// receiver takes it if `id` owns it, the voting receiver votes on it.
fn publish(config: &OutputConfig, state: &mut OutputState, id: Id, command: Command) {
    let right = state.right;
    let cap = config.exclusive_bound() + 1;
    let owns_exclusive = state.exclusive.owner == Some(id);
    let c = state.controller_mut(id);
    c.command = command;
    if command != Command::Sent(right) {
        c.wrong_in_life = count_up(c.wrong_in_life, cap);
    }
    if command.value().is_some_and(|value| value != right) {
        c.ever_sent_wrong = true;
    }
    if c.fault == Some(Fault::WrongInput) && command.value().is_some() {
        c.wrong_input_in_life = count_up(c.wrong_input_in_life, cap);
    }
    if c.fault == Some(Fault::WrongLaw) && command.value().is_some() {
        c.wrong_law_in_life = count_up(c.wrong_law_in_life, cap);
    }
    if owns_exclusive {
        match command {
            Command::Sent(value) if value != right => {
                c.exclusive_wrong = count_up(c.exclusive_wrong, cap)
            }
            Command::Missing => c.exclusive_missed = count_up(c.exclusive_missed, cap),
            _ => {}
        }
        state.exclusive.taken = command.value();
    }
    voting_receives(config, state);
}

/// The voting receiver after an arrival: it accepts a value once two fresh sources agree on
/// it, then raises the dissent alarm of every source that sent another value and clears it
/// for every source that sent the accepted one.
fn voting_receives(config: &OutputConfig, state: &mut OutputState) {
    if state.voting.accepted.is_none() {
        let sources_needed = match config.mutation {
            Some(OutputMutation::AcceptSingleSource) => 1,
            _ => 2,
        };
        if let Some(value) = Value::ALL
            .into_iter()
            .find(|value| state.senders_of(*value) >= sources_needed)
        {
            state.voting.accepted = Some(value);
            state.voting.hold_alarm = false;
        }
    }
    if let Some(accepted) = state.voting.accepted {
        for (index, c) in state.controllers.iter().enumerate() {
            if let Command::Sent(value) = c.command {
                state.voting.dissent[index] = value != accepted;
            }
        }
    }
}

/// The current input closes: the voting receiver holds it (and raises the hold alarm) if it
/// accepted nothing, and every controller runs its cross-check on it, before it answers the
/// next input (with `CompareAfterNextCommand`, on the input before instead).
fn close_input(config: &OutputConfig, state: &mut OutputState) {
    state.closed_without_pair = state.agreed_value().is_none();
    if state.voting.accepted.is_none() {
        state.voting.hold_alarm = true;
    }
    let closing = state.controllers.map(|c| c.command);
    let lagging = config.mutation == Some(OutputMutation::CompareAfterNextCommand);
    let judged = if lagging {
        state.controllers.map(|c| c.previous)
    } else {
        closing
    };
    let inputs_wrong = state
        .controllers
        .map(|c| c.fault == Some(Fault::WrongInput));
    let laws_wrong = state.controllers.map(|c| c.fault == Some(Fault::WrongLaw));
    cross_check(config, state, &judged, &inputs_wrong, &laws_wrong);
    for (c, command) in state.controllers.iter_mut().zip(closing) {
        c.previous = if lagging && c.has_role() {
            command
        } else {
            Command::NoInstance
        };
    }
}

/// The next input opens with its right command: every controller with a role owes it an
/// answer, and the exclusive receiver's owner is the strongest writer left.
fn open_input(state: &mut OutputState, right: Value) {
    state.right = right;
    state.voting.accepted = None;
    state.exclusive = ExclusiveReceiver {
        owner: strongest_writer(state),
        taken: None,
    };
    for c in state.controllers.iter_mut() {
        c.command = if c.has_role() {
            Command::Pending
        } else {
            Command::NoInstance
        };
    }
}

/// The controller whose command differs from (or is missing beside) two agreeing others'.
/// Only a full comparison of three commands judges anyone.
pub fn odd_one_out(judged: &[Command; CONTROLLERS]) -> Option<Id> {
    let answered = judged
        .iter()
        .all(|command| matches!(command, Command::Sent(_) | Command::Missing));
    if !answered {
        return None;
    }
    (0..CONTROLLERS)
        .find(|&odd| {
            let others: Vec<Command> = (0..CONTROLLERS)
                .filter(|&index| index != odd)
                .map(|index| judged[index])
                .collect();
            others[0].value().is_some() && others[0] == others[1] && judged[odd] != others[0]
        })
        .and_then(|index| Id::try_from(index + 1).ok())
}

/// The controller whose input differs from two others' that agree (input congruence): each
/// command carries the digest of the input it answers, so only controllers that sent a
/// command are compared, and a wrong input agrees with no other input (two wrong inputs
/// differ).
pub fn odd_on_input(
    judged: &[Command; CONTROLLERS],
    inputs_wrong: &[bool; CONTROLLERS],
) -> Option<Id> {
    the_one_that_differs(judged, inputs_wrong)
}

/// The controller whose raw answer (its law's own step before alignment) differs from two
/// others' that agree: each command carries its raw answer, correct laws that answered the
/// same inputs give the same raw answer exactly, and a wrong law's differs from every other
/// (two wrong laws differ). Meant for answers to the same input only (see `cross_check`).
pub fn odd_on_law(judged: &[Command; CONTROLLERS], laws_wrong: &[bool; CONTROLLERS]) -> Option<Id> {
    the_one_that_differs(judged, laws_wrong)
}

/// Of three sent commands, the one whose carried digest differs (`differs`) when the two
/// others' are alike: exactly one differing. Only a full comparison of three sent commands
/// judges anyone.
fn the_one_that_differs(
    judged: &[Command; CONTROLLERS],
    differs: &[bool; CONTROLLERS],
) -> Option<Id> {
    if judged.iter().any(|command| command.value().is_none()) {
        return None;
    }
    let odd: Vec<usize> = (0..CONTROLLERS).filter(|&i| differs[i]).collect();
    match odd[..] {
        [odd] => Id::try_from(odd + 1).ok(),
        _ => None,
    }
}

/// Each controller with a role compares its own command, the input it answered and its raw
/// answer with the two others': the odd one out on any counts the input, and leaves once it
/// has counted N (`OutputConfig::odd_limit`), raising its input or law alarm about itself if it
/// was odd on input or on law.
fn cross_check(
    config: &OutputConfig,
    state: &mut OutputState,
    judged: &[Command; CONTROLLERS],
    inputs_wrong: &[bool; CONTROLLERS],
    laws_wrong: &[bool; CONTROLLERS],
) {
    let odd = odd_one_out(judged);
    let odd_input = match config.mutation {
        Some(OutputMutation::NoInputCongruence) => None,
        _ => odd_on_input(judged, inputs_wrong),
    };
    // Raw answers are compared only between answers to the same input: a controller that read
    // another input is not judged on law (its raw answer comes from that input), and of the two
    // left nobody can tell which law is wrong.
    let odd_law = match config.mutation {
        Some(OutputMutation::NoRawCompare) => None,
        _ if inputs_wrong.contains(&true) => None,
        _ => odd_on_law(judged, laws_wrong),
    };
    for c in state.controllers.iter_mut().filter(|c| c.has_role()) {
        if odd_input == Some(c.id) {
            c.odd_on_input = true;
        }
        if odd_law == Some(c.id) {
            c.odd_on_law = true;
        }
        if [odd, odd_input, odd_law].contains(&Some(c.id)) {
            c.odd_count = count_up(c.odd_count, config.odd_limit);
        } else if config.cross_check == CrossCheck::Consecutive {
            c.odd_count = 0;
        }
    }
    let leavers: Vec<Id> = state
        .controllers
        .iter()
        .filter(|c| c.has_role() && c.odd_count >= config.odd_limit)
        .map(|c| c.id)
        .collect();
    for id in &leavers {
        let c = state.controller_mut(*id);
        c.input_alarm = c.odd_on_input;
        c.law_alarm = c.odd_on_law;
        leave(state, *id);
    }
    if !leavers.is_empty() {
        rank_roles(state);
    }
}

/// A controller reports a local fault and leaves the bus: FAILED, no role, its command
/// instance gone. The voting receiver keeps its dissent alarm about it until it agrees again.
fn leave(state: &mut OutputState, id: Id) {
    let c = state.controller_mut(id);
    c.left_as = c.role;
    c.role = None;
    c.phase = Phase::Failed;
    c.command = Command::NoInstance;
}

/// The remaining role holders close ranks in their order: the role model's promotion,
/// abstracted to strength order.
fn rank_roles(state: &mut OutputState) {
    let mut holders: Vec<(Role, Id)> = state
        .controllers
        .iter()
        .filter_map(|c| c.role.map(|role| (role, c.id)))
        .collect();
    holders.sort();
    for (rank, (_, id)) in holders.into_iter().enumerate() {
        state.controller_mut(id).role = Role::at(rank);
    }
}

/// The controller whose writer the exclusive receiver follows: the strongest role's.
fn strongest_writer(state: &OutputState) -> Option<Id> {
    state
        .controllers
        .iter()
        .filter_map(|c| c.role.map(|role| (role.strength(), c.id)))
        .max()
        .map(|(_, id)| id)
}

/// A FAILED controller starts again as a new life in the lowest free role, answering the
/// current input; its output is correct again, or (`still_wrong`) keeps its fault.
fn restart(state: &mut OutputState, id: Id, still_wrong: bool) {
    let holders = state.controllers.iter().filter(|c| c.has_role()).count();
    let c = state.controller_mut(id);
    *c = Controller {
        phase: Phase::Steady,
        role: Role::at(holders),
        fault: if still_wrong { c.fault } else { None },
        restarted: true,
        ever_sent_wrong: c.ever_sent_wrong,
        ..Controller::new(id, Role::Tertiary)
    };
    state.exclusive.owner = strongest_writer(state);
    note_wrong_controllers(state);
}
