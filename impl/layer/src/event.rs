//! The controller's JSON event lines (`rl controller --json-events`): one [`EventLine`] per
//! line on stdout, the record of what the controller did. The runtime writes them; the demo,
//! the benchmark, the process tests and the conformance checks read them back with the same
//! type, so writer and readers cannot drift apart.
//!
//! Every line carries `t_ms` (the controller's round clock: wall-clock milliseconds), `id`,
//! `incarnation` and `event`, the kind, with that kind's fields beside it:
//! ```text
//! {"t_ms":1795370649251,"id":1,"incarnation":117661410823791923,"event":"output",
//!  "role":"primary","strength":30}
//! ```
//! Fields may be added later, never removed or renamed; readers ignore fields they do not
//! know.

use crate::core::network::{AlarmCause, Network, Verdict};
use crate::core::{AlarmReason, Assignment, ControllerId, Incarnation, Role, Status, Strength};
use crate::cross_check::OddOn;
use crate::failed_exit::{Failure, FailureCause, EXIT_STATUS};
use crate::wire::Certainty;
use serde::{Deserialize, Serialize};

/// One line of `rl controller --json-events`: who, when, and what happened.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EventLine {
    /// The controller's round clock when it happened (wall-clock milliseconds).
    pub t_ms: u64,
    /// The reporting controller's configured id.
    pub id: ControllerId,
    /// The controller's current life: a new value at every start, and when it starts again
    /// (resumed, detached, deposed).
    pub incarnation: Incarnation,
    /// What happened: the `event` field and its kind's fields, side by side in the line.
    #[serde(flatten)]
    pub event: Event,
}

