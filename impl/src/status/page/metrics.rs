//! `/metrics`: the board and the watch in the Prometheus text exposition format 0.0.4, so a
//! Prometheus server (or anything that reads that format) can scrape `rl status --serve`.
//!
//! Every family has its `# HELP` and `# TYPE`; label values are escaped as the format asks
//! (backslash, double quote, newline). A family with no sample is still described, so a
//! dashboard sees it exists.

use super::Watch;
use crate::status::StatusView;
use rl_layer::core::types::Role;
use serde::Serialize;
use std::fmt::Write;

/// The content type of the 0.0.4 text format.
pub const CONTENT_TYPE: &str = "text/plain; version=0.0.4; charset=utf-8";

/// One metric family being written.
struct Family<'a> {
    out: &'a mut String,
    name: &'static str,
    /// The redundancy group, a label of every sample (several `rl status --serve` of several
    /// groups scrape into one Prometheus).
    group: &'a str,
}

impl Family<'_> {
    fn sample(&mut self, labels: &[(&str, String)], value: impl std::fmt::Display) {
        let _ = write!(self.out, "{}", self.name);
        let pairs: Vec<String> = std::iter::once(("group", self.group.to_string()))
            .chain(labels.iter().cloned())
            .map(|(k, v)| format!("{k}=\"{}\"", escape_label(&v)))
            .collect();
        let _ = write!(self.out, "{{{}}}", pairs.join(","));
        let _ = writeln!(self.out, " {value}");
    }
}

fn family<'a>(
    out: &'a mut String,
    group: &'a str,
    name: &'static str,
    kind: &str,
    help: &str,
) -> Family<'a> {
    let _ = writeln!(out, "# HELP {name} {help}");
    let _ = writeln!(out, "# TYPE {name} {kind}");
    Family { out, name, group }
}

/// A label value escaped for the text format.
fn escape_label(value: &str) -> String {
    value
        .replace('\\', "\\\\")
        .replace('"', "\\\"")
        .replace('\n', "\\n")
}

/// How a value serializes (`"Lost"`, `"A"`) as a label value.
fn label_of(value: &impl Serialize) -> String {
    match serde_json::to_value(value) {
        Ok(serde_json::Value::String(s)) => s,
        Ok(other) => other.to_string(),
        Err(_) => "?".into(),
    }
}

fn flag(on: bool) -> u8 {
    u8::from(on)
}

/// The exposition of `view` and `watch`.
pub fn render(view: &StatusView, watch: &Watch) -> String {
    let mut out = String::new();
    let id = |id: u8| ("controller", id.to_string());

    let mut f = family(
        &mut out,
        &view.group,
        "rl_alive",
        "gauge",
        "1 when the controller was heard within the dead-man deadline.",
    );
    for c in &view.controllers {
        f.sample(&[id(c.report.id)], flag(c.alive));
    }
    let mut f = family(
        &mut out,
        &view.group,
        "rl_role",
        "gauge",
        "1 for the role a live controller last announced (primary, secondary, tertiary, none).",
    );
    // A controller not heard for the dead-man deadline holds no role and commands nothing as
    // far as anyone can tell: its last announcement is not exported beside the live ones.
    for c in view.controllers.iter().filter(|c| c.alive) {
        for role in Role::ALL {
            let held = c.report.role == Some(role);
            f.sample(&[id(c.report.id), ("role", role.name().into())], flag(held));
        }
        f.sample(
            &[id(c.report.id), ("role", "none".into())],
            flag(c.report.role.is_none()),
        );
    }
    let mut f = family(
        &mut out,
        &view.group,
        "rl_strength",
        "gauge",
        "The ownership strength a live controller commands with (0: it does not command).",
    );
    for c in view.controllers.iter().filter(|c| c.alive) {
        f.sample(&[id(c.report.id)], c.report.strength.unwrap_or_default());
    }
    let mut f = family(
        &mut out,
        &view.group,
        "rl_phase",
        "gauge",
        "1 for the phase the controller last announced.",
    );
    for c in &view.controllers {
        f.sample(
            &[id(c.report.id), ("phase", c.report.phase.name().into())],
            1,
        );
    }
    let mut f = family(
        &mut out,
        &view.group,
        "rl_last_heard_ms",
        "gauge",
        "Milliseconds since the controller's last heartbeat.",
    );
    for c in &view.controllers {
        f.sample(&[id(c.report.id)], c.last_heard_ms);
    }
    let mut f = family(
        &mut out,
        &view.group,
        "rl_heartbeats_seen_total",
        "counter",
        "Heartbeats the status process took in from the controller.",
    );
    for (controller, count) in watch.heartbeats_seen() {
        f.sample(&[id(*controller)], count);
    }
    let mut f = family(
        &mut out,
        &view.group,
        "rl_controller_alarm",
        "gauge",
        "1 per raised controller alarm: about which controller, why, and how many raised it.",
    );
    for a in &view.alarms {
        f.sample(
            &[
                ("about", a.about.to_string()),
                ("reason", label_of(&a.reason)),
            ],
            1,
        );
    }
    let mut f = family(
        &mut out,
        &view.group,
        "rl_controller_alarm_reporters",
        "gauge",
        "How many controllers raise the alarm.",
    );
    for a in &view.alarms {
        f.sample(
            &[
                ("about", a.about.to_string()),
                ("reason", label_of(&a.reason)),
            ],
            a.raised_by.len(),
        );
    }
    let mut f = family(
        &mut out,
        &view.group,
        "rl_network_alarm",
        "gauge",
        "1 per raised network alarm: a whole network (controller=\"\") or one controller's \
         transceiver on it.",
    );
    for a in &view.network_alarms {
        let controller = a.controller.map_or(String::new(), |c| c.to_string());
        f.sample(
            &[
                ("network", label_of(&a.network)),
                ("controller", controller),
                ("certainty", a.certainty.name().into()),
            ],
            1,
        );
    }
    let mut f = family(
        &mut out,
        &view.group,
        "rl_commander",
        "gauge",
        "The id of the strongest live commanding controller, the actuator's owner (0: none).",
    );
    f.sample(&[], watch.commander().map_or(0, |c| c.id));
    let mut f = family(
        &mut out,
        &view.group,
        "rl_commander_changes_total",
        "counter",
        "Changes of the commanding controller seen since the status process started.",
    );
    f.sample(&[], watch.commander_changes());
    let mut f = family(
        &mut out,
        &view.group,
        "rl_commander_last_gap_ms",
        "gauge",
        "At the last commander change: milliseconds from the previous commander's last \
         heartbeat to the change (absent before the first change).",
    );
    if let Some(gap) = watch.last_gap_ms() {
        f.sample(&[], gap);
    }
    out
}
