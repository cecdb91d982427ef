//! [`Board`]: what one redundancy group's controllers say, kept from their samples (the latest
//! heartbeat per controller, the controller and network alarms raised now), and the
//! [`StatusView`] of it at a given time. Pure: samples and times in, a view out, so the demo,
//! the benchmarks and the tests use it without DDS; [`BoardFeed`](super::BoardFeed) feeds it
//! from DDS.

use super::view::{AlarmView, ControllerView, NetworkAlarmView, StatusView};
use rl_layer::core::network::AlarmSubject;
use rl_layer::core::types::{AlarmReason, ControllerId};
use rl_layer::core::Heartbeat;
use rl_layer::wire::{Certainty, ControllerAlarm, NetworkAlarm};
use std::collections::BTreeMap;

/// A raised controller alarm as the board keeps it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct RaisedAlarm {
    reason: AlarmReason,
    since_ms: Option<u64>,
    /// The reporter's life that raised it: a later life of the reporter (its heartbeat says)
    /// no longer holds it, as a process that ended cannot clear what it raised (a controller
    /// that left with its `input_disagrees` alarm up, then restarted).
    reporter_incarnation: rl_layer::core::types::Incarnation,
}

/// The latest heartbeat per controller and the raised alarms of one redundancy group.
#[derive(Clone, Debug, Default)]
pub struct Board {
    /// The redundancy group whose topics feed it.
    group: String,
    heartbeats: BTreeMap<ControllerId, (Heartbeat, u64)>,
    /// (about, reporter, impostor) -> reason, first raise and the reporter's life that raised
    /// it, for raised alarms: one protocol alarm per controller and reporter (Failed replaces
    /// Lost), an impostor alarm beside it.
    alarms: BTreeMap<(ControllerId, ControllerId, bool), RaisedAlarm>,
    /// (subject, reporter) -> how sure and why, for raised network alarms.
    network_alarms: BTreeMap<(AlarmSubject, ControllerId), (Certainty, String)>,
}

impl Board {
    /// An empty board of the redundancy group `group` (`dds.group`).
    pub fn for_group(group: &str) -> Board {
        Board {
            group: group.to_string(),
            ..Board::default()
        }
    }

    /// The redundancy group it shows ("" for the group without a name).
    pub fn group(&self) -> &str {
        &self.group
    }

    pub fn heartbeat(&mut self, heartbeat: Heartbeat, now_ms: u64) {
        self.heartbeats.insert(heartbeat.id, (heartbeat, now_ms));
    }

    /// A controller alarm raised or cleared; `stamped_ms` is when its reporter wrote it (Unix
    /// milliseconds), if known.
    pub fn alarm(&mut self, alarm: &ControllerAlarm, stamped_ms: Option<u64>) {
        let key = (
            alarm.about,
            alarm.reporter,
            alarm.reason == AlarmReason::Impostor,
        );
        if alarm.raised {
            // A republished alarm keeps the time it was first raised.
            let since_ms = self
                .alarms
                .get(&key)
                .filter(|kept| kept.reporter_incarnation == alarm.reporter_incarnation)
                .map_or(stamped_ms, |kept| kept.since_ms);
            self.alarms.insert(
                key,
                RaisedAlarm {
                    reason: alarm.reason,
                    since_ms,
                    reporter_incarnation: alarm.reporter_incarnation,
                },
            );
        } else {
            self.alarms.remove(&key);
        }
    }

    pub fn network_alarm(&mut self, alarm: &NetworkAlarm) {
        let key = (alarm.subject, alarm.reporter);
        match alarm.raised {
            Some(certainty) => {
                self.network_alarms
                    .insert(key, (certainty, alarm.cause.clone()));
            }
            None => {
                self.network_alarms.remove(&key);
            }
        }
    }

    /// The latest heartbeat of a controller.
    pub fn latest(&self, id: ControllerId) -> Option<&Heartbeat> {
        self.heartbeats.get(&id).map(|(h, _)| h)
    }

    /// When the board took in controller `id`'s last heartbeat (its `now_ms` then).
    pub fn last_heard_ms(&self, id: ControllerId) -> Option<u64> {
        self.heartbeats.get(&id).map(|(_, at)| *at)
    }

    /// The controllers heard within `alive_within_ms`.
    pub fn alive(&self, now_ms: u64, alive_within_ms: u64) -> impl Iterator<Item = &Heartbeat> {
        self.heartbeats
            .values()
            .filter(move |(_, at)| now_ms.saturating_sub(*at) <= alive_within_ms)
            .map(|(h, _)| h)
    }

