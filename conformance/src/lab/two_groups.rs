//! `two-groups`: two redundancy groups on one LAN and one DDS domain, as a board hosts a
//! navigation and an actuator controller. Each controller host runs two `rl controller`s, one
//! per group (`[dds] group`, so RL's topics and the network monitor's carry the group's name
//! and ids 1-3 are per group), and each group commands its own topic (`nav/servo_control`,
//! `act/servo_control`), read on the actuator side by its own `rl servo` and (when the Connext
//! judge runs) its own Connext reader; one `rl shapes` serves both (the camera topic is the
//! application's).
//!
//! Both groups form P=C1 S=C2 T=C3 with each group's actuators following its C1; 2 s into
//! judging both C1s are killed at the same instant (one SIGKILL each, sent back to back), and
//! each is restarted as `kill-primary` restarts its Primary: nav's 3 s after the kill, act's
//! 5 s after, so each group's network monitor can be seen following its own C1. After the
//! liveness phase each group is judged as one (`super::judge` with `kill-primary`'s bounds,
//! the model, `super::network_alarms`) and against the other (`super::cross_talk`).
//!
//! It is its own run, not a [`super::scenario::Scenario`]: a [`super::session::Session`] runs
//! one group, so the two groups' processes are started and paced here, with the session's
//! formation check (`super::session::formed`). This module holds the groups, their processes
//! and the schedule; [`verdict`] judges each group and writes the output:
//! `DIR/two-groups-seedN/` with `result.json` (both groups) and the group configurations, and
//! in `nav/` and `act/` what a one-group run leaves (`super::run::write_outputs`); each
//! group's picture is `DIR/two-groups-seedN-GROUP.svg`. Not in either matrix.

use super::clock::LabClock;
use super::error::LabError;
use super::expect::{self, UnknownScenario};
use super::faults::{Fault, Target};
use super::judge::FaultRecord;
use super::lan::{Lan, Node, CONTROLLER_IDS};
use super::network_alarms;
use super::observe::Observations;
use super::procs::{Life, Line, Procs};
use super::run;
use super::session::{self, Setup, FORMATION_TIMEOUT};
use std::path::Path;
use std::sync::mpsc::{self, Receiver};
use std::time::{Duration, Instant};
use verdict::Judging;
pub use verdict::{summary, TwoGroupsOutcome};

pub mod verdict;

/// The scenario's name in `lab list` and `lab run`.
pub const NAME: &str = "two-groups";

/// Why it runs under voting only: its judges (`super::cross_talk`, the network monitors'
/// groups) are of three-controller groups, and each group's bounds are `kill-primary`'s.
pub const ONLY_VOTING: &str =
    "its two groups are voting groups of three, judged by kill-primary's bounds under voting";

/// One redundancy group of the scenario.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Group {
    /// Its `[dds] group`.
    pub name: &'static str,
    /// When its killed C1 is restarted, after the kill (ms).
    pub restart_after_ms: u64,
}

/// The two groups: nav's C1 back when `kill-primary`'s is, act's two seconds later.
pub const GROUPS: [Group; 2] = [
    Group {
        name: "nav",
        restart_after_ms: 3000,
    },
    Group {
        name: "act",
        restart_after_ms: 5000,
    },
];

/// When both Primaries are killed, after judging starts: when `kill-primary` kills.
pub const KILL_AT_MS: u64 = 2000;
/// The controller each group loses, and the life its readers must move to.
pub const KILLED: u8 = 1;
pub const SUCCESSOR: &str = "C2";

impl Group {
    /// The topic it commands on.
    pub fn command_topic(&self) -> String {
        format!("{}/servo_control", self.name)
    }

    /// Its `rl.toml`, for its controllers and its servo: the group and its command topic,
    /// the defaults otherwise (as every lab run).
    pub fn config(&self) -> String {
        format!(
            "[dds]\ngroup = \"{}\"\ncommand_topic = \"{}\"\n",
            self.name,
            self.command_topic()
        )
    }
}

/// What `lab list` says of it.
pub fn about() -> String {
    let names: Vec<&str> = GROUPS.iter().map(|g| g.name).collect();
    format!(
        "two groups ({}) on one LAN, each host running one controller of each: kill -9 both \
         Primaries at once; one owner change in each group, no cross-talk",
        names.join(", ")
    )
}

/// Its schedule, as `lab list` shows schedules.
pub fn describe() -> String {
    let restarts: Vec<String> = GROUPS
        .iter()
        .map(|g| {
            format!(
                "{}'s restarted {:.1} s later",
                g.name,
                g.restart_after_ms as f64 / 1000.0
            )
        })
        .collect();
    format!(
        "at {:.1} s: kill -9 C1 of every group at once; {}",
        KILL_AT_MS as f64 / 1000.0,
        restarts.join(", ")
    )
}

