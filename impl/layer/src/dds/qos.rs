//! The QoS of every RL endpoint, in one place (the paper's topic table, docs/protocol.md).
//!
//! RustDDS fixes a writer's QoS at creation, and a reader's requested deadline must be at
//! least the writer's offered one, so both sides of a topic take their values from the same
//! configuration.

use crate::config::Timing;
use crate::core::types::Strength;
use rustdds::{
    policy::{Deadline, Durability, History, Lifespan, Liveliness, Ownership, Reliability},
    Duration, QosPolicies, QosPolicyBuilder,
};

/// How long a reliable writer may block when its history is full (keep-last writers never
/// are).
const RELIABLE_MAX_BLOCKING_MS: u64 = 100;

/// Command samples a reader keeps between takes: deep enough that the owner's sample is never
/// pushed out by other writers' samples before the arbiter sees it.
pub const COMMAND_READER_HISTORY_DEPTH: i32 = 32;

fn duration_ms(ms: u64) -> Duration {
    Duration::from_millis(i64::try_from(ms).unwrap_or(i64::MAX))
}

fn reliable() -> Reliability {
    Reliability::Reliable {
        max_blocking_time: duration_ms(RELIABLE_MAX_BLOCKING_MS),
    }
}

/// The heartbeat deadline: twice the heartbeat period (paper).
pub fn heartbeat_deadline_ms(timing: &Timing) -> u64 {
    timing.heartbeat_period_ms.saturating_mul(2)
}

/// Controller heartbeat: best effort (a late heartbeat is worthless, never retried), keep
/// last 1 per controller, deadline 2 x period. Same for writer and reader.
pub fn heartbeat(timing: &Timing) -> QosPolicies {
    QosPolicyBuilder::new()
        .reliability(Reliability::BestEffort)
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 1 })
        .deadline(Deadline(duration_ms(heartbeat_deadline_ms(timing))))
        .build()
}

/// Vote record: reliable and TRANSIENT_LOCAL, keep last 1 per controller, so a late joiner
/// reads every controller's latest vote.
pub fn vote() -> QosPolicies {
    QosPolicyBuilder::new()
        .reliability(reliable())
        .durability(Durability::TransientLocal)
        .history(History::KeepLast { depth: 1 })
        .build()
}

/// Network alarms: reliable and TRANSIENT_LOCAL, keep last 1 per reporter and subject, so a
/// late reader (`rl status` started afterwards) gets every alarm's latest state.
pub fn network_alarm() -> QosPolicies {
    QosPolicyBuilder::new()
        .reliability(reliable())
        .durability(Durability::TransientLocal)
        .history(History::KeepLast { depth: 1 })
        .build()
}

/// Network heartbeat (RLNHB): best effort, keep last 1 per controller, deadline
/// `deadline_ms`; the network monitor keeps its own deadlines (rl_core::network), the QoS
/// states the contract for other readers.
pub fn network_heartbeat(deadline_ms: u64) -> QosPolicies {
    QosPolicyBuilder::new()
        .reliability(Reliability::BestEffort)
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 1 })
        .deadline(Deadline(duration_ms(deadline_ms)))
        .build()
}

/// Controller alarms: reliable and TRANSIENT_LOCAL, keep last 1 per reporter, controller and
/// kind, so a late reader (`rl status` started afterwards) gets every alarm's latest state.
pub fn alarm() -> QosPolicies {
    QosPolicyBuilder::new()
        .reliability(reliable())
        .durability(Durability::TransientLocal)
        .history(History::KeepLast { depth: 1 })
        .build()
}

/// The liveliness lease the command writer offers: three command deadlines (300 ms). Readers
/// that fail over on liveliness rather than on the deadline (Cyclone DDS) switch after it;
/// a reader requesting a shorter lease would not match.
pub fn command_liveliness_lease_ms(timing: &Timing) -> u64 {
    timing.command_deadline_ms.saturating_mul(3)
}

