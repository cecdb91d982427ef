//! The protocol's vocabulary: controller ids, roles, phases, lives and vote assignments.
//! (The rule variants a check runs with are in [`crate::fixes`].)
//!
//! These names are shared (by meaning, never by code) with the implementation in `impl/`.

use serde::{Deserialize, Serialize};
use std::fmt;

/// A controller's configured id (1-based). Roles at system initialization go by lowest id.
pub type Id = u8;

/// The most controllers the model supports: three voters plus one that must be ignored.
pub const MAX_CONTROLLERS: usize = 4;

/// The number of roles; a controller beyond this many is ignored.
pub const ROLE_COUNT: usize = 3;

/// The strength of a Primary whose result was agreed without a majority of the last backed
/// result's members (F11): below every standby of a majority, above every Tertiary.
pub const PROVISIONAL_PRIMARY_STRENGTH: u8 = 15;

/// The strength a Secondary commands at when it takes over from a Primary whose commands
/// reach the actuator late (F17): above the Primary's, so none of the late Primary's samples
/// still in flight can take the actuator back.
pub const TAKEOVER_STRENGTH: u8 = 35;

/// A voted role. The order is the order of precedence: Primary drives the actuator.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Role {
    Primary,
    Secondary,
    Tertiary,
}

impl Role {
    pub const ALL: [Role; ROLE_COUNT] = [Role::Primary, Role::Secondary, Role::Tertiary];

    /// The role at a position of an assignment (0 = Primary).
    pub fn at(rank: usize) -> Option<Role> {
        Role::ALL.get(rank).copied()
    }

    pub fn rank(self) -> usize {
        self as usize
    }

    /// DDS ownership strength of the command writer for this role (paper: 30/20/10). A
    /// provisional result's Primary commands at [`PROVISIONAL_PRIMARY_STRENGTH`] instead.
    pub fn strength(self) -> u8 {
        match self {
            Role::Primary => 30,
            Role::Secondary => 20,
            Role::Tertiary => 10,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Role::Primary => "Primary",
            Role::Secondary => "Secondary",
            Role::Tertiary => "Tertiary",
        }
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
    /// Found itself in a voting minority: stops commanding and voting until restarted.
    Failed,
}

impl Phase {
    pub const ALL: [Phase; 4] = [
        Phase::Initializing,
        Phase::Voting,
        Phase::Steady,
        Phase::Failed,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Phase::Initializing => "initializing",
            Phase::Voting => "voting",
            Phase::Steady => "steady",
            Phase::Failed => "failed",
        }
    }
}

/// Whether a controller's process runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Life {
    /// Not started yet: a late joiner before it joins.
    NotStarted,
    Up,
    /// Stopped (SIGSTOP, a stall) with its memory intact: it neither sends nor receives nor
    /// commands until it resumes.
    Paused,
    /// Crashed; may restart as a new incarnation.
    Down,
}

/// One controller incarnation named in a vote: a restarted controller is a different holder.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct Holder {
    pub id: Id,
    pub incarnation: u8,
}

/// A vote's content: who should hold Primary, Secondary and Tertiary (in that order).
/// Holes only ever appear at the end (the prefix rule): `P=2 S=3 T=-`.
#[derive(Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
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
    pub fn role_of(&self, id: Id) -> Option<Role> {
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

    pub fn holder(&self, role: Role) -> Option<Id> {
        self.0[role.rank()].map(|h| h.id)
    }

    pub fn holders(&self) -> impl Iterator<Item = Holder> + '_ {
        self.0.iter().flatten().copied()
    }

    pub fn members(&self) -> impl Iterator<Item = Id> + '_ {
        self.holders().map(|h| h.id)
    }

    pub fn len(&self) -> usize {
        self.holders().count()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    pub fn contains(&self, id: Id) -> bool {
        self.members().any(|member| member == id)
    }

    /// True when no role is held below an empty one.
    pub fn is_prefix(&self) -> bool {
        let mut hole = false;
        for slot in self.0 {
            match slot {
                None => hole = true,
                Some(_) if hole => return false,
                Some(_) => {}
            }
        }
        true
    }
}

impl fmt::Debug for Assignment {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{self}")
    }
}

impl fmt::Display for Assignment {
    /// `P=1 S=2 T=3`, with `-` for an empty role and `#n` for a restarted incarnation.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (rank, slot) in self.0.iter().enumerate() {
            if rank > 0 {
                write!(f, " ")?;
            }
            let letter = ["P", "S", "T"][rank];
            match slot {
                Some(h) if h.incarnation > 0 => write!(f, "{letter}={}#{}", h.id, h.incarnation)?,
                Some(h) => write!(f, "{letter}={}", h.id)?,
                None => write!(f, "{letter}=-")?,
            }
        }
        Ok(())
    }
}
