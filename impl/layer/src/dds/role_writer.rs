//! The writer whose DDS ownership strength follows the controller's role, for any sample type,
//! keyed or not: the pixytracker's `pixy/servo_control` is one application of it.
//!
//! RustDDS fixes a writer's QoS at creation, so a new strength means a new writer (a new
//! GUID); how the old and the new writer hand over decides whether the actuator ever falls to
//! a weaker controller or blips to a standby, so it lives here once, for every topic.

use super::{qos, DdsError};
use crate::config::Timing;
use crate::core::types::{Role, Strength, TAKEOVER_STRENGTH};
use rustdds::{
    dds::{CreateError, WriteError},
    no_key,
    serialization::CDRSerializerAdapter,
    with_key, Publisher, QosPolicies, RTPSEntity, Timestamp, Topic, TopicDescription, TopicKind,
    GUID,
};
use serde::Serialize;
use std::marker::PhantomData;
use std::time::{Duration, Instant};
use tracing::warn;

/// How a topic's samples are keyed, and so which RustDDS writer carries them: [`NoKey`] (one
/// instance, as `pixy/servo_control`) or [`WithKey`] (one instance per key, as a heading per
/// axis). The application picks one with the writer; it cannot be implemented outside RL.
pub trait Keying<T>: private::Sealed + Send + 'static {
    /// The RustDDS writer of this kind.
    #[doc(hidden)]
    type Raw: RTPSEntity + Send;
    /// The DDS topic kind.
    const KIND: TopicKind;
    #[doc(hidden)]
    fn create(
        publisher: &Publisher,
        topic: &Topic,
        qos: QosPolicies,
    ) -> Result<Self::Raw, CreateError>;
    #[doc(hidden)]
    fn write(raw: &Self::Raw, sample: T, at: Timestamp) -> Result<(), WriteError<T>>;
    #[doc(hidden)]
    fn set_max_send_gap(raw: &Self::Raw, gap: Option<Duration>);
    #[doc(hidden)]
    fn stopped_after_gap(raw: &Self::Raw) -> bool;
}

/// An unkeyed topic: every controller's writer writes the one instance.
#[derive(Debug)]
pub struct NoKey;

/// A keyed topic (`T: rustdds::Keyed`): ownership is decided per instance, so each key has
/// its own owner, and a controller's role moves all of them at once.
#[derive(Debug)]
pub struct WithKey;

mod private {
    pub trait Sealed {}
    impl Sealed for super::NoKey {}
    impl Sealed for super::WithKey {}
}

impl<T> Keying<T> for NoKey
where
    T: Serialize + Send + 'static,
{
    type Raw = no_key::DataWriter<T, CDRSerializerAdapter<T>>;
    const KIND: TopicKind = TopicKind::NoKey;

    fn create(
        publisher: &Publisher,
        topic: &Topic,
        qos: QosPolicies,
    ) -> Result<Self::Raw, CreateError> {
        publisher.create_datawriter_no_key::<T, CDRSerializerAdapter<T>>(topic, Some(qos))
    }

    fn write(raw: &Self::Raw, sample: T, at: Timestamp) -> Result<(), WriteError<T>> {
        raw.write(sample, Some(at))
    }

    fn set_max_send_gap(raw: &Self::Raw, gap: Option<Duration>) {
        raw.set_max_send_gap(gap);
    }

    fn stopped_after_gap(raw: &Self::Raw) -> bool {
        raw.stopped_after_gap()
    }
}

impl<T> Keying<T> for WithKey
where
    T: rustdds::Keyed + Serialize + Send + 'static,
    T::K: rustdds::Key,
{
    type Raw = with_key::DataWriter<T, CDRSerializerAdapter<T>>;
    const KIND: TopicKind = TopicKind::WithKey;

    fn create(
        publisher: &Publisher,
        topic: &Topic,
        qos: QosPolicies,
    ) -> Result<Self::Raw, CreateError> {
        publisher.create_datawriter::<T, CDRSerializerAdapter<T>>(topic, Some(qos))
    }

    fn write(raw: &Self::Raw, sample: T, at: Timestamp) -> Result<(), WriteError<T>> {
        raw.write(sample, Some(at))
    }

    fn set_max_send_gap(raw: &Self::Raw, gap: Option<Duration>) {
        raw.set_max_send_gap(gap);
    }

    fn stopped_after_gap(raw: &Self::Raw) -> bool {
        raw.stopped_after_gap()
    }
}

