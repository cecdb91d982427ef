//! The controller-side cross-check, pure: each controller compares its own answer to an input
//! with the two others' answers to the same input (read from the voted topic), and a controller
//! that is the odd one out of three at N inputs of one life reports a local fault and leaves.
//! This protects an exclusive-ownership reader too, which takes the Primary's commands whatever
//! they are: a wrong Primary leaves after at most N wrong answers, and the actuator moves to the
//! next strongest writer (one owner change). The output model's rules 4 and 5
//! (`model/src/outputs/`, docs/protocol.md "Output voting"):
//!
//! - **Odd one out**: of an input that two peers answered, when those two agree with each
//!   other ([`VoteRule::agree`]) and its own answer agrees with neither. Only a full comparison
//!   judges anyone: with one peer's answer (or none) nobody can tell which is wrong. Agreeing
//!   with neither, not merely with one, so that tolerance, which is not transitive, never makes
//!   a correct controller odd: its answer is within the tolerance of the correct peer's.
//! - **Per life**: N odd inputs in one life, in a row or not (a count that forgets never
//!   catches a controller wrong at every other input: finding O2 of docs/findings.md); a new
//!   life counts from zero.
//! - **Order**: an input is judged when the controller answers the next one, before that answer
//!   goes out ([`CrossCheck::answer`]), so the N-th odd answer of a life is its last.
//! - **Late answers**: when the peers' answers to an input came after the controller answered
//!   the next one (the model's timing assumption broken: a loaded host, a slow link), the input
//!   is judged at the first later input at which they are in (up to [`PENDING_KEPT`] inputs
//!   back), so a wrong controller leaves on a slow bus too; each answer that went out before
//!   its input was judged (or never judged) is counted in [`OddOneOut::late`], so the bound at
//!   an exclusive reader, N wrong answers, is N + `late` when the assumption did not hold.
//! - **Judged in step**: an input is judged only if, before answering it, the controller took
//!   the group's position from the accepted answers to the input it answered before, and the
//!   newest input it took the group's position at is that one ([`CrossCheck::aligned`]; the
//!   tracker's bumpless transfer): at a newer one the group answered an input it did not (a
//!   camera frame lost to it), and its law's memory of the last input differs from theirs.
//!   An application with state (the tracker integrates its errors) answers from that state; taken from the group at the input
//!   before, the state is the group's, and an answer that differs is its own computation's
//!   fault. Otherwise it answered from its own state (at formation, a controller that began
//!   tracking a frame later than the others; or the group's answers came late), which is not
//!   wrong. This is the model's timing assumption, answers to an input arriving before the
//!   next input, met for both inputs; without it an input is not compared, as in the model.
//!
//! Input congruence (the triplex flight controls' rule: a channel is compared on what it read
//! as well as on what it computed), judged before the output and whether or not in step, since
//! an application that aligns its state to the group's can compute the group's output from a
//! wrong input, and the fault is then masked and latent:
//!
//! - **Another value of the same input**: two peers answered the input with the same digest
//!   ([`crate::wire::Voted::input_digest`]) and its own differs: odd on input, counted per life
//!   toward the same N as odd outputs ([`OddOn::Input`]; the output model's rule 4).
//! - **Inputs the group never had**: its input has no peer's answer, while two peers, agreeing
//!   on an input between them, both answered inputs newer than it (a peer answers its inputs
//!   in order, and reliably enough that a peer's answer to one of them is seldom missed):
//!   a foreign input. [`FOREIGN_LIMIT`] of them in a row, none of its inputs shared with a
//!   peer in between, and it leaves: a controller reading another camera, or a replayed or
//!   frozen stream. In a row, as a frame both peers skipped under load (their camera readers
//!   keep only the newest frame) is no fault of its own; and only for an answer judged within
//!   three of its own answers after it, as one kept while the peers' answers were not coming
//!   (a cut) is no evidence when they come again for newer inputs.
//!
//! Raw answers (the output model's rule 4 on the law), judged after the output, in step: its
//! answer agreed with the peers' within the tolerance, yet its law may be wrong by less than
//! the tolerance at every input, masked because each input starts from the group's position
//! (a wrong gain, a wrong build). Each answer carries its raw answer ([`RawAnswer`]: the law's
//! own step, and the input before it that the step's memory came from), the same bit for bit
//! at every correct controller that answered the same two inputs:
//!
//! - **Another raw answer**: two peers answered the input with the same input digest and the
//!   same raw answer from the same input before as its own, and its raw answer differs: odd
//!   on its law, counted per life toward the same N ([`OddOn::Law`]). Exactly, not within a
//!   tolerance: the step is a function of the two inputs alone, so any difference is its
//!   computation's. Only with two peers' raw answers in when it is judged, as the model
//!   judges only a full comparison; a peer that answered from another input before (a frame
//!   it skipped) is not compared.
//!
//! Where it differs from the model: a controller that omits its answers judges nothing (its
//! own answer is what it compares), so an omission is the receiver's to catch (a silent
//! controller goes stale at the voting reader; the exclusive reader's deadline moves on).

