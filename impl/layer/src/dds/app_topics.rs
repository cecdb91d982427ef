//! An application's own topics on RL's session: the role writer's DDS writer, the reader a
//! standby follows the owner with, and both ends of a voted topic (every controller's own
//! instance, shared ownership: crate::vote_feed). They go on the participant the command topic
//! is on (the device participant when device topics are open), as the application's outputs
//! are device topics too.

use super::{
    create_error, create_topic, qos, DdsError, Keying, Reader, Session, StrengthWriter, Writer,
};
use crate::core::types::Strength;
use crate::wire::VotedSample;
use rustdds::serialization::CDRSerializerAdapter;
use rustdds::{CDRDeserializerAdapter, DomainParticipant, Publisher, Subscriber, TopicKind};
use serde::{de::DeserializeOwned, Serialize};

impl Session {
    fn device_side(&self) -> (&DomainParticipant, &Publisher, &Subscriber) {
        match &self.device {
            Some(device) => (&device.participant, &device.publisher, &device.subscriber),
            None => (&self.participant, &self.publisher, &self.subscriber),
        }
    }

    /// A writer of an application's own topic `name` (DDS type name `type_name`), with the
    /// command topic's QoS: exclusive ownership at `strength` (`None` = no writer until a
    /// strength is set), the command deadline. It goes on the participant the command topic
    /// is on (the device participant when device topics are open).
    pub fn strength_writer<T, K>(
        &self,
        name: &str,
        type_name: &str,
        strength: Option<Strength>,
    ) -> Result<StrengthWriter<T, K>, DdsError>
    where
        T: Clone,
        K: Keying<T>,
    {
        let (participant, publisher, _) = self.device_side();
        let topic = create_topic(participant, name, type_name, K::KIND)?;
        StrengthWriter::new(publisher.clone(), topic, self.timing.clone(), strength)
    }

    /// A best-effort reader of an application's own unkeyed topic `name` (DDS type name
    /// `type_name`), as a standby follows the owner of a role-written topic
    /// (crate::owner_feed, crate::api::Redundancy::owner_feed).
    pub fn plain_reader<T>(
        &self,
        name: &str,
        type_name: &str,
    ) -> Result<Reader<crate::wire::Plain<T>>, DdsError>
    where
        T: Clone + serde::de::DeserializeOwned + Send + 'static,
    {
        let (participant, _, subscriber) = self.device_side();
        let topic = create_topic(participant, name, type_name, TopicKind::NoKey)?;
        let raw = subscriber
            .create_datareader_no_key::<crate::wire::Plain<T>, CDRDeserializerAdapter<_>>(
                &topic,
                Some(qos::command_follower_reader(&self.timing)),
            )
            .map_err(|e| create_error("reader", &topic, e))?;
        Ok(Reader::unkeyed(raw, &topic))
    }

    /// This controller's writer of the voted topic `name` (DDS type name `type_name`): its own
    /// instance, keyed by its id, SHARED ownership ([`qos::voted_command_writer`]).
    pub fn voted_writer<T>(
        &self,
        name: &str,
        type_name: &str,
    ) -> Result<Writer<VotedSample<T>>, DdsError>
    where
        T: Clone + Serialize + Send + 'static,
    {
        let (participant, publisher, _) = self.device_side();
        let topic = create_topic(participant, name, type_name, TopicKind::WithKey)?;
        let raw = publisher
            .create_datawriter::<VotedSample<T>, CDRSerializerAdapter<_>>(
                &topic,
                Some(qos::voted_command_writer(&self.timing)),
            )
            .map_err(|e| create_error("writer", &topic, e))?;
        Ok(Writer::keyed(raw, &topic))
    }

    /// A reader of every controller's instance of the voted topic `name` (DDS type name
    /// `type_name`), as a voting receiver reads it ([`qos::voted_command_reader`]).
    pub fn voted_reader<T>(
        &self,
        name: &str,
        type_name: &str,
    ) -> Result<Reader<VotedSample<T>>, DdsError>
    where
        T: Clone + DeserializeOwned + Send + 'static,
    {
        self.voted_reader_with(name, type_name, qos::voted_command_reader(&self.timing))
    }

    /// As [`Session::voted_reader`], best effort: for a controller that follows the vote to
    /// align its own state, which needs only the latest answers
    /// ([`qos::voted_follower_reader`]).
    pub fn voted_follower_reader<T>(
        &self,
        name: &str,
        type_name: &str,
    ) -> Result<Reader<VotedSample<T>>, DdsError>
    where
        T: Clone + DeserializeOwned + Send + 'static,
    {
        self.voted_reader_with(name, type_name, qos::voted_follower_reader(&self.timing))
    }

    fn voted_reader_with<T>(
        &self,
        name: &str,
        type_name: &str,
        qos: rustdds::QosPolicies,
    ) -> Result<Reader<VotedSample<T>>, DdsError>
    where
        T: Clone + DeserializeOwned + Send + 'static,
    {
        let (participant, _, subscriber) = self.device_side();
        let topic = create_topic(participant, name, type_name, TopicKind::WithKey)?;
        let raw = subscriber
            .create_datareader::<VotedSample<T>, CDRDeserializerAdapter<_>>(&topic, Some(qos))
            .map_err(|e| create_error("reader", &topic, e))?;
        Ok(Reader::keyed(raw, &topic))
    }
}