/// Command writer (`pixy/servo_control`): reliable, EXCLUSIVE ownership at `strength`,
/// deadline = the command deadline, automatic liveliness with a short lease, keep last 1 (as
/// the original tracker), and a lifespan of one command deadline: a command older than that
/// is never sent nor repaired (RustDDS fix 18), since a reader would take it for the writer
/// being alive and on time. A command written just before a stall (SIGSTOP) would otherwise
/// go out when the process resumes and take the actuator back for a moment.
pub fn command_writer(timing: &Timing, strength: Strength) -> QosPolicies {
    QosPolicyBuilder::new()
        .reliability(reliable())
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 1 })
        .ownership(Ownership::Exclusive {
            strength: strength.value(),
        })
        .deadline(Deadline(duration_ms(timing.command_deadline_ms)))
        .liveliness(Liveliness::Automatic {
            lease_duration: duration_ms(command_liveliness_lease_ms(timing)),
        })
        .lifespan(Lifespan {
            duration: duration_ms(timing.command_deadline_ms),
        })
        .build()
}

/// The longest a voting controller's command writer may go between two sends before it stops
/// for good (RustDDS fix 20, crate::dds::StrengthWriter::set_max_send_gap), ms: the command
/// deadline less one republish period (90 ms by default), or halfway between the period and the
/// deadline where the period is over a third of the deadline. Under the deadline, so the stop
/// comes before any reader could have moved to the next writer: a send after the gap would take
/// the actuator back. Over the period by as much as the deadline's margin, so a healthy
/// writer never meets it; and over a starved link's injected lateness (70 ms, the F17 traces)
/// plus a period, so a late but steady writer keeps its commands.
pub fn command_max_send_gap_ms(timing: &Timing) -> u64 {
    let deadline = timing.command_deadline_ms;
    let period = timing.command_republish_ms.min(deadline);
    deadline.saturating_sub(period).max((deadline + period) / 2)
}

/// Command reader: EXCLUSIVE (matches only exclusive writers), reliable, the same deadline,
/// and a deeper history so every writer's sample reaches the arbiter.
pub fn command_reader(timing: &Timing) -> QosPolicies {
    command_reader_with(timing, reliable())
}

/// A controller's reader of the other controllers' commands, which it follows while standing
/// by (bumpless transfer, the tracker of `rl controller`): as [`command_reader`] but best effort, since only
/// the latest command matters to it. A reliable reader would acknowledge every sample of
/// every command writer (RustDDS asks for an acknowledgement with each sample): on a slow
/// link those acknowledgements were half of a controller's traffic.
pub fn command_follower_reader(timing: &Timing) -> QosPolicies {
    command_reader_with(timing, Reliability::BestEffort)
}

fn command_reader_with(timing: &Timing, reliability: Reliability) -> QosPolicies {
    QosPolicyBuilder::new()
        .reliability(reliability)
        .durability(Durability::Volatile)
        .history(History::KeepLast {
            depth: COMMAND_READER_HISTORY_DEPTH,
        })
        .ownership(Ownership::Exclusive { strength: 0 })
        .deadline(Deadline(duration_ms(timing.command_deadline_ms)))
        .build()
}

/// Voted command samples a reader keeps per instance (controller id) between takes: the
/// writer keeps 1, but a reader's instance is shared by every participant writing that id, so
/// a forger's samples must not push the controller's own out before the trust check sees them
/// (crate::vote_feed).
pub const VOTED_READER_HISTORY_DEPTH: i32 = 4;

/// Voted command writer (`pixy/servo_control_voted`, every controller's own instance, keyed
/// by its id): reliable, SHARED ownership (every instance has one writer; the receiver votes
/// among them, nobody owns the topic), keep last 1, deadline = the command deadline, and as
/// the command writer a short liveliness lease and a lifespan of one deadline (a command
/// written before a stall never goes out late). Reliable rather than best effort: the vote
/// needs two controllers' answers to the same input, and a lost answer that a repair would
/// have brought (keep last 1: never a superseded one) leaves the receiver holding when one
/// other controller is down or dissents.
pub fn voted_command_writer(timing: &Timing) -> QosPolicies {
    QosPolicyBuilder::new()
        .reliability(reliable())
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 1 })
        .ownership(Ownership::Shared)
        .deadline(Deadline(duration_ms(timing.command_deadline_ms)))
        .liveliness(Liveliness::Automatic {
            lease_duration: duration_ms(command_liveliness_lease_ms(timing)),
        })
        .lifespan(Lifespan {
            duration: duration_ms(timing.command_deadline_ms),
        })
        .build()
}