/// What a controller reports, by kind (the `event` field).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "event", rename_all = "snake_case")]
pub enum Event {
    /// The voting thread started (before its first round).
    Started,
    /// Held before voting (a `fault-injection` build under `RL_HOLD_START`): its DDS endpoints
    /// exist and it waits for `start-voting` on its stdin before its clock starts, while
    /// discovery goes on. How many participants have a heartbeat writer and a heartbeat
    /// reader, as discovered so far (its own included): the DDS-level replay starts a trace's
    /// processes this way and lets them vote once all have found each other. Incarnation 0:
    /// none yet.
    Held {
        /// Participants with a heartbeat writer, discovered (its own included).
        heartbeat_writers: usize,
        /// Participants with a heartbeat reader, discovered (its own included).
        heartbeat_readers: usize,
    },
    /// The protocol state changed (phase, role, strength, agreed result, vote or membership).
    Status {
        /// The protocol state after the change (boxed: the largest event by far).
        status: Box<Status>,
    },
    /// The command output changed: commanding at `strength` for `role`, or silent (`null`).
    Output {
        /// The role it commands for; `null` when silent.
        role: Option<Role>,
        /// The command writer's DDS ownership strength (30, 20, 10; 15 provisional, 35
        /// takeover); `null` when silent.
        strength: Option<Strength>,
    },
    /// A durable vote record was published; `null` withdraws the vote.
    Vote {
        /// The role assignment voted for; `null` when the vote is withdrawn.
        vote: Option<Assignment>,
    },
    /// A controller alarm about peer `about` was raised or cleared.
    Alarm {
        /// The id of the peer the alarm is about.
        about: ControllerId,
        /// Why it is raised: lost, failed or impostor.
        reason: AlarmReason,
        /// `true` when raised, `false` when cleared.
        raised: bool,
    },
    /// The status LEDs now show this pattern (its console form).
    Leds {
        /// The four LEDs' colours as the console bank prints them.
        leds: String,
    },
    /// The network monitor raised or cleared a network alarm: about `network` as a whole
    /// (`controller` null) or controller `controller`'s transceiver on it. A raised alarm
    /// says how sure (`certainty`) and why (`cause`); a cleared one has neither.
    NetworkAlarm {
        /// The network (A or B) it is about.
        network: Network,
        /// The controller whose transceiver on it is at fault; `null` for the whole network.
        controller: Option<ControllerId>,
        /// `true` when raised, `false` when cleared.
        raised: bool,
        /// How sure the monitor is; absent when cleared.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        certainty: Option<Certainty>,
        /// Why it is raised (the monitor's finding, its alternatives, or the links no small
        /// set of faults explains); absent when cleared.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        cause: Option<AlarmCause>,
    },
    /// The network monitor's conclusion changed: in words (`none` when every link is good)
    /// and as the verdict itself (the findings every smallest explanation shares, the
    /// alternatives, or the links left unexplained).
    NetworkConclusion {
        /// The conclusion in words; `none` when every link is good.
        conclusion: String,
        /// The conclusion as the monitor reached it.
        verdict: Verdict,
    },
    /// A heartbeat of peer `from` arrived and was dropped by the fault-injection control (a
    /// `fault-injection` build only): the DDS-level replay checks every loss it injects
    /// against these, so an injected loss is told apart from a real one.
    HeartbeatDropped {
        /// The id of the peer whose heartbeat was dropped.
        from: ControllerId,
    },
    /// A heartbeat of peer `from` arrived a round late (it waited `waited_ms` beyond the
    /// fastest delivery from that peer, past its round's end) and was dropped as lost
    /// (`rl_core::Core::sent_before_this_round`).
    HeartbeatLate {
        /// The id of the peer whose heartbeat came late.
        from: ControllerId,
        /// How long (ms) it came after the fastest delivery from that peer.
        waited_ms: u64,
    },
    /// The voting loop fell behind (starved, stalled): the round end of this line stands for
    /// `rounds` more round boundaries that passed without one (`rl_core::Command::RoundEndsMissed`).
    /// The model's `Oversleep`: what it did not hear in them is lost to it.
    RoundEndsMissed {
        /// Round boundaries passed without a round end of their own.
        rounds: u64,
    },
    /// The voting loop did not run for `stalled_ms` (at least a peer deadline: a SIGSTOP, a
    /// frozen machine): the controller starts again as the incarnation of this line, silent
    /// until it has heard a round and joined below the controllers that kept running.
    Resumed {
        /// How long (ms) the voting loop did not run.
        stalled_ms: u64,
    },
    /// Every link of the controller lost its carrier (crate::link_watch): it starts again as
    /// the incarnation of this line, silent until it has heard a round and joined below.
    Detached,
    /// A peer took over from the controller, whose commands reached it late (F17): it starts
    /// again as the incarnation of this line, silent until it has heard a round and joined
    /// below.
    Deposed,
    /// Its cross-check found its commands the odd one out of three at `odd_limit` inputs of
    /// this life (crate::cross_check): it reports a local fault and leaves (a `stopped` line
    /// with reason `local_fault` follows).
    OddOneOut {
        /// What it was odd on: its output, or its input (input congruence; an
        /// `input_disagrees` alarm about itself precedes the line).
        #[serde(default)]
        on: OddOn,
        /// The inputs (the application's tags) at which it was the odd one out, oldest first.
        inputs: Vec<u64>,
        /// N: the odd inputs in one life at which a controller leaves.
        odd_limit: u32,
        /// The peers that agreed with each other at the last of them.
        peers: Vec<ControllerId>,
        /// Its answers since the last one judged not odd that went out before they could be
        /// judged at their next input (crate::cross_check::OddOneOut::late): 0 when the
        /// timing assumption held, and then an exclusive reader took at most `odd_limit` of
        /// its wrong answers in this life, else at most `odd_limit` + `late`.
        #[serde(default)]
        late: u32,
    },
    /// The voting thread stopped cleanly: asked to (no other fields), or on its own after the
    /// controller failed itself. Then `reason` says why (`outvoted`, `local_fault`),
    /// `disagreed_with` lists the peers whose votes differed from its own, and `exit_status`
    /// is what `rl controller` exits with to be restarted (crate::failed_exit).
    Stopped {
        /// Why it failed itself; absent when asked to stop.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        reason: Option<FailureCause>,
        /// The ids of the peers whose votes differed from its own; absent when none.
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        disagreed_with: Vec<ControllerId>,
        /// The status `rl controller` exits with to be restarted (75); absent when asked to
        /// stop.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        exit_status: Option<u8>,
    },
}

impl Event {
    /// The kind as written in the `event` field (`status`, `alarm`, ...).
    pub fn kind(&self) -> &'static str {
        match self {
            Event::Started => "started",
            Event::Held { .. } => "held",
            Event::Status { .. } => "status",
            Event::Output { .. } => "output",
            Event::Vote { .. } => "vote",
            Event::Alarm { .. } => "alarm",
            Event::Leds { .. } => "leds",
            Event::NetworkAlarm { .. } => "network_alarm",
            Event::NetworkConclusion { .. } => "network_conclusion",
            Event::HeartbeatDropped { .. } => "heartbeat_dropped",
            Event::HeartbeatLate { .. } => "heartbeat_late",
            Event::RoundEndsMissed { .. } => "round_ends_missed",
            Event::Resumed { .. } => "resumed",
            Event::Detached => "detached",
            Event::Deposed => "deposed",
            Event::OddOneOut { .. } => "odd_one_out",
            Event::Stopped { .. } => "stopped",
        }
    }

    /// `stopped`, as asked to.
    pub fn stopped() -> Event {
        Event::Stopped {
            reason: None,
            disagreed_with: Vec::new(),
            exit_status: None,
        }
    }

    /// `stopped` after failing itself, to be restarted.
    pub fn stopped_failed(failure: &Failure) -> Event {
        Event::Stopped {
            reason: Some(failure.cause),
            disagreed_with: failure.disagreed_with.clone(),
            exit_status: Some(EXIT_STATUS),
        }
    }
}

