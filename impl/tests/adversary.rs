//! Adversary tests: real `rl` processes on loopback DDS facing a participant that tries to
//! take over the control plane (forged heartbeats, a high-strength command writer) or a
//! keystore that is missing, expired or does not belong together. Each module is one kind
//! of defence; each test uses its own DDS domain (140-149).

mod support;

mod adversary {
    #[cfg(feature = "security")]
    pub mod security;
}
