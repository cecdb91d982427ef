//! Output voting at the receiver, pure: every controller with a role publishes its own answer
//! to each input on a voted topic (crate::wire::VotedSample), and the receiving application
//! takes a value only when at least two fresh controllers agree on it. The paper's
//! hyper-critical extension: the receiver "selects the best two or three command instances and
//! alarms any dissenting command source". RL's role vote alone never compares command values,
//! so a Primary that keeps heartbeating but computes wrong commands drives an exclusive reader
//! for as long as it lives; a voting reader refuses its values and names it.
//!
//! [`VoteReader`] is pure, like crate::arbiter: answers and times (milliseconds on any
//! monotonic scale) in, [`VoteEvent`]s out; crate::vote_feed reads the topic over DDS into it.
//! What agrees and how agreeing answers make one value is the application's, a [`VoteRule`]
//! ([`ServoRule`] for servo commands: a tolerance per axis, the median of the agreeing).
//!
//! The rules (docs/protocol.md, "Output voting at the receiver"):
//! - **Fresh**: a controller counts while its last answer arrived within
//!   [`VoteSettings::freshness_ms`] (the command deadline; writers answer at least that often).
//!   Answers are compared only when they answer the same input, and the vote is on the newest
//!   input that two fresh controllers have answered: a controller answering another input (one
//!   frame behind, or ahead) abstains on this one.
//! - **Accepted**: the largest set of answers that agree pairwise, if it has two or more (ties:
//!   {1,2} before {1,3} before {2,3}); its value is [`VoteRule::combine`] of them. A later answer to the accepted
//!   input that agrees with every member joins the set (the value is combined again).
//! - **Dissent**: a controller whose answer to a decided input disagrees with the agreeing set
//!   dissents; at its [`VoteSettings::dissent_after`]th dissent (counted in a row or not, since
//!   its alarm was last cleared: a count that forgets misses a controller wrong at every other
//!   input, finding O2 of docs/findings.md) it is alarmed ([`VoteEvent::Dissent`], raised), and
//!   the alarm stays until it has agreed on `dissent_after` inputs in a row. Each controller is
//!   judged once per input. Its value is never taken. With `dissent_after` 1 this is the output
//!   model's receiver (`model/src/outputs/`): raised at a dissent, cleared at an agreement.
//! - **No majority**: when every fresh controller has answered the newest input and no two
//!   agree, or when nothing has been accepted (nor the accepted input confirmed by two fresh
//!   members) for `freshness_ms`, the receiver holds its last accepted value or goes to a safe
//!   value ([`Fallback`]), reported once ([`VoteEvent::NoMajority`]) until a value is accepted
//!   again.

use crate::core::types::ControllerId;
use crate::wire::{ServoControl, Voted};
use std::collections::{BTreeMap, BTreeSet};

/// What agrees and how agreeing answers make one value: the application's half of the vote.
pub trait VoteRule<T> {
    /// Whether two answers to the same input agree (symmetric; it need not be transitive).
    fn agree(&self, a: &T, b: &T) -> bool;
    /// The value of a set of pairwise agreeing answers (two or more, by controller id).
    fn combine(&self, agreeing: &[T]) -> T;
}

/// The default tolerance per servo axis, in servo units (0..=1000): one PD step of the tracker
/// at a large error (about 50 px off centre moves an axis by about 25), so two controllers a
/// camera frame apart still agree, while a command off by more is refused.
pub const SERVO_TOLERANCE_DEFAULT: u16 = 25;

/// Servo commands agree when pan and tilt each differ by at most their tolerance and the
/// frequency is the same; agreeing commands combine into the median of each axis (the lower
/// middle one of an even count: always a value a controller sent).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ServoRule {
    /// Largest pan difference that agrees.
    pub pan_tolerance: u16,
    /// Largest tilt difference that agrees.
    pub tilt_tolerance: u16,
}

impl Default for ServoRule {
    fn default() -> ServoRule {
        ServoRule {
            pan_tolerance: SERVO_TOLERANCE_DEFAULT,
            tilt_tolerance: SERVO_TOLERANCE_DEFAULT,
        }
    }
}

impl VoteRule<ServoControl> for ServoRule {
    fn agree(&self, a: &ServoControl, b: &ServoControl) -> bool {
        a.pan.abs_diff(b.pan) <= self.pan_tolerance
            && a.tilt.abs_diff(b.tilt) <= self.tilt_tolerance
            && a.frequency == b.frequency
    }

