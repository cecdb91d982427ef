//! Leaving after failing itself: a controller that votes itself FAILED exits, to be restarted
//! (paper: "Any unit that does not agree with the two votes of the other controllers will take
//! itself offline and/or restart").
//!
//! The core fails a controller that stays outvoted past the grace, or whose application
//! reports a fault, and keeps it FAILED for the rest of its life: only a new incarnation takes
//! part again. So the voting thread notes when and why its core reported FAILED ([`Failure`]),
//! says so (console line, log line; the status event and the LEDs already show FAILED), and
//! stops once `timing.failed_exit_delay_ms` has passed and a heartbeat has announced FAILED to
//! the peers ([`PendingExit`]). `rl controller` then leaves DDS and exits with
//! [`EXIT_STATUS`], on which the systemd unit restarts it; the new incarnation joins in the
//! lowest free role.

use crate::core::{Assignment, ControllerId, ControllerState};
use serde::{Deserialize, Serialize};
use std::fmt;

/// The exit status of a controller that failed itself: `EX_TEMPFAIL` of sysexits.h ("try
/// again later"), distinct from 1 (a runtime error) and 2 (bad configuration or arguments).
pub const EXIT_STATUS: u8 = 75;

/// Why a controller failed itself.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FailureCause {
    /// Its vote disagreed with the agreeing votes of the others for longer than the grace.
    Outvoted,
    /// Its application reported a fault (`Redundancy::report_fault`).
    LocalFault,
}

impl FailureCause {
    /// As the JSON event writes it.
    pub fn name(self) -> &'static str {
        match self {
            FailureCause::Outvoted => "outvoted",
            FailureCause::LocalFault => "local_fault",
        }
    }
}

/// How a controller failed itself: why, and whose votes it disagreed with.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Failure {
    /// The id of the controller that failed itself.
    pub id: ControllerId,
    /// Why: outvoted, or a fault its application reported.
    pub cause: FailureCause,
    /// Live peers whose last vote differed from its own, by id.
    pub disagreed_with: Vec<ControllerId>,
    /// Its own last vote.
    pub own_vote: Option<Assignment>,
    /// The vote of those peers, when they all voted the same.
    pub their_vote: Option<Assignment>,
}

impl Failure {
    /// The failure of the controller whose state is now `state` (FAILED), which voted
    /// `own_vote` just before; `local_fault`: its application reported a fault.
    pub fn observe(
        state: &ControllerState,
        own_vote: Option<Assignment>,
        local_fault: bool,
    ) -> Failure {
        let cause = if local_fault {
            FailureCause::LocalFault
        } else {
            FailureCause::Outvoted
        };
        let differing: Vec<(ControllerId, Assignment)> = match own_vote {
            Some(own) => state
                .live_peers()
                .filter_map(|(id, peer)| peer.heard_vote.map(|vote| (id, vote)))
                .filter(|(_, vote)| *vote != own)
                .collect(),
            None => Vec::new(),
        };
        let their_vote = differing
            .first()
            .map(|(_, vote)| *vote)
            .filter(|first| differing.iter().all(|(_, vote)| vote == first));
        Failure {
            id: state.id,
            cause,
            disagreed_with: differing.iter().map(|(id, _)| *id).collect(),
            own_vote,
            their_vote,
        }
    }
}

impl fmt::Display for Failure {
    /// `C3 voted itself FAILED: outvoted by C1, C2 (they voted P=1 S=2 T=-, it voted P=1 S=2 T=3)`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.cause {
            FailureCause::LocalFault => {
                write!(f, "C{} FAILED: its application reported a fault", self.id)
            }
            FailureCause::Outvoted => {
                write!(f, "C{} voted itself FAILED: outvoted", self.id)?;
                if !self.disagreed_with.is_empty() {
                    let ids: Vec<String> = self
                        .disagreed_with
                        .iter()
                        .map(|id| format!("C{id}"))
                        .collect();
                    write!(f, " by {}", ids.join(", "))?;
                }
                if let (Some(theirs), Some(own)) = (self.their_vote, self.own_vote) {
                    write!(f, " (they voted {theirs}, it voted {own})")?;
                }
                Ok(())
            }
        }
    }
}

/// The voting thread's wait between failing and stopping.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PendingExit {
    /// How and why the controller failed itself.
    pub failure: Failure,
    /// Round-clock milliseconds at which the delay is over.
    exit_at_ms: u64,
    /// A heartbeat announcing FAILED has gone out, so the peers hear why it goes.
    announced: bool,
}

