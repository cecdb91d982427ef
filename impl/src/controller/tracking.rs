//! The tracker's state in `rl controller`: its control law and the frame it answered last
//! ([`Tracker`]), and where it takes the group's position from ([`Alignment`], bumpless
//! transfer): the voted commands, or the owner's answers until the vote works. Apart from the
//! controller's loop because the rules of alignment (which frame an answer is for, a frame
//! lost or not yet taken) are the part of the tracker that keeps three controllers alike.

use super::without_voting_if_refused;
use crate::tracker::lockstep::Lockstep;
use crate::tracker::{control_law, ControlLaw, ServoCommand};
use rl_layer::api::{Redundancy, VoteFeed};
use rl_layer::config::{ArchitectureName, Config};
use rl_layer::core::types::ControllerId;
use rl_layer::cross_check::CrossCheck;
use rl_layer::owner_feed::OwnerFeed;
use rl_layer::vote_reader::{ServoRule, VoteEvent, VoteSettings};
use rl_layer::wire::{input_digest, RawAnswer, ServoControl, VOTED_SERVO_CONTROL_TYPE_NAME};

/// The digest of a camera frame's values as the law reads them: the ball's x, then y, each
/// as 4 little-endian bytes.
pub(super) fn frame_digest(ball: (i32, i32)) -> u64 {
    let mut bytes = [0u8; 8];
    bytes[..4].copy_from_slice(&ball.0.to_le_bytes());
    bytes[4..].copy_from_slice(&ball.1.to_le_bytes());
    input_digest(&bytes)
}

/// The raw answer to a frame: the law's step (pan, then tilt, each as 8 little-endian bytes)
/// from the frame answered before, `after`.
pub(super) fn raw_answer(after: u64, step: Option<(i64, i64)>) -> RawAnswer {
    match step {
        Some((pan, tilt)) if after != 0 => {
            let mut bytes = [0u8; 16];
            bytes[..8].copy_from_slice(&pan.to_le_bytes());
            bytes[8..].copy_from_slice(&tilt.to_le_bytes());
            RawAnswer {
                after,
                digest: input_digest(&bytes),
            }
        }
        _ => RawAnswer::NONE,
    }
}

/// The tracker's control law (and a lockstep pair's second implementation beside it), the
/// camera frame it answered last, and its answers to that frame.
pub(super) struct Tracker {
    pub(super) pan_tilt: Box<dyn ControlLaw>,
    /// A lockstep pair's controller runs the other implementation beside it and compares.
    lockstep: Option<Lockstep>,
    /// The camera frame the commands answer (its source timestamp), for the voted topic.
    pub(super) frame: u64,
    /// The digest of that frame's values as the law read them (the ball's x and y; 0: no
    /// frame yet), compared with the peers' on the voted topic (input congruence).
    pub(super) frame_digest: u64,
    /// Its raw answer to that frame: the law's step from the frame before, compared exactly
    /// with the peers' (rl_layer::cross_check).
    pub(super) raw: RawAnswer,
    /// Its answer to that frame: a re-publication repeats it. The tracker's state, aligned to
    /// the group since, is for the next frame; a re-publication computed from it would be a
    /// second, different answer to the same frame (two wrong values per frame from a wrong
    /// controller at an exclusive reader, where the model bounds wrong answers per input).
    answer: Option<ServoCommand>,
    /// The second implementation's answer to the same frame (a lockstep pair only).
    second_answer: Option<ServoCommand>,
}

impl Tracker {
    pub(super) fn new(config: &Config) -> Tracker {
        let (law, frequency_hz) = (config.tracker.law, config.tracker.servo_frequency_hz);
        Tracker {
            pan_tilt: control_law(law, frequency_hz),
            lockstep: (config.architecture == ArchitectureName::Pair)
                .then(|| Lockstep::beside(law, frequency_hz)),
            frame: 0,
            frame_digest: 0,
            raw: RawAnswer::NONE,
            answer: None,
            second_answer: None,
        }
    }

    /// The second implementation takes the position the first was aligned to, if any.
    pub(super) fn align_second(&mut self, aligned: Option<(u16, u16)>) {
        if let (Some((pan, tilt)), Some(lockstep)) = (aligned, self.lockstep.as_mut()) {
            lockstep.align(pan, tilt);
        }
    }

