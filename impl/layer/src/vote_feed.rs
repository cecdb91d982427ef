//! A voted topic read over DDS into the pure vote (crate::vote_reader): the thin adapter.
//!
//! Each controller with a role writes its own instance of the voted topic (keyed by its id;
//! crate::api::Redundancy::voted_writer). A sample counts only if the participant that wrote
//! it speaks for the controller id it carries, as the heartbeats bind ids to participants
//! (crate::trust, crate::identity): a participant claiming another controller's id, or one
//! that sends no heartbeats, is refused (warned once per writer), so nobody on the LAN can add
//! a vote. A forger that also forges heartbeats for ids nobody uses is stopped only by DDS
//! Security, as on the exclusive topic (docs/protocol.md, "Hostile input").
//!
//! `rl servo --vote` and `rl shapes --vote` follow the servo commands' vote with it; a
//! controller application reads its own group's vote through
//! crate::api::Redundancy::vote_feed.

use crate::core::types::Strength;
use crate::dds::{guid_hex, DdsError, Reader, Session};
use crate::trust::CommandTrust;
use crate::vote_reader::{ServoRule, VoteEvent, VoteReader, VoteRule, VoteSettings};
use crate::wire::{
    HeartbeatSample, ServoControl, Voted, VotedSample, VOTED_SERVO_CONTROL_TYPE_NAME,
};
use tracing::warn;

/// Votes on the answers of one voted topic as they arrive.
pub struct VoteFeed<T: Clone, R> {
    answers: Reader<VotedSample<T>>,
    heartbeats: Reader<HeartbeatSample>,
    trust: CommandTrust,
    votes: VoteReader<T, R>,
    refused_count: u64,
}

impl<T, R> VoteFeed<T, R>
where
    T: Clone + serde::de::DeserializeOwned + Send + 'static,
    R: VoteRule<T>,
{
    /// The vote on the voted topic `topic` (DDS type name `type_name`) of the session's
    /// group, whose controllers are known from the session's heartbeat reader.
    pub fn open(
        session: &Session,
        topic: &str,
        type_name: &str,
        rule: R,
        settings: VoteSettings<T>,
    ) -> Result<VoteFeed<T, R>, DdsError> {
        let answers = session.voted_reader(topic, type_name)?;
        let heartbeats = session.heartbeat_reader()?;
        let peer_deadline_ms = session.timing().peer_deadline_ms;
        Ok(Self::open_following(
            heartbeats,
            answers,
            peer_deadline_ms,
            VoteReader::new(rule, settings),
        ))
    }

    /// As [`VoteFeed::open`], read best effort ([`Session::voted_follower_reader`]): for a
    /// controller that follows the vote to align its own state.
    pub fn following(
        session: &Session,
        topic: &str,
        type_name: &str,
        rule: R,
        settings: VoteSettings<T>,
    ) -> Result<VoteFeed<T, R>, DdsError> {
        let answers = session.voted_follower_reader(topic, type_name)?;
        let heartbeats = session.heartbeat_reader()?;
        let peer_deadline_ms = session.timing().peer_deadline_ms;
        Ok(Self::open_following(
            heartbeats,
            answers,
            peer_deadline_ms,
            VoteReader::new(rule, settings),
        ))
    }

    /// The vote `votes` over `answers`, whose controllers `heartbeats` announce (another
    /// group's, [`Session::group_heartbeat_reader`], for that group's output);
    /// `peer_deadline_ms` is how long a silent controller's id stays bound to its participant.
    pub fn open_following(
        heartbeats: Reader<HeartbeatSample>,
        answers: Reader<VotedSample<T>>,
        peer_deadline_ms: u64,
        votes: VoteReader<T, R>,
    ) -> VoteFeed<T, R> {
        VoteFeed {
            answers,
            heartbeats,
            trust: CommandTrust::new(peer_deadline_ms, false),
            votes,
            refused_count: 0,
        }
    }

    /// The answer reader and the heartbeat reader, to register with a poll.
    pub fn readers(&self) -> [&dyn rustdds::mio::Evented; 2] {
        [&self.answers, &self.heartbeats]
    }

    /// Takes in what arrived (heartbeats first: they name the participants of the answers
    /// that follow) and votes at `now_ms` (milliseconds on the caller's monotonic clock);
    /// call it at least every few milliseconds, also without arrivals, so a lapsed majority is
    /// reported in time.
    pub fn take(&mut self, now_ms: u64) -> Vec<VoteEvent<T>> {
        self.take_seeing(now_ms, |_| {})
    }

    /// As [`VoteFeed::take`], showing `seen` every answer that counts, as it arrives (a
    /// controller's cross-check compares its own answers with them, crate::cross_check).
    pub fn take_seeing(
        &mut self,
        now_ms: u64,
        mut seen: impl FnMut(&Voted<T>),
    ) -> Vec<VoteEvent<T>> {
        for heartbeat in self.heartbeats.take() {
            self.trust.heartbeat(&heartbeat, now_ms);
        }
        let mut events = Vec::new();
        for sample in self.answers.take() {
            // Shared ownership: no strength; the trust checks the participant only.
            match self.trust.admit(sample.writer, Strength(0)) {
                Ok(speaks_for) if speaks_for == sample.value.from => {
                    seen(&sample.value);
                    events.extend(self.votes.offer(sample.value, now_ms));
                }
                admitted => {
                    self.refused_count += 1;
                    if self.trust.first_warning(sample.writer) {
                        let speaks_for = admitted.ok();
                        warn!(
                            writer = %guid_hex(sample.writer),
                            "voted answer in controller {}'s name refused: its participant \
                             speaks for {speaks_for:?}",
                            sample.value.from
                        );
                    }
                }
            }
        }
        events.extend(self.votes.tick(now_ms));
        events
    }

    /// The vote itself: the last accepted value, the dissenting controllers.
    pub fn votes(&self) -> &VoteReader<T, R> {
        &self.votes
    }

    /// Breaks the vote's rule on purpose (a `mutation` build; crate::vote_reader::VoteMutation).
    #[cfg(feature = "mutation")]
    pub fn mutate(&mut self, mutation: crate::vote_reader::VoteMutation) {
        self.votes.mutate(mutation);
    }

    /// How many answers were refused (their participant does not speak for their id).
    pub fn refused_count(&self) -> u64 {
        self.refused_count
    }
}

impl VoteFeed<ServoControl, ServoRule> {
    /// The vote on the servo commands of the session's group: `dds.voted_command_topic`
    /// ([`crate::config::Dds::voted_topic_name`]), type [`VOTED_SERVO_CONTROL_TYPE_NAME`].
    pub fn servo_commands(
        session: &Session,
        rule: ServoRule,
        settings: VoteSettings<ServoControl>,
    ) -> Result<VoteFeed<ServoControl, ServoRule>, DdsError> {
        let topic = session.config().voted_topic_name();
        Self::open(
            session,
            &topic,
            VOTED_SERVO_CONTROL_TYPE_NAME,
            rule,
            settings,
        )
    }
}
