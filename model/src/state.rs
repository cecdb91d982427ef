//! The model's state: what each controller knows, what the network holds, and the ghost
//! history the properties read. The actions that move it are in crate::action.
//!
//! Time is counted in rounds of one heartbeat period; see docs/model.md for the abstraction.
//! Network state is kept as small as the timing assumption allows: a bit per link for "this
//! round's heartbeat is lost" and a bit per link for "a vote has been in flight for a round".

pub use crate::action::{Action, ActionKind};
use crate::types::{Assignment, Id, Life, Phase, Role, MAX_CONTROLLERS};
use serde::{Deserialize, Serialize};
use std::fmt;

/// What a controller knows of one peer (the paper's RedundancyInfo entry).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Peer {
    /// `Some(incarnation)` while the peer is believed alive.
    pub alive: Option<u8>,
    /// Rounds since its last heartbeat (the dead-man count, inverted).
    pub silent_rounds: u8,
    /// Its latest vote received, with the incarnation that sent it.
    pub vote: Option<(u8, Assignment)>,
    /// Marked FAILED: it cast a minority vote.
    pub failed: bool,
    /// Consecutive rounds its vote has disagreed with a majority.
    pub dissent_rounds: u8,
    /// A controller-failed alarm is raised for it (lost or FAILED) and not yet cleared.
    pub alarm: bool,
    /// The agreed result its last heartbeat carried (`Some` = it belongs to the running
    /// system: an incumbent).
    pub heard_agreed: Option<Assignment>,
    /// The vote its last heartbeat carried.
    pub heard_vote: Option<Assignment>,
    /// Its last heartbeat said it commands at Primary strength.
    pub claims_primary: bool,
    /// The epoch of the agreed result its last heartbeat carried (F11).
    pub heard_epoch: u32,
    /// That result was provisional (F11).
    pub heard_provisional: bool,
    /// The established command strength its last heartbeat reported (F13).
    pub heard_strength: Option<u8>,
}

impl Peer {
    pub fn incumbent(&self) -> bool {
        self.alive.is_some() && !self.failed && self.heard_agreed.is_some()
    }
}

/// One controller as the protocol sees it.
#[derive(Clone, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Controller {
    pub id: Id,
    pub life: Life,
    /// Starts at 0, +1 on every restart; heartbeats and votes carry it.
    pub incarnation: u8,
    pub phase: Phase,
    pub role: Option<Role>,
    /// The ownership strength it publishes commands with; `None` = silent.
    pub output: Option<u8>,
    /// It found a running system before voting (a durable vote, or a role in a heartbeat).
    pub late_joiner: bool,
    /// Rounds since the last new peer was heard, while initializing.
    pub window_quiet_rounds: u8,
    /// The last result that reached agreement.
    pub agreed: Option<Assignment>,
    /// Its own published vote.
    pub vote: Option<Assignment>,
    /// Ghost, set at restart: bit `id - 1` for every controller that held a role then; a
    /// restarted controller must come in below all of them.
    pub held_roles_at_restart: u8,
    /// Consecutive rounds in which two peers agreed on a result different from its vote.
    pub self_dissent_rounds: u8,
    /// Indexed by id - 1; its own entry is unused.
    pub peers: [Peer; MAX_CONTROLLERS],
    /// F11: the epoch of its agreed result.
    pub epoch: u32,
    /// F11: bit `id - 1` for each member of the last result agreed with a majority.
    pub quorum_base: u8,
    /// F11: its agreed result lacks a majority of `quorum_base`.
    pub provisional: bool,
    /// F11: rounds since it became provisional (saturates at 1): a provisional Primary keeps
    /// its strength for the round in which the majority side elects its own Primary.
    pub provisional_rounds: u8,
    /// The previous, weaker command writer that keeps writing while the actuator discovers
    /// the new one (a raise re-creates the writer; RustDDS cannot change its strength).
    pub retiring: Option<u8>,
    /// The newest writer was created this round: heartbeats still report the old strength.
    pub fresh_writer: bool,
    /// The actuator has not discovered the newest writer yet.
    pub undiscovered: bool,
    /// F17: it took over from this Primary (id, incarnation), whose commands arrived late,
    /// and commands at [`crate::types::TAKEOVER_STRENGTH`] until it hears that Primary's next
    /// incarnation.
    pub took_over_from: Option<(Id, u8)>,
    /// F17: it heard a peer that took over from it; it starts again at the round's end.
    pub deposed: bool,
}

impl Controller {
    pub fn new(id: Id, life: Life) -> Controller {
        Controller {
            id,
            life,
            incarnation: 0,
            phase: Phase::Initializing,
            role: None,
            output: None,
            late_joiner: false,
            window_quiet_rounds: 0,
            agreed: None,
            vote: None,
            held_roles_at_restart: 0,
            self_dissent_rounds: 0,
            peers: [Peer::default(); MAX_CONTROLLERS],
            epoch: 0,
            quorum_base: 0,
            provisional: false,
            provisional_rounds: 0,
            retiring: None,
            fresh_writer: false,
            undiscovered: false,
            took_over_from: None,
            deposed: false,
        }
    }

