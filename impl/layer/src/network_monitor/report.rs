//! What the network monitor tells: each alarm raised or cleared (on the network alarm topic,
//! as a console or journal line and as a JSON event) and each change of its conclusion.
//!
//! Network alarms do not touch the status LEDs: the paper's four LEDs show the controllers'
//! roles and the controller's own state, and an operator reads network alarms from the
//! console, the journal and `rl status` (docs/protocol.md, "Network monitoring").

use crate::core::network::{AlarmCause, AlarmSubject, Conclusion};
use crate::core::types::{ControllerId, Incarnation};
use crate::dds::Writer;
use crate::event::{Event, EventLine};
use crate::wire::{fit_cause, Certainty, NetworkAlarm, NetworkAlarmSample};
use std::io::Write;
use tracing::{info, warn};

/// Where the monitor reports, and as whom.
pub struct Reporter {
    pub id: ControllerId,
    pub incarnation: Incarnation,
    pub json_events: bool,
    pub alarms_out: Writer<NetworkAlarmSample>,
}

/// How sure an alarm's cause is.
pub fn certainty(cause: &AlarmCause) -> Certainty {
    match cause {
        AlarmCause::Concluded(_) => Certainty::Concluded,
        AlarmCause::Suspected { .. } => Certainty::Suspected,
        AlarmCause::Unexplained { .. } => Certainty::Unexplained,
    }
}

/// The network alarm sample's value for a subject raised (`Some(cause)`) or cleared (`None`),
/// its cause cut to what the wire carries.
fn alarm_of(
    reporter: ControllerId,
    reporter_incarnation: Incarnation,
    subject: AlarmSubject,
    cause: Option<&AlarmCause>,
) -> NetworkAlarm {
    NetworkAlarm {
        reporter,
        reporter_incarnation,
        subject,
        raised: cause.map(certainty),
        cause: cause.map_or_else(String::new, |cause| fit_cause(&cause.to_string())),
    }
}

/// The controller a subject names, if it is a transceiver.
fn controller_of(subject: AlarmSubject) -> Option<ControllerId> {
    match subject {
        AlarmSubject::Network(_) => None,
        AlarmSubject::Transceiver { controller, .. } => Some(controller),
    }
}

fn network_of(subject: AlarmSubject) -> crate::core::network::Network {
    match subject {
        AlarmSubject::Network(network) | AlarmSubject::Transceiver { network, .. } => network,
    }
}

impl Reporter {
    /// Publishes, shows and records an alarm raised (`Some(cause)`) or cleared (`None`).
    pub fn alarm(&self, subject: AlarmSubject, cause: Option<&AlarmCause>, t_ms: u64) {
        let raised = cause.map(certainty);
        let cause_text = cause.map(ToString::to_string);
        let line = match (&raised, &cause_text) {
            (Some(certainty), Some(text)) => format!(
                "C{}: network alarm RAISED: {subject}: {text} ({})",
                self.id,
                certainty.name()
            ),
            _ => format!("C{}: network alarm cleared: {subject}", self.id),
        };
        self.console(&line);
        self.event(
            Event::NetworkAlarm {
                network: network_of(subject),
                controller: controller_of(subject),
                raised: raised.is_some(),
                certainty: raised,
                cause: cause.cloned(),
            },
            t_ms,
        );
        let alarm = alarm_of(self.id, self.incarnation, subject, cause);
        if let Err(error) = self.alarms_out.write(&alarm) {
            warn!("network alarm not published: {error}");
        }
    }

    /// Logs and records a new conclusion.
    pub fn conclusion(&self, conclusion: &Conclusion, t_ms: u64) {
        info!(
            "C{}: network monitor concludes: {}",
            self.id, conclusion.verdict
        );
        self.event(
            Event::NetworkConclusion {
                conclusion: conclusion.verdict.to_string(),
                verdict: conclusion.verdict.clone(),
            },
            t_ms,
        );
    }