use crate::core::types::ControllerId;
use crate::vote_reader::VoteRule;
use crate::wire::RawAnswer;
use std::collections::BTreeMap;

/// The default N: odd-one-out inputs in one life before a controller leaves. The model's
/// value: N = 1 removes a correct controller at one glitch; N = 2 tolerates one per life at
/// the price of one more wrong command at an exclusive reader (K = N, docs/protocol.md).
pub const ODD_LIMIT_DEFAULT: u32 = 2;

/// Inputs of peers' answers kept for the comparison: the newest few (a peer answering far
/// ahead of this controller is compared with nothing).
const INPUTS_KEPT: usize = 8;

/// Its own answers kept unjudged while the peers' answers to them are not all in: the newest
/// few (with a peer gone, its answers are never compared and are let go).
pub const PENDING_KEPT: usize = 4;

/// Late inputs remembered for [`OddOneOut::late`] (a bound on memory; more than this many
/// late answers since the last agreement report this many).
const LATE_KEPT: usize = 64;

/// Foreign inputs in a row (see the module's rules) at which a controller leaves: at 30
/// camera frames a second, 5 frames are 167 ms, judged at most [`PENDING_KEPT`] frames later.
pub const FOREIGN_LIMIT: usize = 5;

/// A foreign input counts only when judged within this many of its own answers after it: the
/// peers' answer to the group's next frame arrives as it answers its own next one, so a
/// foreign frame is judged one or two answers on (three on a loaded host); an answer kept
/// longer (its peers' answers not coming, then coming again for newer inputs after a cut) is
/// no evidence. Of the [`PENDING_KEPT`] answers kept through a cut, at most this many look
/// foreign when it heals, so one more lost answer after it still leaves fewer than
/// [`FOREIGN_LIMIT`].
const FOREIGN_JUDGED_WITHIN: usize = 3;

/// What a controller was the odd one out of three on.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OddOn {
    /// Its answers: its output agreed with neither of two agreeing peers'.
    #[default]
    Output,
    /// Its input, at one of the odd inputs at least: another value of an input two agreeing
    /// peers answered alike, or inputs neither of them received (input congruence).
    Input,
    /// Its law, at one of the odd inputs at least: its output agreed, its raw answer differed
    /// from two agreeing peers' raw answers to the same input from the same input before.
    Law,
}

/// Why a controller leaves: the inputs at which it was the odd one out of three.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OddOneOut {
    /// What it was odd on.
    pub on: OddOn,
    /// The odd-one-out inputs of this life, oldest first (`odd_limit` of them; on input,
    /// the odd or foreign inputs).
    pub inputs: Vec<u64>,
    /// N.
    pub odd_limit: u32,
    /// The peers that agreed with each other at the last of them.
    pub peers: Vec<ControllerId>,
    /// Its answers since the last one judged not odd that went out before they were judged
    /// at their next input (the peers' answers, or the group's position, came later; judged
    /// later or never): 0 when the model's timing assumption held, and then an exclusive
    /// reader took at most `odd_limit` wrong answers of this life; at most `odd_limit` + `late`.
    pub late: u32,
}

