//! Exclusive ownership on the reading side, with DDS semantics.
//!
//! RustDDS readers deliver every matched writer's samples whatever its ownership strength, so
//! a reader that must follow only the owner (the servo simulator, tools) passes each sample
//! through an [`Arbiter`]. It is pure: no I/O, no clock (time is an argument in milliseconds
//! on any monotonic scale), no threads.
//!
//! The rules (DDS 1.4 §2.2.3.9 OWNERSHIP, for the single instance of an unkeyed topic):
//! - The owner is the strongest writer that is alive and whose last *accepted* sample is
//!   within the deadline (`now - last <= deadline_ms`). Only the owner's own samples renew its
//!   deadline: a weaker writer's samples never do. (Cyclone DDS renews the instance deadline
//!   on any writer's sample, so it never fails over while a weaker writer keeps publishing;
//!   the test `cyclone_renewal_would_be_caught` shows the checks here catch that behaviour.)
//! - A sample from a writer that outranks the current owner is accepted at once and makes it
//!   the owner. A sample from a weaker writer is accepted only when there is no live owner
//!   (after a deadline miss or `writer_lost`) and no other writer that outranks it is alive
//!   (its last sample within the deadline): the ownership passes to the strongest live writer,
//!   not to whichever sample happens to arrive first after the miss.
//! - Equal strengths: the specification only asks for a consistent choice; RL takes the lower
//!   writer id (GUID, compared byte-wise), as RTI Connext does. The protocol never lets two
//!   role holders command at the same strength, so this matters only for stray writers.
//! - A writer's strength is taken from each offer, so a strength change of a live writer
//!   applies from its next sample. RustDDS cannot change a writer's strength: it re-creates
//!   the writer, which is a new GUID; the old one ages out or is reported lost.

use crate::core::types::Strength;
use std::collections::BTreeMap;

/// The outcome of offering one sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Decision<W> {
    /// Deliver the sample to the application.
    pub accepted: bool,
    /// Set when this sample made a different writer the owner.
    pub owner_changed: Option<OwnerChange<W>>,
}

/// A change of owner.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OwnerChange<W> {
    /// The previous owner; `None` at the first owner.
    pub from: Option<W>,
    /// The writer that owns the instance from this sample on.
    pub to: W,
    /// Time since the previous owner's last accepted sample; `None` at the first owner.
    pub gap_ms: Option<u64>,
}

/// What renews the owner's deadline. Only `OwnerOnly` is DDS semantics; the other exists so a
/// test can show the scenario checks fail on Cyclone's behaviour.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Renewal {
    OwnerOnly,
    #[cfg(test)]
    AnySample,
}

#[derive(Clone, Copy, Debug)]
struct Owner<W> {
    writer: W,
    strength: Strength,
    last_accepted_ms: u64,
}

/// The exclusive-ownership arbiter of one instance. `W` is the writer identity (a GUID).
#[derive(Clone, Debug)]
pub struct Arbiter<W> {
    deadline_ms: u64,
    owner: Option<Owner<W>>,
    /// The owner before the current one (or the expired owner when there is none), for the
    /// gap of the next change.
    previous: Option<Owner<W>>,
    /// Last known strength of each writer seen.
    strengths: BTreeMap<W, Strength>,
    /// Time of each writer's last sample (accepted or not): whether it is alive.
    last_seen_ms: BTreeMap<W, u64>,
    /// Time of the last sample of any writer, used only by `Renewal::AnySample`.
    last_any_ms: u64,
    renewal: Renewal,
}

impl<W: Ord + Copy> Arbiter<W> {
    /// An arbiter with no owner yet; an owner loses the instance when `deadline_ms` (ms) pass
    /// without an accepted sample of its own.
    pub fn new(deadline_ms: u64) -> Arbiter<W> {
        Arbiter {
            deadline_ms,
            owner: None,
            previous: None,
            strengths: BTreeMap::new(),
            last_seen_ms: BTreeMap::new(),
            last_any_ms: 0,
            renewal: Renewal::OwnerOnly,
        }
    }

    /// The deadline (ms): how long the owner may go without an accepted sample before it
    /// loses the instance.
    pub fn deadline_ms(&self) -> u64 {
        self.deadline_ms
    }

    /// Does `a` (strength, id) outrank `b`?
    fn outranks(a: (Strength, W), b: (Strength, W)) -> bool {
        a.0 > b.0 || (a.0 == b.0 && a.1 < b.1)
    }