/// One group's processes and what they printed.
struct GroupRun {
    group: Group,
    procs: Procs,
    lines: Receiver<Line>,
    observed: Observations,
    kill: Option<FaultRecord>,
}

/// Both groups on their LAN. Field order is drop order: processes before the LAN.
struct TwoGroups {
    groups: Vec<GroupRun>,
    lan: Lan,
    clock: LabClock,
    connext: bool,
    judged_from_ms: f64,
}

/// Starts group `group`'s servo and Connext reader on `lan`, its configuration in `dir`.
fn start_group(
    group: Group,
    setup: &Setup,
    lan: &Lan,
    clock: LabClock,
    dir: &Path,
) -> Result<GroupRun, LabError> {
    let config = dir.join(format!("{}.toml", group.name));
    std::fs::write(&config, group.config()).map_err(|e| LabError::output(&config, e))?;
    let (sender, lines) = mpsc::channel();
    let mut procs = Procs::new(setup.rl.clone(), setup.domain, lan, clock, sender);
    procs.mutation = setup.mutation.clone();
    procs.config = Some(config.clone());
    let domain = setup.domain.to_string();
    let config = config.display().to_string();
    let servo = ["servo", "--json", "--domain", &domain, "--config", &config];
    procs.start_helper("servo", Node::Actuator, None, &servo)?;
    if setup.connext {
        session::start_connext(&mut procs, Some(&group.command_topic()))?;
    }
    Ok(GroupRun {
        group,
        procs,
        lines,
        observed: Observations::default(),
        kill: None,
    })
}

impl TwoGroups {
    /// Builds the LAN, starts every process and waits until both groups have formed.
    fn start(setup: &Setup, dir: &Path) -> Result<TwoGroups, LabError> {
        std::fs::create_dir_all(dir).map_err(|e| LabError::output(dir, e))?;
        let lan = Lan::build(&Lan::fresh_prefix())?;
        let clock = LabClock::start();
        let mut groups = Vec::new();
        for group in GROUPS {
            groups.push(start_group(group, setup, &lan, clock, dir)?);
        }
        let domain = setup.domain.to_string();
        let camera = ["shapes", "--domain", &domain];
        if let Some(first) = groups.first_mut() {
            first
                .procs
                .start_helper("camera", Node::Camera, None, &camera)?;
        }
        for id in CONTROLLER_IDS {
            for group in &mut groups {
                group.procs.start_controller(id)?;
            }
        }
        let mut lab = TwoGroups {
            groups,
            lan,
            clock,
            connext: setup.connext,
            judged_from_ms: 0.0,
        };
        lab.await_formation()?;
        lab.judged_from_ms = lab.clock.now_ms();
        Ok(lab)
    }

