//! Typed readers and writers over RustDDS: decoding with validation on the way in, encoding
//! with the same validation on the way out, and the re-creatable command writer.

use super::{qos, DdsError};
use crate::config::Timing;
use crate::core::types::TAKEOVER_STRENGTH;
use crate::wire::{ServoControl, WireSample};
use rustdds::{
    dds::{ReadError, WriteError},
    mio, no_key,
    serialization::CDRSerializerAdapter,
    with_key, CDRDeserializerAdapter, Keyed, Publisher, RTPSEntity, ReadCondition, Timestamp,
    Topic, TopicDescription, GUID,
};
use serde::{de::DeserializeOwned, Serialize};
use std::io;
use std::time::{Duration, Instant};
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

/// The command writer of one controller, whose ownership strength follows its role.
///
/// RustDDS fixes a writer's QoS at creation, so a new strength means a new writer (a new
/// GUID). Going up (a promotion), the new writer is created first and the old one keeps
/// writing the same commands for two command deadlines, while readers discover the new
/// writer and learn its strength: the actuator never falls to a weaker controller in between.
/// Going down or to `None` (no role), the old writer is dropped at once: a controller must
/// never keep commanding above its role.
///
/// A standby's raise (from a standby strength to a higher one below the Primary's) waits the
/// same two command deadlines before its new writer is created: the controller above it raised in the same
/// round, and until readers have discovered that controller's new writer, its retiring one
/// holds the old strength, which the standby's new writer would tie (DDS then picks by GUID,
/// and the actuator would blip to the standby and back). The Primary's raise is never delayed.
///
/// While it commands at the Secondary's strength it keeps a writer at the takeover strength
/// ready, which writes nothing: a takeover from a late Primary (F17) moves to it at once, to
/// a writer every reader has already discovered. Leaving the takeover strength for another
/// hands over like a promotion: that writer owns the actuator, and retires as above.
pub struct CommandWriter {
    publisher: Publisher,
    topic: Topic,
    timing: Timing,
    strength: Option<i32>,
    writer: Option<RawCommandWriter>,
    /// The previous, weaker writer during a promotion, and when it is dropped.
    retiring: Option<(RawCommandWriter, Instant)>,
    /// A standby's raise waiting for the writers above it: the strength, and from when it
    /// may be created.
    waiting_raise: Option<(i32, Instant)>,
    /// The takeover writer kept ready while it commands at the Secondary's strength.
    ready: Option<RawCommandWriter>,
}

type RawCommandWriter = no_key::DataWriter<ServoControl, CDRSerializerAdapter<ServoControl>>;

impl CommandWriter {
    pub(super) fn new(
        publisher: Publisher,
        topic: Topic,
        timing: Timing,
        strength: Option<i32>,
    ) -> Result<CommandWriter, DdsError> {
        let mut writer = CommandWriter {
            publisher,
            topic,
            timing,
            strength: None,
            writer: None,
            retiring: None,
            waiting_raise: None,
            ready: None,
        };
        // The strength asked for at creation is taken at once: no controller above is
        // retiring a writer because of it.
        writer.apply_strength(strength)?;
        Ok(writer)
    }

    /// Changes the strength: a no-op when unchanged, else a new writer (or none for `None`).
    /// On error there is no writer and the strength reads `None`.
    pub fn set_strength(&mut self, strength: Option<i32>) -> Result<(), DdsError> {
        if strength == self.strength && strength.is_some() == self.writer.is_some() {
            self.waiting_raise = None;
            return Ok(());
        }
        if self.standby_raise_waits(strength) {
            return Ok(());
        }
        self.apply_strength(strength)
    }

