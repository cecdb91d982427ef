//! Everything that knows DDS: the participant, the topics, their QoS, typed readers and
//! writers, the ROS 2 node that shares the participant, and [`WakeSwitch`], which turns a
//! reader's wake-ups of a poll on and off (a reader registers with a poll only once).
//!
//! A [`Session`] is one DDS participant on the configured domain, created through a ros2-client
//! `Context` so a ROS 2 node ([`Session::ros_node`]) lives on the same participant. All of a
//! controller's endpoints come from one session; the constructors name the paper's topics:
//!
//! | endpoint | topic (config) | key | QoS ([`qos`]) |
//! |---|---|---|---|
//! | heartbeat reader/writer | `heartbeat_topic` | controller id | best effort, keep last 1, deadline 2 x period |
//! | vote reader/writer | `vote_topic` | controller id | reliable, transient local, keep last 1 |
//! | alarm reader/writer | `controller_alarm_topic` | reporter, controller, impostor or not | reliable, transient local, keep last 1 |
//! | network alarm reader/writer | `network_alarm_topic` | reporter, network, controller | reliable, transient local, keep last 1 |
//! | [`StrengthWriter`], command reader | `command_topic` | - | reliable, EXCLUSIVE, strength by role, deadline = command deadline |
//! | [`StrengthWriter`] of an application's topic | its name | the application's | as the command topic |
//! | voted reader/writer ([`Session::voted_reader`]) | `voted_command_topic` or an application's | controller id | reliable, SHARED, deadline = command deadline, writer keep last 1 |
//! | camera reader/writer | `camera_topic` | colour | best effort reader, reliable writer, keep last 1 |
//!
//! Readers are non-blocking ([`Reader::take`]) and mio 0.6 `Evented` (use `rustdds::mio`,
//! re-exported here as [`mio`]), so one thread can wait on all of them with a `mio::Poll`.
//!
//! **Who wrote a command.** A command sample does not name its controller. Every RTPS entity's
//! GUID starts with its participant's 12-byte GUID prefix, and a controller's heartbeat writer
//! and command writer come from the same session, hence the same participant. So a reader of
//! both topics maps the heartbeat's writer GUID prefix to the heartbeat's `from` id
//! ([`ControllerDirectory`]) and then any command's writer GUID to that controller, with no
//! extra field on the wire. The writer's ownership strength comes from discovery
//! ([`Session::command_writer_strengths`], RustDDS `discovered_writers()`).

mod app_topics;
#[cfg(feature = "fault-injection")]
pub mod command_link;
mod endpoint;
mod groups;
mod network;
mod participants;
pub mod qos;
mod role_writer;
mod ros;
mod wake_switch;
mod writer_offers;

pub use endpoint::{guid_hex, Reader, Received, Writer};
pub use network::NetworkParticipant;
pub use participants::{participant_key, ControllerDirectory, ParticipantKey};
pub use role_writer::{Keying, NoKey, StrengthWriter, WithKey};
pub use ros::StatusPublisher;
pub use rustdds::{mio, GUID};
pub use wake_switch::WakeSwitch;
pub use writer_offers::WriterOffer;

use crate::config::{Dds, Timing};
use crate::core::types::Strength;
use crate::wire::{
    AlarmSample, HeartbeatSample, NetworkAlarmSample, ServoControl, ShapeTypeExtended, VoteSample,
    WireError, WireSample,
};
use ros2_client::Context;
use rustdds::{
    serialization::CDRSerializerAdapter, CDRDeserializerAdapter, DomainParticipant,
    DomainParticipantBuilder, Publisher, QosPolicies, QosPolicyBuilder, RTPSEntity, Subscriber,
    Topic, TopicDescription, TopicKind,
};
use std::collections::BTreeSet;
use std::time::Duration;

