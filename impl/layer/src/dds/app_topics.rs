//! An application's own topics on RL's session: the role writer's DDS writer and the reader a
//! standby follows the owner with. They go on the participant the command topic is on (the
//! device participant when device topics are open), as the application's outputs are device
//! topics too.

use super::{create_error, create_topic, qos, DdsError, Keying, Reader, Session, StrengthWriter};
use crate::core::types::Strength;
use rustdds::{CDRDeserializerAdapter, DomainParticipant, Publisher, Subscriber, TopicKind};

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
}