    /// The command strength its heartbeat reports: a writer created this round is not yet
    /// established (the actuator may not know it), so the previous one is reported.
    pub fn established_strength(&self) -> Option<u8> {
        if self.fresh_writer {
            self.retiring
        } else {
            self.output
        }
    }

    /// The strongest of its writers the actuator knows, while its process runs.
    pub fn visible_strength(&self) -> Option<u8> {
        if !self.is_up() {
            return None;
        }
        let newest = self.output.filter(|_| !self.undiscovered);
        newest.max(self.retiring)
    }

    /// Changes the command strength the way the DDS adapter does: a raise creates the new
    /// writer and keeps the old one writing until the actuator has discovered the new one; a
    /// lowering or silence drops the old writer at once, except from the takeover strength
    /// to another (F17), which hands over like a raise.
    pub fn set_output(&mut self, strength: Option<u8>) {
        if strength == self.output {
            return;
        }
        let raise = matches!((self.output, strength), (Some(old), Some(new)) if new > old);
        // F17: leaving the takeover strength for the Primary's hands over like a raise: the
        // takeover writer is the actuator's owner, and nobody else commands above 30 then.
        let from_takeover =
            self.output == Some(crate::types::TAKEOVER_STRENGTH) && strength.is_some();
        self.retiring = if raise || from_takeover {
            self.output.max(self.retiring)
        } else {
            None
        };
        self.output = strength;
        self.fresh_writer = strength.is_some();
        self.undiscovered = strength.is_some();
    }

    /// F17: takes over from the Primary `from` (its incarnation `incarnation`) at the takeover
    /// strength, on the writer it keeps ready for this: the actuator already knows it.
    pub fn take_over(&mut self, from: Id, incarnation: u8) {
        self.took_over_from = Some((from, incarnation));
        self.set_output(Some(crate::types::TAKEOVER_STRENGTH));
        self.undiscovered = false;
    }

    /// A new round: the writers created in the last one are established (the actuator has
    /// discovered them) and the retired ones are gone (discovery within a round, the timing
    /// assumption).
    pub fn establish_writers(&mut self) {
        self.fresh_writer = false;
        self.undiscovered = false;
        self.retiring = None;
    }

    pub fn is_up(&self) -> bool {
        self.life == Life::Up
    }

    /// Up and not FAILED: a controller that takes part in voting.
    pub fn is_active(&self) -> bool {
        self.is_up() && self.phase != Phase::Failed
    }

    pub fn peer(&self, id: Id) -> &Peer {
        &self.peers[usize::from(id - 1)]
    }

    pub fn peer_mut(&mut self, id: Id) -> &mut Peer {
        &mut self.peers[usize::from(id - 1)]
    }

    /// F15: the members of its last backed result that it no longer hears are more than half
    /// of that result: they could back a result (and elect a Primary) of their own.
    pub fn lost_could_outvote(&self) -> bool {
        let heard = self.members().fold(0u8, |mask, id| mask | 1 << (id - 1));
        let lost = self.quorum_base & !heard;
        lost.count_ones() * 2 > self.quorum_base.count_ones()
    }

    /// Peers believed alive and not marked FAILED, with itself: its membership view.
    pub fn members(&self) -> impl Iterator<Item = Id> + '_ {
        let own = self.id;
        self.peers
            .iter()
            .enumerate()
            .filter(move |(index, peer)| {
                *index + 1 == usize::from(own) || (peer.alive.is_some() && !peer.failed)
            })
            .map(|(index, _)| (index + 1) as Id)
    }
}

