//! The readable difference between the model's abstract state and an observed one, shared by
//! every check that compares them (the core-level replay, the DDS-level replay, trace
//! validation), so a reviewer reads one format everywhere.

use model::traces::{AbstractController, AbstractState};
use model::Life;
use std::fmt::Write;

/// `{1,3}`: a set of controller ids as the model's renderings show them.
pub fn id_set<'a>(ids: impl IntoIterator<Item = &'a u8>) -> String {
    let list: Vec<String> = ids.into_iter().map(u8::to_string).collect();
    format!("{{{}}}", list.join(","))
}

/// The fields of an abstract controller, named and rendered for a diff.
pub fn fields(c: &AbstractController) -> Vec<(&'static str, String)> {
    let opt = |s: Option<String>| s.unwrap_or_else(|| "-".to_string());
    vec![
        ("life", format!("{:?}", c.life).to_lowercase()),
        ("incarnation", c.incarnation.to_string()),
        ("phase", opt(c.phase.map(|p| p.name().to_string()))),
        ("role", opt(c.role.map(|r| r.name().to_lowercase()))),
        ("strength", opt(c.strength.map(|s| s.to_string()))),
        ("sees", id_set(&c.sees)),
        ("failed", id_set(&c.failed)),
        ("alarms", id_set(&c.alarms)),
        ("agreed", opt(c.agreed.clone())),
        ("vote", opt(c.vote.clone())),
    ]
}

/// Width of the field-name column of a state diff.
pub const NAME_WIDTH: usize = 13;
/// Width of the model's column of a state diff (an assignment is at most 17 characters).
pub const VALUE_WIDTH: usize = 24;

/// Expected (model) against observed, per controller; differing rows marked `>>`. `column`
/// heads the observed side's column (`core`, `processes`), `whose` opens the first line:
///
/// ```text
///   C2               model                   core
///   >> role          secondary               primary
///      strength      20                      20
/// ```
pub fn state_diff(
    column: &str,
    whose: &str,
    expected: &AbstractState,
    observed: &AbstractState,
) -> String {
    let mut out = format!("  {whose} state differs from the model's (>> marks a difference):\n");
    let mut matching = Vec::new();
    let count = expected.controllers.len().max(observed.controllers.len());
    for index in 0..count {
        let model_side = expected.controllers.get(index);
        let core_side = observed.controllers.get(index);
        if model_side == core_side {
            if let Some(c) = model_side {
                matching.push(format!("C{}", c.id));
            }
            continue;
        }
        let id = model_side.or(core_side).map_or(0, |c| c.id);
        let _ = writeln!(
            out,
            "  {:<width$}{:<VALUE_WIDTH$}{column}",
            format!("C{id}"),
            "model",
            width = 3 + NAME_WIDTH
        );
        let rows_model = model_side.map(fields).unwrap_or_default();
        let rows_core = core_side.map(fields).unwrap_or_default();
        for row in 0..rows_model.len().max(rows_core.len()) {
            let name = rows_model
                .get(row)
                .or(rows_core.get(row))
                .map_or("", |(name, _)| name);
            let model_value = rows_model.get(row).map_or("(absent)", |(_, v)| v.as_str());
            let core_value = rows_core.get(row).map_or("(absent)", |(_, v)| v.as_str());
            let mark = if model_value == core_value {
                "  "
            } else {
                ">>"
            };
            let _ = writeln!(
                out,
                "  {mark} {name:<NAME_WIDTH$}{model_value:<VALUE_WIDTH$}{core_value}"
            );
        }
    }
    if !matching.is_empty() {
        let _ = writeln!(out, "  {}: as the model says", matching.join(", "));
    }
    let owner = |o: Option<u8>| o.map_or("none".to_string(), |id| format!("C{id}"));
    let mark = if expected.actuator_owner == observed.actuator_owner {
        "  "
    } else {
        ">>"
    };
    let _ = writeln!(
        out,
        "  {mark} actuator owner: model {}, {column} {}",
        owner(expected.actuator_owner),
        owner(observed.actuator_owner)
    );
    out
}

/// `C2 up#0  steady        secondary  out=20  alarms{1}`
pub fn controller_line(c: &AbstractController) -> String {
    match c.life {
        Life::NotStarted => return format!("C{} not started", c.id),
        Life::Down => return format!("C{} down (incarnation {})", c.id, c.incarnation),
        Life::Paused => return format!("C{} paused (incarnation {})", c.id, c.incarnation),
        Life::Up => {}
    }
    let phase = c.phase.map_or("-", |p| p.name());
    let role = match (c.role, c.phase) {
        (Some(role), _) => role.name().to_lowercase(),
        (None, Some(model::Phase::Steady)) => "spare".to_string(),
        (None, _) => "no-role".to_string(),
    };
    let strength = c
        .strength
        .map_or("silent".to_string(), |s| format!("out={s}"));
    let mut line = format!(
        "C{} up#{:<2} {phase:<13} {role:<10} {strength:<7}",
        c.id, c.incarnation
    );
    if !c.failed.is_empty() {
        let _ = write!(line, " FAILED{}", id_set(&c.failed));
    }
    let _ = write!(line, " alarms{}", id_set(&c.alarms));
    line
}