    /// The owner if its deadline has not passed at `now_ms`.
    fn live_owner(&self, now_ms: u64) -> Option<Owner<W>> {
        let owner = self.owner?;
        let last = match self.renewal {
            Renewal::OwnerOnly => owner.last_accepted_ms,
            #[cfg(test)]
            Renewal::AnySample => self.last_any_ms.max(owner.last_accepted_ms),
        };
        (now_ms.saturating_sub(last) <= self.deadline_ms).then_some(owner)
    }

    /// Drops the owner if its deadline has passed at `now_ms`.
    fn expire(&mut self, now_ms: u64) {
        if let Some(owner) = self.owner {
            if self.live_owner(now_ms).is_none() {
                self.previous = Some(owner);
                self.owner = None;
            }
        }
    }

    /// Offers a sample of `writer`, whose ownership strength is `strength`, received at
    /// `now_ms`. Times must not go backwards (an earlier time is treated as `now`).
    pub fn offer(&mut self, writer: W, strength: Strength, now_ms: u64) -> Decision<W> {
        self.strengths.insert(writer, strength);
        self.expire(now_ms);
        self.last_any_ms = self.last_any_ms.max(now_ms);
        let seen = self.last_seen_ms.entry(writer).or_insert(now_ms);
        *seen = (*seen).max(now_ms);

        match self.owner.as_mut() {
            // The owner's own sample: the only thing that renews its deadline.
            Some(owner) if owner.writer == writer => {
                owner.strength = strength;
                owner.last_accepted_ms = owner.last_accepted_ms.max(now_ms);
                return Decision {
                    accepted: true,
                    owner_changed: None,
                };
            }
            Some(owner) if !Self::outranks((strength, writer), (owner.strength, owner.writer)) => {
                return Decision {
                    accepted: false,
                    owner_changed: None,
                };
            }
            Some(_) => {}
            None => {
                if self.stronger_writer_alive(writer, strength, now_ms) {
                    return Decision {
                        accepted: false,
                        owner_changed: None,
                    };
                }
            }
        }
        // The writer takes over from the live owner it outranks, or from nobody: then `before`
        // is the owner that expired or was lost.
        let before = self.owner.or(self.previous);
        self.owner = Some(Owner {
            writer,
            strength,
            last_accepted_ms: now_ms,
        });
        let owner_changed = match before {
            Some(before) if before.writer == writer => None,
            Some(before) => {
                self.previous = Some(before);
                Some(OwnerChange {
                    from: Some(before.writer),
                    to: writer,
                    gap_ms: Some(now_ms.saturating_sub(before.last_accepted_ms)),
                })
            }
            None => Some(OwnerChange {
                from: None,
                to: writer,
                gap_ms: None,
            }),
        };
        Decision {
            accepted: true,
            owner_changed,
        }
    }

    /// Another writer that outranks `writer` has sent a sample within the deadline.
    fn stronger_writer_alive(&self, writer: W, strength: Strength, now_ms: u64) -> bool {
        self.last_seen_ms.iter().any(|(&other, &seen)| {
            other != writer
                && now_ms.saturating_sub(seen) <= self.deadline_ms
                && self.strengths.get(&other).is_some_and(|&other_strength| {
                    Self::outranks((other_strength, other), (strength, writer))
                })
        })
    }

    /// The writer is gone (deleted, or its liveliness lost): it no longer owns anything.
    pub fn writer_lost(&mut self, writer: W) {
        self.strengths.remove(&writer);
        self.last_seen_ms.remove(&writer);
        if let Some(owner) = self.owner {
            if owner.writer == writer {
                self.previous = Some(owner);
                self.owner = None;
            }
        }
    }

    /// The live owner at `now_ms`, if any.
    pub fn owner(&self, now_ms: u64) -> Option<W> {
        self.live_owner(now_ms).map(|owner| owner.writer)
    }

    /// The owner's strength at `now_ms`, if there is a live owner.
    pub fn owner_strength(&self, now_ms: u64) -> Option<Strength> {
        let writer = self.owner(now_ms)?;
        self.strengths.get(&writer).copied()
    }

    /// Time of the current (or last expired) owner's last accepted sample.
    pub fn last_accepted_ms(&self) -> Option<u64> {
        self.owner
            .or(self.previous)
            .map(|owner| owner.last_accepted_ms)
    }

    /// The last strength offered by a writer still known.
    pub fn strength_of(&self, writer: W) -> Option<Strength> {
        self.strengths.get(&writer).copied()
    }

