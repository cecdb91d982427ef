//! Keeping this controller's rounds on the others' rounds: which peer's phase it follows, and
//! by how much its round clock must move.
//!
//! Rounds are aligned to multiples of the heartbeat period on the caller's clock, and a
//! heartbeat goes out a quarter period after each boundary (the crate's header), so a peer's
//! heartbeat lands in the same round everywhere while the controllers' boundaries are less
//! than a quarter period apart. Clocks read at start do not promise that (a Raspberry Pi has
//! no real-time clock, a ship's LAN may have no time server, crystals drift by up to about
//! 100 ppm), so the caller reports when a heartbeat that woke it arrived
//! (`Input::HeartbeatArrival`), and the core answers with the correction
//! (`Command::MoveClock`).
//!
//! The reference is the Primary; before there is one, the lowest id heard below its own. A
//! Primary follows nobody, so the system keeps the Primary's phase: a newcomer takes it at
//! its first heartbeat, before its first decision, and a running system is never moved by a
//! newcomer. A member moves only on two measurements a round apart that agree, and by half,
//! so two members that briefly name different Primaries meet halfway instead of swapping
//! phases.

use crate::report::SelfReport;
use crate::state::ControllerState;
use crate::types::{ControllerId, Role};

/// Decides, per heartbeat received, whether and by how much to move the round clock.
#[derive(Clone, Debug)]
pub struct PhaseFollower {
    period_ms: u64,
    /// Where in its round the reference's heartbeat should arrive: the core's heartbeat offset
    /// plus a millisecond of transit.
    expected_phase_ms: u64,
    /// Errors within this are jitter (scheduling, transit) and left alone.
    dead_zone_ms: u64,
    /// When a heartbeat reporting a Primary was last heard, to fall back on the lowest id only
    /// when there is none.
    primary_heard_ms: Option<u64>,
    /// The last error measured and not yet acted on: (reference, error, when). A member's
    /// correction needs two measurements a round apart that agree, because one heartbeat can
    /// arrive late (delivered with others when DDS discovery matches its writer, or when its
    /// sender was not scheduled in time).
    unconfirmed: Option<(ControllerId, i64, u64)>,
}

impl PhaseFollower {
    /// For rounds of `period_ms` with heartbeats sent `heartbeat_offset_ms` into a round.
    pub fn new(period_ms: u64, heartbeat_offset_ms: u64) -> PhaseFollower {
        PhaseFollower {
            period_ms: period_ms.max(1),
            expected_phase_ms: heartbeat_offset_ms + 1,
            dead_zone_ms: (period_ms / 16).max(2),
            primary_heard_ms: None,
            unconfirmed: None,
        }
    }

    /// The correction (ms, signed) to apply to the round clock now that `heartbeat` arrived at
    /// `now_ms` on it, for a controller in state `own`; `None` when it sets no phase.
    pub fn on_heartbeat(
        &mut self,
        own: &ControllerState,
        heartbeat: &SelfReport,
        now_ms: u64,
    ) -> Option<i64> {
        let reports_primary = heartbeat.role == Some(Role::Primary);
        let primary_recently = self
            .primary_heard_ms
            .is_some_and(|heard| now_ms.saturating_sub(heard) <= 2 * self.period_ms);
        if reports_primary {
            self.primary_heard_ms = Some(now_ms);
        }
        if !is_reference(own, heartbeat.id, reports_primary, primary_recently) {
            return None;
        }
        let error_ms = self.error_ms(now_ms);
        if error_ms.unsigned_abs() <= self.dead_zone_ms {
            self.unconfirmed = None;
            return None;
        }
        let member = own.agreed.is_some() && own.role.is_some();
        let confirmed = self.unconfirmed.is_some_and(|(from, earlier_ms, at_ms)| {
            from == heartbeat.id
                && now_ms.saturating_sub(at_ms) >= self.period_ms / 2
                && (error_ms - earlier_ms).unsigned_abs() <= self.dead_zone_ms
        });
        // A newcomer moves at once, before its first decision; a member's rounds are the
        // system's, so it moves on nothing less than two measurements that agree.
        if member && !confirmed {
            self.unconfirmed = Some((heartbeat.id, error_ms, now_ms));
            return None;
        }
        self.unconfirmed = None;
        // Ahead of the reference (its heartbeat arrives late in our round): move back.
        let correction_ms = -error_ms;
        Some(if member {
            correction_ms / 2
        } else {
            correction_ms
        })
    }