    fn combine(&self, agreeing: &[ServoControl]) -> ServoControl {
        ServoControl {
            pan: lower_median(agreeing.iter().map(|c| c.pan)),
            tilt: lower_median(agreeing.iter().map(|c| c.tilt)),
            frequency: lower_median(agreeing.iter().map(|c| c.frequency)),
        }
    }
}

/// The median of `values`, the lower middle one of an even count; 0 for none.
pub fn lower_median(values: impl Iterator<Item = u16>) -> u16 {
    let mut sorted: Vec<u16> = values.collect();
    sorted.sort_unstable();
    match sorted.len() {
        0 => 0,
        n => sorted[(n - 1) / 2],
    }
}

/// What the receiver does when no two controllers agree.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Fallback<T> {
    /// Keep the last accepted value (the actuator stays where it is).
    Hold,
    /// Go to this value (a safe position).
    Safe(T),
}

/// How a [`VoteReader`] votes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct VoteSettings<T> {
    /// How long a controller's last answer keeps it fresh (the command deadline).
    pub freshness_ms: u64,
    /// Dissents (decided inputs, in a row or not) that raise a controller's alarm, and
    /// agreements in a row that clear it (1: at the first, as the output model's receiver; the
    /// default 3 rides out a controller a frame out of step at formation, measured once or twice
    /// in four formations of `rl controller`s).
    pub dissent_after: u32,
    /// What to do without a majority.
    pub fallback: Fallback<T>,
}

/// The default of [`VoteSettings::dissent_after`].
pub const DISSENT_AFTER_DEFAULT: u32 = 3;

impl<T> VoteSettings<T> {
    /// Holding without a majority, alarming after [`DISSENT_AFTER_DEFAULT`] dissents.
    pub fn holding(freshness_ms: u64) -> VoteSettings<T> {
        VoteSettings {
            freshness_ms,
            dissent_after: DISSENT_AFTER_DEFAULT,
            fallback: Fallback::Hold,
        }
    }
}

/// What the reader decided.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum VoteEvent<T> {
    /// `value` is the voted answer to `input`, from the agreeing controllers (by id). Given
    /// again when a later answer joins the agreeing set.
    Accepted {
        /// The input answered.
        input: u64,
        /// The combined value of the agreeing answers.
        value: T,
        /// The controllers whose answers agreed, by id.
        agreeing: Vec<ControllerId>,
    },
    /// The dissent alarm about `source` was raised (its answer `value` to `input` disagreed
    /// with the agreeing set, `dissent_after` decided inputs in a row) or cleared (`value`,
    /// its answer to `input`, agreed again).
    Dissent {
        /// The dissenting controller.
        source: ControllerId,
        /// `true` raised, `false` cleared.
        raised: bool,
        /// The input of the answer that raised or cleared it.
        input: u64,
        /// That answer.
        value: T,
    },
    /// No two fresh controllers agree: the receiver falls back (`value`: the last accepted
    /// one when holding, `None` if there is none, or the safe value). Reported once until a
    /// value is accepted again.
    NoMajority {
        /// The newest input the fresh controllers answered without agreeing; `None` when
        /// fewer than two answered any input within the freshness.
        input: Option<u64>,
        /// The fresh controllers, by id.
        fresh: Vec<ControllerId>,
        /// What the receiver does.
        fallback: Fallback<T>,
        /// The value it holds or goes to.
        value: Option<T>,
    },
}

/// A controller's newest answer and when it arrived.
#[derive(Clone, Debug)]
struct Answer<T> {
    input: u64,
    value: T,
    received_ms: u64,
}

/// A controller's standing: its dissents since its alarm was last cleared (in a row or not),
/// its agreements in a row, whether it is alarmed, the last input it was judged on.
#[derive(Clone, Copy, Debug, Default)]
struct Standing {
    dissents: u32,
    agreements_in_a_row: u32,
    alarmed: bool,
    judged_input: Option<u64>,
}

/// The accepted input: its agreeing answers and their value.
#[derive(Clone, Debug)]
struct Acceptance<T> {
    input: u64,
    agreeing: BTreeMap<ControllerId, T>,
    value: T,
}

/// Answers considered for one input at most (the lowest ids): the search for the largest
/// agreeing set goes through every subset of them.
pub const MAX_VOTERS: usize = 8;

