//! Typed readers and writers over RustDDS: decoding with validation on the way in, encoding
//! with the same validation on the way out (the re-creatable writer whose strength follows
//! the role is in `role_writer.rs`).

use super::DdsError;
use crate::wire::WireSample;
use rustdds::{
    dds::{ReadError, WriteError},
    mio, no_key,
    serialization::CDRSerializerAdapter,
    with_key, CDRDeserializerAdapter, Keyed, RTPSEntity, ReadCondition, Timestamp, Topic,
    TopicDescription, GUID,
};
use serde::{de::DeserializeOwned, Serialize};
use std::io;
use tracing::warn;

/// One validated sample and where it came from.
#[derive(Clone, Debug, PartialEq)]
pub struct Received<T> {
    /// The decoded, validated value.
    pub value: T,
    /// The writer's GUID; its prefix is the writing participant's.
    pub writer: GUID,
    /// The writer's source timestamp (RL's writers stamp every sample); `None` when unstamped.
    pub source_timestamp: Option<Timestamp>,
    /// When the sender wrote it, on the sender's clock, for the types that carry it
    /// ([`WireSample::sent_ms`]).
    pub sent_ms: Option<u64>,
}

/// A sample as RustDDS delivers it, before validation.
struct RawSample<S> {
    sample: S,
    writer: GUID,
    source_timestamp: Option<Timestamp>,
}

/// What `Reader` needs from a keyed or an unkeyed RustDDS reader.
trait RawReader<S>: mio::Evented {
    /// Takes every available sample (disposals dropped).
    fn take_raw(&mut self) -> Result<Vec<RawSample<S>>, ReadError>;
    fn guid(&self) -> GUID;
}

impl<S> RawReader<S> for with_key::DataReader<S, CDRDeserializerAdapter<S>>
where
    S: Keyed + DeserializeOwned + 'static,
    S::K: DeserializeOwned,
{
    fn take_raw(&mut self) -> Result<Vec<RawSample<S>>, ReadError> {
        let samples = self.take(usize::MAX, ReadCondition::any())?;
        Ok(samples
            .into_iter()
            .filter_map(|sample| {
                let writer = sample.sample_info().writer_guid();
                let source_timestamp = sample.sample_info().source_timestamp();
                match sample.into_value() {
                    with_key::Sample::Value(sample) => Some(RawSample {
                        sample,
                        writer,
                        source_timestamp,
                    }),
                    with_key::Sample::Dispose(_) => None,
                }
            })
            .collect())
    }

    fn guid(&self) -> GUID {
        RTPSEntity::guid(self)
    }
}

impl<S> RawReader<S> for no_key::DataReader<S, CDRDeserializerAdapter<S>>
where
    S: DeserializeOwned + 'static,
{
    fn take_raw(&mut self) -> Result<Vec<RawSample<S>>, ReadError> {
        let samples = self.take(usize::MAX, ReadCondition::any())?;
        Ok(samples
            .into_iter()
            .map(|sample| {
                let writer = sample.sample_info().writer_guid();
                let source_timestamp = sample.sample_info().source_timestamp();
                RawSample {
                    sample: sample.into_value(),
                    writer,
                    source_timestamp,
                }
            })
            .collect())
    }

    fn guid(&self) -> GUID {
        RTPSEntity::guid(self)
    }
}

/// Rounds of `take` per call: each undecodable sample costs one round (RustDDS stops at it and
/// resumes after it), so this bounds the work one call does on a flood of garbage.
const MAX_TAKE_ROUNDS: usize = 256;

/// A reader of one topic that yields only validated values. Non-blocking: [`Reader::take`]
/// returns what has arrived. It is a mio 0.6 `Evented` (`rustdds::mio`), readable when
/// samples arrive; register it edge-triggered and drain it with `take` on each event.
pub struct Reader<S: WireSample> {
    raw: Box<dyn RawReader<S> + Send>,
    topic: String,
    malformed_count: u64,
}

