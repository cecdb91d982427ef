//! One run of a scenario, start to verdict: a session on its own LAN, the safety phase (the
//! schedule's faults), the liveness phase (no faults: it must settle), the judges, and the
//! run's output: `DIR/NAME-seedN/` with `result.json` (measurements, verdict, the replay
//! command), `timeline.txt`, `stderr.log` and `events/` (the recording trace validation
//! reads), and the picture `DIR/NAME-seedN.svg` beside it. A run against a deliberately
//! broken `rl` (`--mutation M`, `super::mutation`) is `NAME-seedN-mutation-M` (with the voting
//! reader's rule broken, `--vote-mutation M`: `NAME-seedN-mutation-vote-M`), and says so in its
//! result and summary. A wrong-output run (`super::wrong_output`) is judged at the voting
//! reader too, and draws its tracking error to `DIR/NAME-seedN-tracking.svg`.

use super::architecture::{self, Architecture};
use super::error::LabError;
use super::expect::SETTLE_ROUNDS;
use super::judge::{self, FaultRecord, Metrics};
use super::network_alarms::{self, NapReport, Recorded};
use super::plot;
use super::scenario::Scenario;
use super::session::{Session, Setup};
use super::validation::{self, Verdict};
use super::wrong_output::{self, OutputReport};
use rl_layer::wire::Certainty;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The fault-free phase after the last heal: the model's bound and room for DDS discovery
/// of a restarted controller.
pub const LIVENESS: Duration = Duration::from_secs(10);
/// Trace validation of a long or lossy run can search for a while; past this it is reported
/// as not finished (a failure when the scenario expects the model to accept).
const VALIDATION_TIMEOUT: Duration = Duration::from_secs(180);

/// What a run measured and decided.
#[derive(Clone, Debug, Serialize)]
pub struct Outcome {
    pub scenario: String,
    pub about: String,
    pub seed: u64,
    /// The architecture the controllers ran (`super::architecture`).
    pub architecture: &'static str,
    /// The deliberately broken rule the controllers ran (`--mutation`), or `vote-NAME` for the
    /// voting reader's (`--vote-mutation`); `None`: RL's rules.
    pub mutation: Option<String>,
    pub faults: Vec<FaultRecord>,
    pub metrics: Metrics,
    #[serde(serialize_with = "validation::serialize_verdict")]
    pub validation: Verdict,
    /// The network alarm judge's measurements and verdict (net scenarios only).
    pub network: Option<NapReport>,
    /// Every network alarm raised or cleared, in any scenario (`network_alarms::changes`).
    pub network_alarm_changes: Vec<String>,
    /// The wrong-output judges' measurements and verdict (wrong-output scenarios only).
    pub output: Option<OutputReport>,
    /// Every expectation missed; empty: the run passed.
    pub failures: Vec<String>,
    pub dir: PathBuf,
    pub picture: PathBuf,
    /// The command that runs this again.
    pub replay: String,
}

impl Outcome {
    pub fn passed(&self) -> bool {
        self.failures.is_empty()
    }
}

/// The command that replays scenario `name` with `seed` (and `setup`'s mutation, with its
/// `rl`, which must be a `mutation` build).
pub fn replay_command(name: &str, seed: u64, setup: &Setup) -> String {
    let architecture = match setup.architecture {
        Architecture::Voting => String::new(),
        other => format!(" --architecture {}", architecture::name(other)),
    };
    let command = format!(
        "cargo run --release -p conformance --bin lab -- run {name} --seed {seed}{architecture}"
    );
    match (&setup.mutation, &setup.vote_mutation) {
        (Some(mutation), _) => format!(
            "{command} --rl {} --mutation {mutation}",
            setup.rl.display()
        ),
        (None, Some(mutation)) => format!(
            "{command} --rl {} --vote-mutation {mutation}",
            setup.rl.display()
        ),
        (None, None) => command,
    }
}

