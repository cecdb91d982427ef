//! One system under test on its own virtual LAN: the LAN built, the processes started, the
//! formation awaited (P=C1 S=C2 T=C3 steady, both actuators following C1 for a second), then
//! faults applied and healed on schedule while every line is taken in, then a fault-free
//! liveness phase. Dropping a session stops its processes and then removes its LAN. The
//! wrong-output scenarios add a voting reader beside the exclusive ones and have the camera
//! print its frames ([`Setup::output_readers`]).

use super::architecture::{self, Architecture};
use super::clock::LabClock;
use super::error::LabError;
use super::faults::{self, Applied, Target};
use super::judge::FaultRecord;
use super::lan::{Lan, Node};
use super::observe::Observations;
use super::procs::{Line, Procs};
use super::scenario::Step;
use rl_layer::core::{Phase, Role, Status};
use std::path::PathBuf;
use std::sync::mpsc::{self, Receiver};
use std::time::{Duration, Instant};

mod schedule;
use schedule::{defer_after_heals, sort_due};

/// How a session is set up.
#[derive(Clone, Debug)]
pub struct Setup {
    /// The `rl` binary (glibc build: the clock faults preload libfaketime into it).
    pub rl: PathBuf,
    /// DDS domain inside the namespaces (they isolate runs from each other).
    pub domain: u16,
    /// Start the Connext reader as a second actuator judge.
    pub connext: bool,
    /// Go on, with a warning, when a judge cannot run (`--lenient`); otherwise that is an
    /// error.
    pub lenient: bool,
    /// The deliberately broken rule the controllers run (`RL_MUTATION`; a `mutation` build of
    /// `rl` only): `super::mutation`.
    pub mutation: Option<String>,
    /// The deliberately broken voting rule the voting reader runs (`RL_VOTE_MUTATION`; a
    /// `mutation` build of `rl` only): `super::mutation`.
    pub vote_mutation: Option<String>,
    /// Start `rl servo --vote --json` on the actuator node beside the exclusive readers, and
    /// `rl shapes` with `--json` (its frames: the tracking error): the wrong-output scenarios
    /// (`super::wrong_output`).
    pub output_readers: bool,
    /// What the camera's gimbal follows.
    pub camera: Camera,
    /// The redundancy architecture the controllers run (`super::architecture`).
    pub architecture: Architecture,
}

/// What the camera's gimbal follows: the exclusive command topic's owner (`rl shapes`, the
/// paper's pan-tilt) or the vote on the voted topic (`rl shapes --vote`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Camera {
    #[default]
    Exclusive,
    Vote,
}

impl Setup {
    /// The broken rule a run carries, for its output's name and its summary: the controllers'
    /// mutation, or `vote-NAME` for the voting reader's.
    pub fn mutation_label(&self) -> Option<String> {
        match (&self.mutation, &self.vote_mutation) {
            (Some(controllers), _) => Some(controllers.clone()),
            (None, Some(voting)) => Some(format!("vote-{voting}")),
            (None, None) => None,
        }
    }
}

/// The Connext reader's command deadline: the paper's reader QoS, as the actuator tests use.
pub const CONNEXT_DEADLINE_MS: u64 = 200;
/// The Connext reader (Python, RTI Connext): the second actuator judge.
pub const CONNEXT_READER: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../impl/tests/interop/connext_reader.py"
);
/// Starts the Connext reader on the actuator side, reading the configured command topic or
/// `topic` (a group's).
pub fn start_connext(procs: &mut Procs, topic: Option<&str>) -> Result<(), LabError> {
    let domain = procs.domain().to_string();
    let deadline_ms = CONNEXT_DEADLINE_MS.to_string();
    let mut args = vec![
        CONNEXT_READER,
        &domain,
        "--duration",
        "1000000",
        "--deadline-ms",
        &deadline_ms,
    ];
    if let Some(topic) = topic {
        args.extend(["--topic", topic]);
    }
    procs.start_helper("connext", Node::Actuator, Some("python3"), &args)
}

/// `rl shapes` on the camera node: at the frame rate the wrong-output bounds count in
/// (`super::wrong_output::CAMERA_RATE_HZ`, its default), following what `setup.camera` says,
/// printing its frames when the wrong-output judges read them.
fn start_camera(procs: &mut Procs, setup: &Setup) -> Result<(), LabError> {
    let domain = procs.domain().to_string();
    let rate = super::wrong_output::CAMERA_RATE_HZ.to_string();
    let mut args = vec!["shapes", "--domain", &domain, "--rate-hz", &rate];
    if setup.camera == Camera::Vote {
        args.push("--vote");
    }
    if setup.output_readers {
        args.push("--json");
    }
    procs.start_helper(
        super::wrong_output::readings::CAMERA,
        Node::Camera,
        None,
        &args,
    )
}