    /// How late (positive) or early the reference's heartbeat arrived in this round, within
    /// half a period either way.
    fn error_ms(&self, now_ms: u64) -> i64 {
        let period = self.period_ms as i64;
        let phase_ms = (now_ms % self.period_ms) as i64;
        let error_ms = (phase_ms - self.expected_phase_ms as i64).rem_euclid(period);
        if error_ms >= period / 2 {
            error_ms - period
        } else {
            error_ms
        }
    }
}

/// Whether a heartbeat from `sender` sets the phase of controller `own`: the Primary its
/// agreed result names (or, without one, any controller reporting Primary); with no Primary
/// heard lately, a lower id. A Primary follows nobody.
fn is_reference(
    own: &ControllerState,
    sender: ControllerId,
    sender_reports_primary: bool,
    primary_heard_recently: bool,
) -> bool {
    if own.role == Some(Role::Primary) || sender == own.id {
        return false;
    }
    if sender_reports_primary {
        let named = own.agreed.and_then(|agreed| agreed.holder(Role::Primary));
        return named.is_none_or(|primary| primary == sender);
    }
    !primary_heard_recently && sender < own.id
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::types::{Assignment, Holder};

    const PERIOD_MS: u64 = 250;
    const OFFSET_MS: u64 = 62;

    fn state(
        id: ControllerId,
        role: Option<Role>,
        primary: Option<ControllerId>,
    ) -> ControllerState {
        let mut state = ControllerState::new(id, 7);
        state.role = role;
        state.agreed = primary.map(|id| Assignment::from_ranked([Holder { id, incarnation: 5 }]));
        state
    }

    fn heartbeat(id: ControllerId, role: Option<Role>) -> SelfReport {
        SelfReport {
            role,
            ..SelfReport::initial(id, 9)
        }
    }

    /// The correction after the same heartbeat phase in two consecutive rounds (the first
    /// only ever sets the measurement aside).
    fn confirmed(
        follower: &mut PhaseFollower,
        own: &ControllerState,
        heartbeat: &SelfReport,
        arrival_ms: u64,
    ) -> Option<i64> {
        let first = follower.on_heartbeat(own, heartbeat, arrival_ms - PERIOD_MS);
        assert_eq!(first, None, "acted on one measurement");
        follower.on_heartbeat(own, heartbeat, arrival_ms)
    }

    #[test]
    fn a_newcomer_takes_the_primarys_phase_at_once() {
        let mut follower = PhaseFollower::new(PERIOD_MS, OFFSET_MS);
        let newcomer = state(3, None, None);
        // Our clock is 100 ms ahead: the Primary's heartbeat, sent 62 ms into its round,
        // arrives 162 ms (+1 transit) into ours.
        let arrival_ms = 10 * PERIOD_MS + OFFSET_MS + 1 + 100;
        let from_primary = heartbeat(1, Some(Role::Primary));
        let correction = follower.on_heartbeat(&newcomer, &from_primary, arrival_ms);
        assert_eq!(correction, Some(-100));
    }

    #[test]
    fn a_clock_behind_moves_forward_and_a_member_moves_halfway() {
        let mut follower = PhaseFollower::new(PERIOD_MS, OFFSET_MS);
        let member = state(2, Some(Role::Secondary), Some(1));
        // 80 ms behind: the heartbeat arrives 80 ms before the expected phase.
        let arrival_ms = 10 * PERIOD_MS + OFFSET_MS + 1 - 80;
        let from_primary = heartbeat(1, Some(Role::Primary));
        let correction = confirmed(&mut follower, &member, &from_primary, arrival_ms);
        assert_eq!(correction, Some(40));
    }

    #[test]
    fn jitter_within_the_dead_zone_moves_nothing() {
        let mut follower = PhaseFollower::new(PERIOD_MS, OFFSET_MS);
        let member = state(2, Some(Role::Secondary), Some(1));
        let arrival_ms = 10 * PERIOD_MS + OFFSET_MS + 1 + 5;
        let correction =
            follower.on_heartbeat(&member, &heartbeat(1, Some(Role::Primary)), arrival_ms);
        assert_eq!(correction, None);
    }

    #[test]
    fn the_error_wraps_to_the_nearer_boundary() {
        let follower = PhaseFollower::new(PERIOD_MS, OFFSET_MS);
        // 63 + 130 = 193 ms into the round: 120 ms early is nearer than 130 ms late.
        assert_eq!(follower.error_ms(10 * PERIOD_MS + 193), -120);
        assert_eq!(follower.error_ms(10 * PERIOD_MS + 63 + 124), 124);
        assert_eq!(follower.error_ms(10 * PERIOD_MS + 10), -53);
    }

    #[test]
    fn a_primary_follows_nobody_and_nobody_follows_a_higher_id_or_another_primary() {
        let mut follower = PhaseFollower::new(PERIOD_MS, OFFSET_MS);
        let late_ms = 10 * PERIOD_MS + OFFSET_MS + 1 + 100;
        let twice = |follower: &mut PhaseFollower, own: &ControllerState, from: &SelfReport| {
            [late_ms, late_ms + PERIOD_MS].map(|at_ms| follower.on_heartbeat(own, from, at_ms))
        };
        let primary = state(1, Some(Role::Primary), Some(1));
        let from_secondary = heartbeat(2, Some(Role::Secondary));
        assert_eq!(
            twice(&mut follower, &primary, &from_secondary),
            [None, None]
        );
        // Forming, no Primary anywhere: C2 follows C1, never C3.
        let forming = state(2, None, None);
        let mut fresh = PhaseFollower::new(PERIOD_MS, OFFSET_MS);
        assert_eq!(
            twice(&mut fresh, &forming, &heartbeat(3, None)),
            [None, None]
        );
        assert_eq!(
            twice(&mut fresh, &forming, &heartbeat(1, None)),
            [Some(-100), Some(-100)]
        );
        // A Secondary of C1's result does not follow C3 reporting itself Primary.
        let secondary = state(2, Some(Role::Secondary), Some(1));
        let other_primary = heartbeat(3, Some(Role::Primary));
        let mut member = PhaseFollower::new(PERIOD_MS, OFFSET_MS);
        assert_eq!(twice(&mut member, &secondary, &other_primary), [None, None]);
    }

    #[test]
    fn with_a_primary_heard_a_lower_id_sets_no_phase() {
        let mut follower = PhaseFollower::new(PERIOD_MS, OFFSET_MS);
        let joiner = state(3, None, None);
        let late_ms = 10 * PERIOD_MS + OFFSET_MS + 1 + 100;
        let from_primary = heartbeat(2, Some(Role::Primary));
        assert!(follower
            .on_heartbeat(&joiner, &from_primary, late_ms)
            .is_some());
        // C1, a Tertiary now, is lower than C3 but not the Primary.
        let from_tertiary = heartbeat(1, Some(Role::Tertiary));
        assert_eq!(
            follower.on_heartbeat(&joiner, &from_tertiary, late_ms + 10),
            None
        );
    }

    #[test]
    fn one_odd_arrival_moves_no_member() {
        let mut follower = PhaseFollower::new(PERIOD_MS, OFFSET_MS);
        let joiner = state(3, Some(Role::Tertiary), Some(1));
        let from_primary = heartbeat(1, Some(Role::Primary));
        let round_ms = 10 * PERIOD_MS;
        // Delivered 100 ms late once (discovery, scheduling), then on time: nothing moves.
        assert_eq!(
            follower.on_heartbeat(&joiner, &from_primary, round_ms + OFFSET_MS + 101),
            None
        );
        let next_ms = round_ms + PERIOD_MS + OFFSET_MS + 1;
        assert_eq!(follower.on_heartbeat(&joiner, &from_primary, next_ms), None);
        // Two late arrivals that disagree move nothing either.
        let late_ms = round_ms + 2 * PERIOD_MS + OFFSET_MS + 60;
        assert_eq!(follower.on_heartbeat(&joiner, &from_primary, late_ms), None);
        let later_ms = round_ms + 3 * PERIOD_MS + OFFSET_MS + 110;
        assert_eq!(
            follower.on_heartbeat(&joiner, &from_primary, later_ms),
            None
        );
    }
}