impl std::fmt::Display for OddOneOut {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let peers: Vec<String> = self.peers.iter().map(|id| format!("C{id}")).collect();
        let odd_on = match self.on {
            OddOn::Output => None,
            OddOn::Input => Some(("input", "input disagrees")),
            OddOn::Law => Some(("its law", "raw answers disagree")),
        };
        if let Some((on, what)) = odd_on {
            return write!(
                f,
                "the odd one out of three on {on} at {} inputs of this life ({}): its {what} \
                 with both of {}, which agree",
                self.inputs.len(),
                self.inputs
                    .iter()
                    .map(u64::to_string)
                    .collect::<Vec<_>>()
                    .join(", "),
                peers.join(" and ")
            );
        }
        write!(
            f,
            "the odd one out of three at {} inputs of this life ({}): its answers disagree \
             with both of {}, which agree",
            self.inputs.len(),
            self.inputs
                .iter()
                .map(u64::to_string)
                .collect::<Vec<_>>()
                .join(", "),
            peers.join(" and ")
        )?;
        if self.late > 0 {
            write!(
                f,
                " ({} answers went out before they could be judged at their next input)",
                self.late
            )?;
        }
        Ok(())
    }
}

/// What the controller does with its answer to a new input.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Judgement {
    /// Publish it.
    Answer,
    /// Publish nothing more: report a local fault and leave (`Redundancy::report_odd_one_out`).
    Leave(OddOneOut),
}

/// The controller's answer to one input.
#[derive(Clone, Debug)]
struct OwnAnswer<T> {
    input: u64,
    /// The digest of the input's values (0: none).
    digest: u64,
    /// Its raw answer.
    raw: RawAnswer,
    value: T,
    /// Computed from the group's position at the input answered before.
    in_step: bool,
    /// Its own answers to later inputs so far (1 when judged on time).
    answered_after: usize,
}

/// One controller's cross-check (see the module's rules).
#[derive(Clone, Debug)]
pub struct CrossCheck<T, R> {
    own: ControllerId,
    rule: R,
    odd_limit: u32,
    /// Peers' answers by input, the newest [`INPUTS_KEPT`] inputs.
    peers: BTreeMap<u64, BTreeMap<ControllerId, PeerAnswer<T>>>,
    /// Its own answers not judged yet, oldest first: the input it answers now (judged at the
    /// next input) and earlier ones whose peers' answers are not all in.
    pending: Vec<OwnAnswer<T>>,
    /// Late answers since the last one judged not odd, by input (see [`OddOneOut::late`]).
    late: std::collections::BTreeSet<u64>,
    /// The newest input whose group position it took in this life.
    aligned_to: Option<u64>,
    /// The group has answered an input alike, all three, in this life (see
    /// [`CrossCheck::all_agreed`]): nothing is judged before.
    group_formed: bool,
    /// This life's odd-one-out inputs.
    odd_inputs: Vec<u64>,
    /// This life's inputs whose value disagreed with two agreeing peers' (odd on input; also
    /// in `odd_inputs`, which counts both grounds toward N).
    odd_on_input: Vec<u64>,
    /// This life's inputs whose raw answer disagreed with two agreeing peers' (odd on its
    /// law; also in `odd_inputs`).
    odd_on_law: Vec<u64>,
    /// The foreign inputs since its last input shared with a peer.
    foreign: Vec<u64>,
    /// Decided to leave, and why: nothing more is answered in this life.
    left: Option<OddOneOut>,
}

impl<T: Clone, R: VoteRule<T>> CrossCheck<T, R> {
    /// The cross-check of controller `own`, agreeing by `rule`, leaving at `odd_limit` odd
    /// inputs in one life (0: never; the check only counts).
    pub fn new(own: ControllerId, rule: R, odd_limit: u32) -> CrossCheck<T, R> {
        CrossCheck {
            own,
            rule,
            odd_limit,
            peers: BTreeMap::new(),
            pending: Vec::new(),
            late: std::collections::BTreeSet::new(),
            aligned_to: None,
            group_formed: false,
            odd_inputs: Vec::new(),
            odd_on_input: Vec::new(),
            odd_on_law: Vec::new(),
            foreign: Vec::new(),
            left: None,
        }
    }