/// A DDS failure, with the entity and topic it concerns.
#[derive(Debug, thiserror::Error)]
pub enum DdsError {
    /// The domain participant could not be created (no usable network interface, a bad
    /// domain id).
    #[error("cannot join DDS domain {domain}: {reason}")]
    Participant {
        /// The DDS domain id it tried to join.
        domain: u16,
        /// What failed (the publisher, the subscriber), as RustDDS or ros2-client reported it.
        reason: String,
    },
    /// A topic, reader or writer could not be created (`what` names which).
    #[error("cannot create the {what} of topic {topic}: {reason}")]
    Create {
        /// The entity that failed: `topic`, `reader`, `writer` or `command writer`.
        what: &'static str,
        /// The name of the topic it was for.
        topic: String,
        /// What RustDDS reported.
        reason: String,
    },
    /// RustDDS refused a write (its background thread gone, or the sample not serializable).
    #[error("cannot write on topic {topic}: {source}")]
    Write {
        /// The name of the topic written to.
        topic: String,
        /// RustDDS's write error, without the sample.
        source: rustdds::dds::WriteError<()>,
    },
    /// The sample would not pass the readers' validation, so it was not sent.
    #[error("refusing to write an invalid sample on topic {topic}: {source}")]
    Invalid {
        /// The name of the topic it was for.
        topic: String,
        /// The field at fault and why.
        source: WireError,
    },
    /// A ROS 2 node, publisher or graph operation failed (`what` names which).
    #[error("ROS 2 {what}: {reason}")]
    Ros {
        /// The operation that failed (`node`, `status topic`, `status publish`, ...).
        what: &'static str,
        /// What ros2-client reported.
        reason: String,
    },
    /// The configuration's keystore is missing, unreadable or wrong (names the file): a
    /// usage error, not a network one.
    #[error(transparent)]
    Keystore(#[from] crate::security::KeystoreError),
}

struct Topics {
    heartbeat: Topic,
    vote: Topic,
    alarm: Topic,
    network_alarm: Topic,
    command: Topic,
    camera: Topic,
}

impl Topics {
    /// RL's topics on `participant`, the device topics on `device_participant` (the same one
    /// unless device topics are open), with the names of `dds` (already grouped).
    fn create(
        participant: &DomainParticipant,
        device_participant: &DomainParticipant,
        dds: &Dds,
    ) -> Result<Topics, DdsError> {
        Ok(Topics {
            heartbeat: create_topic(
                participant,
                &dds.heartbeat_topic,
                HeartbeatSample::TYPE_NAME,
                TopicKind::WithKey,
            )?,
            vote: create_topic(
                participant,
                &dds.vote_topic,
                VoteSample::TYPE_NAME,
                TopicKind::WithKey,
            )?,
            alarm: create_topic(
                participant,
                &dds.controller_alarm_topic,
                AlarmSample::TYPE_NAME,
                TopicKind::WithKey,
            )?,
            network_alarm: create_topic(
                participant,
                &dds.network_alarm_topic,
                NetworkAlarmSample::TYPE_NAME,
                TopicKind::WithKey,
            )?,
            command: create_topic(
                device_participant,
                &dds.command_topic,
                ServoControl::TYPE_NAME,
                TopicKind::NoKey,
            )?,
            camera: create_topic(
                device_participant,
                &dds.camera_topic,
                ShapeTypeExtended::TYPE_NAME,
                TopicKind::WithKey,
            )?,
        })
    }
}

/// The unsecured participant of the device topics (command, camera) beside a secured one,
/// with `[security] open_device_topics`: a camera or actuator without DDS Security talks to
/// it, while RL's own topics stay on the secured participant.
struct DeviceParticipant {
    participant: DomainParticipant,
    publisher: Publisher,
    subscriber: Subscriber,
}

/// One DDS participant and the RL topics on it (and with open device topics, a second,
/// unsecured participant for those).
pub struct Session {
    context: Context,
    participant: DomainParticipant,
    publisher: Publisher,
    subscriber: Subscriber,
    device: Option<DeviceParticipant>,
    topics: Topics,
    /// The names of this session's group.
    config: Dds,
    /// The names as configured, before the group ([`Session::group_names`]).
    written: Dds,
    timing: Timing,
}

/// RustDDS's participant status events (discovered and lost participants, readers, writers)
/// that wait to be read at most. RL reads none: it learns of its peers from their heartbeats
/// and of writers' strengths by querying discovery. The queue is allocated at its full size and
/// an unread one keeps its events for good: RustDDS's default, 2048, cost 0.6 MB and more per
/// participant, three participants in a controller with its network monitor
/// (docs/performance.md, "Resources").
pub const PARTICIPANT_STATUS_EVENTS_KEPT: usize = 16;

/// How often each of RL's participants announces itself (SPDP; RustDDS's default is 10 s). A
/// controller restarted while its packets did not get through (outvoted by one-way loss, it
/// exits and systemd starts it again) is heard by its peers only at its next announcement
/// after the link heals: with 10 s that took it 11 to 37 rounds to rejoin, beyond the model's
/// 10 (docs/faults.md, "One-way loss settles late"). At 1 s: one announcement of a few hundred
/// bytes a second per participant, the lease it announces unchanged.
pub const SPDP_PUBLISH_PERIOD: Duration = Duration::from_secs(1);

/// A participant builder for `domain` with RL's settings for every participant it creates.
fn participant_builder(domain: u16) -> DomainParticipantBuilder {
    DomainParticipantBuilder::new(domain)
        .status_channel_capacity(PARTICIPANT_STATUS_EVENTS_KEPT)
        .spdp_publish_period(SPDP_PUBLISH_PERIOD)
}

/// A publisher and a subscriber with default QoS (each endpoint sets its own); `role` prefixes
/// the error (`device `).
fn publisher_and_subscriber(
    participant: &DomainParticipant,
    role: &str,
) -> Result<(Publisher, Subscriber), DdsError> {
    let error = |what: &str, e: rustdds::dds::CreateError| DdsError::Participant {
        domain: participant.domain_id(),
        reason: format!("{role}{what}: {e}"),
    };
    let default_qos = QosPolicyBuilder::new().build();
    let publisher = participant
        .create_publisher(&default_qos)
        .map_err(|e| error("publisher", e))?;
    let subscriber = participant
        .create_subscriber(&default_qos)
        .map_err(|e| error("subscriber", e))?;
    Ok((publisher, subscriber))
}

fn create_topic(
    participant: &DomainParticipant,
    name: &str,
    type_name: &str,
    kind: TopicKind,
) -> Result<Topic, DdsError> {
    // Endpoints set their QoS in full; the topic adds nothing.
    participant
        .create_topic(
            name.to_string(),
            type_name.to_string(),
            &QosPolicies::qos_none(),
            kind,
        )
        .map_err(|e| DdsError::Create {
            what: "topic",
            topic: name.to_string(),
            reason: e.to_string(),
        })
}

impl Session {
    /// Joins `dds.domain` and creates the RL topics. `timing` sets the deadlines.
    pub fn new(dds: &Dds, timing: &Timing) -> Result<Session, DdsError> {
        Session::open(dds, timing, false, None)
    }

