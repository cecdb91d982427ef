//! The network monitor's vocabulary: the two networks, the like controllers (ids 1..=3), the
//! twelve directed links between them, what is known of each link, and the network heartbeat
//! (RLNHB) that carries one controller's row of that knowledge to its peers.
//!
//! Everything here is plain data with serde, so the adapter can put it on the wire as it is.
//! Link sets are bit sets of the twelve links: the conclusion's search ORs and compares them
//! thousands of times per evaluation.

use crate::types::ControllerId;
use serde::{Deserialize, Serialize};
use std::fmt;

/// How many like controllers a network monitor watches (ids 1..=3, the three-way vote).
pub const NAP_CONTROLLERS: usize = 3;

/// The slot (0..3) of a like controller's id, `None` for any other id.
pub fn slot(id: ControllerId) -> Option<usize> {
    (1..=NAP_CONTROLLERS as ControllerId)
        .contains(&id)
        .then(|| usize::from(id) - 1)
}

/// The id of a slot (0..3).
fn id_of(slot: usize) -> ControllerId {
    // slot < NAP_CONTROLLERS = 3, so the cast is exact.
    slot as ControllerId + 1
}

/// One of the two redundant networks.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub enum Network {
    /// The first network (the paper's N1).
    A,
    /// The second network (the paper's N2).
    B,
}

impl Network {
    /// Both networks, A first.
    pub const ALL: [Network; 2] = [Network::A, Network::B];

    /// 0 for A, 1 for B.
    pub fn index(self) -> usize {
        match self {
            Network::A => 0,
            Network::B => 1,
        }
    }

    /// The other network.
    pub fn other(self) -> Network {
        match self {
            Network::A => Network::B,
            Network::B => Network::A,
        }
    }
}

impl fmt::Display for Network {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Network::A => "A",
            Network::B => "B",
        })
    }
}

/// The like controllers configured to run (a duplex pair is two of the three ids).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Members(u8);

impl Members {
    /// All three like controllers.
    pub const ALL: Members = Members(0b111);

    /// The like controllers among `ids` (ids outside 1..=3 are left out).
    pub fn of(ids: &[ControllerId]) -> Members {
        Members(
            ids.iter()
                .filter_map(|&id| slot(id))
                .fold(0, |bits, s| bits | 1 << s),
        )
    }

    /// Whether `id` is a configured like controller.
    pub fn contains(self, id: ControllerId) -> bool {
        slot(id).is_some_and(|s| self.0 & 1 << s != 0)
    }

    /// The member ids, ascending.
    pub fn iter(self) -> impl Iterator<Item = ControllerId> {
        (0..NAP_CONTROLLERS)
            .filter(move |s| self.0 & 1 << s != 0)
            .map(id_of)
    }
}

/// A directed link: `from`'s network heartbeat reaching `to` on `network`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct Link {
    /// The sender.
    pub from: ControllerId,
    /// The receiver.
    pub to: ControllerId,
    /// The network it crosses.
    pub network: Network,
}

impl Link {
    /// How many directed links three controllers have on two networks.
    pub const COUNT: usize = 12;

    /// The link from `from` to `to` on `network`.
    pub fn new(from: ControllerId, to: ControllerId, network: Network) -> Link {
        Link { from, to, network }
    }

    /// Its bit in a [`LinkSet`]: `network * 6 + from_slot * 2 + (to_slot, skipping from_slot)`;
    /// `None` unless both ends are like controllers and differ.
    pub fn index(self) -> Option<usize> {
        let (from, to) = (slot(self.from)?, slot(self.to)?);
        if from == to {
            return None;
        }
        let to_rank = if to > from { to - 1 } else { to };
        Some(self.network.index() * 6 + from * 2 + to_rank)
    }

    /// The link at bit `index` (0..12).
    fn at(index: usize) -> Link {
        let network = Network::ALL[index / 6];
        let from = (index % 6) / 2;
        let to_rank = index % 2;
        let to = if to_rank >= from {
            to_rank + 1
        } else {
            to_rank
        };
        Link::new(id_of(from), id_of(to), network)
    }

    /// All twelve links, in bit order (network A first).
    pub fn all() -> impl Iterator<Item = Link> {
        (0..Link::COUNT).map(Link::at)
    }
}

impl fmt::Display for Link {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}->{} on {}", self.from, self.to, self.network)
    }
}

/// A set of directed links (a bit per link).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct LinkSet(u16);

impl LinkSet {
    /// No link.
    pub const EMPTY: LinkSet = LinkSet(0);

    /// Every link matching `keep`.
    pub fn filter(keep: impl Fn(Link) -> bool) -> LinkSet {
        Link::all()
            .filter(|&link| keep(link))
            .fold(LinkSet::EMPTY, LinkSet::with)
    }

    /// Every link between two members (the links a configuration has).
    pub fn among(members: Members) -> LinkSet {
        LinkSet::filter(|l| members.contains(l.from) && members.contains(l.to))
    }