/// `NAME-seedN`, or `NAME-seedN-mutation-M`: the name of a run's output.
pub fn output_name(name: &str, seed: u64, mutation: Option<&str>) -> String {
    match mutation {
        Some(mutation) => format!("{name}-seed{seed}-mutation-{mutation}"),
        None => format!("{name}-seed{seed}"),
    }
}

/// [`output_name`] of a run under `architecture`: `NAME-seedN-duplex`, `NAME-seedN-pair`
/// (voting's has no suffix).
fn output_name_in(
    architecture: Architecture,
    name: &str,
    seed: u64,
    mutation: Option<&str>,
) -> String {
    let base = output_name(name, seed, mutation);
    match architecture {
        Architecture::Voting => base,
        other => format!("{base}-{}", architecture::name(other)),
    }
}

/// Runs `scenario` (seed `seed`) and writes its output under `out`.
pub fn run(scenario: &Scenario, seed: u64, setup: &Setup, out: &Path) -> Result<Outcome, LabError> {
    let scenario = &under(scenario, setup.architecture)?;
    let expected = scenario.expected_in(setup.architecture)?;
    let setup = &scenario.session_setup(setup);
    let mut session = start(scenario, seed, setup)?;
    session.play(&scenario.steps)?;
    session.pump(LIVENESS)?;
    let dead = session.dead();
    let end_ms = session.clock.now_ms();
    let lives = session.procs.lives.clone();
    let injections = session.procs.injections.clone();
    session.stop()?;
    wrong_output::require_acknowledged(&injections, &session.observed.stderr, &setup.rl)?;
    super::mutation::require_vote_mutation_announced(
        setup.vote_mutation.as_deref(),
        &setup.rl,
        &session.observed.stderr,
    )?;
    let mut metrics = judge::measure(
        &session.observed,
        &lives,
        &session.faults,
        session.judged_from_ms,
        end_ms,
        setup.architecture,
        setup.connext,
    );
    metrics.dead = dead;
    let name = output_name_in(
        setup.architecture,
        &scenario.name,
        seed,
        setup.mutation_label().as_deref(),
    );
    let dir = out.join(&name);
    let _ = std::fs::remove_dir_all(&dir);
    let events = dir.join("events");
    validation::write_recording(&events, &session.observed, &lives)?;
    let validation = validate_in(setup.architecture, events);
    // A recording the trace validation does not check is judged by the judges alone.
    let judged = match &validation {
        Err(validation::NotAccepted::NotVoting(_)) => Ok(()),
        other => other.as_ref().map(|_| ()),
    };
    let mut failures = judge::failures(&metrics, &expected, judged);
    let network = network_report(scenario, &session, &lives, setup);
    if let Some(report) = &network {
        failures.extend(report.failures.iter().cloned());
    }
    let output = scenario.output.map(|output| {
        let recorded = wrong_output::Recorded {
            architecture: setup.architecture,
            observed: &session.observed,
            lives: &lives,
            injections: &injections,
            faults: &session.faults,
            servo_owners: &metrics.servo_owners,
            connext_owners: metrics.connext_owners.as_deref(),
            judged_from_ms: session.judged_from_ms,
            end_ms,
        };
        wrong_output::judge(&recorded, output)
    });
    if let Some(report) = &output {
        failures.extend(report.failures.iter().cloned());
    }
    let picture = out.join(format!("{name}.svg"));
    let outcome = Outcome {
        scenario: scenario.name.clone(),
        about: scenario.about.clone(),
        seed,
        architecture: architecture::name(setup.architecture),
        mutation: setup.mutation_label(),
        faults: session.faults.clone(),
        metrics,
        validation,
        network,
        network_alarm_changes: network_alarms::changes(&session.observed.network),
        output,
        failures,
        dir: dir.clone(),
        picture: picture.clone(),
        replay: replay_command(&scenario.name, seed, setup),
    };
    plot::draw(&picture, &outcome, &session.observed, &lives, end_ms)?;
    write_outputs(&dir, &outcome, &session.observed)?;
    if outcome.output.is_some() {
        let tracking = out.join(format!("{name}-tracking.svg"));
        wrong_output::files::write_outputs(&dir, &tracking, &outcome, &session.observed)?;
    }
    Ok(outcome)
}