    /// A peer's answer `value` to `input`, whose values had the digest `digest` (0: none),
    /// with its raw answer `raw`, as it arrived (trusted: its participant speaks for `from`).
    /// Its own answers, read back, are ignored: it compares what it computed.
    pub fn peer_answer(
        &mut self,
        from: ControllerId,
        input: u64,
        digest: u64,
        raw: RawAnswer,
        value: T,
    ) {
        if from == self.own {
            return;
        }
        let answer = PeerAnswer { digest, raw, value };
        self.peers.entry(input).or_default().insert(from, answer);
        while self.peers.len() > INPUTS_KEPT {
            self.peers.pop_first();
        }
    }

    /// The vote accepted an input on which all three controllers agreed: from now on in this
    /// life the peers compute from the group's position too, and its answers are judged. At
    /// formation a peer takes its position from the owner's commands until the vote works,
    /// so two peers may agree with each other and not with a right controller in step (the
    /// lab's `partition-actuator-with-two` saw a right Primary leave 0.2 s after formation).
    pub fn all_agreed(&mut self) {
        self.group_formed = true;
    }

    /// The controller took the group's position from the answers to `input` (bumpless
    /// transfer): its answer to the next input is the group's to compare.
    pub fn aligned(&mut self, input: u64) {
        self.aligned_to = self.aligned_to.max(Some(input));
    }

    /// Its answer `value` to `input`, whose values had the digest `digest` (0: none), with its
    /// raw answer `raw`, before it goes out: judges the inputs it answered before (rule 5,
    /// input congruence and raw answers; late ones as soon as the peers' answers are in) and
    /// says whether to publish. Answering the same input again (a re-publication) only
    /// replaces the answer kept for it.
    pub fn answer(&mut self, input: u64, digest: u64, raw: RawAnswer, value: T) -> Judgement {
        if let Some(left) = &self.left {
            return Judgement::Leave(left.clone());
        }
        if let Some(last) = self.pending.last_mut().filter(|p| p.input == input) {
            last.value = value;
            return Judgement::Answer;
        }
        let previous = self.pending.last().map(|p| p.input);
        // The group's position at exactly the input it answered before: at a newer one, the
        // group answered an input it did not (a camera frame lost to it, or peers ahead), and
        // its law's memory of the last frame (the PD's previous error) is not the group's.
        let in_step = self.group_formed && previous.is_some_and(|p| self.aligned_to == Some(p));
        for mut answer in std::mem::take(&mut self.pending) {
            if answer.input > input {
                continue;
            }
            let on_time = Some(answer.input) == previous;
            answer.answered_after += 1;
            if let Some(verdict) = self.judge(answer, on_time) {
                self.left = Some(verdict.clone());
                return Judgement::Leave(verdict);
            }
        }
        while self.pending.len() >= PENDING_KEPT {
            let let_go = self.pending.remove(0);
            self.note_late(let_go.input);
        }
        self.pending.push(OwnAnswer {
            input,
            digest,
            raw,
            value,
            in_step,
            answered_after: 0,
        });
        Judgement::Answer
    }

