//! What the core needs to know about itself and its timing, in rounds.
//!
//! The adapter converts its configured durations (heartbeat period, peer deadline, window) to
//! round counts once; the rules that follow from them (the minority grace) are derived here,
//! in one place.

use crate::types::{ControllerId, Incarnation};

/// Round-based lengths the rules use, derived from the configured timing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rounds {
    /// A peer silent for this many rounds is lost (the dead-man deadline / period).
    pub dead_after_rounds: u32,
    /// The initialization window closes after this many rounds without a new peer.
    pub window_rounds: u32,
}

impl Rounds {
    /// Rounds a minority vote is tolerated before its voter is marked FAILED: one more than
    /// the dead-man deadline, so every voter has noticed the same loss first (finding F4).
    pub fn minority_grace_rounds(&self) -> u32 {
        self.dead_after_rounds + 1
    }
}

/// One controller's identity and timing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CoreConfig {
    /// This controller's configured id.
    pub id: ControllerId,
    /// A new value at every start of the process (e.g. the start time in ms).
    pub incarnation: Incarnation,
    /// One round.
    pub heartbeat_period_ms: u64,
    /// The rules' lengths in rounds.
    pub rounds: Rounds,
    /// How long a controller that failed itself stays up, announcing FAILED, before it leaves
    /// ([`crate::Command::Exit`]); `None`: it never leaves by itself.
    pub failed_exit_delay_ms: Option<u64>,
    /// Which architecture's rules it runs (three-way voting unless configured otherwise).
    pub architecture: crate::architectures::Architecture,
    /// A deliberately broken rule to run with (the conformance suite's mutation check).
    #[cfg(feature = "mutation")]
    pub mutation: Option<crate::mutation::Mutation>,
}

impl CoreConfig {
    /// A controller with the correct rules.
    pub fn new(
        id: ControllerId,
        incarnation: Incarnation,
        heartbeat_period_ms: u64,
        rounds: Rounds,
    ) -> CoreConfig {
        CoreConfig {
            id,
            incarnation,
            heartbeat_period_ms,
            rounds,
            failed_exit_delay_ms: None,
            architecture: crate::architectures::Architecture::Voting,
            #[cfg(feature = "mutation")]
            mutation: None,
        }
    }

    /// The same controller leaving `delay_ms` after it failed itself (and announced it).
    pub fn with_failed_exit_delay_ms(self, delay_ms: u64) -> CoreConfig {
        CoreConfig {
            failed_exit_delay_ms: Some(delay_ms),
            ..self
        }
    }

    /// The same controller running another architecture's rules.
    pub fn with_architecture(self, architecture: crate::architectures::Architecture) -> CoreConfig {
        CoreConfig {
            architecture,
            ..self
        }
    }

    /// The same controller running with `mutation` (`None` = the correct rules).
    #[cfg(feature = "mutation")]
    pub fn with_mutation(self, mutation: Option<crate::mutation::Mutation>) -> CoreConfig {
        CoreConfig { mutation, ..self }
    }

    /// The heartbeat goes out this long after the round boundary.
    pub fn heartbeat_offset_ms(&self) -> u64 {
        self.heartbeat_period_ms / 4
    }

    /// Whether a controller whose links all lose their carrier (a pulled cable) starts again
    /// as a new incarnation (the model's F16). The carrier is the runtime's to see
    /// (impl/layer/src/link_watch.rs), the decision is the protocol's: always, but under the
    /// `StayWhenUnplugged` mutation.
    pub fn restarts_when_unplugged(&self) -> bool {
        #[cfg(feature = "mutation")]
        return !crate::mutation::stays_when_unplugged(self);
        #[cfg(not(feature = "mutation"))]
        true
    }

    /// Whether a controller whose voting loop stood still for a peer deadline starts again as
    /// a new incarnation (the model's F12). The stall is the runtime's to see
    /// (impl/layer/src/stall.rs), the decision is the protocol's: always, but under the
    /// `KeepIncarnationOnResume` mutation.
    pub fn restarts_when_resumed(&self) -> bool {
        #[cfg(feature = "mutation")]
        return !crate::mutation::keeps_incarnation_on_resume(self);
        #[cfg(not(feature = "mutation"))]
        true
    }

    /// Whether a deliberately broken rule is configured (the invariants are then not asserted:
    /// breaking them is the point).
    pub fn is_mutated(&self) -> bool {
        #[cfg(feature = "mutation")]
        return self.mutation.is_some();
        #[cfg(not(feature = "mutation"))]
        false
    }
}