/// History the properties need but no controller knows (ghost variables).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct History {
    pub losses: u8,
    pub crashes: u8,
    pub restarts: u8,
    /// Fault-free rounds since the last crash, restart, join or loss (saturates).
    pub quiet_rounds: u8,
    /// A heartbeat was lost and the controllers have not settled since: the two sides of an
    /// asymmetric partition may both act (see `properties::partitioned`).
    pub partition_open: bool,
    /// A role holder moved to a lower role outside a partition window.
    pub demoted_outside_partition: Option<Role>,
    /// A restarted controller took a role above one that a live controller held when it
    /// restarted.
    pub restart_jumped_queue: bool,
    /// A Secondary became Primary (witness).
    pub secondary_promoted: bool,
    /// A controller re-voted because of lost heartbeats of a peer that was still up (witness).
    pub revoted_after_loss: bool,
    pub pauses: u8,
    pub isolations: u8,
    /// Starved links (`Action::Starve`).
    pub starvations: u8,
    /// A witness: a Secondary took over from a starved Primary (F17).
    pub took_over: bool,
    /// A link was starved and the system has not settled since with every link working.
    pub starvation_open: bool,
    /// Slowed processes (`Action::Slow`).
    pub slowdowns: u8,
    /// A process was slowed and the system has not settled since with none slowed.
    pub slowdown_open: bool,
    /// Rounds in which a slowed controller's heartbeat missed its peers' round end (not
    /// `losses`: they are the slowdown's episode, see `Config::late_heartbeats_per_slowdown`).
    pub late_heartbeats: u8,
    /// Bit `id - 1` for each controller that lost the Primary role to a gray fault (a slowed
    /// process, a stall) and is still slowed or paused: it must not be made Primary again.
    pub sick_lost_primary: u8,
    /// A controller of `sick_lost_primary` held the Primary role again.
    pub sick_repromoted: bool,
    /// A witness: a Primary doubted itself (F18) and started again.
    pub doubted: bool,
    /// Fault episodes begun: crashes, pauses, cuts and link failures (a link failure is one
    /// episode however many heartbeats it loses, see `links_down`). Each may move the
    /// actuator once.
    pub faults: u8,
    /// Bits `link_bit(a, b) | link_bit(b, a)` for each link between two controllers whose
    /// heartbeat, either way, was lost in the last round: a loss on it now continues that
    /// link's failure (one episode, from the link going down to a round it carries its
    /// heartbeats again) rather than begin another.
    pub links_down: u16,
    /// Owner changes at the actuator (saturates one above `faults`).
    pub owner_changes: u8,
    /// Bit `id - 1` for each controller the actuator changed to since the last settled state.
    pub change_targets: u8,
    /// The actuator's owner at the last settled state.
    pub settled_owner: Option<Id>,
    /// The actuator changed to a controller that was neither the owner at the last settled
    /// state nor the next settled Primary.
    pub stray_owner: bool,
    /// Bit `id - 1` for each controller paused or cut off since the last settled state.
    pub away: u8,
    /// A controller back from a pause or a cut took the Primary role from a Primary that
    /// stayed with the majority.
    pub primary_taken_back: bool,
    /// A witness: a paused or cut-off controller came back below a Primary elected meanwhile.
    pub returned_below: bool,
    /// The controllers have settled at least once on a backed result (a majority system
    /// exists).
    pub formed: bool,
}

#[derive(Clone, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct State {
    pub controllers: Vec<Controller>,
    /// Bit `link_bit(from, to)`: this round's heartbeat on that link is lost.
    pub lost_links: u16,
    /// Bit `link_bit(from, to)`: `from`'s vote has been undelivered to `to` for a whole round;
    /// it must arrive before the round ends (the timing assumption).
    pub overdue_votes: u16,
    /// Bit `id - 1`: the controller is cut off from its peers (`Action::Isolate`).
    pub isolated: u8,
    /// Bit `id - 1`: of the cut-off controllers, those the actuator does not hear either
    /// (`Action::Unplug`).
    #[serde(default, skip_serializing_if = "no_bits")]
    pub unplugged: u8,
    /// Bit `id - 1`: the controller's links are starved (`Action::Starve`).
    #[serde(default, skip_serializing_if = "no_bits")]
    pub starved: u8,
    /// Bit `id - 1`: the controller's process is slowed (`Action::Slow`).
    #[serde(default, skip_serializing_if = "no_bits")]
    pub slowed: u8,
    /// Bit `id - 1`: of the starved or slowed controllers, those whose command deadline the
    /// actuator has missed (`Action::Lag`): their writers count as silent.
    #[serde(default, skip_serializing_if = "no_bits")]
    pub lagging: u8,
    /// The controller whose commands the actuator follows (the last one, while none is
    /// visible).
    pub owner: Option<Id>,
    /// Bit `link_bit(a, b)`: at equal strength the actuator prefers `a`'s writers to `b`'s
    /// (the GUID order, learnt when a tie first arises; a new life forgets it).
    pub tie_order: u16,
    pub history: History,
}

fn no_bits(bits: &u8) -> bool {
    *bits == 0
}

pub fn link_bit(from: Id, to: Id) -> u16 {
    1 << (usize::from(from - 1) * MAX_CONTROLLERS + usize::from(to - 1))
}

impl State {
    pub fn controller(&self, id: Id) -> &Controller {
        &self.controllers[usize::from(id - 1)]
    }

    pub fn controller_mut(&mut self, id: Id) -> &mut Controller {
        &mut self.controllers[usize::from(id - 1)]
    }

    pub fn up(&self) -> impl Iterator<Item = &Controller> {
        self.controllers.iter().filter(|c| c.is_up())
    }

    /// The controller the actuator accepts commands from (`crate::protocol::actuator`).
    pub fn actuator_owner(&self) -> Option<Id> {
        self.owner
    }

    /// Whether the heartbeat from `from` to `to` is lost this round (a one-round loss or a
    /// cut).
    pub fn link_lost(&self, from: Id, to: Id) -> bool {
        self.lost_links & link_bit(from, to) != 0
            || (self.isolated & (1 << (from - 1) | 1 << (to - 1))) != 0
    }
}

impl fmt::Debug for State {
    /// The explorer shows states with `{:#?}`: a table a reviewer can read.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for c in &self.controllers {
            writeln!(f, "{}", crate::render::controller_line(c))?;
        }
        writeln!(f, "{}", crate::render::network_line(self))
    }
}

impl fmt::Debug for Controller {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", crate::render::controller_line(self))
    }
}
