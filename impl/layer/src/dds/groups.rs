//! Other redundancy groups on the session's domain: which groups are there (from discovery) and
//! readers of any group's heartbeats and alarms on this session's participant. `rl status` shows
//! every group on the domain with them, and an application of one group follows the owner of
//! another group's topic (the paper's chain: an actuator group steered by a navigation group)
//! by that group's heartbeats. A session's own endpoints stay its own group's
//! ([`Session::heartbeat_reader`] and the rest).

use super::{create_topic, qos, DdsError, Reader, Session};
use crate::config::Dds;
use crate::wire::{AlarmSample, HeartbeatSample, NetworkAlarmSample, WireSample};
use rustdds::TopicKind;
use std::collections::BTreeSet;

impl Session {
    /// The names group `group` uses on this domain, from this session's configuration as
    /// written (`""`: the names as configured).
    pub fn group_names(&self, group: &str) -> Dds {
        self.written.of_group(group)
    }

    /// The groups whose controllers' heartbeat writers discovery knows on this domain (this
    /// session's own group only if another participant of it writes heartbeats), by their
    /// heartbeat topic's name ([`Dds::group_of_heartbeat_topic`]); `""` is the group without a
    /// name.
    pub fn discovered_groups(&self) -> BTreeSet<String> {
        self.participant
            .discovered_writers()
            .into_iter()
            .filter_map(|writer| {
                self.written
                    .group_of_heartbeat_topic(&writer.publication_topic_data.topic_name)
            })
            .collect()
    }

    /// A reader of group `group`'s heartbeats, as [`Session::heartbeat_reader`] reads this
    /// session's group.
    pub fn group_heartbeat_reader(&self, group: &str) -> Result<Reader<HeartbeatSample>, DdsError> {
        let name = self.group_names(group).heartbeat_topic;
        self.group_reader(&name, qos::heartbeat(&self.timing))
    }

    /// A reader of group `group`'s controller alarms, as [`Session::alarm_reader`].
    pub fn group_alarm_reader(&self, group: &str) -> Result<Reader<AlarmSample>, DdsError> {
        let name = self.group_names(group).controller_alarm_topic;
        self.group_reader(&name, qos::alarm())
    }

    /// A reader of group `group`'s network alarms, as [`Session::network_alarm_reader`].
    pub fn group_network_alarm_reader(
        &self,
        group: &str,
    ) -> Result<Reader<NetworkAlarmSample>, DdsError> {
        let name = self.group_names(group).network_alarm_topic;
        self.group_reader(&name, qos::network_alarm())
    }

    fn group_reader<S>(&self, name: &str, qos: rustdds::QosPolicies) -> Result<Reader<S>, DdsError>
    where
        S: WireSample + rustdds::Keyed + serde::de::DeserializeOwned + Send + 'static,
        S::K: serde::de::DeserializeOwned + Send,
    {
        // RL's topics live on the main participant, whichever group they belong to.
        let topic = create_topic(&self.participant, name, S::TYPE_NAME, TopicKind::WithKey)?;
        self.keyed_reader(&topic, qos)
    }
}