impl PendingExit {
    /// `failure` happened at `now_ms`; it may stop `delay_ms` later.
    pub fn new(failure: Failure, now_ms: u64, delay_ms: u64) -> PendingExit {
        PendingExit {
            failure,
            exit_at_ms: now_ms.saturating_add(delay_ms),
            announced: false,
        }
    }

    /// A heartbeat announcing FAILED went out.
    pub fn announced(&mut self) {
        self.announced = true;
    }

    /// Whether it stops now.
    pub fn is_due(&self, now_ms: u64) -> bool {
        self.announced && now_ms >= self.exit_at_ms
    }

    /// How long the voting loop may sleep before it is due; `None` until the announcement
    /// (the heartbeat timer wakes the loop for that).
    pub fn wait_ms(&self, now_ms: u64) -> Option<u64> {
        self.announced
            .then(|| self.exit_at_ms.saturating_sub(now_ms))
    }

    /// What the operator reads when it fails: why, and when it exits with which status.
    pub fn notice(&self, now_ms: u64) -> String {
        format!(
            "{}; exits in {} ms with status {EXIT_STATUS} to be restarted",
            self.failure,
            self.exit_at_ms.saturating_sub(now_ms)
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::{Holder, Peer, Phase};

    fn result(ids: &[ControllerId]) -> Assignment {
        Assignment::from_ranked(ids.iter().map(|&id| Holder { id, incarnation: 0 }))
    }

    /// C3, FAILED, hearing `votes` from live peers.
    fn failed_c3(votes: &[(ControllerId, Option<Assignment>)]) -> ControllerState {
        let mut state = ControllerState::new(3, 0);
        state.phase = Phase::Failed;
        for &(id, vote) in votes {
            let peer = Peer {
                alive: Some(0),
                heard_vote: vote,
                ..Peer::default()
            };
            state.peers.insert(id, peer);
        }
        state
    }

    #[test]
    fn an_outvoted_controller_names_the_peers_it_disagreed_with() {
        let theirs = result(&[1, 2]);
        let own = result(&[1, 2, 3]);
        let mut state = failed_c3(&[(1, Some(theirs)), (2, Some(theirs)), (4, Some(own))]);
        state.peers.insert(5, Peer::default()); // lost long ago: not counted
        let failure = Failure::observe(&state, Some(own), false);
        assert_eq!(failure.cause, FailureCause::Outvoted);
        assert_eq!(failure.disagreed_with, vec![1, 2]);
        assert_eq!(failure.their_vote, Some(theirs));
        assert_eq!(
            failure.to_string(),
            "C3 voted itself FAILED: outvoted by C1, C2 (they voted P=1 S=2 T=-, it voted P=1 S=2 T=3)"
        );
    }

    #[test]
    fn differing_votes_are_not_summarised_and_a_local_fault_says_so() {
        let state = failed_c3(&[(1, Some(result(&[1, 2]))), (2, Some(result(&[2, 1])))]);
        let failure = Failure::observe(&state, Some(result(&[3])), false);
        assert_eq!(failure.disagreed_with, vec![1, 2]);
        assert_eq!(failure.their_vote, None);
        assert_eq!(
            failure.to_string(),
            "C3 voted itself FAILED: outvoted by C1, C2"
        );
        let fault = Failure::observe(&state, None, true);
        assert_eq!(fault.cause, FailureCause::LocalFault);
        assert!(fault.disagreed_with.is_empty());
        assert_eq!(
            fault.to_string(),
            "C3 FAILED: its application reported a fault"
        );
    }

    #[test]
    fn it_exits_after_the_delay_and_not_before_the_announcement() {
        let failure = Failure::observe(&failed_c3(&[]), None, true);
        let mut exit = PendingExit::new(failure.clone(), 1_000, 300);
        assert_eq!(
            exit.notice(1_000),
            "C3 FAILED: its application reported a fault; exits in 300 ms with status 75 to \
             be restarted"
        );
        assert!(!exit.is_due(5_000), "not before a heartbeat said FAILED");
        assert_eq!(exit.wait_ms(1_100), None);
        exit.announced();
        assert!(!exit.is_due(1_299));
        assert_eq!(exit.wait_ms(1_100), Some(200));
        assert!(exit.is_due(1_300));
        let mut at_once = PendingExit::new(failure, 1_000, 0);
        assert!(!at_once.is_due(1_000));
        at_once.announced();
        assert!(at_once.is_due(1_062));
        assert_eq!(at_once.wait_ms(1_062), Some(0));
    }
}
