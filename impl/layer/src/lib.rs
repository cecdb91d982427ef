//! # RL: the Redundancy Layer for three-way voting controllers over DDS
//!
//! Three controllers heartbeat each other, vote roles Primary/Secondary/Tertiary, and publish
//! their commands with DDS exclusive ownership at a strength set by their role, so the actuator
//! follows the next controller within the command deadline when the Primary dies.
//!
//! This crate is what a controller application links: the pure voting core and thin adapters
//! around it. The `rl` command (the Pixytracker controller, the simulators, the status table,
//! the demo, the benchmarks, the key tool) is built on its public API alone, in the crate above
//! it (`impl/`).
//!
//! - [`api`]: what an application sees of RL, [`api::Redundancy`]; [`runtime`] is the voting
//!   thread that runs the core over DDS; [`event`] is the JSON event line it prints with
//!   `--json-events`.
//! - [`core`]: the protocol as a state machine, `step(input, now) -> commands`; no I/O, clock
//!   or threads. It follows the model in `model/` rule for rule (docs/protocol.md).
//! - [`wire`], [`dds`]: the DDS sample types (docs/rl.idl), and the participant, topics and QoS
//!   they travel with.
//! - [`arbiter`]: exclusive ownership with DDS semantics on the reading side (RustDDS readers
//!   do not enforce it); [`trust`]: which writers an actuator obeys (a controller's, at most
//!   at the takeover strength); [`owner_feed`]: a topic's owner's samples through both, for an
//!   actuator and for a standby that continues from where the owner was, dropping a sample
//!   past its writer's lifespan; [`delay`]: a writer's delay against its own best, which that
//!   lifespan and the runtime's view of late peers are judged by.
//! - [`vote_reader`]: output voting at the receiver, pure: every controller's answer to each
//!   input on a voted topic, a value taken only when two fresh controllers agree, a dissenting
//!   one alarmed; [`vote_feed`] reads a voted topic over DDS into it. [`cross_check`]: a
//!   controller's own answers compared with the two others', the odd one out of three at N
//!   inputs of a life leaving, pure.
//! - [`identity`] (the core's): each controller id bound to the DDS participant it speaks
//!   from, so a forged heartbeat is not believed and a duplicate id is alarmed.
//! - [`round_clock`]: the voting loop's clock, moved as the core says to follow the Primary's
//!   round phase, so the controllers share round boundaries whatever their wall clocks say.
//! - [`stall`]: detects a voting loop that stood still for a peer deadline, and
//!   [`link_watch`] links that all lose their carrier (a pulled cable); the core then starts a
//!   new incarnation, so it cannot take the actuator back.
//! - [`network_monitor`]: the Network Alarm Participant, the core's network monitor run over
//!   one DDS participant per network.
//! - [`leds`], [`console`]: the status LEDs and the console line, both pure functions of what
//!   a controller knows.
//! - [`config`]: the configuration (`rl.toml`), every field with the paper's default.
//! - [`service`], [`logging`], [`malloc`]: running under systemd (readiness, watchdog,
//!   journald), and a small resident footprint; [`failed_exit`]: a controller that votes
//!   itself FAILED leaves, to be restarted.
//! - [`security`]: DDS Security keystores, their generation and their start-up check.
//! - [`error`]: what the layer reports, and the exit code a command derives from it.
//!
//! docs/architecture.md draws the layout and the RL API on one page.

#![deny(missing_docs)]

pub mod api;
pub mod arbiter;
pub mod config;
pub mod console;
pub mod cross_check;
pub use rl_core as core;
pub mod dds;
pub mod delay;
pub mod error;
pub mod event;
pub mod failed_exit;
pub use rl_core::identity;
pub mod leds;
pub mod link_watch;
pub mod logging;
pub mod malloc;
pub mod network_monitor;
pub mod owner_feed;
pub mod round_clock;
pub mod runtime;
pub mod security;
pub mod service;
pub mod stall;
pub mod trust;
pub mod vote_feed;
pub mod vote_reader;
pub mod wire;

pub use error::Error;
