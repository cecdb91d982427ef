//! What the voting loop shows of its status: the console line, the LEDs, the JSON event
//! lines, the ROS 2 status topic and the status the application reads. Apart from the
//! loop, which decides, so each stays short.

use super::{Leds, Voting};
use crate::core::{AlarmReason, Status};
use crate::cross_check::OddOn;
use crate::event::{Event, EventLine};
use crate::leds::{LedBank, LedPattern};
use std::io::Write;
use tracing::{info, warn};

impl Voting {
    /// What a person sees follows the status: the status event and console line when it
    /// changed, the LEDs when their pattern did.
    pub(super) fn show(&mut self, status: Status) {
        let leds = crate::leds::pattern_of(&status);
        if leds != self.shown_leds {
            self.shown_leds = leds;
            self.show_leds(leds);
        }
        if status == self.shown_status {
            return;
        }
        if status.duplicate_id_heartbeats > self.shown_status.duplicate_id_heartbeats {
            warn!(
                "another controller is using id {} (its heartbeats are ignored; check --id)",
                status.report.id
            );
        }
        self.console(&crate::console::console_line(&status));
        self.status(status.clone());
        self.shown_status = status;
    }

    pub(super) fn show_leds(&mut self, pattern: LedPattern) {
        let shown = match &mut self.leds {
            Leds::Gpio(bank) => Some(bank.show(pattern)),
            Leds::Console(console) if self.options.console_leds && !self.options.json_events => {
                Some(console.show(pattern))
            }
            Leds::Console(_) => None,
        };
        if let Some(Err(error)) = shown {
            warn!("LEDs: {error}");
        }
        self.event(Event::Leds {
            leds: pattern.to_string(),
        });
    }

    /// A line for the operator: on stdout, or in the log when stdout carries JSON events.
    pub(super) fn console(&self, line: &str) {
        if self.options.json_events {
            info!("{line}");
        } else {
            println!("{line}");
        }
    }

    pub(super) fn publish_ros_status(&self, status: &Status) {
        if let Some(ros) = &self.endpoints.ros_status {
            if let Ok(text) = serde_json::to_string(status) {
                if let Err(error) = ros.publish(&text) {
                    warn!("ROS 2 status not published: {error}");
                }
            }
        }
    }

    pub(super) fn status(&mut self, status: Status) {
        self.publish_ros_status(&status);
        self.event(Event::Status {
            status: Box::new(status.clone()),
        });
        *self.shared.status() = status;
    }

    /// The voting loop fell behind (starved, stalled): its round end stood for `rounds` more.
    pub(super) fn fell_behind(&self, rounds: u64) {
        warn!("the voting loop fell behind: one round end for {rounds} more missed");
        self.event(Event::RoundEndsMissed { rounds });
    }

    /// One JSON event line on stdout (with `--json-events`): the record of what it did.
    /// The same line goes to the application's subscriptions (crate::api::Redundancy::events).
    pub(super) fn event(&self, event: Event) {
        let mut subscribers = self.shared.subscribers();
        if !self.options.json_events && subscribers.is_empty() {
            return;
        }
        let line = EventLine {
            t_ms: self.events_at_ms.unwrap_or_else(|| self.clock.now_ms()),
            id: self.core.config().id,
            incarnation: self.core.config().incarnation,
            event,
        };
        subscribers.retain(|subscriber| subscriber.send(line.clone()).is_ok());
        drop(subscribers);
        if self.options.json_events {
            let mut out = std::io::stdout().lock();
            let _ = writeln!(out, "{}", line.to_json());
            let _ = out.flush();
        }
    }

    /// Why the application's fault was reported, when its cross-check found it the odd one
    /// out of three: in the log and as an `odd_one_out` event line, before it fails.
    pub(super) fn report_odd_one_out(&mut self) {
        let reason = self
            .shared
            .odd_one_out
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .take();
        if let Some(reason) = reason {
            let id = self.core.config().id;
            warn!("C{id} leaves: {reason}");
            // Its input or its law, not its output, is wrong: named so before it leaves,
            // as the FAILED its peers alarm says only that it failed.
            match reason.on {
                OddOn::Input => self.alarm(id, AlarmReason::InputDisagrees, true),
                OddOn::Law => self.alarm(id, AlarmReason::LawDisagrees, true),
                OddOn::Output => {}
            }
            self.event(Event::OddOneOut {
                on: reason.on,
                inputs: reason.inputs,
                odd_limit: reason.odd_limit,
                peers: reason.peers,
                late: reason.late,
            });
        }
    }
}
