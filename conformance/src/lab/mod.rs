//! # The fault lab: RL under real network and process faults
//!
//! Each run builds a virtual LAN of network namespaces (three controllers, the actuator side,
//! the camera; two bridges), starts real `rl` processes in it, forms P/S/T, applies a
//! scenario's faults (kill, pause, a freeze or a CPU starvation without a signal, partitions, cuts, one-way and random loss, multicast drop,
//! flapping, clock offsets, a rate-limited link, a link into one net or a whole net down,
//! wrong commands), heals them, lets the system settle, and
//! judges what the actuators (`rl servo --json` and an RTI Connext reader; `rl servo --vote`
//! too when commands go wrong) and the controllers' own events show. docs/faults.md has the
//! scenarios, the judges and the figures.
//!
//! Modules, in the order a run uses them:
//! - [`host`]: root, tools, system commands; [`lan`]: the namespaces, links and bridges, and
//!   their removal (drop, signals); [`clock`]: the lab clock;
//! - [`procs`]: the processes in their namespaces; [`session`]: a formed system and its
//!   schedule; [`faults`] (with [`nft`] and [`cgroup`]): each fault's apply and heal;
//! - [`scenario`]: named and seeded random schedules; [`expect`]: what each one's judges
//!   accept, in one place;
//! - [`observe`]: the lines taken in, on one clock; [`judge`]: the measurements and the
//!   verdict; [`network_alarms`]: the network alarms of the net scenarios against what each
//!   expects; [`validation`]: the recorded events against the model;
//! - [`run`]: one run start to verdict and its output; [`plot`]: its picture; [`matrix`]:
//!   many runs and the table; [`soak`]: long runs with resource sampling; [`mutation`]: runs
//!   against a deliberately broken `rl`, which must fail; [`traffic`]: what each controller
//!   sends and receives, fault-free;
//! - [`architecture`]: what differs when the controllers run the duplex or the pair;
//! - [`wrong_output`]: controllers whose commands go wrong while their roles stay, judged at
//!   the exclusive readers and a voting one, with the camera's tracking error;
//! - [`two_groups`]: two redundancy groups on one LAN, each host running a controller of
//!   each, both Primaries killed at once, each group judged as one run and, by
//!   [`cross_talk`], against the other.

pub mod architecture;
pub mod cgroup;
pub mod clock;
pub mod cross_talk;
pub mod error;
pub mod expect;
pub mod faults;
pub mod host;
pub mod judge;
pub mod lan;
pub mod matrix;
pub mod mutation;
pub mod network_alarms;
pub mod nft;
pub mod observe;
pub mod plot;
pub mod procs;
pub mod run;
pub mod scenario;
pub mod session;
pub mod soak;
pub mod traffic;
pub mod two_groups;
pub mod validation;
pub mod wrong_output;

pub use error::LabError;