    /// Takes in every group's lines and notices exits for `duration`.
    fn pump(&mut self, duration: Duration) -> Result<(), LabError> {
        let until = Instant::now() + duration;
        loop {
            let mut took = false;
            for group in &mut self.groups {
                while let Ok(line) = group.lines.try_recv() {
                    group.observed.ingest(line, &self.clock, &group.procs.lives);
                    took = true;
                }
                group.procs.poll()?;
            }
            let left = until.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Ok(());
            }
            if !took {
                std::thread::sleep(left.min(Duration::from_millis(5)));
            }
        }
    }

    /// Waits until every group is formed as a one-group run is (`session::formed`).
    fn await_formation(&mut self) -> Result<(), LabError> {
        let started = Instant::now();
        loop {
            let now = self.clock.now_ms();
            let mut all_formed = true;
            for group in &self.groups {
                let formed = session::formed(&group.procs, &group.observed, now, self.connext);
                if let Some(refused) = mutation_refused(group, formed) {
                    return Err(refused);
                }
                all_formed &= formed;
            }
            if all_formed {
                return Ok(());
            }
            if started.elapsed() > FORMATION_TIMEOUT {
                return Err(LabError::NoFormation {
                    waited_s: FORMATION_TIMEOUT.as_secs(),
                    detail: self.formation_detail(now),
                });
            }
            self.pump(Duration::from_millis(100))?;
        }
    }

    /// Each group's state, for a formation that did not happen.
    fn formation_detail(&self, now: f64) -> String {
        let groups: Vec<String> = self
            .groups
            .iter()
            .map(|g| {
                format!(
                    "{}: formed {}; servo commands {}, Connext samples {}; dead: {:?}; stderr: {:?}",
                    g.group.name,
                    session::formed(&g.procs, &g.observed, now, self.connext),
                    g.observed.servo_commands.len(),
                    g.observed.connext.len(),
                    g.procs.dead(&CONTROLLER_IDS),
                    g.observed.stderr.iter().rev().take(3).collect::<Vec<_>>()
                )
            })
            .collect();
        groups.join(" | ")
    }

    /// `kill -9` of every group's C1 at the same instant: the signals first, back to back,
    /// then each reaped and recorded.
    fn kill_every_primary(&mut self) -> Result<f64, LabError> {
        let pids: Vec<u32> = self
            .groups
            .iter()
            .filter_map(|g| g.procs.pid(KILLED))
            .collect();
        let applied_ms = self.clock.now_ms();
        for pid in pids {
            rl::procs::signal(pid, libc::SIGKILL).map_err(|e| {
                LabError::command("kill", &["-KILL", &pid.to_string()], e.to_string())
            })?;
        }
        for group in &mut self.groups {
            group.procs.kill(KILLED);
            group.kill = Some(FaultRecord {
                label: Fault::Kill(Target::Id(KILLED)).to_string(),
                applied_ms,
                healed_ms: None,
                target: Some(KILLED),
                alarm_within_ms: None,
            });
        }
        Ok(applied_ms)
    }

    /// Restarts each group's C1 when its group says, after the kill at `killed_ms`.
    fn restart_in_turn(&mut self, killed_ms: f64) -> Result<(), LabError> {
        let mut order: Vec<usize> = (0..self.groups.len()).collect();
        order.sort_by_key(|i| self.groups[*i].group.restart_after_ms);
        for i in order {
            let due_ms = killed_ms + self.groups[i].group.restart_after_ms as f64;
            let wait_ms = (due_ms - self.clock.now_ms()).max(0.0);
            self.pump(Duration::from_secs_f64(wait_ms / 1000.0))?;
            let healed_ms = self.clock.now_ms();
            let group = &mut self.groups[i];
            group.procs.start_controller(KILLED)?;
            if let Some(kill) = &mut group.kill {
                kill.healed_ms = Some(healed_ms);
            }
        }
        Ok(())
    }

    /// Stops every process (controllers with SIGTERM) and takes in their last lines.
    fn stop(&mut self) -> Result<(), LabError> {
        for group in &mut self.groups {
            group.procs.stop_all();
        }
        self.pump(Duration::from_millis(300))
    }
}

/// With a mutation: why a group's controllers do not run it, if they do not.
fn mutation_refused(group: &GroupRun, formed: bool) -> Option<LabError> {
    let name = group.procs.mutation.as_deref()?;
    let labels: Vec<String> = group.procs.lives.iter().map(Life::label).collect();
    let (rl, stderr) = (group.procs.rl(), &group.observed.stderr);
    super::mutation::refused(name, rl, stderr, &labels, formed)
}

/// Runs `two-groups` (seed `seed`, which only names the output) and writes its output under
/// `out`.
pub fn run(seed: u64, setup: &Setup, out: &Path) -> Result<TwoGroupsOutcome, LabError> {
    let expected = expect::for_scenario(NAME, &[Fault::Kill(Target::Id(KILLED))])?;
    let network = network_alarms::for_scenario(NAME).ok_or_else(|| UnknownScenario {
        name: NAME.to_string(),
    })?;
    let name = run::output_name(NAME, seed, setup.mutation.as_deref());
    let dir = out.join(&name);
    let _ = std::fs::remove_dir_all(&dir);
    let mut lab = TwoGroups::start(setup, &dir)?;
    let monitored = lab.groups.iter().all(|g| g.procs.two_networks);
    if !monitored && !setup.lenient {
        return Err(LabError::MissingJudge {
            judge: "the network alarm judge".into(),
            fix: format!("{} has no --network-a", setup.rl.display()),
        });
    }
    eprintln!(
        "lab: {NAME} (seed {seed}) on LAN {}: formed at {:.1} s; {}",
        lab.lan.prefix,
        lab.judged_from_ms / 1000.0,
        describe()
    );
    lab.pump(Duration::from_millis(KILL_AT_MS))?;
    let killed_ms = lab.kill_every_primary()?;
    lab.restart_in_turn(killed_ms)?;
    lab.pump(run::LIVENESS)?;
    let dead: Vec<Vec<String>> = lab
        .groups
        .iter()
        .map(|g| g.procs.dead(&CONTROLLER_IDS))
        .collect();
    let end_ms = lab.clock.now_ms();
    let lives: Vec<Vec<Life>> = lab.groups.iter().map(|g| g.procs.lives.clone()).collect();
    lab.stop()?;
    let judging = Judging {
        expected,
        network,
        setup,
        seed,
        name,
        out,
        end_ms,
        monitored,
    };
    verdict::judge(&lab, &lives, dead, &judging)
}

#[cfg(test)]
mod tests;