/// `scenario` as `architecture` runs it, or why it does not.
fn under(scenario: &Scenario, architecture: Architecture) -> Result<Scenario, LabError> {
    scenario
        .under(architecture)
        .map_err(|reason| LabError::NotUnderArchitecture {
            scenario: scenario.name.clone(),
            architecture: architecture::name(architecture),
            reason,
        })
}

/// The recording in `events` against the model: the trace validation is of the voting rules,
/// so the duplex's and the pair's are not checked here (`model check --architecture` checks
/// their rules).
fn validate_in(architecture: Architecture, events: PathBuf) -> Verdict {
    match architecture {
        Architecture::Voting => validate_with_timeout(events),
        other => Err(validation::NotAccepted::NotVoting(architecture::name(
            other,
        ))),
    }
}

/// A formed session for `scenario`, announced on stderr; refused when its network alarm judge
/// cannot run (unless `--lenient`), or when a voting reader's mutation is asked of a scenario
/// without one.
fn start(scenario: &Scenario, seed: u64, setup: &Setup) -> Result<Session, LabError> {
    if setup.vote_mutation.is_some() && scenario.output.is_none() {
        return Err(LabError::NoVotingReader {
            scenario: scenario.name.clone(),
        });
    }
    let session = Session::start(setup)?;
    if scenario.network.is_some() && !session.procs.two_networks && !setup.lenient {
        return Err(LabError::MissingJudge {
            judge: "the network alarm judge".into(),
            fix: format!(
                "{} has no --network-a (no network alarm participants)",
                setup.rl.display()
            ),
        });
    }
    let broken = setup
        .mutation_label()
        .map_or(String::new(), |m| format!(", mutation {m}"));
    eprintln!(
        "lab: {} (seed {seed}{broken}) on LAN {}: formed at {:.1} s; {}",
        scenario.name,
        session.prefix(),
        session.judged_from_ms / 1000.0,
        super::scenario::describe(&scenario.steps)
    );
    Ok(session)
}

/// The network alarm judge's report, for a scenario that has one.
fn network_report(
    scenario: &Scenario,
    session: &Session,
    lives: &[super::procs::Life],
    setup: &Setup,
) -> Option<NapReport> {
    let expected = scenario.network.as_ref()?;
    let monitored = session.procs.two_networks;
    if !monitored {
        eprintln!(
            "lab: {} has no --network-a (no network alarm participants): the network alarm checks are skipped (--lenient), controller alarms and roles still judged",
            setup.rl.display()
        );
    }
    let recorded = Recorded {
        network: &session.observed.network,
        controller: &session.observed.controller,
        lives,
        faults: &session.faults,
        judged_from_ms: session.judged_from_ms,
    };
    Some(network_alarms::judge(&recorded, expected, monitored))
}

/// Trace validation in a thread, given up after `VALIDATION_TIMEOUT`.
pub fn validate_with_timeout(dir: PathBuf) -> Verdict {
    let (sender, receiver) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = sender.send(validation::validate_recording(&dir));
    });
    receiver
        .recv_timeout(VALIDATION_TIMEOUT)
        .unwrap_or(Err(validation::NotAccepted::TimedOut(VALIDATION_TIMEOUT)))
}

/// `result.json`, `stderr.log`, `actuators.log` and `timeline.txt` of a run in `dir`.
pub fn write_outputs(
    dir: &Path,
    outcome: &Outcome,
    observed: &super::observe::Observations,
) -> Result<(), LabError> {
    let write = |name: &str, text: String| {
        let path = dir.join(name);
        std::fs::write(&path, text).map_err(|e| LabError::output(&path, e))
    };
    write(
        "result.json",
        serde_json::to_string_pretty(outcome).unwrap_or_default(),
    )?;
    let stderr: String = observed
        .stderr
        .iter()
        .map(|(source, text)| format!("{source}: {text}\n"))
        .collect();
    write("stderr.log", stderr)?;
    write("actuators.log", actuator_samples(observed))?;
    write("timeline.txt", timeline(outcome))
}