    /// The same on two redundant networks: every datagram goes out on every interface, so
    /// losing one network loses nothing. By default RustDDS sends to each reader over the one
    /// interface it first heard that reader on, and takes about 30 s to notice that it died
    /// (docs/protocol.md, "Two networks").
    pub fn on_every_interface(dds: &Dds, timing: &Timing) -> Result<Session, DdsError> {
        Session::open(dds, timing, true, None)
    }

    /// A session as `new` or `on_every_interface` make it, secured with `keystore` when one
    /// is given (DDS Security: authenticated, access-controlled topics; crate::security).
    pub fn with_keystore(
        dds: &Dds,
        timing: &Timing,
        every_interface: bool,
        keystore: Option<&crate::security::Keystore>,
    ) -> Result<Session, DdsError> {
        Session::open(dds, timing, every_interface, keystore)
    }

    /// The session a command's configuration asks for: its keystore checked and used, on
    /// every interface when two networks are configured.
    pub fn for_config(config: &crate::config::Config) -> Result<Session, DdsError> {
        let keystore = crate::security::keystore_of(config)?;
        Session::open(
            &config.dds,
            &config.timing,
            config.networks.configured(),
            keystore.as_ref(),
        )
    }

    fn open(
        dds: &Dds,
        timing: &Timing,
        every_interface: bool,
        keystore: Option<&crate::security::Keystore>,
    ) -> Result<Session, DdsError> {
        // The group's names, once: the topics, the ROS 2 namespace and the strengths' lookup.
        let written = dds.clone();
        let grouped = dds.grouped();
        let dds = &grouped;
        let participant_error = |reason: String| DdsError::Participant {
            domain: dds.domain,
            reason,
        };
        let context = {
            let builder = participant_builder(dds.domain).send_on_every_interface(every_interface);
            #[cfg(feature = "security")]
            let builder = match keystore {
                Some(keystore) => builder.builtin_security(keystore.participant_files()),
                None => builder,
            };
            let participant = builder
                .build()
                .map_err(|e| participant_error(e.to_string()))?;
            Context::from_domain_participant(participant)
        }
        .map_err(|e| participant_error(e.to_string()))?;
        let participant = context.domain_participant();
        let (publisher, subscriber) = publisher_and_subscriber(&participant, "")?;
        let device = match keystore {
            Some(keystore) if keystore.open_device_topics => {
                let participant = participant_builder(dds.domain)
                    .send_on_every_interface(every_interface)
                    .build()
                    .map_err(|e| participant_error(format!("device participant: {e}")))?;
                let (publisher, subscriber) = publisher_and_subscriber(&participant, "device ")?;
                Some(DeviceParticipant {
                    participant,
                    publisher,
                    subscriber,
                })
            }
            _ => None,
        };
        let device_participant = device.as_ref().map_or(&participant, |d| &d.participant);
        let topics = Topics::create(&participant, device_participant, dds)?;
        Ok(Session {
            context,
            participant,
            publisher,
            subscriber,
            device,
            topics,
            config: dds.clone(),
            written,
            timing: timing.clone(),
        })
    }

