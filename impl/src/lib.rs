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
//! - [`wire`], [`dds`]: the DDS sample types, and the participant, topics and QoS they
//!   travel with.
//! - [`arbiter`]: exclusive ownership with DDS semantics on the reading side (RustDDS readers
//!   do not enforce it).
//! - [`identity`]: each controller id bound to the DDS participant it speaks from, so a forged
//!   heartbeat is not believed and a duplicate id is alarmed.
//! - [`controller`]: `rl controller`, the tracker run through the RL API; [`api`] is what an
//!   application sees of RL; [`runtime`] is the voting thread that runs the core over DDS;
//!   [`event`] is the JSON event line it prints with `--json-events`.
//! - [`round_clock`]: the voting loop's clock, which follows the Primary's round phase so the
//!   controllers share round boundaries whatever their wall clocks say.
//! - [`stall`]: a voting loop that stood still for a peer deadline restarts as a new
//!   incarnation, so it cannot take the actuator back; [`link_watch`]: so does one whose
//!   links all lose their carrier (a pulled cable).
//! - [`network_monitor`]: the Network Alarm Participant, the core's network monitor run over
//!   one DDS participant per network.
//! - [`tracker`]: the paper's application (pan/tilt from the camera's circle).
//! - [`leds`], [`console`]: the status LEDs and the console line, both pure functions of what
//!   a controller knows.
//! - [`config`]: the configuration (`rl.toml`), every field with the paper's default.
//! - [`sim`]: the camera (`rl shapes`) and actuator (`rl servo`) simulators, and the ball and
//!   gimbal the simulated camera sees.
//! - [`status`], [`status_page`]: `rl status`, the live status table, and its page over HTTP.
//! - [`demo`], [`bench`](mod@bench), [`procs`]: the demo, the benchmarks, and the child
//!   processes they start and kill.
//! - [`service`], [`logging`]: running under systemd (readiness, watchdog, journald);
//!   [`failed_exit`]: a controller that votes itself FAILED leaves, to be restarted.
//! - [`security`]: DDS Security keystores (`rl keys`) and their start-up check.
//! - [`error`]: the top-level error, what a command reports and its exit code.
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
pub mod link_watch;
pub mod logging;
pub mod malloc;
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
