//! The one actuator view of a role-written topic: its samples read through the writer trust
//! (crate::trust: only a live controller's writers, at most at the takeover strength 35, unless
//! any writer is taken) and the ownership arbiter (crate::arbiter, DDS exclusive ownership on
//! the reading side), with each writer's strength from discovery and its controller from the
//! heartbeats.
//!
//! Discovery normally precedes a writer's data; a sample from a writer not yet discovered
//! triggers a re-read of discovery (at most every 10 ms) and, if still unknown, is offered at
//! strength 0 (the DDS default), so it can only win when no other writer is live. Writers that
//! disappear from discovery (deleted, e.g. re-created at a new strength) are reported lost to
//! the arbiter. Samples taken together arrived together (a stall of this process or of the
//! network delivers a burst): the strongest writer's go first, so ownership passes to the
//! strongest live writer and not to whichever sample leads the burst.
//!
//! LIFESPAN is applied on the reading side too (DDS 1.4 2.2.3.16: a sample is not delivered
//! past its source timestamp plus the writer's lifespan, which RustDDS's readers do not apply
//! to unfragmented samples): a sample later than its writer's own best delay of the last 2 s
//! by more than the lifespan the writer announced ([`crate::delay`]: the clocks need not agree)
//! is [`Delivery::Expired`] and never offered to the arbiter. A stalled or starved writer's
//! old command, sent when its process runs again, would otherwise take the actuator back from
//! the controller it had fallen to (RL's command writers announce a lifespan of one command
//! deadline, and also drop such samples before sending, RustDDS fix 18; this side holds
//! whatever delayed the sample after that check).
//!
//! `rl servo` reports every sample's fate ([`OwnerFeed::deliveries`]); `rl controller` follows
//! the commanding controller's commands while it stands by (bumpless transfer), the camera
//! simulator's gimbal obeys the owner, and an application follows the owner of its own topic
//! (crate::api::Redundancy::owner_feed), all with [`OwnerFeed::take`].

use crate::arbiter::{Arbiter, Decision};
use crate::core::types::{ControllerId, Strength};
use crate::dds::{ControllerDirectory, DdsError, Reader, Session, WriterOffer, GUID};
use crate::delay::{delay_ms, DelayBaseline};
use crate::trust::{CommandTrust, Refusal};
use crate::wire::{HeartbeatSample, WireSample};
use std::collections::BTreeMap;

/// How often discovery is re-read for writers' strengths and removed writers.
const STRENGTH_REFRESH_MS: u64 = 100;
/// The soonest discovery is re-read again for a writer of unknown strength.
const UNKNOWN_WRITER_REFRESH_MS: u64 = 10;

/// What became of one sample.
#[derive(Clone, Debug, PartialEq)]
pub enum Delivery<V> {
    /// The writer is not trusted: not offered to the arbiter.
    Refused {
        /// Its writer.
        writer: GUID,
        /// Why.
        refusal: Refusal,
    },
    /// Older than its writer's lifespan when it arrived: not offered to the arbiter.
    Expired {
        /// Its writer.
        writer: GUID,
        /// How much later it arrived than the writer's best delay of the last 2 s, in ms.
        late_ms: i64,
        /// The lifespan its writer announced, in ms.
        lifespan_ms: u64,
    },
    /// Offered to the arbiter at `strength`: accepted (the owner's) or not, and whether it
    /// made its writer the owner.
    Offered {
        /// The sample.
        value: V,
        /// Its writer.
        writer: GUID,
        /// The writer's strength (0 while discovery has not announced it).
        strength: Strength,
        /// Whether discovery had announced the writer's strength.
        strength_known: bool,
        /// How much later it arrived than the writer's best delay of the last 2 s, in ms
        /// (`None`: no source timestamp).
        late_ms: Option<i64>,
        /// The arbiter's decision.
        decision: Decision<GUID>,
    },
}

/// The owner's samples of one topic, as they arrive.
pub struct OwnerFeed<S: WireSample> {
    samples: Reader<S>,
    heartbeats: Reader<HeartbeatSample>,
    arbiter: Arbiter<GUID>,
    trust: CommandTrust,
    directory: ControllerDirectory,
    offers: BTreeMap<GUID, WriterOffer>,
    /// Each writer's delays, for its samples' age; forgotten with the writer's discovery.
    delays: BTreeMap<GUID, DelayBaseline>,
    last_refresh_ms: Option<u64>,
}