/// The receiver's vote over the controllers' answers (see the module's rules).
#[derive(Clone, Debug)]
pub struct VoteReader<T, R> {
    rule: R,
    settings: VoteSettings<T>,
    answers: BTreeMap<ControllerId, Answer<T>>,
    standings: BTreeMap<ControllerId, Standing>,
    accepted: Option<Acceptance<T>>,
    /// When a majority last stood (an acceptance, or the accepted input confirmed by two fresh
    /// members); before any, when the first answer arrived.
    majority_at_ms: Option<u64>,
    /// A no-majority was reported and no value has been accepted since.
    without_majority: bool,
    /// Every answer is taken alone as it arrives: false, true only under a deliberately
    /// broken rule ([`VoteMutation::AcceptSingleSource`]).
    one_source_decides: bool,
}

/// The receiver's deliberately broken rules (a `mutation` build), to show that the tests and
/// the lab's judges catch a broken vote: `RL_VOTE_MUTATION=accept-single-source` on `rl servo
/// --vote` or `rl shapes --vote`.
#[cfg(feature = "mutation")]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VoteMutation {
    /// A value is accepted from one source: every answer to the accepted input or a newer one
    /// is taken alone as it arrives, so each answer of a wrong controller reaches the
    /// application, whatever order the answers come in.
    AcceptSingleSource,
}

#[cfg(feature = "mutation")]
impl VoteMutation {
    /// The environment variable that names one.
    pub const VARIABLE: &'static str = "RL_VOTE_MUTATION";

    /// The mutation `RL_VOTE_MUTATION` names: `Ok(None)` when it is unset, an error naming
    /// the value when it names none.
    pub fn from_env() -> Result<Option<VoteMutation>, String> {
        match std::env::var(Self::VARIABLE) {
            Err(_) => Ok(None),
            Ok(name) if name == "accept-single-source" => {
                Ok(Some(VoteMutation::AcceptSingleSource))
            }
            Ok(name) => Err(format!(
                "{}={name} is not a vote mutation; known: accept-single-source",
                Self::VARIABLE
            )),
        }
    }
}

impl<T: Clone, R: VoteRule<T>> VoteReader<T, R> {
    /// A reader with no answers yet.
    pub fn new(rule: R, settings: VoteSettings<T>) -> VoteReader<T, R> {
        VoteReader {
            rule,
            settings,
            answers: BTreeMap::new(),
            standings: BTreeMap::new(),
            accepted: None,
            majority_at_ms: None,
            without_majority: false,
            one_source_decides: false,
        }
    }

    /// Breaks its rule on purpose (`mutation`).
    #[cfg(feature = "mutation")]
    pub fn mutate(&mut self, mutation: VoteMutation) {
        match mutation {
            VoteMutation::AcceptSingleSource => self.one_source_decides = true,
        }
    }

    /// Takes in `answer`, received at `now_ms`, and votes. Times must not go backwards.
    pub fn offer(&mut self, answer: Voted<T>, now_ms: u64) -> Vec<VoteEvent<T>> {
        self.majority_at_ms.get_or_insert(now_ms);
        if self.one_source_decides {
            return self.take_alone(answer, now_ms);
        }
        self.answers.insert(
            answer.from,
            Answer {
                input: answer.input,
                value: answer.value,
                received_ms: now_ms,
            },
        );
        self.vote(now_ms)
    }

    /// The broken rule ([`VoteMutation::AcceptSingleSource`]): `answer` is taken alone when it
    /// answers the accepted input or a newer one.
    fn take_alone(&mut self, answer: Voted<T>, now_ms: u64) -> Vec<VoteEvent<T>> {
        if self
            .accepted_input()
            .is_some_and(|accepted| answer.input < accepted)
        {
            return Vec::new();
        }
        let accepted = Acceptance {
            input: answer.input,
            agreeing: BTreeMap::from([(answer.from, answer.value.clone())]),
            value: answer.value,
        };
        let events = vec![Self::acceptance_event(&accepted)];
        self.accepted = Some(accepted);
        self.majority_at_ms = Some(now_ms);
        self.without_majority = false;
        events
    }

    /// Votes again at `now_ms` without a new answer (controllers go stale, a majority lapses).
    pub fn tick(&mut self, now_ms: u64) -> Vec<VoteEvent<T>> {
        self.vote(now_ms)
    }

    /// The last accepted value, if any.
    pub fn accepted(&self) -> Option<&T> {
        self.accepted.as_ref().map(|a| &a.value)
    }

    /// The input of the last accepted value, if any.
    pub fn accepted_input(&self) -> Option<u64> {
        self.accepted.as_ref().map(|a| a.input)
    }

    /// Whether the receiver is without a majority now (a no-majority reported, nothing
    /// accepted since).
    pub fn without_majority(&self) -> bool {
        self.without_majority
    }