    /// Judges its earlier `answer` (`on_time`: at the input after it): kept pending while the
    /// peers' answers are not all in; the verdict when it is the N-th odd input of the life.
    fn judge(&mut self, answer: OwnAnswer<T>, on_time: bool) -> Option<OddOneOut> {
        let mut input = self.compare_input(answer.input, answer.digest);
        let kept_long = answer.answered_after > FOREIGN_JUDGED_WITHIN;
        if matches!(input, InputComparison::Foreign(_)) && kept_long {
            // Kept while the peers' answers were not coming (a cut, a loaded host): that they
            // came back for newer inputs says nothing of the peers' answers to this one.
            input = InputComparison::Unknown;
        }
        match input {
            InputComparison::Odd(peers) => {
                self.odd_on_input.push(answer.input);
                return self.count_odd(answer.input, OddOn::Input, peers);
            }
            InputComparison::Foreign(peers) => {
                if !on_time {
                    self.note_late(answer.input);
                }
                self.foreign.push(answer.input);
                return (self.odd_limit > 0 && self.foreign.len() >= FOREIGN_LIMIT)
                    .then(|| self.odd_on(OddOn::Input, self.foreign.clone(), peers));
            }
            InputComparison::Shared => self.foreign.clear(),
            InputComparison::Unknown => {}
        }
        if !answer.in_step {
            if input == InputComparison::Unknown && !self.peers.is_empty() {
                // Its input is judged once the peers' answers are in (or let go).
                self.pending.push(answer);
            } else {
                self.note_late(answer.input);
            }
            return None;
        }
        match self.compare(answer.input, &answer.value) {
            Comparison::Incomplete => {
                self.pending.push(answer);
                None
            }
            Comparison::NotOdd => {
                self.late.retain(|late| *late > answer.input);
                let peers = self.compare_raw(&answer)?;
                self.odd_on_law.push(answer.input);
                self.count_odd(answer.input, OddOn::Law, peers)
            }
            Comparison::Odd(peers) => {
                if !on_time {
                    self.note_late(answer.input);
                }
                self.count_odd(answer.input, OddOn::Output, peers)
            }
        }
    }

    /// Counts `input` odd (`on` it), against `peers`: the verdict if it is the N-th of the
    /// life. Odd on input or on its law at any of them, it says so (the model's alarms about
    /// itself), input first.
    fn count_odd(&mut self, input: u64, on: OddOn, peers: Vec<ControllerId>) -> Option<OddOneOut> {
        self.odd_inputs.push(input);
        self.odd_inputs.sort_unstable();
        let limit = self.odd_limit as usize;
        let on = if !self.odd_on_input.is_empty() {
            OddOn::Input
        } else if !self.odd_on_law.is_empty() {
            OddOn::Law
        } else {
            on
        };
        (limit > 0 && self.odd_inputs.len() >= limit)
            .then(|| self.odd_on(on, self.odd_inputs.clone(), peers))
    }

    /// The two peers whose raw answers to `answer`'s input agree with each other and not with
    /// its own, from the same input before and the same input values (see the module's rules
    /// on raw answers); none when it gives no raw answer or fewer than two peers' compare.
    fn compare_raw(&self, answer: &OwnAnswer<T>) -> Option<Vec<ControllerId>> {
        if !answer.raw.is_some() {
            return None;
        }
        let comparable: Vec<(ControllerId, u64)> = self
            .peers
            .get(&answer.input)?
            .iter()
            .filter(|(_, peer)| {
                peer.digest == answer.digest
                    && peer.raw.is_some()
                    && peer.raw.after == answer.raw.after
            })
            .map(|(from, peer)| (*from, peer.raw.digest))
            .collect();
        if comparable.iter().any(|(_, d)| *d == answer.raw.digest) {
            return None;
        }
        agreeing_pair(&comparable)
    }

    /// The verdict: odd `on` at `inputs`, against `peers`.
    fn odd_on(&self, on: OddOn, inputs: Vec<u64>, peers: Vec<ControllerId>) -> OddOneOut {
        OddOneOut {
            on,
            inputs,
            odd_limit: self.odd_limit,
            peers,
            late: u32::try_from(self.late.len()).unwrap_or(u32::MAX),
        }
    }

    /// How its input `input`, whose values had the digest `digest`, compares with the
    /// peers' (see the module's rules on input congruence).
    fn compare_input(&self, input: u64, digest: u64) -> InputComparison {
        if let Some(answers) = self.peers.get(&input) {
            let digests: Vec<(ControllerId, u64)> = answers
                .iter()
                .map(|(from, peer)| (*from, peer.digest))
                .filter(|(_, peer_digest)| *peer_digest != 0)
                .collect();
            if digest == 0 || digests.iter().any(|(_, d)| *d == digest) {
                return InputComparison::Shared;
            }
            return match agreeing_pair(&digests) {
                Some(peers) => InputComparison::Odd(peers),
                None if answers.len() >= 2 => InputComparison::Shared,
                None => InputComparison::Unknown,
            };
        }
        // Not one peer answered it. Foreign once two peers that agree on an input both
        // answered newer ones (and its input is not older than every input kept).
        let kept_from = self.peers.keys().next().copied();
        if digest == 0 || kept_from.is_none_or(|oldest| input < oldest) {
            return InputComparison::Unknown;
        }
        let newer = (std::ops::Bound::Excluded(input), std::ops::Bound::Unbounded);
        let agreeing_later = self.peers.range(newer).rev().find_map(|(_, answers)| {
            let digests: Vec<(ControllerId, u64)> = answers
                .iter()
                .map(|(from, peer)| (*from, peer.digest))
                .filter(|(_, d)| *d != 0)
                .collect();
            agreeing_pair(&digests)
        });
        match agreeing_later {
            Some(peers) => InputComparison::Foreign(peers),
            None => InputComparison::Unknown,
        }
    }

