//! # Conformance: RL's implementation checked against its model
//!
//! The model (`model/`) is the specification; its trace generator writes paths through the
//! protocol (`traces/`), each step an action and the abstract state it leads to. This crate
//! replays them against the implementation (`impl/`, package `rl`) and checks, after every
//! step, that the implementation is in the state the model says (docs/conformance.md).
//!
//! - [`abstraction`]: the one abstraction function from implementation state to model state
//!   (the only code that knows both crates' types);
//! - [`trace`]: reading the trace files and their index;
//! - [`diff`]: the readable difference between the model's state and an observed one, one
//!   format for every check, so a mismatch reads the same everywhere;
//! - [`core_replay`]: the core-level replay: real `rl_layer::core::Core`s on a simulated clock and
//!   network, one model action at a time, with a readable diff on a mismatch; its
//!   [`transcript`](core_replay::transcript) module writes the readable per-trace transcripts
//!   kept as golden snapshots, and its [`coverage`](core_replay::coverage) module counts which
//!   (action kind x stage) pairs the replayed traces exercised;
//! - [`record`]: recorded runs (the controllers' JSON events) and what each controller
//!   reported at every round boundary;
//! - [`validate`]: trace validation, the other direction: a recorded run checked to be a
//!   behaviour the model allows;
//! - [`dds_replay`]: the DDS-level replay: which traces it takes and how each is timed on
//!   real processes (pure, from the model), and the run itself: real `rl controller`
//!   processes and an `rl servo` over DDS, faults applied for real;
//! - [`lab`]: the fault lab (binary `lab`): real processes on a virtual LAN of network
//!   namespaces under network, process and clock faults, judged at two actuators and against
//!   the model (docs/faults.md).

pub mod abstraction;
pub mod core_replay;
pub mod dds_replay;
pub mod diff;
pub mod lab;
pub mod record;
pub mod trace;
pub mod validate;
