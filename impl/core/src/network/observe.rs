//! Per-link deadline tracking: which directed links one monitor knows to be Good, Fail or
//! Unknown right now.
//!
//! A link `X -> Y on N` is Good when Y heard X's network heartbeat on N within the deadline.
//! The links into this controller are measured here directly; the links into a peer come from
//! the row that peer last reported (in a heartbeat heard on either network), and are Unknown
//! once that report is a deadline old: a stale row says nothing about now.
//!
//! Nothing is Fail during the first deadline after the start: a peer not heard yet may simply
//! not have had its turn (the RLNHB deadline of the paper starts with the reader).

use super::links::{
    slot, Hearing, Link, LinkMatrix, LinkState, Members, Network, NetworkHeartbeat, NAP_CONTROLLERS,
};
use crate::types::ControllerId;

/// A peer's last reported row and when it arrived.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Report {
    received_ms: u64,
    hearing: Hearing,
}

/// What one monitor has heard, and when.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Observer {
    me: ControllerId,
    members: Members,
    deadline_ms: u64,
    started_ms: u64,
    /// `heard_ms[peer_slot][network]`: the last arrival of that peer's heartbeat on that network.
    heard_ms: [[Option<u64>; 2]; NAP_CONTROLLERS],
    /// The latest row each peer reported (on whichever network it arrived last).
    reports: [Option<Report>; NAP_CONTROLLERS],
    /// Heartbeats dropped: from this controller's own id or from a non-member.
    ignored_heartbeats: u64,
}

impl Observer {
    /// The monitor of controller `me`, started at `now_ms`; a link is Fail once `deadline_ms`
    /// passes without its heartbeat (at least 1 ms).
    pub fn new(me: ControllerId, members: Members, deadline_ms: u64, now_ms: u64) -> Observer {
        Observer {
            me,
            members,
            deadline_ms: deadline_ms.max(1),
            started_ms: now_ms,
            heard_ms: [[None; 2]; NAP_CONTROLLERS],
            reports: [None; NAP_CONTROLLERS],
            ignored_heartbeats: 0,
        }
    }

    /// Takes in a heartbeat that arrived on `received_on` at `now_ms`. Returns false (and
    /// counts it) when it is not from a peer member: a heartbeat with this controller's own id
    /// means another process is configured with it.
    pub fn hear(
        &mut self,
        received_on: Network,
        heartbeat: &NetworkHeartbeat,
        now_ms: u64,
    ) -> bool {
        let peer = match slot(heartbeat.from) {
            Some(s) if heartbeat.from != self.me && self.members.contains(heartbeat.from) => s,
            _ => {
                self.ignored_heartbeats += 1;
                return false;
            }
        };
        self.heard_ms[peer][received_on.index()] = Some(now_ms);
        self.reports[peer] = Some(Report {
            received_ms: now_ms,
            hearing: heartbeat.hearing,
        });
        true
    }

    /// Heartbeats dropped so far (own id or not a member).
    pub fn ignored_heartbeats(&self) -> u64 {
        self.ignored_heartbeats
    }

    /// Whether something heard at `at_ms` is still within the deadline at `now_ms`.
    fn fresh(&self, at_ms: u64, now_ms: u64) -> bool {
        now_ms.saturating_sub(at_ms) < self.deadline_ms
    }

    /// This controller's own row: what it hears of each peer member on each network.
    pub fn hearing(&self, now_ms: u64) -> Hearing {
        let mut hearing = Hearing::default();
        let in_grace = self.fresh(self.started_ms, now_ms);
        for peer in self.members.iter().filter(|&id| id != self.me) {
            for network in Network::ALL {
                let heard_ms = slot(peer).and_then(|s| self.heard_ms[s][network.index()]);
                let state = match heard_ms {
                    Some(at_ms) if self.fresh(at_ms, now_ms) => LinkState::Good,
                    _ if in_grace => LinkState::Unknown,
                    _ => LinkState::Fail,
                };
                hearing.set(peer, network, state);
            }
        }
        hearing
    }

    /// The row `receiver` reported, if it arrived within the deadline.
    fn fresh_report(&self, receiver: ControllerId, now_ms: u64) -> Option<Hearing> {
        let report = self.reports[slot(receiver)?]?;
        self.fresh(report.received_ms, now_ms)
            .then_some(report.hearing)
    }

    /// Every link between members as known at `now_ms`: this controller's own row measured,
    /// the peers' rows as they last reported them (Unknown when stale); links touching a
    /// non-member stay Unknown.
    pub fn matrix(&self, now_ms: u64) -> LinkMatrix {
        let mut matrix = LinkMatrix::unknown();
        let own = self.hearing(now_ms);
        for receiver in self.members.iter() {
            let row = if receiver == self.me {
                Some(own)
            } else {
                self.fresh_report(receiver, now_ms)
            };
            let Some(row) = row else { continue };
            for sender in self.members.iter().filter(|&id| id != receiver) {
                for network in Network::ALL {
                    matrix.set(
                        Link::new(sender, receiver, network),
                        row.of(sender, network),
                    );
                }
            }
        }
        matrix
    }

    /// The first instant after `now_ms` at which the matrix changes by itself (a heartbeat or
    /// a report goes stale, or the start-up grace ends), if any.
    pub fn next_change_ms(&self, now_ms: u64) -> Option<u64> {
        let heard = self.heard_ms.iter().flatten().flatten().copied();
        let reported = self.reports.iter().flatten().map(|r| r.received_ms);
        heard
            .chain(reported)
            .chain([self.started_ms])
            .map(|at_ms| at_ms.saturating_add(self.deadline_ms))
            .filter(|&expires_ms| expires_ms > now_ms)
            .min()
    }
}