    /// The controllers whose dissent alarm is raised, by id.
    pub fn dissenting(&self) -> Vec<ControllerId> {
        let alarmed = self.standings.iter().filter(|(_, s)| s.alarmed);
        alarmed.map(|(id, _)| *id).collect()
    }

    /// The settings it votes with.
    pub fn settings(&self) -> &VoteSettings<T> {
        &self.settings
    }

    fn fresh(&self, now_ms: u64) -> BTreeSet<ControllerId> {
        let freshness = self.settings.freshness_ms;
        let fresh = self.answers.iter();
        let fresh = fresh.filter(|(_, a)| now_ms.saturating_sub(a.received_ms) <= freshness);
        fresh.map(|(id, _)| *id).collect()
    }

    /// The fresh controllers' answers to `input`, by id (at most [`MAX_VOTERS`]).
    fn answers_to(&self, input: u64, fresh: &BTreeSet<ControllerId>) -> Vec<(ControllerId, T)> {
        let answering = fresh.iter().filter_map(|id| {
            let answer = self.answers.get(id)?;
            (answer.input == input).then(|| (*id, answer.value.clone()))
        });
        answering.take(MAX_VOTERS).collect()
    }

    /// The newest input that two fresh controllers answer.
    fn newest_shared_input(&self, fresh: &BTreeSet<ControllerId>) -> Option<u64> {
        let mut count: BTreeMap<u64, usize> = BTreeMap::new();
        for id in fresh {
            if let Some(answer) = self.answers.get(id) {
                *count.entry(answer.input).or_default() += 1;
            }
        }
        count
            .into_iter()
            .rev()
            .find(|(_, n)| *n >= 2)
            .map(|(i, _)| i)
    }

    fn vote(&mut self, now_ms: u64) -> Vec<VoteEvent<T>> {
        let mut events = Vec::new();
        let fresh = self.fresh(now_ms);
        let accepted_input = self.accepted_input();
        match self.newest_shared_input(&fresh) {
            Some(input) if Some(input) == accepted_input => {
                self.judge_late_answers(input, &fresh, now_ms, &mut events);
            }
            Some(input) if accepted_input.is_none_or(|accepted| input > accepted) => {
                self.decide(input, &fresh, now_ms, &mut events);
            }
            _ => {}
        }
        let lapsed = self
            .majority_at_ms
            .is_some_and(|at| now_ms.saturating_sub(at) > self.settings.freshness_ms);
        if lapsed {
            self.fall_back(None, &fresh, &mut events);
        }
        events
    }

    /// Votes on a new input: accepts the largest agreeing set, or falls back once every fresh
    /// controller has answered it (or a newer one) and no two agree.
    fn decide(
        &mut self,
        input: u64,
        fresh: &BTreeSet<ControllerId>,
        now_ms: u64,
        events: &mut Vec<VoteEvent<T>>,
    ) {
        let answers = self.answers_to(input, fresh);
        match largest_agreeing(&self.rule, &answers) {
            Some(agreeing) => {
                let agreeing: BTreeMap<ControllerId, T> = agreeing
                    .into_iter()
                    .map(|index| answers[index].clone())
                    .collect();
                let values: Vec<T> = agreeing.values().cloned().collect();
                let value = self.rule.combine(&values);
                let accepted = Acceptance {
                    input,
                    agreeing,
                    value,
                };
                events.push(Self::acceptance_event(&accepted));
                self.accepted = Some(accepted);
                self.majority_at_ms = Some(now_ms);
                self.without_majority = false;
                for (id, value) in answers {
                    self.judge(id, input, value, events);
                }
            }
            None => {
                let all_in = fresh
                    .iter()
                    .all(|id| self.answers.get(id).is_some_and(|a| a.input >= input));
                if all_in {
                    self.fall_back(Some(input), fresh, events);
                }
            }
        }
    }

