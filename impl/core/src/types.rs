//! The protocol's vocabulary: controller ids and incarnations, roles, phases, vote assignments,
//! and the two messages controllers exchange (heartbeat, durable vote record).
//!
//! These names match the model's (`model/src/types.rs`) by meaning; the code is separate so the
//! specification stays independent of the implementation.

use serde::{Deserialize, Serialize};
use std::fmt;

/// A controller's configured id (1-based). At system initialization roles go by lowest id.
pub type ControllerId = u8;

/// Distinguishes the lives of one controller id: a new value at every start. Only equality
/// matters (a new incarnation retires the old one), never order.
pub type Incarnation = u64;

/// The number of roles; a controller beyond this many is ignored.
pub const ROLE_COUNT: usize = 3;

/// A DDS ownership strength (the OWNERSHIP_STRENGTH QoS, a `long`): how strongly a writer
/// claims an exclusive-ownership topic. A reader obeys the strongest live writer. RL's command
/// writers use 30/20/10 by role (the paper), 15 for a provisional Primary and 35 for a
/// takeover; a reader may meet any other value from writers that are not RL's.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize,
)]
#[serde(transparent)]
pub struct Strength(pub i32);

impl Strength {
    /// The DDS default, a writer that announced none.
    pub const DEFAULT: Strength = Strength(0);

    /// The QoS value.
    pub fn value(self) -> i32 {
        self.0
    }
}

impl fmt::Display for Strength {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.0)
    }
}

/// The strength a Primary commands with while its result is provisional (agreed without a
/// majority, a side cut off from the rest): above a lone standby's 10, below the Secondary
/// strength of the side that kept the majority, so that side's Primary wins even while it
/// holds 20 (finding F11).
pub const PROVISIONAL_PRIMARY_STRENGTH: Strength = Strength(15);

/// The strength a Secondary commands with when it takes over from a Primary whose commands
/// arrive late (finding F17): above the Primary's 30, so none of the late Primary's samples
/// still in flight can take the actuator back.
pub const TAKEOVER_STRENGTH: Strength = Strength(35);

/// How a peer's commands reach this controller, as the adapter measures them: each sample's
/// delay against the least delay seen from the same writer, so no clocks need agree (F17).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Arrival {
    /// No recent command from it.
    #[default]
    Unheard,
    /// Its recent commands arrive with their usual delay.
    OnTime,
    /// Its recent commands arrive later than its usual delay by more than the lateness bound.
    Late,
}

/// A voted role. The order is the order of precedence: Primary drives the actuator.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Role {
    /// Drives the actuator (strength 30).
    Primary,
    /// First standby (strength 20).
    Secondary,
    /// Second standby (strength 10): validates a majority vote.
    Tertiary,
}

impl Role {
    /// Every role, in order of precedence.
    pub const ALL: [Role; ROLE_COUNT] = [Role::Primary, Role::Secondary, Role::Tertiary];

    /// The role at a position of an assignment (0 = Primary).
    pub fn at(rank: usize) -> Option<Role> {
        Role::ALL.get(rank).copied()
    }

    /// Position in the assignment: 0 = Primary.
    pub fn rank(self) -> usize {
        self as usize
    }

    /// DDS ownership strength of the command writer for this role (paper: 30/20/10).
    pub fn strength(self) -> Strength {
        Strength(match self {
            Role::Primary => 30,
            Role::Secondary => 20,
            Role::Tertiary => 10,
        })
    }

    /// The role a command strength stands for, if any.
    pub fn from_strength(strength: Strength) -> Option<Role> {
        Role::ALL
            .into_iter()
            .find(|role| role.strength() == strength)
    }

    /// Its lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            Role::Primary => "primary",
            Role::Secondary => "secondary",
            Role::Tertiary => "tertiary",
        }
    }
}

impl fmt::Display for Role {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Where a running controller is in the protocol.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Phase {
    /// Heartbeating and listening, waiting for the initialization window to close.
    Initializing,
    /// Has published a vote and waits for a majority of identical votes.
    Voting,
    /// Holds the agreed result (a role, or none when it is a spare beyond three).
    Steady,
    /// Found itself in a voting minority (or detected its own fault): stops commanding and
    /// voting until restarted.
    Failed,
}

impl Phase {
    /// Every phase.
    pub const ALL: [Phase; 4] = [
        Phase::Initializing,
        Phase::Voting,
        Phase::Steady,
        Phase::Failed,
    ];

