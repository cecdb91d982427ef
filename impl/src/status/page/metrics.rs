//! `/metrics`: every group's board and watch in the Prometheus text exposition format 0.0.4,
//! so a Prometheus server (or anything that reads that format) can scrape `rl status --serve`.
//!
//! Each metric family is written once, its `# HELP` and `# TYPE` first, then the samples of
//! every group shown, told apart by the `group` label every sample has (the format allows one
//! TYPE line per family, so groups cannot be rendered one after the other). Label values are
//! escaped as the format asks (backslash, double quote, newline). A family with no sample is
//! still described, so a dashboard sees it exists.

use super::Watch;
use crate::status::StatusView;
use rl_layer::core::types::Role;
use serde::Serialize;
use std::fmt::Write;

/// The content type of the 0.0.4 text format.
pub const CONTENT_TYPE: &str = "text/plain; version=0.0.4; charset=utf-8";

/// One metric family's samples of one group being written.
struct Family<'a> {
    out: &'a mut String,
    name: &'static str,
    /// The redundancy group, a label of every sample ("" for the group without a name).
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

/// A metric family: its name, type and help, and how it samples one group.
struct FamilySpec {
    name: &'static str,
    kind: &'static str,
    help: &'static str,
    samples: fn(&mut Family<'_>, &StatusView, &Watch),
}

/// Every family, in the order written.
const FAMILIES: &[FamilySpec] = &[
    FamilySpec {
        name: "rl_alive",
        kind: "gauge",
        help: "1 when the controller was heard within the dead-man deadline.",
        samples: alive,
    },
    FamilySpec {
        name: "rl_role",
        kind: "gauge",
        help:
            "1 for the role a live controller last announced (primary, secondary, tertiary, none).",
        samples: role,
    },
    FamilySpec {
        name: "rl_strength",
        kind: "gauge",
        help: "The ownership strength a live controller commands with (0: it does not command).",
        samples: strength,
    },
    FamilySpec {
        name: "rl_phase",
        kind: "gauge",
        help: "1 for the phase the controller last announced.",
        samples: phase,
    },
    FamilySpec {
        name: "rl_last_heard_ms",
        kind: "gauge",
        help: "Milliseconds since the controller's last heartbeat.",
        samples: last_heard,
    },
    FamilySpec {
        name: "rl_heartbeats_seen_total",
        kind: "counter",
        help: "Heartbeats the status process took in from the controller.",
        samples: heartbeats_seen,
    },
    FamilySpec {
        name: "rl_controller_alarm",
        kind: "gauge",
        help: "1 per raised controller alarm: about which controller, why, and how many raised it.",
        samples: controller_alarm,
    },
    FamilySpec {
        name: "rl_controller_alarm_reporters",
        kind: "gauge",
        help: "How many controllers raise the alarm.",
        samples: controller_alarm_reporters,
    },
    FamilySpec {
        name: "rl_network_alarm",
        kind: "gauge",
        help: "1 per raised network alarm: a whole network (controller=\"\") or one controller's \
               transceiver on it.",
        samples: network_alarm,
    },
    FamilySpec {
        name: "rl_commander",
        kind: "gauge",
        help: "The id of the strongest live commanding controller, the actuator's owner (0: none).",
        samples: commander,
    },
    FamilySpec {
        name: "rl_commander_changes_total",
        kind: "counter",
        help: "Changes of the commanding controller seen since the status process started.",
        samples: commander_changes,
    },
    FamilySpec {
        name: "rl_commander_last_gap_ms",
        kind: "gauge",
        help: "At the last commander change: milliseconds from the previous commander's last \
               heartbeat to the change (absent before the first change).",
        samples: commander_last_gap,
    },
];

/// The exposition of every group shown: each `(view, watch)` is one group's.
pub fn render(groups: &[(&StatusView, &Watch)]) -> String {
    let mut out = String::new();
    for spec in FAMILIES {
        let _ = writeln!(out, "# HELP {} {}", spec.name, spec.help);
        let _ = writeln!(out, "# TYPE {} {}", spec.name, spec.kind);
        for (view, watch) in groups {
            let mut family = Family {
                out: &mut out,
                name: spec.name,
                group: &view.group,
            };
            (spec.samples)(&mut family, view, watch);
        }
    }
    out
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

fn id(id: u8) -> (&'static str, String) {
    ("controller", id.to_string())
}

fn alive(f: &mut Family<'_>, view: &StatusView, _: &Watch) {
    for c in &view.controllers {
        f.sample(&[id(c.report.id)], flag(c.alive));
    }
}

fn role(f: &mut Family<'_>, view: &StatusView, _: &Watch) {
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
}

fn strength(f: &mut Family<'_>, view: &StatusView, _: &Watch) {
    for c in view.controllers.iter().filter(|c| c.alive) {
        f.sample(&[id(c.report.id)], c.report.strength.unwrap_or_default());
    }
}

fn phase(f: &mut Family<'_>, view: &StatusView, _: &Watch) {
    for c in &view.controllers {
        f.sample(
            &[id(c.report.id), ("phase", c.report.phase.name().into())],
            1,
        );
    }
}

fn last_heard(f: &mut Family<'_>, view: &StatusView, _: &Watch) {
    for c in &view.controllers {
        f.sample(&[id(c.report.id)], c.last_heard_ms);
    }
}

fn heartbeats_seen(f: &mut Family<'_>, _: &StatusView, watch: &Watch) {
    for (controller, count) in watch.heartbeats_seen() {
        f.sample(&[id(*controller)], count);
    }
}

fn controller_alarm(f: &mut Family<'_>, view: &StatusView, _: &Watch) {
    for a in &view.alarms {
        let labels = [
            ("about", a.about.to_string()),
            ("reason", label_of(&a.reason)),
        ];
        f.sample(&labels, 1);
    }
}

fn controller_alarm_reporters(f: &mut Family<'_>, view: &StatusView, _: &Watch) {
    for a in &view.alarms {
        let labels = [
            ("about", a.about.to_string()),
            ("reason", label_of(&a.reason)),
        ];
        f.sample(&labels, a.raised_by.len());
    }
}

fn network_alarm(f: &mut Family<'_>, view: &StatusView, _: &Watch) {
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
}

fn commander(f: &mut Family<'_>, _: &StatusView, watch: &Watch) {
    f.sample(&[], watch.commander().map_or(0, |c| c.id));
}

fn commander_changes(f: &mut Family<'_>, _: &StatusView, watch: &Watch) {
    f.sample(&[], watch.commander_changes());
}

fn commander_last_gap(f: &mut Family<'_>, _: &StatusView, watch: &Watch) {
    if let Some(gap) = watch.last_gap_ms() {
        f.sample(&[], gap);
    }
}