/// Every sample both actuators took, in time order: lab seconds, the reader, the writer's
/// participant (the controller id where known) and entity id, so a switch can be traced to
/// the very writer (a controller re-creates its writer at each new strength), and the command;
/// and the commands `rl servo` dropped as past their writer's lifespan.
fn actuator_samples(observed: &super::observe::Observations) -> String {
    let who = |sample: &super::observe::ActuatorSample| {
        observed
            .participant_ids
            .get(&sample.participant)
            .map_or_else(|| sample.participant.clone(), |id| format!("C{id}"))
    };
    let mut lines: Vec<(f64, String)> = observed
        .servo_expired
        .iter()
        .map(|(sample, late_ms)| {
            let line = format!(
                "{:9.3} s  servo    {} writer {} expired, {late_ms} ms late\n",
                sample.at_ms / 1000.0,
                who(sample),
                sample.writer_entity
            );
            (sample.at_ms, line)
        })
        .collect();
    for (reader, samples) in [
        ("servo", &observed.servo_commands),
        ("connext", &observed.connext),
    ] {
        for sample in samples {
            let who = who(sample);
            let command = sample.pan_tilt.map_or(String::new(), |(pan, tilt)| {
                format!(" pan {pan} tilt {tilt}")
            });
            lines.push((
                sample.at_ms,
                format!(
                    "{:9.3} s  {reader:<8} {who} writer {}{command}\n",
                    sample.at_ms / 1000.0,
                    sample.writer_entity
                ),
            ));
        }
    }
    lines.sort_by(|a, b| a.0.total_cmp(&b.0));
    lines.into_iter().map(|(_, line)| line).collect()
}

/// Faults and owner changes at both actuators in time order (seconds on the lab clock).
pub fn timeline(outcome: &Outcome) -> String {
    timeline_of(&outcome.faults, &outcome.metrics)
}

/// [`timeline`] of any judged stretch: a run, or one soak cycle.
pub fn timeline_of(faults: &[FaultRecord], m: &Metrics) -> String {
    let mut entries: Vec<(f64, String)> = Vec::new();
    for fault in faults {
        entries.push((fault.applied_ms, format!("fault     {}", fault.label)));
        if let Some(healed) = fault.healed_ms {
            entries.push((healed, format!("heal      {}", fault.label)));
        }
    }
    entries.push((m.judged_from_ms, "lab       judging starts".into()));
    for (judge, spans) in [
        ("rl servo", Some(&m.servo_owners)),
        ("connext", m.connext_owners.as_ref()),
    ] {
        // An owner that ended before judging began is not this stretch's (a soak cycle's
        // timeline would otherwise start with every earlier cycle's owners).
        for span in spans
            .into_iter()
            .flatten()
            .filter(|span| span.to_ms >= m.judged_from_ms)
        {
            entries.push((span.from_ms, format!("{judge:<9} owner {}", span.owner)));
        }
    }
    entries.sort_by(|a, b| a.0.total_cmp(&b.0));
    entries
        .into_iter()
        .map(|(at, text)| format!("{:>8.3} s  {text}\n", at / 1000.0))
        .collect()
}