    /// Its lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            Phase::Initializing => "initializing",
            Phase::Voting => "voting",
            Phase::Steady => "steady",
            Phase::Failed => "failed",
        }
    }
}

impl fmt::Display for Phase {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// One controller incarnation named in a vote: a restarted controller is a different holder.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct Holder {
    /// The controller's id.
    pub id: ControllerId,
    /// Its process life.
    pub incarnation: Incarnation,
}

/// A vote's content: who should hold Primary, Secondary and Tertiary, in that order. Holes
/// only ever appear at the end: `P=2 S=3 T=-`.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize,
)]
pub struct Assignment(pub [Option<Holder>; ROLE_COUNT]);

impl Assignment {
    /// Builds an assignment from holders listed in order of precedence (at most three used).
    pub fn from_ranked(holders: impl IntoIterator<Item = Holder>) -> Assignment {
        let mut slots = [None; ROLE_COUNT];
        for (slot, holder) in slots.iter_mut().zip(holders) {
            *slot = Some(holder);
        }
        Assignment(slots)
    }

    /// The role of a controller id, whatever its incarnation.
    pub fn role_of(&self, id: ControllerId) -> Option<Role> {
        self.0
            .iter()
            .position(|slot| slot.is_some_and(|h| h.id == id))
            .and_then(Role::at)
    }

    /// The role of exactly this incarnation.
    pub fn role_of_holder(&self, holder: Holder) -> Option<Role> {
        self.0
            .iter()
            .position(|slot| *slot == Some(holder))
            .and_then(Role::at)
    }

    /// The controller id holding a role.
    pub fn holder(&self, role: Role) -> Option<ControllerId> {
        self.0[role.rank()].map(|h| h.id)
    }

    /// Whether this controller id holds a role.
    pub fn contains(&self, id: ControllerId) -> bool {
        self.role_of(id).is_some()
    }

    /// How many roles are filled.
    pub fn len(&self) -> usize {
        self.0.iter().flatten().count()
    }

    /// Whether no role is filled.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Holes only at the end (no Secondary without a Primary, no Tertiary without both).
    pub fn is_prefix(&self) -> bool {
        let filled = self.len();
        self.0.iter().take(filled).all(Option::is_some)
    }

    /// The ids holding roles, in role order.
    pub fn holders(&self) -> impl Iterator<Item = Holder> + '_ {
        self.0.iter().flatten().copied()
    }
}

impl fmt::Display for Assignment {
    /// `P=1 S=2 T=3` (ids only: incarnations are process-start stamps, too long to read).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (index, (role, slot)) in ["P", "S", "T"].iter().zip(self.0.iter()).enumerate() {
            if index > 0 {
                f.write_str(" ")?;
            }
            match slot {
                Some(holder) => write!(f, "{role}={}", holder.id)?,
                None => write!(f, "{role}=-")?,
            }
        }
        Ok(())
    }
}

/// The durable vote record (paper: the Vote topic): the latest vote of one controller
/// incarnation, kept for late readers and tools. Decisions read the copy in heartbeats.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct VoteRecord {
    /// The voter's id.
    pub from: ControllerId,
    /// The voter's process life.
    pub incarnation: Incarnation,
    /// `None` = the vote is withdrawn (the controller failed itself).
    pub vote: Option<Assignment>,
}

/// Why a controller-failed alarm is raised.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AlarmReason {
    /// Its heartbeats stopped for the dead-man deadline.
    Lost,
    /// It cast a minority vote past the grace, or announced its own failure.
    Failed,
    /// Samples in its name came from a participant other than the one it speaks from while
    /// that one was alive: another process configured with its id, or a forgery. The
    /// adapter raises it (the core never sees such samples).
    Impostor,
    /// Its input disagreed with the input two agreeing peers answered (input congruence),
    /// whatever its output: another value of the same input, or inputs neither peer
    /// received. The controller raises it about itself before it leaves (the application's
    /// cross-check; the core never sees inputs).
    InputDisagrees,
    /// Its raw answer (its law's own step, before alignment) disagreed with the raw answers
    /// two agreeing peers gave to the same input, while its output agreed: a wrong law that
    /// alignment masks. The controller raises it about itself before it leaves (the
    /// application's cross-check; the core never sees answers).
    LawDisagrees,
    /// It stood still, or was starved, past a command deadline (a stop, a frozen machine, a
    /// starved CPU, its own commands lapsed as the actuator's owner) and started again as a
    /// new incarnation. The new life raises it about itself and clears it once it has run for
    /// the settle bound without another stall (the adapter's stall detection; F12, F18).
    Stalled,
}