    /// The live controller commanding at the highest strength (ties: lowest id).
    pub fn commander(&self, now_ms: u64, alive_within_ms: u64) -> Option<&Heartbeat> {
        self.alive(now_ms, alive_within_ms)
            .filter(|h| h.strength.is_some())
            .min_by_key(|h| (std::cmp::Reverse(h.strength), h.id))
    }

    /// What the board shows at `now_ms`: controllers heard within `alive_within_ms` are alive.
    pub fn view(&self, now_ms: u64, alive_within_ms: u64) -> StatusView {
        StatusView {
            group: self.group.clone(),
            controllers: self.controller_views(now_ms, alive_within_ms),
            alarms: self.alarm_views(),
            network_alarms: self.network_alarm_views(),
        }
    }

    fn controller_views(&self, now_ms: u64, alive_within_ms: u64) -> Vec<ControllerView> {
        self.heartbeats
            .values()
            .map(|(h, at)| {
                let since = now_ms.saturating_sub(*at);
                ControllerView {
                    report: *h,
                    alive: since <= alive_within_ms,
                    last_heard_ms: since,
                }
            })
            .collect()
    }

    /// One entry per controller and reason, with every reporter and the first raise's time;
    /// an alarm whose reporter has been heard in a later life since is gone with the life
    /// that raised it.
    fn alarm_views(&self) -> Vec<AlarmView> {
        let mut alarms: Vec<AlarmView> = Vec::new();
        let current =
            |(&(_, reporter, _), raised): &(&(ControllerId, ControllerId, bool), &RaisedAlarm)| {
                self.latest(reporter)
                    .is_none_or(|h| h.incarnation <= raised.reporter_incarnation)
            };
        for (&(about, reporter, _), raised) in self.alarms.iter().filter(current) {
            let (reason, since_ms) = (raised.reason, raised.since_ms);
            match alarms
                .iter_mut()
                .find(|a| a.about == about && a.reason == reason)
            {
                Some(view) => {
                    view.raised_by.push(reporter);
                    view.since_ms = match (view.since_ms, since_ms) {
                        (Some(a), Some(b)) => Some(a.min(b)),
                        (a, b) => a.or(b),
                    };
                }
                None => alarms.push(AlarmView {
                    about,
                    reason,
                    raised_by: vec![reporter],
                    since_ms,
                }),
            }
        }
        alarms
    }

