//! Many runs and their table: `matrix` runs every named scenario and a few random seeds,
//! `matrix --ci` the short subset CI runs (under about five minutes on two cores). The table
//! (Markdown, as docs/faults.md shows it) goes to stdout and `DIR/matrix.md`
//! (`DIR/matrix-duplex.md`, `DIR/matrix-pair.md` under `--architecture`, which leaves out the
//! scenarios that architecture does not run and says which).

use super::architecture::{self, Architecture};
use super::error::LabError;
use super::run::{self, Outcome};
use super::scenario::{self, Scenario};
use super::session::Setup;
use super::validation::NotAccepted;
use std::path::Path;

/// The random seeds a full matrix runs, and the one CI runs (a pause of the Primary and a
/// kill of the Secondary: random machinery, safety and liveness phases, with no split whose
/// owner changes vary from run to run).
pub const FULL_SEEDS: [u64; 5] = [1, 2, 3, 7, 8];
pub const CI_SEEDS: [u64; 1] = [7];

/// The scenarios of a matrix, with their seeds.
pub fn plan(ci: bool, architecture: Architecture) -> Vec<(Scenario, u64)> {
    let named = scenario::named()
        .into_iter()
        .filter(|s| !ci || s.in_ci)
        .filter_map(|s| s.under(architecture).ok())
        .map(|s| (s, 1));
    let seeds: &[u64] = if ci { &CI_SEEDS } else { &FULL_SEEDS };
    named
        .chain(seeds.iter().map(|seed| (scenario::random(*seed), *seed)))
        .collect()
}

/// Runs the matrix; a run that cannot be carried out is an error, a failing one is a row.
pub fn run_matrix(ci: bool, setup: &Setup, out: &Path) -> Result<Vec<Outcome>, LabError> {
    let mut outcomes = Vec::new();
    for s in scenario::named().into_iter().filter(|s| !ci || s.in_ci) {
        if let Err(why) = s.under(setup.architecture) {
            eprintln!(
                "lab: {} is not run under the {}: {why}",
                s.name,
                architecture::name(setup.architecture)
            );
        }
    }
    for (scenario, seed) in plan(ci, setup.architecture) {
        let outcome = run::run(&scenario, seed, setup, out)?;
        eprint!("{}", run::summary(&outcome));
        outcomes.push(outcome);
    }
    let table = table(&outcomes);
    let path = match setup.architecture {
        Architecture::Voting => out.join("matrix.md"),
        other => out.join(format!("matrix-{}.md", architecture::name(other))),
    };
    std::fs::write(&path, &table).map_err(|e| LabError::output(&path, e))?;
    print!("{table}");
    Ok(outcomes)
}

/// The Markdown table of `outcomes`.
pub fn table(outcomes: &[Outcome]) -> String {
    let mut text = String::from(
        "| scenario | faults | owner changes (servo/Connext) | largest gap (servo/Connext) | two at top strength | rounds to settle | model | verdict | command |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    for o in outcomes {
        let m = &o.metrics;
        let changes: Vec<String> = m
            .changes_per_fault
            .iter()
            .map(|c| {
                format!(
                    "{}/{}",
                    c.servo,
                    c.connext.map_or("-".into(), |n| n.to_string())
                )
            })
            .collect();
        let gap = |g: Option<(f64, f64)>| g.map_or("-".into(), |(ms, _)| format!("{ms:.0}"));
        // A `|` would end the cell.
        let faults: Vec<String> = o
            .faults
            .iter()
            .map(|f| f.label.replace('|', "\\|"))
            .collect();
        let architecture = match o.architecture {
            "voting" => String::new(),
            other => format!(" --architecture {other}"),
        };
        text.push_str(&format!(
            "| {} | {} | {} | {}/{} ms | {:.0} ms | {} | {} | {} | `lab run {} --seed {}{architecture}` |\n",
            o.scenario,
            faults.join("; "),
            changes.join(", "),
            gap(m.servo_gap),
            gap(m.connext_gap),
            m.two_at_top_ms,
            m.settle_rounds.map_or("never".into(), |r| r.to_string()),
            match &o.validation {
                Ok(_) => "accepted",
                Err(NotAccepted::NotVoting(_)) => "-",
                Err(_) => "rejected",
            },
            if o.passed() { "pass" } else { "FAIL" },
            o.scenario,
            o.seed
        ));
    }
    text
}
