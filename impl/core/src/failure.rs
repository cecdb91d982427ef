//! A controller that fails itself: why, and when it leaves (paper: "Any unit that does not
//! agree with the two votes of the other controllers will take itself offline and/or
//! restart").
//!
//! The core fails a controller that stays outvoted past the grace, or whose application
//! reports a fault, and keeps it FAILED for the rest of its life: only a new incarnation takes
//! part again. At that step the core reports the [`Failure`] (`Command::Failed`), and once a
//! heartbeat has announced FAILED to the peers and the configured delay has passed
//! (`CoreConfig::failed_exit_delay_ms`, [`crate::Timer::Exit`]) it tells the caller to leave
//! (`Command::Exit`); the caller then leaves DDS and exits, to be restarted as a new
//! incarnation that joins in the lowest free role.

use crate::state::ControllerState;
use crate::types::{Assignment, ControllerId};
use serde::{Deserialize, Serialize};
use std::fmt;

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

/// The wait between failing and leaving.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct PendingExit {
    /// How and why the controller failed itself.
    pub failure: Failure,
    /// When the delay is over, on the caller's clock.
    pub exit_at_ms: u64,
    /// A heartbeat announcing FAILED has gone out, so the peers hear why it goes.
    pub announced: bool,
}

impl PendingExit {
    /// When it leaves: once announced, at the end of the delay.
    pub fn due_at_ms(&self) -> Option<u64> {
        self.announced.then_some(self.exit_at_ms)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::state::Peer;
    use crate::types::{Holder, Phase};

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
}