    /// One entry per subject, with every reporter; certainty and cause as the first says.
    fn network_alarm_views(&self) -> Vec<NetworkAlarmView> {
        let mut network_alarms: Vec<NetworkAlarmView> = Vec::new();
        for (&(subject, reporter), (certainty, cause)) in &self.network_alarms {
            let (network, controller) = match subject {
                AlarmSubject::Network(network) => (network, None),
                AlarmSubject::Transceiver {
                    controller,
                    network,
                } => (network, Some(controller)),
            };
            match network_alarms
                .iter_mut()
                .find(|a| a.network == network && a.controller == controller)
            {
                Some(view) => view.raised_by.push(reporter),
                None => network_alarms.push(NetworkAlarmView {
                    network,
                    controller,
                    certainty: *certainty,
                    cause: cause.clone(),
                    raised_by: vec![reporter],
                }),
            }
        }
        network_alarms
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rl_layer::core::network::Network;
    use rl_layer::core::types::{Assignment, Holder, Phase, Role};

    fn hb(from: ControllerId, role: Option<Role>) -> Heartbeat {
        let agreed = Assignment::from_ranked([1, 2, 3].map(|id| Holder { id, incarnation: 0 }));
        Heartbeat {
            id: from,
            incarnation: 0,
            phase: Phase::Steady,
            role,
            strength: role.map(Role::strength),
            agreed: Some(agreed),
            vote: Some(agreed),
            epoch: 1,
            provisional: false,
            established_strength: role.map(Role::strength),
            took_over_from: None,
        }
    }

    #[test]
    fn the_view_lists_controllers_and_marks_the_silent_ones_lost() {
        let mut board = Board::for_group("nav");
        board.heartbeat(hb(1, Some(Role::Primary)), 1000);
        board.heartbeat(hb(2, Some(Role::Secondary)), 1500);
        let view = board.view(1700, 500);
        assert_eq!(view.group, "nav");
        assert_eq!(view.controllers.len(), 2);
        assert!(!view.controllers[0].alive, "700 ms silent > 500 ms");
        assert!(view.controllers[1].alive);
        assert_eq!(board.commander(1700, 500).map(|h| h.id), Some(2));
        let json = serde_json::to_value(&view).unwrap();
        assert_eq!(json["group"], "nav");
        assert_eq!(json["controllers"][1]["role"], "secondary");
        assert_eq!(json["controllers"][1]["strength"], 20);
        let agreed: Assignment = serde_json::from_value(json["controllers"][1]["agreed"].clone())
            .expect("the agreed result reads back as an assignment");
        assert_eq!(agreed.to_string(), "P=1 S=2 T=3");
    }

    #[test]
    fn an_alarm_stays_raised_until_every_reporter_clears_it() {
        let mut board = Board::default();
        let alarm = |reporter, raised| ControllerAlarm {
            reporter,
            reporter_incarnation: 0,
            about: 1,
            about_incarnation: None,
            reason: AlarmReason::Lost,
            raised,
        };
        board.alarm(&alarm(2, true), Some(5_000));
        board.alarm(&alarm(3, true), Some(3_000));
        assert_eq!(board.view(0, 500).alarms[0].raised_by, vec![2, 3]);
        assert_eq!(
            board.view(0, 500).alarms[0].since_ms,
            Some(3_000),
            "the first raise"
        );
        board.alarm(&alarm(2, false), None);
        assert_eq!(board.view(0, 500).alarms[0].raised_by, vec![3]);
        board.alarm(&alarm(3, false), None);
        assert!(board.view(0, 500).alarms.is_empty());
    }

    #[test]
    fn an_alarm_goes_with_the_reporters_life_that_raised_it() {
        let mut board = Board::default();
        let input = ControllerAlarm {
            reporter: 1,
            reporter_incarnation: 7,
            about: 1,
            about_incarnation: None,
            reason: AlarmReason::InputDisagrees,
            raised: true,
        };
        board.alarm(&input, Some(1_000));
        let heartbeat = |incarnation| Heartbeat::initial(1, incarnation);
        board.heartbeat(heartbeat(7), 1_000);
        assert_eq!(
            board.view(1_000, 500).alarms.len(),
            1,
            "its life still runs"
        );
        // It left and restarted: the new life never raised it, and the old one cannot clear it.
        board.heartbeat(heartbeat(8), 3_000);
        assert!(board.view(3_000, 500).alarms.is_empty());
        // Raised again by the new life, it shows again, from the new raise.
        board.alarm(
            &ControllerAlarm {
                reporter_incarnation: 8,
                ..input
            },
            Some(4_000),
        );
        assert_eq!(board.view(4_000, 500).alarms[0].since_ms, Some(4_000));
    }

    #[test]
    fn network_alarms_are_grouped_by_subject_and_cleared_per_reporter() {
        let mut board = Board::default();
        let alarm = |reporter, subject, raised: Option<Certainty>| NetworkAlarm {
            reporter,
            reporter_incarnation: 0,
            subject,
            raised,
            cause: raised.map_or(String::new(), |_| "network B failed".into()),
        };
        let net_b = AlarmSubject::Network(Network::B);
        let c2_a = AlarmSubject::Transceiver {
            controller: 2,
            network: Network::A,
        };
        board.network_alarm(&alarm(1, net_b, Some(Certainty::Concluded)));
        board.network_alarm(&alarm(3, net_b, Some(Certainty::Concluded)));
        board.network_alarm(&alarm(1, c2_a, Some(Certainty::Suspected)));
        let view = board.view(0, 500);
        assert_eq!(view.network_alarms.len(), 2);
        assert_eq!(view.network_alarms[0].raised_by, vec![1, 3]);
        assert_eq!(view.network_alarms[1].controller, Some(2));
        let json = serde_json::to_value(&view).unwrap();
        assert_eq!(json["network_alarms"][0]["network"], "B");
        assert_eq!(
            json["network_alarms"][0]["controller"],
            serde_json::Value::Null
        );
        assert_eq!(json["network_alarms"][1]["certainty"], "suspected");
        for reporter in [1, 3] {
            board.network_alarm(&alarm(reporter, net_b, None));
        }
        board.network_alarm(&alarm(1, c2_a, None));
        assert!(board.view(0, 500).network_alarms.is_empty());
    }
}
