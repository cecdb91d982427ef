//! The voted sample: one controller's answer to one input, on a topic where every controller
//! with a role publishes its own instance (shared ownership) and the receiver votes
//! (crate::vote_reader; docs/protocol.md, "Output voting at the receiver"). The paper's
//! hyper-critical extension: "each command sample could be sent from each controller as an
//! instance where the receiving application selects the best two or three command instances
//! and alarms any dissenting command source".

use super::codes::controller_id;
use super::{ServoControl, WireError, WireSample};
use crate::core::types::ControllerId;
use rustdds::Keyed;
use serde::{Deserialize, Serialize};

/// DDS type name of the voted command topic (`dds.voted_command_topic`): a [`VotedSample`] of
/// [`ServoControl`].
pub const VOTED_SERVO_CONTROL_TYPE_NAME: &str = "rl::VotedServoControl";

/// One controller's answer to one input, as the receiver votes on it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Voted<T> {
    /// The controller that computed it.
    pub from: ControllerId,
    /// The input it answers, as the application tags it (the tracker: the camera sample's
    /// DDS source timestamp, `rustdds::Timestamp::to_ticks`); answers are compared only when
    /// they answer the same input.
    pub input: u64,
    /// A digest of the input's values as this controller received them ([`input_digest`]; 0:
    /// the application gives none): controllers that answered the same input compare it, so
    /// an input that differs is found even where the output it led to agrees (input
    /// congruence, crate::cross_check).
    pub input_digest: u64,
    /// Its raw answer to the input, before alignment ([`RawAnswer`]; [`RawAnswer::NONE`]: the
    /// application gives none): compared exactly with the peers' raw answers to the same
    /// input from the same input before, so a wrong law that alignment corrects at every
    /// input is still found (crate::cross_check).
    pub raw: RawAnswer,
    /// The application's value (a servo command).
    pub value: T,
}

/// What the application's law computed from an input before its state was aligned to the
/// group's (bumpless transfer), as a digest, and the input before it whose memory the law
/// used. Controllers aligned to the group all start an input from the group's position, so
/// their outputs agree within the tolerance however their laws differ by less than it; the
/// law's own step (the tracker: its PD velocity, which depends only on this input and the one
/// before) is the same bit for bit at every correct controller that answered the same two
/// inputs, and a wrong law's is not.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct RawAnswer {
    /// The input answered before, whose memory the raw answer used (0: none).
    pub after: u64,
    /// The digest of the raw answer's values ([`input_digest`] of the bytes the application
    /// names; 0: none).
    pub digest: u64,
}

impl RawAnswer {
    /// No raw answer: nothing to compare.
    pub const NONE: RawAnswer = RawAnswer {
        after: 0,
        digest: 0,
    };

    /// Whether there is one to compare: a digest, from an input before.
    pub fn is_some(&self) -> bool {
        self.after != 0 && self.digest != 0
    }
}

/// The digest of an input's values, `bytes` as the application's law reads them (FNV-1a, 64
/// bits; never 0, which means "no digest"). Controllers digest the same bytes of the same
/// input alike on any machine: the application names the fields and their order.
pub fn input_digest(bytes: &[u8]) -> u64 {
    const OFFSET_BASIS: u64 = 0xcbf2_9ce4_8422_2325;
    const PRIME: u64 = 0x0100_0000_01b3;
    let digest = bytes.iter().fold(OFFSET_BASIS, |hash, byte| {
        (hash ^ u64::from(*byte)).wrapping_mul(PRIME)
    });
    digest.max(1)
}

/// The voted sample on the wire, keyed by the controller id, so each controller writes its own
/// instance. Its DDS type name is given with the topic, as the value type is the
/// application's ([`VOTED_SERVO_CONTROL_TYPE_NAME`] for servo commands; docs/rl.idl).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct VotedSample<T> {
    /// The writing controller's id (0 is refused): the key.
    pub from_id: u8,
    /// The input it answers ([`Voted::input`]).
    pub input: u64,
    /// The digest of that input's values ([`Voted::input_digest`]).
    pub input_digest: u64,
    /// The input before it, from which the raw answer was computed ([`RawAnswer::after`]).
    pub raw_after: u64,
    /// The digest of its raw answer ([`RawAnswer::digest`]).
    pub raw_digest: u64,
    /// The application's value, taken as it is: the rule that votes on it decides what
    /// agrees (crate::vote_reader::VoteRule).
    pub value: T,
}

/// The voted sample of servo commands, as docs/rl.idl declares it.
pub type VotedServoControl = VotedSample<ServoControl>;

impl<T> Keyed for VotedSample<T> {
    type K = u8;
    fn key(&self) -> u8 {
        self.from_id
    }
}

impl<T: Clone> WireSample for VotedSample<T> {
    type Value = Voted<T>;
    /// Empty: the topic is created with the type name the application gives
    /// (crate::dds::Session::voted_reader).
    const TYPE_NAME: &'static str = "";

    fn decode(self) -> Result<Voted<T>, WireError> {
        Ok(Voted {
            from: controller_id("voted.from_id", self.from_id)?,
            input: self.input,
            input_digest: self.input_digest,
            raw: RawAnswer {
                after: self.raw_after,
                digest: self.raw_digest,
            },
            value: self.value,
        })
    }

    fn encode(voted: &Voted<T>) -> VotedSample<T> {
        VotedSample {
            from_id: voted.from,
            input: voted.input,
            input_digest: voted.input_digest,
            raw_after: voted.raw.after,
            raw_digest: voted.raw.digest,
            value: voted.value.clone(),
        }
    }
}