/// `rl servo --vote --json` on the actuator node, with `RL_VOTE_MUTATION` when the run gives
/// it one.
fn start_voting_reader(procs: &mut Procs, setup: &Setup) -> Result<(), LabError> {
    let domain = procs.domain().to_string();
    let dissent_after = super::wrong_output::VOTER_DISSENT_AFTER.to_string();
    let args = [
        "servo",
        "--vote",
        "--json",
        "--domain",
        &domain,
        "--dissent-after",
        &dissent_after,
    ];
    let env: Vec<(String, String)> = setup
        .vote_mutation
        .iter()
        .map(|name| (super::mutation::VOTE_VARIABLE.to_string(), name.clone()))
        .collect();
    let name = super::wrong_output::readings::VOTER;
    procs.start_helper_with(name, Node::Actuator, None, &args, &env)
}

/// Formation, including the Connext reader's start (Python, Connext, discovery).
pub const FORMATION_TIMEOUT: Duration = Duration::from_secs(60);
/// The longest the safety phase waits for the controllers to settle before the next fault: a
/// restart, its initialization window and a vote take a few seconds.
const SETTLE_WAIT_LIMIT: Duration = Duration::from_secs(20);

/// A running system under test. Field order is drop order: processes before the LAN.
pub struct Session {
    pub procs: Procs,
    lan: Lan,
    pub clock: LabClock,
    lines: Receiver<Line>,
    pub observed: Observations,
    pub faults: Vec<FaultRecord>,
    pub judged_from_ms: f64,
    applied: Vec<Option<Applied>>,
    /// The position in `faults` of each applied step's record.
    record_of_step: std::collections::BTreeMap<usize, usize>,
    /// The applied steps whose target was the Primary when they applied.
    primary_steps: std::collections::BTreeSet<usize>,
    connext: bool,
    /// The voting reader runs, and judging waits for it to be steady too.
    output_readers: bool,
    pub architecture: Architecture,
    /// The controllers' configuration file, removed when the session stops.
    config_file: Option<PathBuf>,
}

impl Session {
    /// Builds the LAN, starts every process and waits for the formation.
    pub fn start(setup: &Setup) -> Result<Session, LabError> {
        let lan = Lan::build(&Lan::fresh_prefix())?;
        let clock = LabClock::start();
        let (sender, lines) = mpsc::channel();
        let mut procs = Procs::new(setup.rl.clone(), setup.domain, &lan, clock, sender);
        procs.mutation = setup.mutation.clone();
        let config_file = write_config(setup.architecture, &lan.prefix)?;
        procs.config = config_file.clone();
        let domain = setup.domain.to_string();
        procs.start_helper(
            "servo",
            Node::Actuator,
            None,
            &["servo", "--json", "--domain", &domain],
        )?;
        start_camera(&mut procs, setup)?;
        if setup.output_readers {
            start_voting_reader(&mut procs, setup)?;
        }
        for id in architecture::controller_ids(setup.architecture) {
            procs.start_controller(*id)?;
        }
        if setup.connext {
            start_connext(&mut procs, None)?;
        }
        let mut session = Session {
            procs,
            lan,
            clock,
            lines,
            observed: Observations::default(),
            faults: Vec::new(),
            judged_from_ms: 0.0,
            applied: Vec::new(),
            record_of_step: Default::default(),
            primary_steps: Default::default(),
            connext: setup.connext,
            output_readers: setup.output_readers,
            architecture: setup.architecture,
            config_file,
        };
        session.await_formation()?;
        session.judged_from_ms = session.clock.now_ms();
        Ok(session)
    }

    /// Takes in every line and notices exits for `duration`.
    pub fn pump(&mut self, duration: Duration) -> Result<(), LabError> {
        let until = Instant::now() + duration;
        loop {
            let left = until.saturating_duration_since(Instant::now());
            if let Ok(line) = self.lines.recv_timeout(left.min(Duration::from_millis(20))) {
                self.observed.ingest(line, &self.clock, &self.procs.lives);
                while let Ok(line) = self.lines.try_recv() {
                    self.observed.ingest(line, &self.clock, &self.procs.lives);
                }
            }
            self.procs.poll()?;
            if left.is_zero() {
                return Ok(());
            }
        }
    }

