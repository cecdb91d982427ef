//! The durable vote record: a controller's latest vote, kept by DDS for late joiners.

use super::assignment::{decode_optional, encode_optional, WireAssignment};
use super::codes::controller_id;
use super::{WireError, WireSample};
use crate::core::types::VoteRecord;
use rustdds::Keyed;
use serde::{Deserialize, Serialize};

/// DDS type name of the vote topic.
pub const VOTE_TYPE_NAME: &str = "rl::VoteSample";

/// The durable vote record, keyed by the voter's id (a restarted controller replaces its
/// earlier life's record).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct VoteSample {
    /// The voter's controller id (0 is refused): the key.
    pub from_id: u8,
    /// The voter's life: a new value at every start.
    pub incarnation: u64,
    /// false = the vote is withdrawn.
    pub vote_valid: bool,
    /// The voter's Primary, Secondary and Tertiary (all zero when withdrawn).
    pub vote: WireAssignment,
}

impl Keyed for VoteSample {
    type K = u8;
    fn key(&self) -> u8 {
        self.from_id
    }
}

impl WireSample for VoteSample {
    type Value = VoteRecord;
    const TYPE_NAME: &'static str = VOTE_TYPE_NAME;

    fn decode(self) -> Result<VoteRecord, WireError> {
        Ok(VoteRecord {
            from: controller_id("vote.from_id", self.from_id)?,
            incarnation: self.incarnation,
            vote: decode_optional("vote.vote", self.vote_valid, &self.vote)?,
        })
    }

    fn encode(record: &VoteRecord) -> VoteSample {
        let (vote_valid, vote) = encode_optional(&record.vote);
        VoteSample {
            from_id: record.from,
            incarnation: record.incarnation,
            vote_valid,
            vote,
        }
    }
}