    /// The DDS domain id the session's participant joined.
    pub fn domain_id(&self) -> u16 {
        self.participant.domain_id()
    }

    /// The `[dds]` section it was opened with: domain, topic names, ROS 2 namespace.
    pub fn config(&self) -> &Dds {
        &self.config
    }

    /// The `[timing]` section its QoS deadlines come from.
    pub fn timing(&self) -> &Timing {
        &self.timing
    }

    /// The RustDDS participant, for anything not wrapped here.
    pub fn participant(&self) -> &DomainParticipant {
        &self.participant
    }

    /// The ros2-client context that owns the participant.
    pub fn ros_context(&self) -> &Context {
        &self.context
    }

    /// The GUID of the participant of RL's own topics (not the device participant).
    pub fn participant_guid(&self) -> GUID {
        self.participant.guid()
    }

    /// The prefix of every GUID of this session's entities.
    pub fn participant_key(&self) -> ParticipantKey {
        participant_key(self.participant.guid())
    }

    /// Whether `topic` lives on the device participant (open device topics).
    fn on_device(&self, topic: &Topic) -> bool {
        self.device.is_some()
            && [&self.config.command_topic, &self.config.camera_topic].contains(&&topic.name())
    }

    fn publisher_of(&self, topic: &Topic) -> &Publisher {
        match &self.device {
            Some(device) if self.on_device(topic) => &device.publisher,
            _ => &self.publisher,
        }
    }

    fn subscriber_of(&self, topic: &Topic) -> &Subscriber {
        match &self.device {
            Some(device) if self.on_device(topic) => &device.subscriber,
            _ => &self.subscriber,
        }
    }

    fn keyed_reader<S>(&self, topic: &Topic, qos: QosPolicies) -> Result<Reader<S>, DdsError>
    where
        S: WireSample + rustdds::Keyed + serde::de::DeserializeOwned + Send + 'static,
        S::K: serde::de::DeserializeOwned + Send,
    {
        let raw = self
            .subscriber_of(topic)
            .create_datareader::<S, CDRDeserializerAdapter<S>>(topic, Some(qos))
            .map_err(|e| create_error("reader", topic, e))?;
        Ok(Reader::keyed(raw, topic))
    }

    fn unkeyed_reader<S>(&self, topic: &Topic, qos: QosPolicies) -> Result<Reader<S>, DdsError>
    where
        S: WireSample + serde::de::DeserializeOwned + Send + 'static,
    {
        let raw = self
            .subscriber_of(topic)
            .create_datareader_no_key::<S, CDRDeserializerAdapter<S>>(topic, Some(qos))
            .map_err(|e| create_error("reader", topic, e))?;
        Ok(Reader::unkeyed(raw, topic))
    }

    fn keyed_writer<S>(&self, topic: &Topic, qos: QosPolicies) -> Result<Writer<S>, DdsError>
    where
        S: WireSample + rustdds::Keyed + serde::Serialize + Clone + Send + 'static,
        S::K: serde::Serialize,
    {
        let raw = self
            .publisher_of(topic)
            .create_datawriter::<S, CDRSerializerAdapter<S>>(topic, Some(qos))
            .map_err(|e| create_error("writer", topic, e))?;
        Ok(Writer::keyed(raw, topic))
    }

    /// A reader of every controller's heartbeats (best effort, deadline 2 x period).
    pub fn heartbeat_reader(&self) -> Result<Reader<HeartbeatSample>, DdsError> {
        self.keyed_reader(&self.topics.heartbeat, qos::heartbeat(&self.timing))
    }

    /// This controller's heartbeat writer (best effort, deadline 2 x period).
    pub fn heartbeat_writer(&self) -> Result<Writer<HeartbeatSample>, DdsError> {
        self.keyed_writer(&self.topics.heartbeat, qos::heartbeat(&self.timing))
    }

