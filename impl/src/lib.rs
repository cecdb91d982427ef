//! # RL: a Redundancy Layer for three-way voting controllers over DDS
//!
//! Three controllers heartbeat each other, vote roles Primary/Secondary/Tertiary, and publish
//! their commands with DDS exclusive ownership at a strength set by their role, so the actuator
//! follows the next controller within the command deadline when the Primary dies.
//!
//! The crate is a pure voting core and thin adapters around it:
//!
//! - [`core`]: the protocol as a state machine, `step(input, now) -> commands`; no I/O, clock
//!   or threads. It follows the model in `model/` rule for rule (docs/protocol.md).
//! - [`wire`], [`dds`]: the DDS topics, their QoS and sample types.
//! - [`arbiter`]: exclusive ownership with DDS semantics on the reading side (RustDDS readers
//!   do not enforce it).
//! - [`controller`]: runs the core over DDS; [`api`] is what an application sees of it;
//!   [`event`] is the JSON event line it prints with `--json-events`.
//! - [`tracker`]: the paper's application (pan/tilt from the camera's circle).
//! - [`leds`], [`config`], [`sim`], [`status`], [`demo`], [`bench`]: status LEDs, configuration,
//!   camera and actuator simulators, the live status view, the demo and the benchmarks.
//! - [`service`], [`logging`]: running under systemd (readiness, watchdog, journald);
//!   [`failed_exit`]: a controller that votes itself FAILED leaves, to be restarted.
//! - [`security`]: DDS Security keystores (`rl keys`) and their start-up check.
//!
//! docs/architecture.md draws the layout and the RL API on one page.

pub mod api;
pub mod arbiter;
pub mod bench;
pub mod config;
pub mod console;
pub mod controller;
pub use rl_core as core;
pub mod dds;
pub mod demo;
pub mod error;
pub mod event;
pub mod failed_exit;
pub mod identity;
pub mod leds;
pub mod logging;
pub mod network_monitor;
pub mod procs;
pub mod round_clock;
pub mod runtime;
pub mod security;
pub mod service;
pub mod sim;
pub mod stall;
pub mod status;
pub mod status_page;
pub mod tracker;
pub mod wire;

pub use error::Error;