/// The writer of one topic at the ownership strength it is given, re-created when the strength
/// changes. The application's [`crate::api::RoleWriter`] sets the strength from the role.
///
/// Going up (a promotion), the new writer is created first and the old one keeps writing the
/// same samples for two command deadlines, while readers discover the new writer and learn its
/// strength: the actuator never falls to a weaker controller in between. Going down or to
/// `None` (no role), the old writer is dropped at once: a controller must never keep
/// commanding above its role.
///
/// A standby's raise (from a standby strength to a higher one below the Primary's) waits the
/// same two command deadlines before its new writer is created: the controller above it raised
/// in the same round, and until readers have discovered that controller's new writer, its
/// retiring one holds the old strength, which the standby's new writer would tie (DDS then
/// picks by GUID, and the actuator would blip to the standby and back). The Primary's raise is
/// never delayed.
///
/// While it commands at the Secondary's strength it keeps a writer at the takeover strength
/// ready, which writes nothing: a takeover from a late Primary (F17) moves to it at once, to a
/// writer every reader has already discovered. Leaving the takeover strength for another hands
/// over like a promotion: that writer owns the actuator, and retires as above.
pub struct StrengthWriter<T, K: Keying<T> = NoKey> {
    publisher: Publisher,
    topic: Topic,
    timing: Timing,
    strength: Option<Strength>,
    writer: Option<K::Raw>,
    /// The previous, weaker writer during a promotion, and when it is dropped.
    retiring: Option<(K::Raw, Instant)>,
    /// A standby's raise waiting for the writers above it: the strength, and from when it
    /// may be created.
    waiting_raise: Option<(Strength, Instant)>,
    /// The takeover writer kept ready while it commands at the Secondary's strength.
    ready: Option<K::Raw>,
    /// The longest its DDS writers may go between two sends before they stop for good
    /// (`None`: no bound): see [`StrengthWriter::set_max_send_gap`].
    max_send_gap: Option<Duration>,
    /// Commands held back by the fault-injection control (a starved link's delay), with
    /// their stamps, oldest first.
    #[cfg(feature = "fault-injection")]
    delayed: std::collections::VecDeque<(T, Timestamp, Instant)>,
    samples: PhantomData<fn(T)>,
}

