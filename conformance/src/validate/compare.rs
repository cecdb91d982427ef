//! A model state against a controller's report: which fields differ, and the rows a reader
//! sees.

use crate::diff::{fields, NAME_WIDTH, VALUE_WIDTH};
use model::traces::AbstractController;
use model::{Controller, State};
use std::fmt::Write;

/// The model's abstract view of one controller (`model::traces::abstract_state`).
pub(super) fn abstract_one(reps: &State, c: &Controller) -> AbstractController {
    let index = usize::from(c.id) - 1;
    let mut state = reps.clone();
    state.controllers[index] = c.clone();
    model::traces::abstract_state(&state)
        .controllers
        .swap_remove(index)
}

/// The fields in which a model state disagrees with a report. `sees` and `failed` may both
/// lack peers the report has as seen and FAILED (lost since, without a report).
pub fn differences(model: &AbstractController, observed: &AbstractController) -> Vec<&'static str> {
    let mut out = Vec::new();
    let exact = [
        ("life", model.life == observed.life),
        ("incarnation", model.incarnation == observed.incarnation),
        ("phase", model.phase == observed.phase),
        ("role", model.role == observed.role),
        ("strength", model.strength == observed.strength),
        ("alarms", model.alarms == observed.alarms),
        ("agreed", model.agreed == observed.agreed),
        ("vote", model.vote == observed.vote),
    ];
    out.extend(
        exact
            .iter()
            .filter(|(_, same)| !same)
            .map(|(name, _)| *name),
    );
    let dropped: Vec<u8> = observed
        .sees
        .iter()
        .copied()
        .filter(|id| !model.sees.contains(id))
        .collect();
    let sees_ok = model.sees.iter().all(|id| observed.sees.contains(id))
        && dropped.iter().all(|id| observed.failed.contains(id));
    let failed_expected: Vec<u8> = observed
        .failed
        .iter()
        .copied()
        .filter(|id| !dropped.contains(id))
        .collect();
    if !sees_ok {
        out.push("sees");
    }
    if model.failed != failed_expected {
        out.push("failed");
    }
    out
}

/// Model against report, one row per field, `>>` where they differ.
pub(super) fn field_diff(model: &AbstractController, observed: &AbstractController) -> String {
    let differing = differences(model, observed);
    let mut out = format!(
        "      {:<NAME_WIDTH$}{:<VALUE_WIDTH$}reported\n",
        "", "model"
    );
    for ((name, model_value), (_, observed_value)) in
        fields(model).into_iter().zip(fields(observed))
    {
        let mark = if differing.contains(&name) {
            ">>"
        } else {
            "  "
        };
        let _ = writeln!(
            out,
            "   {mark} {name:<NAME_WIDTH$}{model_value:<VALUE_WIDTH$}{observed_value}"
        );
    }
    out
}