impl EventLine {
    /// Parses one line; `None` for anything else (log text, servo lines, partial output).
    pub fn parse(text: &str) -> Option<EventLine> {
        serde_json::from_str(text).ok()
    }

    /// The reported status, if this is a `status` line.
    pub fn status(&self) -> Option<&Status> {
        match &self.event {
            Event::Status { status } => Some(status),
            _ => None,
        }
    }

    /// One JSON line (no newline).
    pub fn to_json(&self) -> String {
        // Serializing plain data with string keys cannot fail; an empty line would only
        // be skipped by readers.
        serde_json::to_string(self).unwrap_or_default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::network::{Finding, Part};
    use crate::core::{Holder, Phase, SelfReport};

    fn line(event: Event) -> EventLine {
        EventLine {
            t_ms: 1000,
            id: 2,
            incarnation: 77,
            event,
        }
    }

    #[test]
    fn lines_have_the_documented_shape() {
        assert_eq!(
            line(Event::Started).to_json(),
            r#"{"t_ms":1000,"id":2,"incarnation":77,"event":"started"}"#
        );
        assert_eq!(
            line(Event::Output {
                role: Some(Role::Secondary),
                strength: Some(Strength(20))
            })
            .to_json(),
            r#"{"t_ms":1000,"id":2,"incarnation":77,"event":"output","role":"secondary","strength":20}"#
        );
        assert_eq!(
            line(Event::Alarm {
                about: 1,
                reason: AlarmReason::Lost,
                raised: true
            })
            .to_json(),
            r#"{"t_ms":1000,"id":2,"incarnation":77,"event":"alarm","about":1,"reason":"lost","raised":true}"#
        );
        assert_eq!(
            line(Event::HeartbeatDropped { from: 1 }).to_json(),
            r#"{"t_ms":1000,"id":2,"incarnation":77,"event":"heartbeat_dropped","from":1}"#
        );
        assert_eq!(
            line(Event::RoundEndsMissed { rounds: 2 }).to_json(),
            r#"{"t_ms":1000,"id":2,"incarnation":77,"event":"round_ends_missed","rounds":2}"#
        );
        assert_eq!(
            line(Event::Resumed { stalled_ms: 3000 }).to_json(),
            r#"{"t_ms":1000,"id":2,"incarnation":77,"event":"resumed","stalled_ms":3000}"#
        );
        assert_eq!(
            line(Event::Held {
                heartbeat_writers: 2,
                heartbeat_readers: 1
            })
            .to_json(),
            r#"{"t_ms":1000,"id":2,"incarnation":77,"event":"held","heartbeat_writers":2,"heartbeat_readers":1}"#
        );
        assert_eq!(
            line(Event::Detached).to_json(),
            r#"{"t_ms":1000,"id":2,"incarnation":77,"event":"detached"}"#
        );
        assert_eq!(
            line(Event::Deposed).to_json(),
            r#"{"t_ms":1000,"id":2,"incarnation":77,"event":"deposed"}"#
        );
        assert_eq!(
            line(Event::Vote { vote: None }).to_json(),
            r#"{"t_ms":1000,"id":2,"incarnation":77,"event":"vote","vote":null}"#
        );
        assert_eq!(
            line(Event::stopped()).to_json(),
            r#"{"t_ms":1000,"id":2,"incarnation":77,"event":"stopped"}"#
        );
        let failure = Failure {
            id: 2,
            cause: FailureCause::Outvoted,
            disagreed_with: vec![1, 3],
            own_vote: None,
            their_vote: None,
        };
        assert_eq!(
            line(Event::stopped_failed(&failure)).to_json(),
            r#"{"t_ms":1000,"id":2,"incarnation":77,"event":"stopped","reason":"outvoted","disagreed_with":[1,3],"exit_status":75}"#
        );
    }

    #[test]
    fn a_network_alarm_line_reads_as_documented() {
        let text = line(Event::NetworkAlarm {
            network: Network::B,
            controller: None,
            raised: true,
            certainty: Some(Certainty::Concluded),
            cause: Some(AlarmCause::Concluded(Finding::NetworkFailure(Network::B))),
        })
        .to_json();
        assert_eq!(
            text,
            r#"{"t_ms":1000,"id":2,"incarnation":77,"event":"network_alarm","network":"B","controller":null,"raised":true,"certainty":"concluded","cause":{"concluded":{"network_failure":"B"}}}"#
        );
        let transceiver = line(Event::NetworkAlarm {
            network: Network::A,
            controller: Some(2),
            raised: true,
            certainty: Some(Certainty::Suspected),
            cause: Some(AlarmCause::Suspected {
                alternatives: vec![vec![Finding::Transceiver {
                    controller: 2,
                    network: Network::A,
                    part: Part::Transmitter,
                }]],
            }),
        })
        .to_json();
        assert!(
            transceiver.ends_with(
                r#""cause":{"suspected":{"alternatives":[[{"transceiver":{"controller":2,"network":"A","part":"transmitter"}}]]}}}"#
            ),
            "{transceiver}"
        );
    }

    #[test]
    fn every_kind_reads_back_as_written() {
        let holder = Holder {
            id: 1,
            incarnation: 5,
        };
        let assignment = Assignment::from_ranked([holder]);
        let mut status = Status::initial(2, 77);
        status.report = SelfReport {
            phase: Phase::Steady,
            role: Some(Role::Secondary),
            strength: Some(Strength(20)),
            agreed: Some(assignment),
            vote: Some(assignment),
            ..status.report
        };
        status.sees = vec![1, 3];
        status.failed = vec![3];
        status.alarms = vec![(3, AlarmReason::Failed)];
        let events = [
            Event::Started,
            Event::Held {
                heartbeat_writers: 2,
                heartbeat_readers: 2,
            },
            Event::Status {
                status: Box::new(status),
            },
            Event::Output {
                role: None,
                strength: None,
            },
            Event::Vote {
                vote: Some(assignment),
            },
            Event::Alarm {
                about: 3,
                reason: AlarmReason::Failed,
                raised: false,
            },
            Event::Leds {
                leds: "[P:off S:green T:off | own:green]".into(),
            },
            Event::HeartbeatDropped { from: 3 },
            Event::HeartbeatLate {
                from: 3,
                waited_ms: 300,
            },
            Event::NetworkAlarm {
                network: Network::B,
                controller: None,
                raised: true,
                certainty: Some(Certainty::Concluded),
                cause: Some(AlarmCause::Concluded(Finding::NetworkFailure(Network::B))),
            },
            Event::NetworkAlarm {
                network: Network::A,
                controller: Some(2),
                raised: false,
                certainty: None,
                cause: None,
            },
            Event::NetworkConclusion {
                conclusion: "network B failed".into(),
                verdict: Verdict::Explained {
                    certain: vec![Finding::NetworkFailure(Network::B)],
                    alternatives: Vec::new(),
                },
            },
            Event::stopped(),
            Event::Stopped {
                reason: Some(FailureCause::LocalFault),
                disagreed_with: Vec::new(),
                exit_status: Some(EXIT_STATUS),
            },
        ];
        for event in events {
            let written = line(event);
            let text = written.to_json();
            assert_eq!(EventLine::parse(&text), Some(written.clone()), "{text}");
            assert!(text.contains(&format!(r#""event":"{}""#, written.event.kind())));
        }
    }

    #[test]
    fn recorded_lines_with_sorted_keys_and_unknown_fields_parse() {
        // The key order of older recordings (alphabetical), plus a field added later.
        let recorded = r#"{"about":2,"event":"alarm","id":1,"incarnation":9,"raised":false,"reason":"lost","t_ms":1500,"extra":1}"#;
        assert_eq!(
            EventLine::parse(recorded),
            Some(EventLine {
                t_ms: 1500,
                id: 1,
                incarnation: 9,
                event: Event::Alarm {
                    about: 2,
                    reason: AlarmReason::Lost,
                    raised: false
                }
            })
        );
        assert_eq!(EventLine::parse(r#"{"event":"command","t_ms":5}"#), None);
        assert_eq!(
            EventLine::parse(r#"{"t_ms":1,"id":1,"incarnation":1,"event":"dancing"}"#),
            None
        );
        assert_eq!(EventLine::parse("owner: C1"), None);
    }
}