    /// A reader of every controller's latest vote (reliable, transient local).
    pub fn vote_reader(&self) -> Result<Reader<VoteSample>, DdsError> {
        self.keyed_reader(&self.topics.vote, qos::vote())
    }

    /// This controller's vote writer (reliable, transient local, keep last 1).
    pub fn vote_writer(&self) -> Result<Writer<VoteSample>, DdsError> {
        self.keyed_writer(&self.topics.vote, qos::vote())
    }

    /// A reader of the controller alarms, each alarm's latest state (reliable, transient
    /// local).
    pub fn alarm_reader(&self) -> Result<Reader<AlarmSample>, DdsError> {
        self.keyed_reader(&self.topics.alarm, qos::alarm())
    }

    /// A controller alarm writer (reliable, transient local, keep last 1 per key).
    pub fn alarm_writer(&self) -> Result<Writer<AlarmSample>, DdsError> {
        self.keyed_writer(&self.topics.alarm, qos::alarm())
    }

    /// A reader of the network alarms, each alarm's latest state (reliable, transient local).
    pub fn network_alarm_reader(&self) -> Result<Reader<NetworkAlarmSample>, DdsError> {
        self.keyed_reader(&self.topics.network_alarm, qos::network_alarm())
    }

    /// A network alarm writer (reliable, transient local, keep last 1 per key).
    pub fn network_alarm_writer(&self) -> Result<Writer<NetworkAlarmSample>, DdsError> {
        self.keyed_writer(&self.topics.network_alarm, qos::network_alarm())
    }

    /// A reader of every command writer's samples. RustDDS does not enforce exclusive
    /// ownership: pass the samples through [`crate::arbiter::Arbiter`].
    pub fn command_reader(&self) -> Result<Reader<ServoControl>, DdsError> {
        self.unkeyed_reader(&self.topics.command, qos::command_reader(&self.timing))
    }

    /// As [`Self::command_reader`], best effort: for a controller following the commanding
    /// controller while it stands by (see [`qos::command_follower_reader`]).
    pub fn command_follower_reader(&self) -> Result<Reader<ServoControl>, DdsError> {
        self.unkeyed_reader(
            &self.topics.command,
            qos::command_follower_reader(&self.timing),
        )
    }

    /// The command writer at `strength` (`None` = no writer until a strength is set).
    pub fn command_writer(
        &self,
        strength: Option<Strength>,
    ) -> Result<StrengthWriter<ServoControl>, DdsError> {
        StrengthWriter::new(
            self.publisher_of(&self.topics.command).clone(),
            self.topics.command.clone(),
            self.timing.clone(),
            strength,
        )
    }

    /// A camera reader: all colours (filter by `color` yourself: RustDDS has no content
    /// filter).
    pub fn camera_reader(&self) -> Result<Reader<ShapeTypeExtended>, DdsError> {
        self.keyed_reader(&self.topics.camera, qos::camera_reader())
    }

    /// A camera writer, as the shapes simulator uses (reliable, so any camera reader matches).
    pub fn camera_writer(&self) -> Result<Writer<ShapeTypeExtended>, DdsError> {
        self.keyed_writer(&self.topics.camera, qos::camera_writer())
    }

    /// How many participants have a heartbeat writer, and how many a heartbeat reader, as
    /// discovered (this one's own included, once its own announcements come back): the
    /// DDS-level replay starts a trace's processes held and lets them vote once all have
    /// found each other (`rl controller` under `RL_HOLD_START`, a `fault-injection` build).
    pub fn heartbeat_participants_discovered(&self) -> (usize, usize) {
        let topic = &self.config.heartbeat_topic;
        let writers = self
            .participant
            .discovered_writers()
            .into_iter()
            .filter(|w| &w.publication_topic_data.topic_name == topic)
            .map(|w| w.writer_proxy.remote_writer_guid.prefix)
            .collect::<BTreeSet<_>>();
        let readers = self
            .participant
            .discovered_readers()
            .into_iter()
            .filter(|r| r.subscription_topic_data.topic_name() == topic)
            .map(|r| r.reader_proxy.remote_reader_guid.prefix)
            .collect::<BTreeSet<_>>();
        (writers.len(), readers.len())
    }
}

fn create_error(what: &'static str, topic: &Topic, error: rustdds::dds::CreateError) -> DdsError {
    DdsError::Create {
        what,
        topic: topic.name(),
        reason: error.to_string(),
    }
}
