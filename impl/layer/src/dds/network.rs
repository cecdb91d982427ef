//! The network monitor's participants: one per network, each bound to this host's address
//! on that network, carrying only the network heartbeat (RLNHB).
//!
//! A network heartbeat must travel over its own network only, or a dead network stays hidden
//! behind the other. RustDDS listens on the wildcard address whatever it is told, but
//! `with_only_networks([address])` limits what it announces (unicast locators), where it joins
//! and sends multicast, and so where its peers send to; `same_host_loopback(false)` stops its
//! discovery going to 127.0.0.1. Each network also gets its own domain (`dds.domain + 1` for
//! A, `+ 2` for B): different ports, so a datagram for B's participants can never be taken in
//! by A's, whatever interface it arrived on (measured in `impl/tests/two_networks.rs`).

use super::endpoint::{Reader, Writer};
use super::{create_topic, publisher_and_subscriber, qos, DdsError};
use crate::wire::{NetworkHeartbeatSample, WireSample};
use rustdds::{
    serialization::CDRSerializerAdapter, CDRDeserializerAdapter, DomainParticipant, TopicKind,
};
use std::net::Ipv4Addr;

/// One network's participant, with the network heartbeat reader and writer.
pub struct NetworkParticipant {
    participant: DomainParticipant,
    /// The reader of every controller's network heartbeats on this network.
    pub heartbeats_in: Reader<NetworkHeartbeatSample>,
    /// This controller's network heartbeat writer on this network.
    pub heartbeats_out: Writer<NetworkHeartbeatSample>,
}

impl NetworkParticipant {
    /// The participant's GUID (the prefix of its writers' GUIDs).
    pub fn guid(&self) -> rustdds::GUID {
        rustdds::RTPSEntity::guid(&self.participant)
    }

    /// Joins `domain` on the interface with `address` only; `deadline_ms` is the heartbeat's
    /// deadline QoS.
    pub fn bind(
        domain: u16,
        address: Ipv4Addr,
        topic_name: &str,
        deadline_ms: u64,
    ) -> Result<NetworkParticipant, DdsError> {
        let participant_error = |reason: String| DdsError::Participant { domain, reason };
        let participant = super::participant_builder(domain)
            .with_only_networks([address])
            .same_host_loopback(false)
            .build()
            .map_err(|e| participant_error(e.to_string()))?;
        let (publisher, subscriber) = publisher_and_subscriber(&participant, "")?;
        let topic = create_topic(
            &participant,
            topic_name,
            NetworkHeartbeatSample::TYPE_NAME,
            TopicKind::WithKey,
        )?;
        let qos = qos::network_heartbeat(deadline_ms);
        let create_error = |what: &'static str, e: rustdds::dds::CreateError| DdsError::Create {
            what,
            topic: topic_name.to_string(),
            reason: e.to_string(),
        };
        let reader = subscriber
            .create_datareader::<NetworkHeartbeatSample, CDRDeserializerAdapter<_>>(
                &topic,
                Some(qos.clone()),
            )
            .map_err(|e| create_error("reader", e))?;
        let writer = publisher
            .create_datawriter::<NetworkHeartbeatSample, CDRSerializerAdapter<_>>(&topic, Some(qos))
            .map_err(|e| create_error("writer", e))?;
        Ok(NetworkParticipant {
            participant,
            heartbeats_in: Reader::keyed(reader, &topic),
            heartbeats_out: Writer::keyed(writer, &topic),
        })
    }
}