/// The run's summary: measurements, verdict and, on failure, the replay command.
pub fn summary(outcome: &Outcome) -> String {
    let m = &outcome.metrics;
    let gap = |g: Option<(f64, f64)>| g.map_or("-".into(), |(ms, _)| format!("{ms:.0} ms"));
    let mut broken = outcome.mutation.as_ref().map_or(String::new(), |m| {
        format!(", mutation {m}: a deliberately broken rl")
    });
    if outcome.architecture != "voting" {
        broken.push_str(&format!(", under the {}", outcome.architecture));
    }
    let mut text = format!(
        "{} (seed {}{broken}): {}\n  owner changes per fault (servo/connext): {}\n  largest gap: servo {}, connext {}\n  two at top strength: {:.0} ms\n  settled: {}\n  model: {}\n  final roles: {}\n  picture: {}\n",
        outcome.scenario,
        outcome.seed,
        if outcome.passed() { "PASS" } else { "FAIL" },
        m.changes_per_fault
            .iter()
            .map(|c| format!("{} ({}/{})", c.fault, c.servo, c.connext.map_or("-".into(), |n| n.to_string())))
            .collect::<Vec<_>>()
            .join("; "),
        gap(m.servo_gap),
        gap(m.connext_gap),
        m.two_at_top_ms,
        m.settle_rounds.map_or("never".into(), |r| format!("{r} rounds after the last heal or restart (model's bound {SETTLE_ROUNDS})")),
        match &outcome.validation {
            Ok(_) => "accepted".to_string(),
            Err(why) => format!(
                "rejected or unchecked: {}",
                why.to_string().lines().next().unwrap_or("")
            ),
        },
        m.final_roles.join(" "),
        outcome.picture.display(),
    );
    for named in &m.named {
        let when = match (named.named_after_ms, &named.by) {
            (Some(after), Some(by)) => format!("by {by}, {after:.0} ms after it"),
            _ => "never".to_string(),
        };
        text.push_str(&format!(
            "  alarm naming C{} ({}): {when} (bound {:.0} ms)\n",
            named.about, named.fault, named.within_ms
        ));
    }
    if let Some(report) = &outcome.output {
        text.push_str(&wrong_output::summary(report));
    }
    match &outcome.network {
        Some(report) => text.push_str(&network_summary(report)),
        None if !outcome.network_alarm_changes.is_empty() => text.push_str(&format!(
            "  network alarms (not judged here): {}\n",
            outcome.network_alarm_changes.join("; ")
        )),
        None => {}
    }
    for failure in &outcome.failures {
        text.push_str(&format!("  FAILED: {failure}\n"));
    }
    if !outcome.passed() {
        text.push_str(&format!("  replay: {}\n", outcome.replay));
    }
    text
}

/// The network alarm judge's figures: each expected alarm's raise and clear per controller,
/// the conclusions, the controller alarms and role changes.
fn network_summary(report: &NapReport) -> String {
    let ms = |v: Option<f64>| v.map_or("never".into(), |v| format!("{v:.0} ms"));
    let mut text = String::new();
    if !report.network_judged {
        text.push_str("  network alarms: not judged (this rl has no network monitoring)\n");
    }
    // Faults meant to start together that did not: the first held alone meanwhile.
    if report.applied_over_ms > 100.0 {
        text.push_str(&format!(
            "  the faults were applied over {:.0} ms (a loaded machine)\n",
            report.applied_over_ms
        ));
    }
    for t in &report.timings {
        text.push_str(&format!(
            "  network alarm {} at {}: raised {} after the fault ({}), cleared {} after the heal\n",
            t.subject,
            t.observer,
            ms(t.raised_after_ms),
            t.certainty.map_or("-", Certainty::name),
            ms(t.cleared_after_ms),
        ));
    }
    if report.network_judged && report.timings.is_empty() && report.other_alarms.is_empty() {
        text.push_str("  network alarms: none raised\n");
    }
    for line in &report.conclusions {
        text.push_str(&format!("  conclusion {line}\n"));
    }
    let or_none = |items: &[String]| {
        if items.is_empty() {
            "none".to_string()
        } else {
            items.join("; ")
        }
    };
    text.push_str(&format!(
        "  controller alarms: {}\n  role changes: {}\n",
        or_none(&report.controller_alarms),
        or_none(&report.role_changes)
    ));
    text
}