    /// Moves to `strength` now: a new writer (or none for `None`), the old one kept retiring
    /// on a raise.
    fn apply_strength(&mut self, strength: Option<i32>) -> Result<(), DdsError> {
        let takeover = i32::from(TAKEOVER_STRENGTH);
        let promotion = matches!((self.strength, strength), (Some(old), Some(new)) if new > old)
            || (self.strength == Some(takeover) && strength.is_some());
        let old = self.writer.take();
        self.strength = None;
        self.retiring = match (promotion, old) {
            (true, Some(old)) => {
                let overlap =
                    Duration::from_millis(self.timing.command_deadline_ms.saturating_mul(2));
                Some((old, Instant::now() + overlap))
            }
            // Down or silent: the old writer (and any retiring one) goes now.
            _ => None,
        };
        if let Some(strength) = strength {
            let writer = match self.ready.take() {
                Some(ready) if strength == takeover => ready,
                _ => self.create(strength)?,
            };
            self.writer = Some(writer);
            self.strength = Some(strength);
        }
        let secondary = i32::from(crate::core::types::Role::Secondary.strength());
        if self.strength != Some(secondary) {
            self.ready = None;
        } else if self.ready.is_none() {
            // Without it a takeover creates its writer then, which readers discover later.
            self.ready = self
                .create(takeover)
                .inspect_err(|error| warn!("no takeover writer kept ready: {error}"))
                .ok();
        }
        Ok(())
    }

    fn create(&self, strength: i32) -> Result<RawCommandWriter, DdsError> {
        self.publisher
            .create_datawriter_no_key::<ServoControl, CDRSerializerAdapter<ServoControl>>(
                &self.topic,
                Some(qos::command_writer(&self.timing, strength)),
            )
            .map_err(|e| DdsError::Create {
                what: "command writer",
                topic: self.topic.name(),
                reason: e.to_string(),
            })
    }

    /// The DDS ownership strength it commands at; `None` without a writer (no role).
    pub fn strength(&self) -> Option<i32> {
        self.strength
    }

    /// Whether a raise to `strength` must still wait (see the type's notes); starts the wait
    /// at the first request of that strength.
    fn standby_raise_waits(&mut self, strength: Option<i32>) -> bool {
        let primary = i32::from(crate::core::types::Role::Primary.strength());
        // Only a standby moving up ties the writer retiring above it; a first writer (at
        // formation or joining) has nobody above re-creating one.
        let standby_raise = match (self.strength, strength) {
            (Some(old), Some(new)) => new < primary && new > old,
            _ => false,
        };
        if !standby_raise {
            self.waiting_raise = None;
            return false;
        }
        let now = Instant::now();
        let wait = Duration::from_millis(self.timing.command_deadline_ms.saturating_mul(2));
        match self.waiting_raise {
            Some((waiting, from)) if Some(waiting) == strength => now < from,
            _ => {
                self.waiting_raise = strength.map(|new| (new, now + wait));
                true
            }
        }
    }

    /// The current writer's GUID (`None` without a writer).
    pub fn guid(&self) -> Option<GUID> {
        self.writer.as_ref().map(RTPSEntity::guid)
    }

    /// Writes a command; `Ok(false)` when there is no writer (no strength).
    pub fn write(&mut self, command: ServoControl) -> Result<bool, DdsError> {
        if self
            .retiring
            .as_ref()
            .is_some_and(|(_, until)| Instant::now() >= *until)
        {
            self.retiring = None;
        }
        let Some(writer) = &self.writer else {
            return Ok(false);
        };
        let error = |e: WriteError<ServoControl>| DdsError::Write {
            topic: self.topic.name(),
            source: e.forget_data(),
        };
        // Stamped: the writer's lifespan counts from it (crate::dds::qos::command_writer).
        let written = Timestamp::now();
        if let Some((retiring, _)) = &self.retiring {
            retiring.write(command, Some(written)).map_err(error)?;
        }
        writer.write(command, Some(written)).map_err(error)?;
        Ok(true)
    }
}

/// A GUID as 32 lowercase hex digits (participant prefix first), for logs and JSON.
pub fn guid_hex(guid: GUID) -> String {
    guid.to_bytes().iter().map(|b| format!("{b:02x}")).collect()
}
