//! What the network monitor tells: each alarm raised or cleared (on the network alarm topic,
//! as a console or journal line and as a JSON event) and each change of its conclusion.
//!
//! Network alarms do not touch the status LEDs: the paper's four LEDs show the controllers'
//! roles and the controller's own state, and an operator reads network alarms from the
//! console, the journal and `rl status` (docs/protocol.md, "Network monitoring").

use crate::core::network::{AlarmCause, AlarmSubject, Conclusion, Verdict};
use crate::core::types::{ControllerId, Incarnation};
use crate::dds::Writer;
use crate::event::{Event, EventLine};
use crate::wire::{Certainty, NetworkAlarm, NetworkAlarmSample};
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
                cause: cause_text.clone(),
            },
            t_ms,
        );
        let alarm = NetworkAlarm {
            reporter: self.id,
            reporter_incarnation: self.incarnation,
            subject,
            raised,
            cause: cause_text.unwrap_or_default(),
        };
        if let Err(error) = self.alarms_out.write(&alarm) {
            warn!("network alarm not published: {error}");
        }
    }

    /// Logs and records a new conclusion.
    pub fn conclusion(&self, conclusion: &Conclusion, t_ms: u64) {
        let findings = match &conclusion.verdict {
            Verdict::Explained { certain, .. } => certain.iter().map(ToString::to_string).collect(),
            Verdict::None | Verdict::Unexplained { .. } => Vec::new(),
        };
        info!(
            "C{}: network monitor concludes: {}",
            self.id, conclusion.verdict
        );
        self.event(
            Event::NetworkConclusion {
                conclusion: conclusion.verdict.to_string(),
                findings,
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