    /// Answers camera frame `input`, the ball at `ball` (x, y), from the group's position
    /// before it ([`Alignment::before_frame`]), its pan step at `pan_gain_percent` of the law's
    /// (100; otherwise the fault-injection control's wrong gain, a wrong law).
    pub(super) fn answer_frame(
        &mut self,
        (input, ball): (u64, (i32, i32)),
        pan_gain_percent: i64,
        alignment: &mut Alignment,
        cross_check: &mut CrossCheck<ServoControl, ServoRule>,
    ) {
        let skipped =
            alignment.before_frame(input, self.frame, self.pan_tilt.as_mut(), cross_check);
        self.align_second(skipped);
        let from = self.pan_tilt.command();
        let mut answer = self.pan_tilt.update(ball.0, ball.1);
        let mut step = self.pan_tilt.step();
        if let Some((pan, tilt)) = step.filter(|_| pan_gain_percent != 100) {
            let pan = pan.saturating_mul(pan_gain_percent) / 100;
            let moved = i64::from(from.pan).saturating_add(pan).clamp(0, 1000);
            answer.pan = u16::try_from(moved).unwrap_or(answer.pan);
            self.pan_tilt.align(answer.pan, answer.tilt);
            step = Some((pan, tilt));
        }
        self.answer = Some(answer);
        self.second_answer = self.lockstep.as_mut().map(|l| l.update(ball.0, ball.1));
        self.raw = raw_answer(self.frame, step);
        self.frame = input;
        self.frame_digest = frame_digest(ball);
    }

    /// The command to write: its answer to the frame, or the law's position before any.
    pub(super) fn command(&self) -> ServoCommand {
        self.answer.unwrap_or_else(|| self.pan_tilt.command())
    }

    /// A lockstep pair's second implementation and its answer, to compare before writing.
    pub(super) fn compare(&self) -> Option<(&Lockstep, ServoCommand)> {
        self.lockstep.as_ref().zip(self.second_answer)
    }
}

/// Bumpless transfer: where the tracker takes the gimbal's position from. From the voted
/// topic's accepted commands (every controller, the commanding one too), so that a controller
/// computing wrong commands does not pull the others' state after it; until the vote has
/// accepted a command in this life (formation, a new life), from the owner's voted answer to
/// the frame it answered last while another controller commands (without a voted topic, the
/// owner's commands; crate::tracker, `align`). Once the vote has
/// worked, never from the owner again in this life: without a majority (two wrong that
/// disagree) the owner may be a wrong Primary, and a correct controller aligned to it would
/// agree with it at the next frame, making a wrong majority and the other wrong one the odd
/// one out. It keeps its own state then, which is the group's while all compute alike.
pub(super) struct Alignment {
    owner_commands: OwnerFeed<ServoControl>,
    own_participant: rl_layer::dds::ParticipantKey,
    votes: Option<VoteFeed<ServoControl, ServoRule>>,
    /// The vote accepted a command in this life.
    pub(super) voted_in_life: bool,
    /// The peers' answers on the voted topic, by input and controller, the newest
    /// [`ANSWERS_KEPT`] inputs: before the vote works, the owner's answer to the frame this
    /// controller answered last is where it takes the gimbal's position from.
    answers:
        std::collections::BTreeMap<u64, std::collections::BTreeMap<ControllerId, ServoControl>>,
    /// The vote's accepted answers to inputs this controller has not answered yet, the newest
    /// [`ANSWERS_KEPT`]: a loaded controller hears the others' answers to a frame before the
    /// frame itself, and taking that position first would step twice for the frame (its answer
    /// then unlike the group's, and its state too, frame after frame while it lags). Applied
    /// once it has answered that input, or, for an input it never got (a lost frame), before
    /// it answers the next one.
    accepted_ahead: std::collections::BTreeMap<u64, ServoControl>,
}

/// Inputs whose answers [`Alignment`] keeps.
const ANSWERS_KEPT: usize = 8;

impl Alignment {
    pub(super) fn open(rl: &Redundancy, config: &Config) -> Result<Alignment, crate::Error> {
        let dds = |e: rl_layer::dds::DdsError| crate::Error::dds(e);
        // The commanding controller's commands, to follow while standing by.
        let owner_commands = OwnerFeed::open(
            rl.session(),
            rl.session().command_follower_reader().map_err(dds)?,
            config.timing.command_deadline_ms,
            config.timing.peer_deadline_ms,
        )
        .map_err(dds)?;
        let votes = rl.vote_feed(
            &config.dds.voted_topic_name(),
            VOTED_SERVO_CONTROL_TYPE_NAME,
            ServoRule::default(),
            VoteSettings::holding(config.timing.command_deadline_ms),
        );
        let votes = without_voting_if_refused("reader", votes);
        Ok(Alignment {
            owner_commands,
            own_participant: rl.session().participant_key(),
            votes,
            voted_in_life: false,
            answers: std::collections::BTreeMap::new(),
            accepted_ahead: std::collections::BTreeMap::new(),
        })
    }

