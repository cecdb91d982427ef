//! A `two-groups` run's verdict and output (`super`): each group judged as a one-group run is
//! (`crate::lab::judge` with `kill-primary`'s bounds, the model, `crate::lab::network_alarms`)
//! and against the other group (`crate::lab::cross_talk`), its output written as a one-group
//! run's in its own directory, and the run's summary.

use super::{about, Group, TwoGroups, GROUPS, KILLED, NAME, SUCCESSOR};
use crate::lab::cross_talk::{self, CrossTalkReport, Failover, GroupLines};
use crate::lab::error::LabError;
use crate::lab::expect::Expected;
use crate::lab::judge::{self, FaultRecord, Metrics};
use crate::lab::network_alarms::{self, NapExpected, Recorded};
use crate::lab::procs::Life;
use crate::lab::run::{self, Outcome};
use crate::lab::session::Setup;
use crate::lab::{plot, validation};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// A two-groups run's measurements and verdict: each group's as a one-group run's (its
/// owner changes, gaps, model, network alarms; cross-talk failures among its failures), and
/// each group's cross-talk report.
#[derive(Clone, Debug, Serialize)]
pub struct TwoGroupsOutcome {
    pub scenario: String,
    pub about: String,
    pub seed: u64,
    pub mutation: Option<String>,
    /// Each group's configuration, as its controllers and servo read it.
    pub configs: Vec<String>,
    pub groups: Vec<Outcome>,
    pub cross_talk: Vec<CrossTalkReport>,
    pub dir: PathBuf,
    /// The command that runs this again.
    pub replay: String,
}

impl TwoGroupsOutcome {
    pub fn passed(&self) -> bool {
        self.groups.iter().all(Outcome::passed)
    }
}

/// What every group is judged against, and where the run leaves its output.
pub(super) struct Judging<'a> {
    pub expected: Expected,
    pub network: NapExpected,
    pub setup: &'a Setup,
    pub seed: u64,
    /// The run's output name (`two-groups-seed1`).
    pub name: String,
    pub out: &'a Path,
    pub end_ms: f64,
    /// The controllers ran network monitors.
    pub monitored: bool,
}

/// Each group's verdict, the run's outcome, and `result.json` in the run's directory.
pub(super) fn judge(
    lab: &TwoGroups,
    lives: &[Vec<Life>],
    dead: Vec<Vec<String>>,
    judging: &Judging,
) -> Result<TwoGroupsOutcome, LabError> {
    let (seed, setup) = (judging.seed, judging.setup);
    let dir = judging.out.join(&judging.name);
    let mut groups = Vec::new();
    let mut cross_talk = Vec::new();
    for (i, dead) in dead.into_iter().enumerate() {
        let (outcome, report) = judge_group(lab, lives, i, dead, judging)?;
        groups.push(outcome);
        cross_talk.push(report);
    }
    let outcome = TwoGroupsOutcome {
        scenario: NAME.to_string(),
        about: about(),
        seed,
        mutation: setup.mutation.clone(),
        configs: GROUPS.iter().map(Group::config).collect(),
        groups,
        cross_talk,
        dir: dir.clone(),
        replay: run::replay_command(NAME, seed, setup),
    };
    let path = dir.join("result.json");
    let json = serde_json::to_string_pretty(&outcome).unwrap_or_default();
    std::fs::write(&path, json).map_err(|e| LabError::output(&path, e))?;
    Ok(outcome)
}

