//! What discovery says of the remote writers of a topic: the ownership strength and lifespan
//! each EXCLUSIVE writer announced, for the actuator views (crate::owner_feed) that arbitrate
//! ownership and apply the lifespan on the reading side.

use super::{qos, Session, GUID};
use crate::core::types::Strength;
use std::collections::BTreeMap;

impl Session {
    /// Ownership strengths of the remote EXCLUSIVE writers of the command topic, by writer
    /// GUID, from discovery. Writers of this session are not included (RustDDS lists only
    /// remote ones); a deleted writer disappears once its removal is discovered.
    pub fn command_writer_strengths(&self) -> BTreeMap<GUID, Strength> {
        self.writer_strengths(&self.config.command_topic)
    }

    /// Ownership strengths of the remote EXCLUSIVE writers of any topic.
    pub fn writer_strengths(&self, topic_name: &str) -> BTreeMap<GUID, Strength> {
        self.writer_offers(topic_name)
            .into_iter()
            .map(|(writer, offer)| (writer, offer.strength))
            .collect()
    }

    /// What the remote EXCLUSIVE writers of any topic offer, by writer GUID, from discovery.
    pub fn writer_offers(&self, topic_name: &str) -> BTreeMap<GUID, WriterOffer> {
        // RL's own topics are on the main participant; the device topics and every
        // application topic on the device participant, when there is one.
        let control = [
            &self.config.heartbeat_topic,
            &self.config.vote_topic,
            &self.config.controller_alarm_topic,
            &self.config.network_alarm_topic,
        ];
        let participant = match &self.device {
            Some(device) if !control.contains(&&topic_name.to_string()) => &device.participant,
            _ => &self.participant,
        };
        participant
            .discovered_writers()
            .into_iter()
            .filter(|w| w.publication_topic_data.topic_name == topic_name)
            .filter_map(|w| {
                let offered = &w.publication_topic_data;
                qos::exclusive_strength(offered.ownership).map(|strength| {
                    let lifespan_ms = qos::finite_lifespan_ms(offered.lifespan);
                    (
                        offered.key,
                        WriterOffer {
                            strength,
                            lifespan_ms,
                        },
                    )
                })
            })
            .collect()
    }
}

/// What a remote EXCLUSIVE writer announced in discovery, as an actuator view needs it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WriterOffer {
    /// Its ownership strength.
    pub strength: Strength,
    /// Its LIFESPAN in milliseconds (`None`: INFINITE, samples never expire).
    pub lifespan_ms: Option<u64>,
}