impl<S: WireSample + 'static> OwnerFeed<S> {
    /// The owner's samples from `samples` (an actuator's [`Session::command_reader`], a
    /// standing-by controller's best-effort [`Session::command_follower_reader`], or a reader
    /// of an application's topic), with a heartbeat reader on `session`; `deadline_ms` is the
    /// command deadline, `peer_deadline_ms` how long a controller's participant stays trusted
    /// after its last heartbeat.
    pub fn open(
        session: &Session,
        samples: Reader<S>,
        deadline_ms: u64,
        peer_deadline_ms: u64,
    ) -> Result<OwnerFeed<S>, DdsError> {
        Self::open_trusting(
            session,
            samples,
            deadline_ms,
            CommandTrust::new(peer_deadline_ms, false),
        )
    }

    /// As [`OwnerFeed::open`], with the writer trust given (`rl servo --any-writer` takes every
    /// writer, as plain DDS exclusive ownership does).
    pub fn open_trusting(
        session: &Session,
        samples: Reader<S>,
        deadline_ms: u64,
        trust: CommandTrust,
    ) -> Result<OwnerFeed<S>, DdsError> {
        let heartbeats = session.heartbeat_reader()?;
        Ok(Self::open_following(
            heartbeats,
            samples,
            deadline_ms,
            trust,
        ))
    }

    /// As [`OwnerFeed::open_trusting`], with the controllers known from `heartbeats`: another
    /// group's ([`Session::group_heartbeat_reader`]) when the topic is that group's output.
    pub fn open_following(
        heartbeats: Reader<HeartbeatSample>,
        samples: Reader<S>,
        deadline_ms: u64,
        trust: CommandTrust,
    ) -> OwnerFeed<S> {
        OwnerFeed {
            samples,
            heartbeats,
            arbiter: Arbiter::new(deadline_ms),
            trust,
            directory: ControllerDirectory::new(),
            offers: BTreeMap::new(),
            delays: BTreeMap::new(),
            last_refresh_ms: None,
        }
    }

    /// The sample reader and the heartbeat reader, to register with a poll.
    pub fn readers(&self) -> [&dyn rustdds::mio::Evented; 2] {
        [&self.samples, &self.heartbeats]
    }

    fn refresh(&mut self, session: &Session, now_ms: u64) {
        let current = session.writer_offers(self.samples.topic_name());
        for gone in self.offers.keys().filter(|w| !current.contains_key(w)) {
            self.arbiter.writer_lost(*gone);
        }
        self.delays.retain(|writer, _| current.contains_key(writer));
        self.offers = current;
        self.last_refresh_ms = Some(now_ms);
    }

    fn refresh_due(&self, now_ms: u64, period_ms: u64) -> bool {
        self.last_refresh_ms
            .is_none_or(|last| now_ms.saturating_sub(last) >= period_ms)
    }

    /// Every sample that arrived since the last call, in the order offered (heartbeats first:
    /// they name the controllers of the samples that follow), with what became of it.
    pub fn deliveries(&mut self, session: &Session, now_ms: u64) -> Vec<Delivery<S::Value>> {
        for heartbeat in self.heartbeats.take() {
            if self.trust.heartbeat(&heartbeat, now_ms) {
                self.directory.note_heartbeat(&heartbeat);
            }
        }
        if self.refresh_due(now_ms, STRENGTH_REFRESH_MS) {
            self.refresh(session, now_ms);
        }
        let arrived = rustdds::Timestamp::now();
        let mut batch = Vec::new();
        for sample in self.samples.take() {
            if !self.offers.contains_key(&sample.writer)
                && self.refresh_due(now_ms, UNKNOWN_WRITER_REFRESH_MS)
            {
                self.refresh(session, now_ms);
            }
            let offer = self.offers.get(&sample.writer).copied();
            let late_ms = sample.source_timestamp.map(|written| {
                let delays = self.delays.entry(sample.writer).or_default();
                delays.lateness_ms(now_ms, delay_ms(arrived, written))
            });
            batch.push((offer, late_ms, sample));
        }
        // Stable: each writer's samples keep their order.
        batch.sort_by_key(|(offer, _, _)| {
            std::cmp::Reverse(offer.map(|o| o.strength).unwrap_or_default())
        });
        let mut deliveries = Vec::with_capacity(batch.len());
        for (offer, late_ms, sample) in batch {
            let writer = sample.writer;
            let strength = offer.map(|o| o.strength).unwrap_or_default();
            if let Err(refusal) = self.trust.admit(writer, strength) {
                deliveries.push(Delivery::Refused { writer, refusal });
                continue;
            }
            let lifespan_ms = offer.and_then(|o| o.lifespan_ms);
            if let (Some(late_ms), Some(lifespan_ms)) = (late_ms, lifespan_ms) {
                if u64::try_from(late_ms).is_ok_and(|late| late > lifespan_ms) {
                    deliveries.push(Delivery::Expired {
                        writer,
                        late_ms,
                        lifespan_ms,
                    });
                    continue;
                }
            }
            deliveries.push(Delivery::Offered {
                value: sample.value,
                writer,
                strength,
                strength_known: offer.is_some(),
                late_ms,
                decision: self.arbiter.offer(writer, strength, now_ms),
            });
        }
        deliveries
    }

    /// The newest sample the owner sent since the last call, if any, with its writer (its
    /// participant tells whether it is this controller's own: `crate::dds::participant_key`).
    pub fn take(&mut self, session: &Session, now_ms: u64) -> Option<(S::Value, GUID)> {
        self.deliveries(session, now_ms)
            .into_iter()
            .filter_map(|delivery| match delivery {
                Delivery::Offered {
                    value,
                    writer,
                    decision,
                    ..
                } if decision.accepted => Some((value, writer)),
                _ => None,
            })
            .last()
    }

    /// The controller `writer` belongs to, learned from its participant's heartbeats.
    pub fn controller_of(&self, writer: GUID) -> Option<ControllerId> {
        self.directory.controller_of(writer)
    }

    /// The owner at `now_ms`, if its deadline has not run out.
    pub fn owner(&self, now_ms: u64) -> Option<GUID> {
        self.arbiter.owner(now_ms)
    }

    /// The strength the arbiter last saw `writer` at.
    pub fn strength_of(&self, writer: GUID) -> Option<Strength> {
        self.arbiter.strength_of(writer)
    }

    /// Whether this is the first refusal of `writer` (to warn once per writer).
    pub fn first_refusal(&mut self, writer: GUID) -> bool {
        self.trust.first_warning(writer)
    }
}