/// Group `i`'s verdict: as a one-group run's, with its cross-talk judges' failures; writes its
/// output and picture.
fn judge_group(
    lab: &TwoGroups,
    lives: &[Vec<Life>],
    i: usize,
    dead: Vec<String>,
    judging: &Judging,
) -> Result<(Outcome, CrossTalkReport), LabError> {
    let group = &lab.groups[i];
    let name = group.group.name;
    let faults: Vec<FaultRecord> = group.kill.iter().cloned().collect();
    let (observed, own_lives) = (&group.observed, &lives[i]);
    let mut metrics = judge::measure(
        observed,
        own_lives,
        &faults,
        lab.judged_from_ms,
        judging.end_ms,
        super::super::architecture::Architecture::Voting,
        judging.setup.connext,
    );
    metrics.dead = dead;
    let dir = judging.out.join(&judging.name).join(name);
    let events = dir.join("events");
    validation::write_recording(&events, observed, own_lives)?;
    let validation = run::validate_with_timeout(events);
    let mut failures =
        judge::failures(&metrics, &judging.expected, validation.as_ref().map(|_| ()));
    let recorded = Recorded {
        network: &observed.network,
        controller: &observed.controller,
        lives: own_lives,
        faults: &faults,
        judged_from_ms: lab.judged_from_ms,
    };
    let network = network_alarms::judge(&recorded, &judging.network, judging.monitored);
    failures.extend(network.failures.iter().cloned());
    let report = cross_talk_of(lab, lives, i, &metrics, judging.monitored);
    failures.extend(report.failures.iter().cloned());
    let picture = judging.out.join(format!("{}-{name}.svg", judging.name));
    let outcome = Outcome {
        scenario: format!("{NAME}, group {name}"),
        about: about(),
        seed: judging.seed,
        architecture: "voting",
        mutation: judging.setup.mutation.clone(),
        faults,
        metrics,
        validation,
        network: Some(network),
        network_alarm_changes: network_alarms::changes(&observed.network),
        output: None,
        failures,
        dir: dir.clone(),
        picture: picture.clone(),
        replay: run::replay_command(NAME, judging.seed, judging.setup),
    };
    plot::draw(&picture, &outcome, observed, own_lives, judging.end_ms)?;
    run::write_outputs(&dir, &outcome, observed)?;
    Ok((outcome, report))
}

/// Group `i`'s cross-talk judges (`super::cross_talk`), against the other group.
fn cross_talk_of(
    lab: &TwoGroups,
    lives: &[Vec<Life>],
    i: usize,
    metrics: &Metrics,
    monitored: bool,
) -> CrossTalkReport {
    let (group, other) = (&lab.groups[i], (i + 1) % lab.groups.len());
    let name = group.group.name;
    let Some(kill) = group.kill.as_ref() else {
        return CrossTalkReport {
            group: name.to_string(),
            failures: vec![format!("{name}: its C{KILLED} was never killed")],
            ..CrossTalkReport::default()
        };
    };
    let own = GroupLines {
        name,
        observed: &group.observed,
        lives: &lives[i],
    };
    let theirs = &lab.groups[other];
    let them = GroupLines {
        name: theirs.group.name,
        observed: &theirs.observed,
        lives: &lives[other],
    };
    let failover = Failover {
        kill,
        killed: KILLED,
        successor: SUCCESSOR,
    };
    cross_talk::judge(&own, &them, &failover, metrics, monitored)
}

/// The run's summary: each group's as a one-group run's, its cross-talk figures, the verdict.
pub fn summary(outcome: &TwoGroupsOutcome) -> String {
    let verdict = |passed: bool| if passed { "PASS" } else { "FAIL" };
    let groups: Vec<String> = outcome
        .groups
        .iter()
        .zip(&outcome.cross_talk)
        .map(|(o, c)| format!("{} {}", c.group, verdict(o.passed())))
        .collect();
    let mut text = format!(
        "{} (seed {}): {} ({})\n",
        outcome.scenario,
        outcome.seed,
        verdict(outcome.passed()),
        groups.join(", ")
    );
    for (group, report) in outcome.groups.iter().zip(&outcome.cross_talk) {
        text.push_str(&run::summary(group));
        text.push_str(&cross_talk_summary(report, group.faults.first()));
    }
    text
}

/// One group's cross-talk figures.
fn cross_talk_summary(report: &CrossTalkReport, kill: Option<&FaultRecord>) -> String {
    let readers: Vec<String> = report
        .readers
        .iter()
        .map(|r| format!("{} {} of {}", r.reader, r.own, r.samples))
        .collect();
    let mut text = format!(
        "  {}'s readers, samples from its own controllers: {}\n  its servo identified: {}\n  \
         controller incarnations its controllers named: {}\n",
        report.group,
        readers.join(", "),
        report.participants.join(", "),
        report.holders_named
    );
    let since_kill = |at: Option<f64>| match (at, kill) {
        (Some(at), Some(kill)) => format!("{:.0} ms", at - kill.applied_ms),
        _ => "never".into(),
    };
    for span in &report.monitor {
        text.push_str(&format!(
            "  {}'s monitor: C{KILLED} down from {} to {} after the kill (its C{KILLED} restarted after {})\n",
            span.observer,
            since_kill(span.down_from_ms),
            since_kill(span.down_until_ms),
            since_kill(kill.and_then(|k| k.healed_ms)),
        ));
    }
    text
}