    /// A line for the operator: on stdout, or in the log when stdout carries JSON events.
    fn console(&self, line: &str) {
        if self.json_events {
            info!("{line}");
        } else {
            println!("{line}");
        }
    }

    fn event(&self, event: Event, t_ms: u64) {
        if !self.json_events {
            return;
        }
        let line = EventLine {
            t_ms,
            id: self.id,
            incarnation: self.incarnation,
            event,
        };
        let mut out = std::io::stdout().lock();
        let _ = writeln!(out, "{}", line.to_json());
        let _ = out.flush();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::network::alarms::implicated;
    use crate::core::network::{conclude, Finding, Link, LinkMatrix, LinkState, Members, Network};
    use crate::wire::{WireSample, CAUSE_MAX_BYTES};

    /// The longest cause the monitor concludes (measured over all 3^12 link matrices, each
    /// controller observing): four links failed and two good, seen by controller 1, leave 16
    /// smallest explanations, 1,912 bytes of text. Uncut, its sample would fail the writer's
    /// own check (a cause is at most 512 bytes on the wire) and the alarm would never leave.
    #[test]
    fn an_alarm_with_the_longest_cause_is_published_with_the_cause_cut() {
        let mut matrix = LinkMatrix::unknown();
        for (from, to, network) in [
            (1, 2, Network::A),
            (3, 1, Network::A),
            (1, 2, Network::B),
            (2, 3, Network::B),
        ] {
            matrix.set(Link::new(from, to, network), LinkState::Fail);
        }
        for (from, to, network) in [(2, 3, Network::A), (3, 1, Network::B)] {
            matrix.set(Link::new(from, to, network), LinkState::Good);
        }
        let conclusion = conclude(&matrix, Members::ALL, 1);
        let (subject, cause) = implicated(&conclusion)
            .into_iter()
            .max_by_key(|(_, cause)| cause.to_string().len())
            .expect("the failed links implicate a subject");
        let text = cause.to_string();
        assert_eq!(text.len(), 1912, "{text}");

        let alarm = alarm_of(1, 7, subject, Some(&cause));
        assert!(alarm.cause.len() <= CAUSE_MAX_BYTES);
        let kept = alarm
            .cause
            .strip_suffix('…')
            .expect("a cut cause ends with …");
        assert!(text.starts_with(kept), "{}", alarm.cause);
        let sample = NetworkAlarmSample::encode(&alarm);
        assert_eq!(sample.decode(), Ok(alarm));
    }

    proptest::proptest! {
        /// Whatever the monitor sees, every alarm it raises goes out as a sample the
        /// readers accept.
        #[test]
        fn every_alarm_of_any_link_matrix_fits_the_wire(
            states in proptest::array::uniform12(0..3u8),
            observer in 1..=3u8,
        ) {
            let mut matrix = LinkMatrix::unknown();
            for (link, state) in Link::all().zip(states) {
                let state = [LinkState::Unknown, LinkState::Good, LinkState::Fail][state as usize];
                matrix.set(link, state);
            }
            let conclusion = conclude(&matrix, Members::ALL, observer);
            for (subject, cause) in implicated(&conclusion) {
                let alarm = alarm_of(observer, 1, subject, Some(&cause));
                proptest::prop_assert_eq!(
                    NetworkAlarmSample::encode(&alarm).decode(),
                    Ok(alarm)
                );
            }
        }
    }

    #[test]
    fn a_cleared_alarm_has_no_cause_and_a_short_cause_is_whole() {
        let subject = AlarmSubject::Network(Network::B);
        let cleared = alarm_of(2, 9, subject, None);
        assert_eq!((cleared.raised, cleared.cause.as_str()), (None, ""));
        let cause = AlarmCause::Concluded(Finding::NetworkFailure(Network::B));
        let raised = alarm_of(2, 9, subject, Some(&cause));
        assert_eq!(raised.raised, Some(Certainty::Concluded));
        assert_eq!(raised.cause, "network B failed");
    }
}