    /// Answers to the accepted input that arrived after it was accepted: one agreeing with
    /// every member joins the set; one that does not dissents. Two fresh members confirm the
    /// majority.
    fn judge_late_answers(
        &mut self,
        input: u64,
        fresh: &BTreeSet<ControllerId>,
        now_ms: u64,
        events: &mut Vec<VoteEvent<T>>,
    ) {
        for (id, value) in self.answers_to(input, fresh) {
            let judged = self.standings.get(&id).and_then(|s| s.judged_input);
            let Some(accepted) = self.accepted.as_mut() else {
                return;
            };
            if judged == Some(input) || accepted.agreeing.contains_key(&id) {
                continue;
            }
            if accepted
                .agreeing
                .values()
                .all(|m| self.rule.agree(m, &value))
            {
                accepted.agreeing.insert(id, value.clone());
                let values: Vec<T> = accepted.agreeing.values().cloned().collect();
                accepted.value = self.rule.combine(&values);
                events.push(Self::acceptance_event(accepted));
            }
            self.judge(id, input, value, events);
        }
        let confirmed = self.accepted.as_ref().is_some_and(|accepted| {
            accepted
                .agreeing
                .keys()
                .filter(|id| fresh.contains(id))
                .count()
                >= 2
        });
        if confirmed {
            self.majority_at_ms = Some(now_ms);
        }
    }

    fn acceptance_event(accepted: &Acceptance<T>) -> VoteEvent<T> {
        VoteEvent::Accepted {
            input: accepted.input,
            value: accepted.value.clone(),
            agreeing: accepted.agreeing.keys().copied().collect(),
        }
    }

    /// Judges `source`'s answer `value` to the decided `input`, once per input: in the
    /// agreeing set it agrees (clearing its alarm after `dissent_after` in a row), else it
    /// dissents (raising one after `dissent_after` since the alarm was last cleared, in a row
    /// or not: a count that forgets would never name a controller wrong at every other input,
    /// finding O2 of docs/findings.md).
    fn judge(
        &mut self,
        source: ControllerId,
        input: u64,
        value: T,
        events: &mut Vec<VoteEvent<T>>,
    ) {
        let agrees = self
            .accepted
            .as_ref()
            .is_some_and(|a| a.input == input && a.agreeing.contains_key(&source));
        let dissent_after = self.settings.dissent_after.max(1);
        let standing = self.standings.entry(source).or_default();
        if standing.judged_input == Some(input) {
            return;
        }
        standing.judged_input = Some(input);
        let raised = if agrees {
            standing.agreements_in_a_row = standing.agreements_in_a_row.saturating_add(1);
            let clear = standing.alarmed && standing.agreements_in_a_row >= dissent_after;
            if clear {
                *standing = Standing {
                    judged_input: Some(input),
                    ..Standing::default()
                };
            }
            clear.then_some(false)
        } else {
            standing.agreements_in_a_row = 0;
            standing.dissents = standing.dissents.saturating_add(1);
            let due = standing.dissents >= dissent_after && !standing.alarmed;
            standing.alarmed |= due;
            due.then_some(true)
        };
        if let Some(raised) = raised {
            events.push(VoteEvent::Dissent {
                source,
                raised,
                input,
                value,
            });
        }
    }

    /// Reports the fallback once, until a value is accepted again.
    fn fall_back(
        &mut self,
        input: Option<u64>,
        fresh: &BTreeSet<ControllerId>,
        events: &mut Vec<VoteEvent<T>>,
    ) {
        if self.without_majority {
            return;
        }
        self.without_majority = true;
        let value = match &self.settings.fallback {
            Fallback::Hold => self.accepted().cloned(),
            Fallback::Safe(safe) => Some(safe.clone()),
        };
        events.push(VoteEvent::NoMajority {
            input,
            fresh: fresh.iter().copied().collect(),
            fallback: self.settings.fallback.clone(),
            value,
        });
    }
}

/// The indices of the largest set of `answers` (two or more) that agree pairwise; among sets
/// of one size, the first by the bits of their members' places in id order (of three
/// controllers: {1,2}, then {1,3}, then {2,3}).
fn largest_agreeing<T, R: VoteRule<T>>(
    rule: &R,
    answers: &[(ControllerId, T)],
) -> Option<Vec<usize>> {
    let n = answers.len().min(MAX_VOTERS);
    let agree = |i: usize, j: usize| rule.agree(&answers[i].1, &answers[j].1);
    let mut best: Option<Vec<usize>> = None;
    // Subsets in increasing bit order visit lower ids first among sets of one size.
    for mask in 1u32..(1 << n) {
        let members: Vec<usize> = (0..n).filter(|i| mask & (1 << i) != 0).collect();
        if members.len() < 2 || best.as_ref().is_some_and(|b| b.len() >= members.len()) {
            continue;
        }
        let pairwise = members
            .iter()
            .enumerate()
            .all(|(k, &i)| members[k + 1..].iter().all(|&j| agree(i, j)));
        if pairwise {
            best = Some(members);
        }
    }
    best
}

#[cfg(test)]
mod tests;
