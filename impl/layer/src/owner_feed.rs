//! The samples of the writer that owns a role-written topic, as an actuator sees them: the topic
//! read through the ownership arbiter (crate::arbiter, DDS exclusive ownership on the reading
//! side) and the writer trust (crate::trust: only a live controller's writers, at most at the
//! takeover strength 35).
//!
//! `rl controller` follows the commanding controller's commands with it while it stands by
//! (bumpless transfer), and the camera simulator's gimbal obeys the owner's commands with it, as
//! the real pan-tilt does; an application follows the owner of its own topic the same way
//! (crate::api::Redundancy::owner_feed).

use crate::arbiter::Arbiter;
use crate::dds::{DdsError, Reader, Session, GUID};
use crate::trust::CommandTrust;
use crate::wire::{HeartbeatSample, WireSample};
use std::collections::BTreeMap;

/// How often discovery is re-read for writers' strengths.
const STRENGTH_REFRESH_MS: u64 = 100;

/// The owner's samples of one topic, as they arrive.
pub struct OwnerFeed<S: WireSample> {
    samples: Reader<S>,
    heartbeats: Reader<HeartbeatSample>,
    arbiter: Arbiter<GUID>,
    trust: CommandTrust,
    strengths: BTreeMap<GUID, i32>,
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
        Ok(OwnerFeed {
            samples,
            heartbeats: session.heartbeat_reader()?,
            arbiter: Arbiter::new(deadline_ms),
            trust: CommandTrust::new(peer_deadline_ms, false),
            strengths: BTreeMap::new(),
            last_refresh_ms: None,
        })
    }

    fn refresh(&mut self, session: &Session, now_ms: u64) {
        let current = session.writer_strengths(self.samples.topic_name());
        for gone in self.strengths.keys().filter(|w| !current.contains_key(w)) {
            self.arbiter.writer_lost(*gone);
        }
        self.strengths = current;
        self.last_refresh_ms = Some(now_ms);
    }

    /// The newest sample the owner sent since the last call, if any, with its writer (its
    /// participant tells whether it is this controller's own: `crate::dds::participant_key`).
    pub fn take(&mut self, session: &Session, now_ms: u64) -> Option<(S::Value, GUID)> {
        for heartbeat in self.heartbeats.take() {
            self.trust.heartbeat(&heartbeat, now_ms);
        }
        if self
            .last_refresh_ms
            .is_none_or(|last| now_ms.saturating_sub(last) >= STRENGTH_REFRESH_MS)
        {
            self.refresh(session, now_ms);
        }
        let mut batch = Vec::new();
        for sample in self.samples.take() {
            // A writer not yet in discovery: look again, at most every 10 ms.
            if !self.strengths.contains_key(&sample.writer)
                && self
                    .last_refresh_ms
                    .is_none_or(|last| now_ms.saturating_sub(last) >= 10)
            {
                self.refresh(session, now_ms);
            }
            let strength = self.strengths.get(&sample.writer).copied().unwrap_or(0);
            batch.push((strength, sample));
        }
        // A burst goes strongest first, as at `rl servo`.
        batch.sort_by_key(|(strength, _)| std::cmp::Reverse(*strength));
        let mut newest = None;
        for (strength, sample) in batch {
            let writer = sample.writer;
            if self.trust.admit(writer, strength).is_err() {
                continue;
            }
            if self.arbiter.offer(writer, strength, now_ms).accepted {
                newest = Some((sample.value, writer));
            }
        }
        newest
    }
}
