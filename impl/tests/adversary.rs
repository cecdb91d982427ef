//! Hostile input against real controllers: samples forged in a controller's name, a command
//! writer that outbids the roles, garbage on the DDS ports, crafted RTPS fragments against a
//! controller under a memory limit. Each test states what must happen, and where only DDS
//! Security can stop an attack the test says so and shows it (docs/protocol.md, "Hostile
//! input").
//!
//! The forger is this test process: its own DDS participant (`rl_layer::dds::Session`) writes
//! well-formed samples that name a controller it is not. The fragment tests need root (a memory
//! cgroup), so they are ignored by default:
//! `cargo test --release -p rl --test adversary -- --include-ignored`.
//!
//! With the `security` feature, `security` runs the same forgeries and the 4 GB fragment
//! against secured controllers, and checks that broken keystores are refused
//! (docs/security.md): `cargo test --release -p rl --features security --test adversary --
//! --include-ignored`.

mod support;

mod adversary {
    pub mod forged;
    pub mod fragments;
    #[cfg(feature = "security")]
    pub mod security;
}