impl<S> Reader<S>
where
    S: WireSample + 'static,
{
    pub(super) fn keyed(
        raw: with_key::DataReader<S, CDRDeserializerAdapter<S>>,
        topic: &Topic,
    ) -> Reader<S>
    where
        S: Keyed + DeserializeOwned + Send,
        S::K: DeserializeOwned + Send,
    {
        Reader {
            raw: Box::new(raw),
            topic: topic.name(),
            malformed_count: 0,
        }
    }

    pub(super) fn unkeyed(
        raw: no_key::DataReader<S, CDRDeserializerAdapter<S>>,
        topic: &Topic,
    ) -> Reader<S>
    where
        S: DeserializeOwned + Send,
    {
        Reader {
            raw: Box::new(raw),
            topic: topic.name(),
            malformed_count: 0,
        }
    }

    /// Every valid sample that has arrived, oldest first. Samples that fail to decode or to
    /// validate are dropped with a warning and counted.
    pub fn take(&mut self) -> Vec<Received<S::Value>> {
        let mut received = Vec::new();
        for _ in 0..MAX_TAKE_ROUNDS {
            match self.raw.take_raw() {
                Ok(samples) if samples.is_empty() => break,
                Ok(samples) => {
                    for raw in samples {
                        let sent_ms = raw.sample.sent_ms();
                        match raw.sample.decode() {
                            Ok(value) => received.push(Received {
                                value,
                                writer: raw.writer,
                                source_timestamp: raw.source_timestamp,
                                sent_ms,
                            }),
                            Err(error) => self.reject(&format!(
                                "invalid sample from writer {}: {error}",
                                guid_hex(raw.writer)
                            )),
                        }
                    }
                }
                Err(ReadError::Deserialization { reason }) => {
                    self.reject(&format!("undecodable sample: {reason}"));
                }
                Err(ReadError::UnknownKey { details }) => {
                    self.reject(&format!("dispose of an unknown instance: {details}"));
                }
                Err(error) => {
                    warn!(topic = %self.topic, "reader failed: {error}");
                    break;
                }
            }
        }
        received
    }

    /// Warns on the first rejected sample and then at every power of two, so a peer sending
    /// garbage at 30 Hz cannot flood the log.
    fn reject(&mut self, what: &str) {
        self.malformed_count += 1;
        if self.malformed_count.is_power_of_two() {
            warn!(
                topic = %self.topic,
                dropped = self.malformed_count,
                "dropped {what}"
            );
        }
    }

    /// How many samples were dropped as malformed.
    pub fn malformed_count(&self) -> u64 {
        self.malformed_count
    }

    /// The name of the topic it reads.
    pub fn topic_name(&self) -> &str {
        &self.topic
    }

    /// The reader's own GUID.
    pub fn guid(&self) -> GUID {
        self.raw.guid()
    }
}

impl<S: WireSample> mio::Evented for Reader<S> {
    fn register(
        &self,
        poll: &mio::Poll,
        token: mio::Token,
        interest: mio::Ready,
        opts: mio::PollOpt,
    ) -> io::Result<()> {
        self.raw.register(poll, token, interest, opts)
    }

    fn reregister(
        &self,
        poll: &mio::Poll,
        token: mio::Token,
        interest: mio::Ready,
        opts: mio::PollOpt,
    ) -> io::Result<()> {
        self.raw.reregister(poll, token, interest, opts)
    }

    fn deregister(&self, poll: &mio::Poll) -> io::Result<()> {
        self.raw.deregister(poll)
    }
}

/// What `Writer` needs from a keyed or an unkeyed RustDDS writer.
trait RawWriter<S> {
    fn write_raw(&self, sample: S) -> Result<(), WriteError<()>>;
    fn guid(&self) -> GUID;
}

impl<S> RawWriter<S> for with_key::DataWriter<S, CDRSerializerAdapter<S>>
where
    S: Keyed + Serialize,
    S::K: Serialize,
{
    fn write_raw(&self, sample: S) -> Result<(), WriteError<()>> {
        // Stamped, so a reader knows when it was written (a late reader of an alarm: since
        // when it has been raised).
        self.write(sample, Some(Timestamp::now()))
            .map_err(WriteError::forget_data)
    }
    fn guid(&self) -> GUID {
        RTPSEntity::guid(self)
    }
}

impl<S> RawWriter<S> for no_key::DataWriter<S, CDRSerializerAdapter<S>>
where
    S: Serialize,
{
    fn write_raw(&self, sample: S) -> Result<(), WriteError<()>> {
        // Stamped, so a reader knows when it was written (a late reader of an alarm: since
        // when it has been raised).
        self.write(sample, Some(Timestamp::now()))
            .map_err(WriteError::forget_data)
    }
    fn guid(&self) -> GUID {
        RTPSEntity::guid(self)
    }
}

/// A writer of one topic that writes values of the program's types.
pub struct Writer<S: WireSample> {
    raw: Box<dyn RawWriter<S> + Send>,
    topic: String,
}

impl<S> Writer<S>
where
    S: WireSample + Clone + 'static,
{
    pub(super) fn keyed(
        raw: with_key::DataWriter<S, CDRSerializerAdapter<S>>,
        topic: &Topic,
    ) -> Writer<S>
    where
        S: Keyed + Serialize + Send,
        S::K: Serialize,
    {
        Writer {
            raw: Box::new(raw),
            topic: topic.name(),
        }
    }

    /// Encodes and writes `value`. A value that would not pass the readers' validation is
    /// refused (`DdsError::Invalid`) instead of being sent.
    pub fn write(&self, value: &S::Value) -> Result<(), DdsError> {
        let sample = S::encode(value);
        if let Err(source) = sample.clone().decode() {
            return Err(DdsError::Invalid {
                topic: self.topic.clone(),
                source,
            });
        }
        self.write_sample(sample)
    }

    /// Writes a sample as is, without validation: for tests and tools that must be able to
    /// put malformed samples on the wire.
    pub fn write_sample(&self, sample: S) -> Result<(), DdsError> {
        self.raw
            .write_raw(sample)
            .map_err(|source| DdsError::Write {
                topic: self.topic.clone(),
                source,
            })
    }

    /// The name of the topic it writes.
    pub fn topic_name(&self) -> &str {
        &self.topic
    }

    /// The writer's GUID; its prefix is this session's participant's.
    pub fn guid(&self) -> GUID {
        self.raw.guid()
    }
}

/// A GUID as 32 lowercase hex digits (participant prefix first), for logs and JSON.
pub fn guid_hex(guid: GUID) -> String {
    guid.to_bytes().iter().map(|b| format!("{b:02x}")).collect()
}