/// Voted command reader: reliable, SHARED (matches only shared writers), the same deadline,
/// keep last [`VOTED_READER_HISTORY_DEPTH`] per instance.
pub fn voted_command_reader(timing: &Timing) -> QosPolicies {
    voted_reader_with(timing, reliable())
}

/// A controller's reader of the voted topic, which it follows to align its own state: as
/// [`voted_command_reader`] but best effort, as [`command_follower_reader`] is and for the same
/// reason (only the latest answers matter to it, and a reliable reader acknowledges every
/// sample of every writer).
pub fn voted_follower_reader(timing: &Timing) -> QosPolicies {
    voted_reader_with(timing, Reliability::BestEffort)
}

fn voted_reader_with(timing: &Timing, reliability: Reliability) -> QosPolicies {
    QosPolicyBuilder::new()
        .reliability(reliability)
        .durability(Durability::Volatile)
        .history(History::KeepLast {
            depth: VOTED_READER_HISTORY_DEPTH,
        })
        .ownership(Ownership::Shared)
        .deadline(Deadline(duration_ms(timing.command_deadline_ms)))
        .build()
}

/// Camera reader history per colour: about a quarter second of frames at 30 Hz. A tracker
/// whose loop runs late takes every frame since it last ran, in order, rather than only the
/// newest: its control law's memory (the PD's previous error) stays the group's, where a
/// frame lost to one controller alone made its answers to the next frames unlike its peers'
/// (no two agreeing at a voting actuator while another controller was wrong).
pub const CAMERA_READER_HISTORY_DEPTH: i32 = 8;

/// Camera reader (`Circle`): best effort, keep last [`CAMERA_READER_HISTORY_DEPTH`] per
/// colour. A best-effort reader matches both best-effort and reliable shapes writers (RTI
/// Shapes Demo, PixyShapes).
pub fn camera_reader() -> QosPolicies {
    QosPolicyBuilder::new()
        .reliability(Reliability::BestEffort)
        .durability(Durability::Volatile)
        .history(History::KeepLast {
            depth: CAMERA_READER_HISTORY_DEPTH,
        })
        .build()
}

/// Camera writer history. RustDDS applies a writer's keep-last depth to the whole writer, not
/// per instance, and a sample still queued for sending is dropped when a newer one pushes it
/// out: with depth 1, circles of several colours written back to back lose all but the last.
pub const CAMERA_WRITER_HISTORY_DEPTH: i32 = 16;

/// Camera writer (the shapes simulator): reliable, which matches both reliable and
/// best-effort readers, keep last [`CAMERA_WRITER_HISTORY_DEPTH`] samples.
pub fn camera_writer() -> QosPolicies {
    QosPolicyBuilder::new()
        .reliability(reliable())
        .durability(Durability::Volatile)
        .history(History::KeepLast {
            depth: CAMERA_WRITER_HISTORY_DEPTH,
        })
        .build()
}

/// The lifespan a remote writer announced, in whole milliseconds: `None` for none or INFINITE
/// (the DDS default, and what ROS 2 profiles announce).
pub fn finite_lifespan_ms(lifespan: Option<Lifespan>) -> Option<u64> {
    let duration = lifespan?.duration;
    if duration == rustdds::Duration::INFINITE {
        return None;
    }
    // Rounded: on the wire a duration is in 2^-32 s, so 100 ms arrives as 99.999999 ms.
    u64::try_from((duration.to_nanoseconds() + 500_000) / 1_000_000).ok()
}

/// The ownership strength a remote writer announced: `Some` for EXCLUSIVE writers.
pub fn exclusive_strength(ownership: Option<Ownership>) -> Option<Strength> {
    match ownership {
        Some(Ownership::Exclusive { strength }) => Some(Strength(strength)),
        Some(Ownership::Shared) | None => None,
    }
}