    #[cfg(test)]
    fn with_cyclone_renewal(deadline_ms: u64) -> Arbiter<W> {
        Arbiter {
            renewal: Renewal::AnySample,
            ..Arbiter::new(deadline_ms)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DEADLINE_MS: u64 = 100;
    const PRIMARY: u32 = 0x30;
    const SECONDARY: u32 = 0x20;
    const TERTIARY: u32 = 0x10;

    fn accepted(decision: Decision<u32>) -> bool {
        decision.accepted
    }

    /// Writers publishing every `period_ms` from `start_ms` to `end_ms` (exclusive), merged
    /// in time order; returns (time, writer, strength) per sample.
    fn schedule(writers: &[(u32, i32, u64, u64, u64)]) -> Vec<(u64, u32, i32)> {
        let mut samples = Vec::new();
        for &(writer, strength, period_ms, start_ms, end_ms) in writers {
            let mut t = start_ms;
            while t < end_ms {
                samples.push((t, writer, strength));
                t += period_ms;
            }
        }
        samples.sort();
        samples
    }

    #[test]
    fn after_a_miss_the_strongest_live_writer_owns_not_the_first_to_speak() {
        let mut arbiter = Arbiter::new(DEADLINE_MS);
        arbiter.offer(PRIMARY, Strength(30), 0);
        arbiter.offer(SECONDARY, Strength(20), 5);
        arbiter.offer(TERTIARY, Strength(10), 6);
        // The Primary is silent from t=0; at 101 its deadline has passed. The Tertiary speaks
        // first, but the Secondary (last heard at 95) is alive and outranks it.
        arbiter.offer(SECONDARY, Strength(20), 95);
        assert!(!accepted(arbiter.offer(TERTIARY, Strength(10), 101)));
        let decision = arbiter.offer(SECONDARY, Strength(20), 105);
        assert_eq!(
            decision.owner_changed,
            Some(OwnerChange {
                from: Some(PRIMARY),
                to: SECONDARY,
                gap_ms: Some(105)
            })
        );
        // Once the Secondary too has been silent past the deadline, the Tertiary may own.
        assert!(accepted(arbiter.offer(TERTIARY, Strength(10), 206)));
    }

    #[test]
    fn first_sample_makes_the_first_owner() {
        let mut arbiter = Arbiter::new(DEADLINE_MS);
        let decision = arbiter.offer(SECONDARY, Strength(20), 5);
        assert_eq!(
            decision,
            Decision {
                accepted: true,
                owner_changed: Some(OwnerChange {
                    from: None,
                    to: SECONDARY,
                    gap_ms: None
                })
            }
        );
        assert_eq!(arbiter.owner(5), Some(SECONDARY));
        assert_eq!(arbiter.owner_strength(5), Some(Strength(20)));
    }

    #[test]
    fn stronger_writer_takes_over_at_once() {
        let mut arbiter = Arbiter::new(DEADLINE_MS);
        arbiter.offer(SECONDARY, Strength(20), 0);
        arbiter.offer(SECONDARY, Strength(20), 33);
        let decision = arbiter.offer(PRIMARY, Strength(30), 40);
        assert!(decision.accepted);
        assert_eq!(
            decision.owner_changed,
            Some(OwnerChange {
                from: Some(SECONDARY),
                to: PRIMARY,
                gap_ms: Some(7)
            })
        );
        assert!(!accepted(arbiter.offer(SECONDARY, Strength(20), 66)));
    }

    #[test]
    fn weaker_writer_is_ignored_while_the_owner_is_live() {
        let mut arbiter = Arbiter::new(DEADLINE_MS);
        for (t, writer, strength) in schedule(&[
            (PRIMARY, 30, 33, 0, 1000),
            (SECONDARY, 20, 33, 1, 1000),
            (TERTIARY, 10, 50, 2, 1000),
        ]) {
            let decision = arbiter.offer(writer, Strength(strength), t);
            assert_eq!(
                decision.accepted,
                writer == PRIMARY,
                "t={t} writer={writer:x}"
            );
            if t > 0 {
                assert_eq!(decision.owner_changed, None, "t={t}");
            }
        }
    }

    #[test]
    fn silent_owner_fails_over_after_the_deadline_with_the_gap() {
        let mut arbiter = Arbiter::new(DEADLINE_MS);
        // Primary publishes until 300 (last sample at 297), Secondary all along at 30 Hz.
        let mut change = None;
        for (t, writer, strength) in
            schedule(&[(PRIMARY, 30, 33, 0, 300), (SECONDARY, 20, 33, 10, 1000)])
        {
            let decision = arbiter.offer(writer, Strength(strength), t);
            if writer == SECONDARY {
                // Accepted exactly from the first sample after the deadline ran out.
                assert_eq!(decision.accepted, t > 297 + DEADLINE_MS, "t={t}");
                if decision.owner_changed.is_some() {
                    assert!(change.is_none(), "one change only");
                    change = decision.owner_changed.map(|c| (t, c));
                }
            }
        }
        let (t, change) = change.expect("failed over");
        assert_eq!(t, 406); // first Secondary sample after 397
        assert_eq!(change.from, Some(PRIMARY));
        assert_eq!(change.to, SECONDARY);
        assert_eq!(change.gap_ms, Some(406 - 297));
        assert_eq!(arbiter.owner(406), Some(SECONDARY));
    }

    #[test]
    fn deadline_edge_is_inclusive() {
        let mut arbiter = Arbiter::new(DEADLINE_MS);
        arbiter.offer(PRIMARY, Strength(30), 0);
        assert!(!arbiter.offer(SECONDARY, Strength(20), DEADLINE_MS).accepted);
        assert_eq!(arbiter.owner(DEADLINE_MS), Some(PRIMARY));
        assert_eq!(arbiter.owner(DEADLINE_MS + 1), None);
        assert!(
            arbiter
                .offer(SECONDARY, Strength(20), DEADLINE_MS + 1)
                .accepted
        );
    }

    #[test]
    fn owner_returning_takes_over_at_once() {
        let mut arbiter = Arbiter::new(DEADLINE_MS);
        arbiter.offer(PRIMARY, Strength(30), 0);
        arbiter.offer(SECONDARY, Strength(20), 150); // Primary expired at 100
        arbiter.offer(SECONDARY, Strength(20), 180);
        let decision = arbiter.offer(PRIMARY, Strength(30), 190);
        assert!(decision.accepted);
        assert_eq!(
            decision.owner_changed,
            Some(OwnerChange {
                from: Some(SECONDARY),
                to: PRIMARY,
                gap_ms: Some(10)
            })
        );
        assert!(!arbiter.offer(SECONDARY, Strength(20), 200).accepted);
    }

    #[test]
    fn owner_back_after_silence_without_rival_is_no_change() {
        let mut arbiter = Arbiter::new(DEADLINE_MS);
        arbiter.offer(PRIMARY, Strength(30), 0);
        let decision = arbiter.offer(PRIMARY, Strength(30), 500);
        assert!(decision.accepted);
        assert_eq!(decision.owner_changed, None);
    }

    #[test]
    fn equal_strength_goes_to_the_lower_guid() {
        let (low, high) = (0x0100_u32, 0x0200_u32);
        let mut arbiter = Arbiter::new(DEADLINE_MS);
        arbiter.offer(high, Strength(30), 0);
        let decision = arbiter.offer(low, Strength(30), 10);
        assert!(decision.accepted);
        assert_eq!(decision.owner_changed.map(|c| c.to), Some(low));
        assert!(!arbiter.offer(high, Strength(30), 20).accepted);
        // The other order: the higher GUID never displaces the lower one while it is live.
        let mut arbiter = Arbiter::new(DEADLINE_MS);
        arbiter.offer(low, Strength(30), 0);
        assert!(!arbiter.offer(high, Strength(30), 10).accepted);
        assert_eq!(arbiter.owner(10), Some(low));
    }

    #[test]
    fn recreated_writer_with_new_strength_is_a_new_guid() {
        // Secondary promoted: its strength-20 writer is replaced by a strength-30 writer
        // (new GUID); the Primary it replaces is dead.
        let (old_secondary, new_primary) = (0x21_u32, 0x31_u32);
        let mut arbiter = Arbiter::new(DEADLINE_MS);
        arbiter.offer(PRIMARY, Strength(30), 0);
        assert!(!arbiter.offer(old_secondary, Strength(20), 30).accepted);
        // Primary dies after 0; Secondary fails over at 130.
        assert!(arbiter.offer(old_secondary, Strength(20), 130).accepted);
        // Writer re-created at strength 30: takes over at once from its old self.
        arbiter.writer_lost(old_secondary);
        let decision = arbiter.offer(new_primary, Strength(30), 140);
        assert!(decision.accepted);
        assert_eq!(
            decision.owner_changed,
            Some(OwnerChange {
                from: Some(old_secondary),
                to: new_primary,
                gap_ms: Some(10)
            })
        );
        assert_eq!(arbiter.strength_of(old_secondary), None);
        assert_eq!(arbiter.owner_strength(140), Some(Strength(30)));
    }

    #[test]
    fn strength_change_of_a_live_writer_applies_to_its_next_sample() {
        let mut arbiter = Arbiter::new(DEADLINE_MS);
        arbiter.offer(PRIMARY, Strength(30), 0);
        assert!(!arbiter.offer(SECONDARY, Strength(20), 10).accepted);
        // The owner lowers itself to 10: the Secondary now outranks it.
        assert!(arbiter.offer(PRIMARY, Strength(10), 20).accepted);
        let decision = arbiter.offer(SECONDARY, Strength(20), 30);
        assert!(decision.accepted);
        assert_eq!(decision.owner_changed.map(|c| c.to), Some(SECONDARY));
    }

    #[test]
    fn lost_owner_is_replaced_by_the_next_sample_without_waiting() {
        let mut arbiter = Arbiter::new(DEADLINE_MS);
        arbiter.offer(PRIMARY, Strength(30), 0);
        arbiter.writer_lost(PRIMARY);
        assert_eq!(arbiter.owner(1), None);
        let decision = arbiter.offer(TERTIARY, Strength(10), 20);
        assert!(decision.accepted);
        assert_eq!(
            decision.owner_changed,
            Some(OwnerChange {
                from: Some(PRIMARY),
                to: TERTIARY,
                gap_ms: Some(20)
            })
        );
        // Losing a writer that is not the owner changes nothing.
        arbiter.writer_lost(SECONDARY);
        assert_eq!(arbiter.owner(21), Some(TERTIARY));
    }

    #[test]
    fn weaker_writer_first_after_a_miss_then_the_stronger_takes_over() {
        // The paper's aperiodic-topic effect: after a miss, whichever sample comes first wins,
        // until a stronger writer's sample arrives.
        let mut arbiter = Arbiter::new(DEADLINE_MS);
        arbiter.offer(PRIMARY, Strength(30), 0);
        assert!(arbiter.offer(TERTIARY, Strength(10), 200).accepted);
        let decision = arbiter.offer(SECONDARY, Strength(20), 201);
        assert!(decision.accepted);
        assert_eq!(decision.owner_changed.map(|c| c.from), Some(Some(TERTIARY)));
        assert!(!arbiter.offer(TERTIARY, Strength(10), 202).accepted);
    }

    /// How a failover check found the arbiter wanting.
    #[derive(Debug, PartialEq)]
    enum FailoverMiss {
        /// The Secondary was accepted, but later than the deadline plus one period allows.
        TooLate { gap_ms: u64 },
        /// The Secondary was never accepted.
        Never,
    }

    /// The failover check the tests above make, as a function of the arbiter: Primary stops at
    /// 300 while a Secondary keeps publishing at 30 Hz; the Secondary must be accepted within
    /// the deadline plus one period of the Primary's last sample.
    fn fails_over_while_a_weaker_writer_publishes(
        mut arbiter: Arbiter<u32>,
    ) -> Result<u64, FailoverMiss> {
        let mut last_primary_ms = 0;
        for (t, writer, strength) in
            schedule(&[(PRIMARY, 30, 33, 0, 300), (SECONDARY, 20, 33, 10, 2000)])
        {
            let decision = arbiter.offer(writer, Strength(strength), t);
            if writer == PRIMARY {
                last_primary_ms = t;
            } else if decision.accepted {
                let gap_ms = t - last_primary_ms;
                return if gap_ms <= DEADLINE_MS + 33 {
                    Ok(gap_ms)
                } else {
                    Err(FailoverMiss::TooLate { gap_ms })
                };
            }
        }
        Err(FailoverMiss::Never)
    }

    #[test]
    fn cyclone_renewal_would_be_caught() {
        let gap_ms = fails_over_while_a_weaker_writer_publishes(Arbiter::new(DEADLINE_MS))
            .expect("DDS semantics fail over");
        assert!(gap_ms > DEADLINE_MS);
        // The mutant: every sample renews the instance deadline (Cyclone DDS 11). The same
        // check must reject it, or it would not guard the rule.
        let mutant =
            fails_over_while_a_weaker_writer_publishes(Arbiter::with_cyclone_renewal(DEADLINE_MS));
        assert_eq!(mutant, Err(FailoverMiss::Never));
    }

    #[test]
    fn time_going_backwards_does_not_panic_or_extend_ownership() {
        let mut arbiter = Arbiter::new(DEADLINE_MS);
        arbiter.offer(PRIMARY, Strength(30), 1000);
        assert!(arbiter.offer(PRIMARY, Strength(30), 10).accepted);
        assert_eq!(arbiter.last_accepted_ms(), Some(1000));
        assert!(!arbiter.offer(SECONDARY, Strength(20), 5).accepted);
    }
}