impl<T, K> StrengthWriter<T, K>
where
    T: Clone,
    K: Keying<T>,
{
    pub(super) fn new(
        publisher: Publisher,
        topic: Topic,
        timing: Timing,
        strength: Option<Strength>,
    ) -> Result<StrengthWriter<T, K>, DdsError> {
        let mut writer = StrengthWriter {
            publisher,
            topic,
            timing,
            strength: None,
            writer: None,
            retiring: None,
            waiting_raise: None,
            ready: None,
            max_send_gap: None,
            #[cfg(feature = "fault-injection")]
            delayed: std::collections::VecDeque::new(),
            samples: PhantomData,
        };
        // The strength asked for at creation is taken at once: no controller above is
        // retiring a writer because of it.
        writer.apply_strength(strength)?;
        Ok(writer)
    }

    /// Changes the strength: a no-op when unchanged, else a new writer (or none for `None`).
    /// On error there is no writer and the strength reads `None`.
    pub fn set_strength(&mut self, strength: Option<Strength>) -> Result<(), DdsError> {
        if self.stopped_after_gap() {
            // It sends nothing more: a new writer at the strength asked for (a standby's,
            // which no actuator follows; the owner doubts itself first, crate::api).
            let then = match strength {
                Some(strength) => format!("a new one at {} replaces it", strength.value()),
                None => "it goes".to_string(),
            };
            warn!(
                "{}: the command writer at {} stopped after a gap in its sends; {then}",
                self.topic.name(),
                self.strength.map_or(0, Strength::value),
            );
            return self.apply_strength(strength);
        }
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
    fn apply_strength(&mut self, strength: Option<Strength>) -> Result<(), DdsError> {
        let takeover = TAKEOVER_STRENGTH;
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
        let secondary = Role::Secondary.strength();
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

    fn create(&self, strength: Strength) -> Result<K::Raw, DdsError> {
        let writer = K::create(
            &self.publisher,
            &self.topic,
            qos::command_writer(&self.timing, strength),
        )
        .map_err(|e| DdsError::Create {
            what: "role writer",
            topic: self.topic.name(),
            reason: e.to_string(),
        })?;
        K::set_max_send_gap(&writer, self.max_send_gap);
        Ok(writer)
    }

    /// Bounds the gap between two sends of its DDS writers (`None`: no bound): a writer
    /// whose participant finds, at the moment it would send, that its last send was longer
    /// ago stops for good, sending and repairing nothing more (RustDDS fix 20). A reader
    /// that moved to a weaker writer after such a gap would take the actuator back at the
    /// next sample; a starved process runs late in every thread, so only the sending one can
    /// tell in time (crate::stall). Applies to the writers it has and creates.
    pub fn set_max_send_gap(&mut self, gap: Option<Duration>) {
        self.max_send_gap = gap;
        for writer in [&self.writer, &self.ready].into_iter().flatten() {
            K::set_max_send_gap(writer, gap);
        }
        if let Some((retiring, _)) = &self.retiring {
            K::set_max_send_gap(retiring, gap);
        }
    }

    /// Whether its current DDS writer stopped after a gap in its sends
    /// ([`StrengthWriter::set_max_send_gap`]).
    pub fn stopped_after_gap(&self) -> bool {
        self.writer.as_ref().is_some_and(K::stopped_after_gap)
    }

    /// The strength of the DDS writer now (`None`: no writer).
    pub fn strength(&self) -> Option<Strength> {
        self.strength
    }

    /// Whether a raise to `strength` must still wait (see the type's notes); starts the wait
    /// at the first request of that strength.
    fn standby_raise_waits(&mut self, strength: Option<Strength>) -> bool {
        let primary = Role::Primary.strength();
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

    /// The name of the topic it writes.
    pub fn topic_name(&self) -> String {
        self.topic.name()
    }

    /// Writes a sample; `Ok(false)` when there is no writer (no strength).
    pub fn write(&mut self, sample: T) -> Result<bool, DdsError> {
        if self
            .retiring
            .as_ref()
            .is_some_and(|(_, until)| Instant::now() >= *until)
        {
            self.retiring = None;
        }
        if self.writer.is_none() {
            return Ok(false);
        }
        // Stamped: the writer's lifespan counts from it (crate::dds::qos::command_writer).
        let written = Timestamp::now();
        #[cfg(feature = "fault-injection")]
        {
            use super::command_link::{self, CommandLink};
            match command_link::get() {
                CommandLink::OnTime => self.delayed.clear(),
                CommandLink::Held => {
                    self.delayed.clear();
                    return Ok(true);
                }
                CommandLink::Delayed(delay_ms) => {
                    self.delayed.push_back((sample, written, Instant::now()));
                    let delay = Duration::from_millis(delay_ms);
                    while let Some((_, _, at)) = self.delayed.front() {
                        if at.elapsed() < delay {
                            break;
                        }
                        if let Some((late, stamp, _)) = self.delayed.pop_front() {
                            self.send(late, stamp)?;
                        }
                    }
                    return Ok(true);
                }
            }
        }
        self.send(sample, written)?;
        Ok(true)
    }

    /// Writes `sample` stamped `written` on the writer, and on a retiring one.
    fn send(&self, sample: T, written: Timestamp) -> Result<(), DdsError> {
        let error = |e: WriteError<T>| DdsError::Write {
            topic: self.topic.name(),
            source: e.forget_data(),
        };
        if let Some((retiring, _)) = &self.retiring {
            K::write(retiring, sample.clone(), written).map_err(error)?;
        }
        if let Some(writer) = &self.writer {
            K::write(writer, sample, written).map_err(error)?;
        }
        Ok(())
    }
}