    /// The last status the running life of controller `id` reported.
    pub fn status(&self, id: u8) -> Option<&Status> {
        status_of(&self.procs, &self.observed, id)
    }

    /// Which controller a target names now: the role's holder (C1 if nobody claims it); in
    /// a pair, whose members both claim the Primary's role, the Primary is the member whose
    /// commands `rl servo` took last and the Secondary the other. An id the architecture does
    /// not run is [`architecture::controller_for`]'s.
    pub fn resolve(&self, target: Target) -> u8 {
        let ids = architecture::controller_ids(self.architecture);
        let holder = |role: Role| {
            ids.iter().copied().find(|id| {
                self.status(*id)
                    .is_some_and(|s| s.report.role == Some(role))
            })
        };
        let owner = || {
            let last = self.observed.servo_commands.last()?;
            self.observed
                .participant_ids
                .get(&last.participant)
                .copied()
        };
        match (target, self.architecture) {
            (Target::Id(id), architecture) => architecture::controller_for(architecture, id),
            (Target::Primary, Architecture::Pair) => owner().unwrap_or(1),
            (Target::Secondary, Architecture::Pair) => {
                if owner() == Some(2) {
                    1
                } else {
                    2
                }
            }
            (Target::Primary, _) => holder(Role::Primary).unwrap_or(1),
            (Target::Secondary, _) => holder(Role::Secondary).unwrap_or(2),
        }
    }

    /// Whether every sample of the last second at an actuator came from controller `id`.
    fn actuators_follow(&self, id: u8) -> bool {
        actuators_follow(&self.observed, self.clock.now_ms(), id, self.connext)
    }

    fn await_formation(&mut self) -> Result<(), LabError> {
        let started = Instant::now();
        loop {
            let now_ms = self.clock.now_ms();
            let formed = formed_as(
                self.architecture,
                &self.procs,
                &self.observed,
                now_ms,
                self.connext,
            ) && (!self.output_readers
                || self.observed.outputs.voter_steady(
                    now_ms,
                    architecture::controller_ids(self.architecture).len(),
                ));
            if let Some(refused) = self.mutation_refused(formed) {
                return Err(refused);
            }
            if formed {
                return Ok(());
            }
            if started.elapsed() > FORMATION_TIMEOUT {
                // A life that left before judging (the odd one out of three, voted out) is
                // why a run can form without its C1.
                let left: Vec<_> = self
                    .procs
                    .lives
                    .iter()
                    .filter_map(|l| l.exit.as_ref().map(|exit| (l.label(), exit)))
                    .collect();
                let detail = format!(
                    "formed: {formed}; servo commands {}, Connext samples {}; dead: {:?}; exited: {left:?}; odd one out: {:?}; stderr: {:?}",
                    self.observed.servo_commands.len(),
                    self.observed.connext.len(),
                    self.dead(),
                    self.observed.outputs.odd_one_out,
                    self.observed.stderr.iter().rev().take(5).collect::<Vec<_>>()
                );
                return Err(LabError::NoFormation {
                    waited_s: FORMATION_TIMEOUT.as_secs(),
                    detail,
                });
            }
            self.pump(Duration::from_millis(100))?;
        }
    }

    /// With a mutation: why the controllers do not run it, if they do not (`super::mutation`).
    fn mutation_refused(&self, formed: bool) -> Option<LabError> {
        let name = self.procs.mutation.as_deref()?;
        let labels: Vec<String> = self.procs.lives.iter().map(|l| l.label()).collect();
        let rl = self.procs.rl();
        super::mutation::refused(name, rl, &self.observed.stderr, &labels, formed)
    }

