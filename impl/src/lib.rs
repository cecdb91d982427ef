//! # The `rl` command's tools, on the RL library
//!
//! Everything here is built on the public API of the RL library (`rl-layer`, re-exported as
//! [`layer`]): it is what the paper's demonstration needs around the layer, not the layer.
//!
//! - [`controller`]: `rl controller`, the Pixytracker application made redundant through the
//!   RL API, with [`tracker`], its control law (pan/tilt from the camera's circle).
//! - [`chain`]: `rl chain nav|act`, the paper's chain of two redundant applications (a
//!   navigation group aiming, an actuator group commanding the servo) on the same API.
//! - [`sim`]: the camera (`rl shapes`) and actuator (`rl servo`) simulators, and the ball and
//!   gimbal the simulated camera sees.
//! - [`status`]: `rl status`, the live status table, and its page over HTTP ([`status::page`]).
//! - [`demo`], [`bench`](mod@bench), [`procs`]: the demo, the benchmarks, and the child
//!   processes they start and kill.
//! - [`cli`]: what every command shares: its configuration and the signals that stop it.
//! - [`keys`]: `rl keys`, DDS Security keystores for a group.
//! - [`error`]: the command's error, what it reports and its exit code.
//!
//! docs/architecture.md draws the layout on one page.

pub use rl_layer as layer;
pub use rl_layer::core;

pub mod bench;
pub mod chain;
pub mod cli;
pub mod controller;
pub mod demo;
pub mod error;
pub mod keys;
pub mod procs;
pub mod sim;
pub mod status;
pub mod tracker;

pub use error::Error;