    /// Before it answers camera frame `input` (having answered `frame` last): when the vote
    /// accepted an input between the two (a frame lost to this controller), the group's
    /// position at the newest of them is where it steps from. Returns that position, if any.
    pub(super) fn before_frame(
        &mut self,
        input: u64,
        frame: u64,
        pan_tilt: &mut dyn ControlLaw,
        cross_check: &mut CrossCheck<ServoControl, ServoRule>,
    ) -> Option<(u16, u16)> {
        let later = self.accepted_ahead.split_off(&input);
        let skipped = std::mem::replace(&mut self.accepted_ahead, later);
        let (&skipped_input, command) = skipped.range(frame.saturating_add(1)..).next_back()?;
        pan_tilt.align(command.pan, command.tilt);
        cross_check.aligned(skipped_input);
        Some((command.pan, command.tilt))
    }

    /// Aligns `pan_tilt` to what arrived: a voted command for the frame it last answered
    /// (`frame`; one for an older frame would set it back, and one for a frame it has not
    /// answered yet waits for it, [`Alignment::before_frame`]), else, until the vote has worked
    /// in this life, the owner's command. The answers that arrived go to `cross_check`, and so
    /// does the alignment. Returns the position it aligned to, if it did.
    pub(super) fn align(
        &mut self,
        rl: &Redundancy,
        pan_tilt: &mut dyn ControlLaw,
        frame: u64,
        now_ms: u64,
        cross_check: &mut CrossCheck<ServoControl, ServoRule>,
    ) -> Option<(u16, u16)> {
        let owner = self.owner_commands.take(rl.session(), now_ms);
        let mut voted = None;
        if let Some(votes) = self.votes.as_mut() {
            let answers = &mut self.answers;
            let events = votes.take_seeing(now_ms, |answer| {
                cross_check.peer_answer(
                    answer.from,
                    answer.input,
                    answer.input_digest,
                    answer.raw,
                    answer.value,
                );
                answers
                    .entry(answer.input)
                    .or_default()
                    .insert(answer.from, answer.value);
            });
            while self.answers.len() > ANSWERS_KEPT {
                self.answers.pop_first();
            }
            for event in events {
                if let VoteEvent::Accepted {
                    input,
                    value,
                    agreeing,
                } = event
                {
                    if agreeing.len() >= rl_layer::core::types::ROLE_COUNT {
                        cross_check.all_agreed();
                    }
                    self.voted_in_life = true;
                    if input > frame {
                        self.accepted_ahead.insert(input, value);
                    }
                    voted = (input == frame).then_some((input, value)).or(voted);
                }
            }
            while self.accepted_ahead.len() > ANSWERS_KEPT {
                self.accepted_ahead.pop_first();
            }
        }
        // An acceptance that came ahead of its frame, now answered.
        if let Some(value) = self.accepted_ahead.remove(&frame) {
            voted = voted.or(Some((frame, value)));
        }
        // What is left for this frame or before it will never be answered.
        self.accepted_ahead.retain(|input, _| *input > frame);
        match (voted, owner) {
            (Some((input, command)), _) => {
                pan_tilt.align(command.pan, command.tilt);
                cross_check.aligned(input);
                Some((command.pan, command.tilt))
            }
            (None, Some((command, writer)))
                if !self.voted_in_life
                    && rl_layer::dds::participant_key(writer) != self.own_participant =>
            {
                // Not in step for the cross-check. With a voted topic, the owner's own answer
                // to the frame this controller answered last: the exclusive topic does not say
                // which frame its command answers, and a command answering a frame this
                // controller has not taken yet would have it step twice for that frame (two
                // standbys doing so agree with each other and not with a right Primary).
                let command = match self.votes {
                    Some(_) => {
                        let owner = self.owner_commands.controller_of(writer)?;
                        *self.answers.get(&frame)?.get(&owner)?
                    }
                    None => command,
                };
                pan_tilt.align(command.pan, command.tilt);
                Some((command.pan, command.tilt))
            }
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_raw_answer_is_the_step_and_the_frame_before_and_none_without_either() {
        assert_eq!(
            raw_answer(0, Some((2, 3))),
            RawAnswer::NONE,
            "no frame before"
        );
        assert_eq!(raw_answer(7, None), RawAnswer::NONE, "no step yet");
        let raw = raw_answer(7, Some((2, 3)));
        assert!(raw.is_some());
        assert_eq!(raw.after, 7);
        assert_eq!(
            raw,
            raw_answer(7, Some((2, 3))),
            "the same step, the same digest"
        );
        assert_ne!(
            raw.digest,
            raw_answer(7, Some((3, 2))).digest,
            "pan and tilt apart"
        );
        assert_ne!(raw.digest, raw_answer(7, Some((2, 4))).digest);
    }
}