    /// `input`'s answer went out before it was judged at its next input.
    fn note_late(&mut self, input: u64) {
        self.late.insert(input);
        while self.late.len() > LATE_KEPT {
            self.late.pop_first();
        }
    }

    /// A new life (the layer started it again): counts from zero, judged again once in step.
    pub fn new_life(&mut self) {
        self.pending.clear();
        self.late.clear();
        self.aligned_to = None;
        self.group_formed = false;
        self.odd_inputs.clear();
        self.odd_on_input.clear();
        self.odd_on_law.clear();
        self.foreign.clear();
        self.left = None;
    }

    /// The odd-one-out inputs of this life so far.
    pub fn odd_inputs(&self) -> &[u64] {
        &self.odd_inputs
    }

    /// How `value`, its answer to `input`, compares with the peers' answers (see the
    /// module's rules).
    fn compare(&self, input: u64, value: &T) -> Comparison {
        let answers: Vec<(&ControllerId, &T)> = self
            .peers
            .get(&input)
            .map(|peers| {
                peers
                    .iter()
                    .map(|(from, peer)| (from, &peer.value))
                    .collect()
            })
            .unwrap_or_default();
        if answers.iter().any(|(_, peer)| self.rule.agree(value, peer)) {
            return Comparison::NotOdd;
        }
        if answers.len() < 2 {
            return Comparison::Incomplete;
        }
        let agreeing = answers.iter().enumerate().find_map(|(i, (a, first))| {
            let agreeing = answers[i + 1..]
                .iter()
                .find(|(_, second)| self.rule.agree(first, second))?;
            Some(vec![**a, *agreeing.0])
        });
        agreeing.map_or(Comparison::NotOdd, Comparison::Odd)
    }
}

/// A peer's answer to one input, as it arrived.
#[derive(Clone, Debug)]
struct PeerAnswer<T> {
    /// The digest of its input's values (0: none).
    digest: u64,
    raw: RawAnswer,
    value: T,
}

/// Two peers whose digests (non-zero) are equal, if any.
fn agreeing_pair(digests: &[(ControllerId, u64)]) -> Option<Vec<ControllerId>> {
    digests.iter().enumerate().find_map(|(i, (first, digest))| {
        let second = digests[i + 1..].iter().find(|(_, d)| d == digest)?;
        Some(vec![*first, second.0])
    })
}

/// How a controller's input compares with its peers' inputs.
#[derive(Clone, Debug, PartialEq, Eq)]
enum InputComparison {
    /// A peer had the same value of it, or it gives no digest, or the peers that answered it
    /// agree on no value: nothing to say on input.
    Shared,
    /// Not known yet: too few peers' answers.
    Unknown,
    /// Two peers answered it with one value, and its own differs: these two.
    Odd(Vec<ControllerId>),
    /// No peer answered it, while these two, agreeing, answered newer inputs.
    Foreign(Vec<ControllerId>),
}

/// How a controller's answer compares with its peers' answers to the same input.
enum Comparison {
    /// Fewer than two peers' answers, none agreeing with it: not judged yet.
    Incomplete,
    /// It agrees with a peer, or the peers agree with nobody.
    NotOdd,
    /// It agrees with neither of two peers that agree: these two.
    Odd(Vec<ControllerId>),
}

#[cfg(test)]
mod input_tests;
#[cfg(test)]
mod law_tests;
#[cfg(test)]
mod tests;
