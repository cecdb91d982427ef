//! The message when no model state agrees with what the controllers reported: the
//! controller that broke every history, its closest model states field by field, and the
//! record around that boundary.

use super::compare::{differences, field_diff};
use super::search::{Dead, Search};
use super::Rejection;
use crate::record::round_of;
use model::traces::AbstractController;
use std::fmt::Write;

impl Search<'_> {
    pub(super) fn rejection(
        &mut self,
        boundary: u64,
        begin: u64,
        considered: usize,
        dead: Option<Dead>,
    ) -> Box<Rejection> {
        let period = self.timing.period_ms;
        let mut message = String::new();
        let relative = boundary.saturating_sub(begin);
        let _ = writeln!(
            message,
            "the run is not a behaviour of the model: at round boundary {boundary} \
             (t_ms = {}, round {relative} of the run) no model state agrees with what the \
             controllers reported ({considered} alternative histories were followed)",
            boundary * period
        );
        match &dead {
            Some(dead) => dead_section(&mut message, dead),
            None => {
                let _ = writeln!(
                    message,
                    "  no environment choice (join, restart, crash) of the round is allowed by \
                     the model and the record (e.g. a process printed after a later life of \
                     its id started)"
                );
            }
        }
        self.record_around(&mut message, boundary);
        Box::new(Rejection {
            round: Some(boundary),
            message,
        })
    }

    /// The recorded events around `boundary`, with their rounds relative to it.
    fn record_around(&self, message: &mut String, boundary: u64) {
        let period = self.timing.period_ms;
        let _ = writeln!(message, "  the record around it:");
        let from_ms = boundary.saturating_sub(3) * period;
        let until_ms = (boundary + 2) * period;
        for (source, event) in self.recording.events_by_time() {
            if event.t_ms >= from_ms
                && event.t_ms < until_ms
                && !matches!(event.event, rl_layer::event::Event::Leds { .. })
            {
                let number = self.numbers.number(event.id, event.incarnation);
                let _ = writeln!(
                    message,
                    "    {:>8} ms (round {:+}) {source}: {}",
                    event.t_ms,
                    round_of(event.t_ms, period) as i64 - boundary as i64,
                    crate::record::describe_event(event, number)
                );
            }
        }
    }
}

/// The controller none of whose next states agrees with its report, and its closest states.
fn dead_section(message: &mut String, dead: &Dead) {
    let _ = writeln!(
        message,
        "C{} (life #{}) reported at this boundary, against its model state before \
             the round:",
        dead.id, dead.number
    );
    let _ = writeln!(
        message,
        "    before the round: {}",
        model::render::controller_line(&dead.before)
    );
    let _ = writeln!(
        message,
        "    reported one round earlier: {}",
        crate::diff::controller_line(&dead.previous)
    );
    let _ = writeln!(
        message,
        "    reported now:               {}",
        crate::diff::controller_line(&dead.observed)
    );
    // Loss choices that end in the same abstract state are shown once.
    let mut distinct: Vec<(&AbstractController, Vec<String>)> = Vec::new();
    for (view, lost, senders) in &dead.candidates {
        let lost_from: Vec<String> = senders
            .iter()
            .enumerate()
            .filter(|(bit, _)| lost & (1 << bit) != 0)
            .map(|(_, s)| format!("C{s}"))
            .collect();
        let choice = if lost_from.is_empty() {
            "none lost".to_string()
        } else {
            format!("lost from {}", lost_from.join("+"))
        };
        match distinct.iter_mut().find(|(v, _)| *v == view) {
            Some((_, choices)) => choices.push(choice),
            None => distinct.push((view, vec![choice])),
        }
    }
    distinct.sort_by_key(|(view, _)| differences(view, &dead.observed).len());
    let _ = writeln!(
        message,
        "  the closest of the {} distinct states the round can end in for it \
             (>> marks a difference):",
        distinct.len()
    );
    for (view, choices) in distinct.iter().take(3) {
        let _ = writeln!(
            message,
            "  heartbeats to C{}: {}",
            dead.id,
            choices.join(" | ")
        );
        message.push_str(&field_diff(view, &dead.observed));
    }
}