    /// The safety phase: applies and heals `steps` on schedule (times after judging starts).
    ///
    /// One fault at a time is what RL promises about ("one fault, at most one switch"): a
    /// fault the schedule starts while no other is active starts only once the controllers
    /// have settled from the one before (`Session::settled`; a controller outvoted by a
    /// one-way loss, say, restarts after the heal and rejoins seconds later), and the rest of
    /// the schedule moves by that wait. Faults the schedule overlaps on purpose still overlap,
    /// unless one of them hits the controller that is the Primary when it applies: that one
    /// waits until the others have healed and the controllers have settled.
    pub fn play(&mut self, steps: &[Step]) -> Result<(), LabError> {
        let mut origin = self.clock.now_ms();
        let base = self.applied.len();
        self.applied.extend(steps.iter().map(|_| None));
        // (ms after `origin`, apply or heal, step), in order; a deferred step moves.
        let mut due: Vec<(f64, bool, usize)> = steps
            .iter()
            .enumerate()
            .flat_map(|(i, s)| {
                let at = s.at_ms as f64;
                [(at, true, i), (at + s.lasts_ms as f64, false, i)]
            })
            .collect();
        sort_due(&mut due);
        while !due.is_empty() {
            let (at_ms, apply, i) = due.remove(0);
            let wait_ms = (origin + at_ms - self.clock.now_ms()).max(0.0);
            self.pump(Duration::from_secs_f64(wait_ms / 1000.0))?;
            if apply {
                let active: Vec<usize> = (0..steps.len())
                    .filter(|k| self.applied[base + k].is_some())
                    .collect();
                if active.is_empty() {
                    if i > 0 || base > 0 {
                        origin += self.await_settled()?;
                    }
                } else if !self.parts_of_one_fault(steps, i, base, &active)
                    && self.overlap_involves_the_primary(&steps[i], base, &active)
                {
                    defer_after_heals(&mut due, at_ms, i, &active);
                    continue;
                }
                self.apply(&steps[i], base + i)?;
            } else if let Some(applied) = self.applied[base + i].take() {
                let healed_ms = self.clock.now_ms();
                faults::heal(applied, &self.lan, &mut self.procs)?;
                let record = self.record_of_step.get(&(base + i)).copied();
                if let Some(record) = record.and_then(|r| self.faults.get_mut(r)) {
                    record.healed_ms = Some(healed_ms);
                }
            }
        }
        Ok(())
    }

    /// Whether applying `step` now, beside the `active` steps (indices after `base`), would
    /// overlap a fault on the Primary with another fault: the schedule overlaps faults on
    /// different controllers, and which one is the Primary is known only when they apply.
    /// Wrong outputs together are not such an overlap: they move no role, and two of them at
    /// once is the double fault the output model checks (`two-wrong`, docs/protocol.md "Two
    /// wrong controllers"), which must start together or the first is the odd one out alone.
    fn overlap_involves_the_primary(&self, step: &Step, base: usize, active: &[usize]) -> bool {
        if step.fault.is_wrong_output()
            && active
                .iter()
                .all(|k| self.applied_is_wrong_output(base + k))
        {
            return false;
        }
        let primary = self.resolve(Target::Primary);
        let hits_primary = step.fault.target().map(|t| self.resolve(t)) == Some(primary);
        hits_primary
            || active
                .iter()
                .any(|k| self.primary_steps.contains(&(base + k)))
    }

    /// Whether step `i` and every `active` step were scheduled at the same moment on the same
    /// controller: one fault of that controller applied in parts (its links into both nets,
    /// `c2-both-links-down`), which must start together whatever role the controller holds,
    /// and not two faults of which one waits. (Under voting that controller is a standby at
    /// formation; in a pair it may be the member the actuator follows.)
    fn parts_of_one_fault(&self, steps: &[Step], i: usize, base: usize, active: &[usize]) -> bool {
        let id = steps[i].fault.target().map(|t| self.resolve(t));
        id.is_some()
            && active.iter().all(|k| {
                let applied_id = self
                    .applied
                    .get(base + k)
                    .and_then(Option::as_ref)
                    .and_then(|applied| applied.id);
                steps[*k].at_ms == steps[i].at_ms && applied_id == id
            })
    }

    /// Whether the applied step at `index` is a wrong output.
    fn applied_is_wrong_output(&self, index: usize) -> bool {
        self.applied
            .get(index)
            .and_then(Option::as_ref)
            .is_some_and(|applied| applied.fault.is_wrong_output())
    }

    /// Whether the controllers have settled: every one running and settled as its
    /// architecture settles ([`architecture::settled`]: voting's three steady, one in each
    /// role), and the actuators following the Primary.
    fn settled(&self) -> bool {
        let ids = architecture::controller_ids(self.architecture);
        let reports: Vec<&Status> = ids.iter().filter_map(|id| self.status(*id)).collect();
        reports.len() == ids.len()
            && architecture::settled(self.architecture, &reports)
            && self.actuators_follow(self.resolve(Target::Primary))
    }

    /// Waits until [`Session::settled`] (at most [`SETTLE_WAIT_LIMIT`]: a schedule that never
    /// settles goes on, and the settle judge says so); returns the ms waited.
    fn await_settled(&mut self) -> Result<f64, LabError> {
        let started = self.clock.now_ms();
        let limit = Instant::now() + SETTLE_WAIT_LIMIT;
        while !self.settled() && Instant::now() < limit {
            self.pump(Duration::from_millis(100))?;
        }
        Ok(self.clock.now_ms() - started)
    }