    /// Every link on `network`.
    pub fn on(network: Network) -> LinkSet {
        LinkSet::filter(|l| l.network == network)
    }

    /// Every link sent or received by `id`, on both networks.
    pub fn touching(id: ControllerId) -> LinkSet {
        LinkSet::filter(|l| l.from == id || l.to == id)
    }

    /// This set with `link` added (a link outside the twelve is ignored).
    pub fn with(self, link: Link) -> LinkSet {
        match link.index() {
            Some(bit) => LinkSet(self.0 | 1 << bit),
            None => self,
        }
    }

    /// Whether `link` is in the set.
    pub fn contains(self, link: Link) -> bool {
        link.index().is_some_and(|bit| self.0 & 1 << bit != 0)
    }

    /// The links in either set.
    pub fn union(self, other: LinkSet) -> LinkSet {
        LinkSet(self.0 | other.0)
    }

    /// The links in both sets.
    pub fn intersection(self, other: LinkSet) -> LinkSet {
        LinkSet(self.0 & other.0)
    }

    /// The links in this set and not in `other`.
    pub fn minus(self, other: LinkSet) -> LinkSet {
        LinkSet(self.0 & !other.0)
    }

    /// Whether every link of this set is in `other`.
    pub fn is_subset(self, other: LinkSet) -> bool {
        self.0 & !other.0 == 0
    }

    /// Whether the set has no link.
    pub fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// How many links it has.
    pub fn len(self) -> usize {
        self.0.count_ones() as usize
    }

    /// Its links, in bit order.
    pub fn iter(self) -> impl Iterator<Item = Link> {
        (0..Link::COUNT)
            .filter(move |bit| self.0 & 1 << bit != 0)
            .map(Link::at)
    }
}

/// What is known of one link.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum LinkState {
    /// No fresh word on it: its receiver's report is stale, or the receiver started less than
    /// a deadline ago.
    #[default]
    Unknown,
    /// Its receiver heard the sender's network heartbeat within the deadline.
    Good,
    /// Its receiver missed the deadline for the sender's network heartbeat.
    Fail,
}

impl LinkState {
    /// `Fail` for a failed link, `Good` otherwise.
    pub fn known(failed: bool) -> LinkState {
        if failed {
            LinkState::Fail
        } else {
            LinkState::Good
        }
    }
}

/// What one controller hears from its like peers, per peer slot and network: the row of the
/// link matrix it reports in every network heartbeat. Its own slot stays `Unknown`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Hearing {
    /// `heard[peer_slot][network_index]`, slots 0..3 for ids 1..=3.
    pub heard: [[LinkState; 2]; NAP_CONTROLLERS],
}

impl Hearing {
    /// What this row says of `peer`'s heartbeat on `network` (`Unknown` for other ids).
    pub fn of(&self, peer: ControllerId, network: Network) -> LinkState {
        slot(peer).map_or(LinkState::Unknown, |s| self.heard[s][network.index()])
    }

    /// Records what is heard of `peer` on `network` (other ids are ignored).
    pub fn set(&mut self, peer: ControllerId, network: Network, state: LinkState) {
        if let Some(s) = slot(peer) {
            self.heard[s][network.index()] = state;
        }
    }
}

/// A network heartbeat (the paper's RLNHB): published on each network every period, it says
/// "I am alive on this network" and carries the sender's row, so that every monitor that hears
/// it on either network learns the whole matrix even with the other network dead.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct NetworkHeartbeat {
    /// The sender's id.
    pub from: ControllerId,
    /// What the sender hears of its peers on both networks, as of sending.
    pub hearing: Hearing,
}

/// The twelve links' states, as one monitor sees them now.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct LinkMatrix {
    states: [LinkState; Link::COUNT],
}

impl LinkMatrix {
    /// Every link `Unknown`.
    pub fn unknown() -> LinkMatrix {
        LinkMatrix::default()
    }

    /// Every link in `failed` Fail, every other link Good.
    pub fn with_failed(failed: LinkSet) -> LinkMatrix {
        let mut matrix = LinkMatrix::unknown();
        for link in Link::all() {
            matrix.set(link, LinkState::known(failed.contains(link)));
        }
        matrix
    }

    /// What is known of `link` (`Unknown` for a link outside the twelve).
    pub fn get(&self, link: Link) -> LinkState {
        link.index()
            .map_or(LinkState::Unknown, |bit| self.states[bit])
    }

    /// Records the state of `link` (a link outside the twelve is ignored).
    pub fn set(&mut self, link: Link, state: LinkState) {
        if let Some(bit) = link.index() {
            self.states[bit] = state;
        }
    }

    /// The links in `state`.
    pub fn links_in(&self, state: LinkState) -> LinkSet {
        LinkSet::filter(|link| self.get(link) == state)
    }
}