    fn apply(&mut self, step: &Step, index: usize) -> Result<(), LabError> {
        let id = step.fault.target().map(|target| self.resolve(target));
        if id.is_some_and(|id| id == self.resolve(Target::Primary)) {
            self.primary_steps.insert(index);
        }
        let table = format!("labf{index}");
        // Before applying: a restart takes time, and what it causes counts from its start.
        let applied_ms = self.clock.now_ms();
        let applied = faults::apply(&step.fault, id, &table, &self.lan, &mut self.procs)?;
        self.record_of_step.insert(index, self.faults.len());
        self.faults.push(FaultRecord {
            label: applied.fault.to_string(),
            applied_ms,
            healed_ms: None,
            target: id,
            alarm_within_ms: super::expect::alarm_within_ms(&step.fault, self.architecture),
        });
        self.applied[index] = Some(applied);
        Ok(())
    }

    /// The processes that should run and do not, now.
    pub fn dead(&self) -> Vec<String> {
        self.procs
            .dead(architecture::controller_ids(self.architecture))
    }

    /// Stops every process (controllers with SIGTERM) and takes in their last lines.
    pub fn stop(&mut self) -> Result<(), LabError> {
        self.procs.stop_all();
        if let Some(path) = self.config_file.take() {
            let _ = std::fs::remove_file(path);
        }
        self.pump(Duration::from_millis(300))
    }

    /// The LAN's prefix (names of its namespaces and links).
    pub fn prefix(&self) -> &str {
        &self.lan.prefix
    }

    /// The LAN the session runs on.
    pub fn lan(&self) -> &Lan {
        &self.lan
    }
}

/// The last status the running life of controller `id` among `procs` reported.
pub fn status_of<'a>(procs: &Procs, observed: &'a Observations, id: u8) -> Option<&'a Status> {
    let life = procs
        .lives
        .iter()
        .rev()
        .find(|l| l.id == id && l.ended_ms.is_none())?;
    let label = life.label();
    observed
        .controller
        .iter()
        .rev()
        .filter(|e| e.life == label)
        .find_map(|e| e.line.status())
}

/// Whether every sample of the second before `now_ms` at `rl servo` (and at the Connext reader,
/// when it runs) came from controller `id`, at least five at each.
pub fn actuators_follow(observed: &Observations, now_ms: f64, id: u8, connext: bool) -> bool {
    let follows = |samples: &[super::observe::ActuatorSample]| {
        let recent: Vec<_> = samples
            .iter()
            .filter(|s| s.at_ms >= now_ms - 1000.0)
            .collect();
        recent.len() >= 5
            && recent
                .iter()
                .all(|s| observed.participant_ids.get(&s.participant) == Some(&id))
    };
    follows(&observed.servo_commands) && (!connext || follows(&observed.connext))
}

/// The formation judging waits for: P=C1 S=C2 T=C3 steady, the actuators following C1.
pub fn formed(procs: &Procs, observed: &Observations, now_ms: f64, connext: bool) -> bool {
    formed_as(Architecture::Voting, procs, observed, now_ms, connext)
}

/// The formation judging waits for under `architecture` ([`architecture::formation`]): each
/// controller steady in its role at that role's strength, the actuators following one of
/// [`architecture::formed_owners`].
pub fn formed_as(
    architecture: Architecture,
    procs: &Procs,
    observed: &Observations,
    now_ms: f64,
    connext: bool,
) -> bool {
    architecture::formation(architecture)
        .iter()
        .all(|(id, role)| {
            status_of(procs, observed, *id).is_some_and(|s| {
                s.report.phase == Phase::Steady
                    && s.report.role == Some(*role)
                    && s.report.strength == Some(role.strength())
            })
        })
        && architecture::formed_owners(architecture)
            .iter()
            .any(|id| actuators_follow(observed, now_ms, *id, connext))
}

/// Writes `architecture`'s configuration for the controllers of LAN `prefix` to a file of
/// its own in the temporary directory (`None`: voting, which runs on the defaults).
fn write_config(architecture: Architecture, prefix: &str) -> Result<Option<PathBuf>, LabError> {
    let Some(text) = architecture::config_text(architecture) else {
        return Ok(None);
    };
    let path = std::env::temp_dir().join(format!("rl-lab-{prefix}.toml"));
    std::fs::write(&path, text).map_err(|e| LabError::output(&path, e))?;
    Ok(Some(path))
}
