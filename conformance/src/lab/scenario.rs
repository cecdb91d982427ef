//! The scenarios: named fault schedules (`lab list`) and seeded random ones (`random`, whose
//! seed picks the faults, their targets and their times). Each step applies a fault at
//! `at_ms` after judging starts (the system formed, both actuators following the Primary) and
//! heals it `lasts_ms` later; after the last heal a fault-free liveness phase must settle.
//! The wrong-output scenarios are `super::wrong_output`'s, the gray process faults' (freeze,
//! stutter, starvation) `scenario::gray`'s.

use super::architecture::{self, Architecture};
use super::expect::{self, Expected, UnknownScenario};
use super::faults::{Direction, Fault, Target};
use super::lan::Net;
use super::network_alarms::{self, NapExpected};
use super::session::Setup;
use super::wrong_output::{self, OutputScenario};
use rand::{Rng, SeedableRng};

mod gray;

/// One fault of a schedule.
#[derive(Clone, Debug, PartialEq)]
pub struct Step {
    pub at_ms: u64,
    pub fault: Fault,
    pub lasts_ms: u64,
}

/// A named schedule with what its judges expect.
#[derive(Clone, Debug)]
pub struct Scenario {
    pub name: String,
    pub about: String,
    pub steps: Vec<Step>,
    /// Part of `matrix --ci` (the short subset CI runs).
    pub in_ci: bool,
    /// What the network alarm judge expects (`None`: not judged).
    pub network: Option<NapExpected>,
    /// A wrong-output scenario: judged at the voting reader too, its tracking error measured
    /// (`None`: neither).
    pub output: Option<OutputScenario>,
}

impl Scenario {
    /// When the last fault is healed (ms after judging starts).
    pub fn last_heal_ms(&self) -> u64 {
        self.steps
            .iter()
            .map(|s| s.at_ms + s.lasts_ms)
            .max()
            .unwrap_or(0)
    }

    /// The schedule's faults, in order.
    pub fn faults(&self) -> Vec<Fault> {
        self.steps.iter().map(|s| s.fault.clone()).collect()
    }

    /// What its judges accept (`super::expect`); a scenario without its own expectations is
    /// refused.
    pub fn expected(&self) -> Result<Expected, UnknownScenario> {
        expect::for_scenario(&self.name, &self.faults())
    }

    /// What its judges accept under `architecture` (`expect::for_scenario_in`).
    pub fn expected_in(&self, architecture: Architecture) -> Result<Expected, UnknownScenario> {
        expect::for_scenario_in(architecture, &self.name, &self.steps)
    }

    /// The scenario as `architecture` runs it: a fault aimed at a controller it does not run
    /// falls on [`architecture::controller_for`]'s, and the network alarm judge expects
    /// controller alarms only between the controllers it runs. A wrong-output scenario runs
    /// under all three, judged by `wrong_output::architectures` under the other two; the
    /// error says why one is not run.
    pub fn under(&self, architecture: Architecture) -> Result<Scenario, &'static str> {
        if architecture == Architecture::Voting {
            return Ok(self.clone());
        }
        if let Some(why) = self
            .output
            .and_then(|o| wrong_output::not_run_under(o, architecture))
        {
            return Err(why);
        }
        let ids = architecture::controller_ids(architecture);
        let mut scenario = self.clone();
        for step in &mut scenario.steps {
            if let Some(Target::Id(id)) = step.fault.target() {
                step.fault = step
                    .fault
                    .at(architecture::controller_for(architecture, id));
            }
        }
        if let Some(network) = &mut scenario.network {
            network
                .controller_alarms
                .retain(|(observer, about)| ids.contains(observer) && ids.contains(about));
            network_alarms::for_two_members(network);
        }
        Ok(scenario)
    }

    /// `setup` with the readers this scenario needs: a wrong-output one adds the voting
    /// reader and the camera's frames, with the camera following what it says.
    pub fn session_setup(&self, setup: &Setup) -> Setup {
        let mut setup = setup.clone();
        if let Some(output) = self.output {
            setup.output_readers = true;
            setup.camera = output.camera;
        }
        setup
    }
}

fn step(at_s: f64, fault: Fault, lasts_s: f64) -> Step {
    Step {
        at_ms: (at_s * 1000.0) as u64,
        fault,
        lasts_ms: (lasts_s * 1000.0) as u64,
    }
}

fn one(name: &str, about: &str, in_ci: bool, fault: Fault, lasts_s: f64) -> Scenario {
    Scenario {
        name: name.into(),
        about: about.into(),
        steps: vec![step(2.0, fault, lasts_s)],
        in_ci,
        network: network_alarms::for_scenario(name),
        output: None,
    }
}

/// A clock offset on C3 for most of the run, with two kills of the Primary meanwhile, so the
/// offset controller ends up Primary before it is restarted on the true clock.
fn clock(name: &str, offset_s: f64, in_ci: bool) -> Scenario {
    let about = format!("C3's wall clock {offset_s:+} s, two kills of the Primary meanwhile");
    clock_fault(
        name,
        about,
        Fault::ClockOffset(Target::Id(3), offset_s),
        in_ci,
    )
}

/// [`clock`] with C3's clock running fast instead: 1% (10,000 ppm, a hundred times a bad
/// crystal's error) moves its rounds by a quarter period, the heartbeats' margin, in about
/// 6 s, where a Pi's crystal would take ten minutes or more.
fn clock_drift(name: &str, rate: f64, in_ci: bool) -> Scenario {
    let fast_percent = (rate - 1.0) * 100.0;
    let about = format!("C3's clock {fast_percent:+.1}% fast, two kills of the Primary meanwhile");
    clock_fault(name, about, Fault::ClockRate(Target::Id(3), rate), in_ci)
}

fn clock_fault(name: &str, about: String, fault: Fault, in_ci: bool) -> Scenario {
    let p = Target::Primary;
    Scenario {
        name: name.into(),
        about,
        steps: vec![
            step(1.0, fault, 16.0),
            step(5.0, Fault::Kill(p), 2.0),
            step(10.0, Fault::Kill(p), 2.0),
        ],
        in_ci,
        network: network_alarms::for_scenario(name),
        output: None,
    }
}

/// Process faults and splits.
fn process_and_split_scenarios() -> Vec<Scenario> {
    let p = Target::Primary;
    vec![
        one(
            "kill-primary",
            "kill -9 of the Primary, restarted 3 s later",
            true,
            Fault::Kill(p),
            3.0,
        ),
        one(
            "pause-primary",
            "SIGSTOP of the Primary for 3 s",
            true,
            Fault::Pause(p),
            3.0,
        ),
        one(
            "partition-actuator-with-primary",
            "the Primary alone with the actuator | the other two, 5 s",
            true,
            Fault::Partition {
                alone: p,
                actuator_with_alone: true,
            },
            5.0,
        ),
        one(
            "partition-actuator-with-two",
            "the Primary alone | the other two with the actuator, 5 s",
            true,
            Fault::Partition {
                alone: p,
                actuator_with_alone: false,
            },
            5.0,
        ),
        one(
            "cut-primary",
            "the Primary cut off from its peers, not the actuator, 3 s (F9)",
            true,
            Fault::Cut(p),
            3.0,
        ),
        one(
            "cut-secondary",
            "the Secondary cut off from its peers, not the actuator, 3 s",
            false,
            Fault::Cut(Target::Secondary),
            3.0,
        ),
    ]
}

/// Loss, link and clock faults.
fn link_and_clock_scenarios() -> Vec<Scenario> {
    let p = Target::Primary;
    vec![
        one(
            "one-way-out",
            "the Primary's packets to its peers lost (it hears them), 3 s",
            false,
            Fault::OneWay(p, Direction::Out),
            3.0,
        ),
        one(
            "one-way-in",
            "the Primary hears nobody (its peers hear it), 3 s",
            false,
            Fault::OneWay(p, Direction::In),
            3.0,
        ),
        one(
            "loss-5",
            "5% random loss on the Primary's link, 10 s",
            false,
            Fault::Loss(p, 5),
            10.0,
        ),
        one(
            "loss-20",
            "20% random loss on the Primary's link, 10 s",
            true,
            Fault::Loss(p, 20),
            10.0,
        ),
        one(
            "loss-40",
            "40% random loss on the Primary's link, 10 s",
            false,
            Fault::Loss(p, 40),
            10.0,
        ),
        one(
            "multicast-drop",
            "multicast dropped at the Primary, 10 s",
            false,
            Fault::MulticastOnly(p),
            10.0,
        ),
        one(
            "flap-primary",
            "the Primary's link down/up every 0.5-3 s for 10 s",
            false,
            Fault::Flap(p, 7),
            10.0,
        ),
        // Shorter than the peers' decision and longer than either reader's deadline: the
        // window in which a Primary that went on while unplugged would take the actuator back
        // (F16).
        one(
            "unplug-primary",
            "the Primary's cables pulled for 0.3 s and pushed back in",
            false,
            Fault::Unplug(p),
            0.3,
        ),
        one(
            "tbf-primary",
            "the Primary's link at 64 kbit/s (tbf), 10 s",
            false,
            Fault::RateLimit(p, 64),
            10.0,
        ),
        clock("clock-0.1s", 0.1, false),
        clock("clock-period", 0.25, false),
        clock("clock-10s", 10.0, false),
        clock("clock-minus-1h", -3600.0, true),
        clock_drift("clock-drift", 1.01, false),
    ]
}

/// Faults of a net or of one controller's links, judged on the network alarms too
/// (`super::network_alarms`): not in `matrix --ci` (about 30 s each).
fn net_scenarios() -> Vec<Scenario> {
    let c2 = Target::Id(2);
    let at_once = |name: &str, about: &str, faults: [Fault; 2]| Scenario {
        name: name.into(),
        about: about.into(),
        steps: faults
            .into_iter()
            .map(|f| step(2.0, f, NET_FAULT_S))
            .collect(),
        in_ci: false,
        network: network_alarms::for_scenario(name),
        output: None,
    };
    vec![
        one(
            "net-b-down",
            "net B dead for every node, 8 s: a net-B alarm everywhere, voting unaffected",
            false,
            Fault::NetworkDown(Net::B),
            NET_FAULT_S,
        ),
        one(
            "c2-transceiver-a-down",
            "C2's link into net A dead, 8 s: an alarm about C2's transceiver on A",
            false,
            Fault::LinkDown(c2, Net::A),
            NET_FAULT_S,
        ),
        at_once(
            "c2-both-links-down",
            "C2's links into both nets dead, 8 s: controller alarms about C2, no network alarm",
            [Fault::LinkDown(c2, Net::A), Fault::LinkDown(c2, Net::B)],
        ),
        at_once(
            "both-networks-down",
            "both nets dead, 8 s: nobody hears anybody, no network alarm, a double fault possible",
            [Fault::NetworkDown(Net::A), Fault::NetworkDown(Net::B)],
        ),
    ]
}

/// How long a net scenario's faults last: long enough to see an alarm held (raised within
/// a second, cleared within a second and a half of the heal).
const NET_FAULT_S: f64 = 8.0;

/// Every named scenario, in `lab list` order.
pub fn named() -> Vec<Scenario> {
    let mut all = process_and_split_scenarios();
    all.extend(link_and_clock_scenarios());
    all.extend(gray::scenarios());
    all.extend(net_scenarios());
    all.extend(wrong_output::scenarios());
    all
}

/// The named scenario `name`, or `random` with `seed`.
pub fn find(name: &str, seed: u64) -> Option<Scenario> {
    if name == "random" {
        return Some(random(seed));
    }
    let mut scenario = named().into_iter().find(|s| s.name == name)?;
    // The seed varies what a named scenario leaves to chance (the flapping intervals).
    for step in &mut scenario.steps {
        if let Fault::Flap(target, _) = step.fault {
            step.fault = Fault::Flap(target, seed);
        }
    }
    Some(scenario)
}

/// The faults a random schedule draws from (targets are drawn separately).
fn random_fault(rng: &mut impl Rng, target: Target, seed: u64) -> Fault {
    match rng.random_range(0..10) {
        0 => Fault::Kill(target),
        1 => Fault::Pause(target),
        2 => Fault::Partition {
            alone: target,
            actuator_with_alone: rng.random_bool(0.5),
        },
        3 => Fault::Cut(target),
        4 => Fault::OneWay(
            target,
            if rng.random_bool(0.5) {
                Direction::Out
            } else {
                Direction::In
            },
        ),
        5 => Fault::Loss(target, [5, 20, 40][rng.random_range(0..3)]),
        6 => Fault::MulticastOnly(target),
        7 => Fault::Flap(target, seed ^ rng.random::<u64>()),
        8 => Fault::RateLimit(target, 64),
        _ => Fault::ClockOffset(target, [0.1, 0.25, 10.0, -3600.0][rng.random_range(0..4)]),
    }
}

/// A seeded random schedule: 2 to 4 faults in a safety phase of about 20 s, one after the
/// other with random gaps (a fault may start before the previous one is healed when they hit
/// different controllers and neither is a partition or a cut, which involve everyone).
pub fn random(seed: u64) -> Scenario {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let count = rng.random_range(2..=4);
    let mut steps: Vec<Step> = Vec::new();
    let mut at_ms = 1000;
    for _ in 0..count {
        let target = match rng.random_range(0..4) {
            0 => Target::Primary,
            n => Target::Id(n as u8),
        };
        let fault = random_fault(&mut rng, target, seed);
        let lasts_ms = rng.random_range(1000..=5000);
        let overlaps_allowed = steps.last().is_some_and(|prev| {
            !involves_everyone(&prev.fault)
                && !involves_everyone(&fault)
                && prev.fault.target() != Some(target)
                && target != Target::Primary
                && prev.fault.target() != Some(Target::Primary)
        });
        if let Some(prev) = steps.last() {
            let prev_end = prev.at_ms + prev.lasts_ms;
            at_ms = if overlaps_allowed && rng.random_bool(0.5) {
                rng.random_range(prev.at_ms + 200..=prev_end)
            } else {
                prev_end + rng.random_range(500..=4000)
            };
        }
        steps.push(Step {
            at_ms,
            fault,
            lasts_ms,
        });
    }
    Scenario {
        name: "random".into(),
        about: format!("seed {seed}: {}", describe(&steps)),
        steps,
        in_ci: false,
        network: None,
        output: None,
    }
}

fn involves_everyone(fault: &Fault) -> bool {
    matches!(
        fault,
        Fault::Partition { .. } | Fault::Cut(_) | Fault::OneWay(..)
    )
}

/// `at 1.0 s for 3.2 s: kill -9 C2, restart; ...` (`for 3 s`, `for 0.15 s`).
pub fn describe(steps: &[Step]) -> String {
    steps
        .iter()
        .map(|s| {
            // Whole milliseconds shown as they are: a 150 ms freeze is not "0.1 s".
            format!(
                "at {:.1} s for {} s: {}",
                s.at_ms as f64 / 1000.0,
                s.lasts_ms as f64 / 1000.0,
                s.fault
            )
        })
        .collect::<Vec<_>>()
        .join("; ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_seed_gives_the_same_schedule_every_time() {
        assert_eq!(random(42).steps, random(42).steps);
        assert_ne!(random(42).steps, random(43).steps);
    }

    #[test]
    fn names_are_unique_and_found() {
        let names: Vec<String> = named().into_iter().map(|s| s.name).collect();
        let mut unique = names.clone();
        unique.sort();
        unique.dedup();
        assert_eq!(names.len(), unique.len());
        assert!(names.iter().all(|n| find(n, 1).is_some()));
        assert!(find("random", 5).is_some());
        assert!(find("no-such", 5).is_none());
    }

    #[test]
    fn random_schedules_never_draw_a_net_fault() {
        // Their expectations (no network alarm, a controller-level fault's figures) would not
        // hold for a net or link fault.
        for seed in 0..500 {
            for step in random(seed).steps {
                assert!(
                    !matches!(step.fault, Fault::LinkDown(..) | Fault::NetworkDown(_)),
                    "seed {seed}"
                );
            }
        }
    }

    #[test]
    fn net_scenarios_are_judged_on_network_alarms_and_not_in_ci() {
        for s in named() {
            let net = s.name.starts_with("net-")
                || s.name.starts_with("c2-")
                || s.name == "both-networks-down";
            assert_eq!(s.network.is_some(), net, "{}", s.name);
            if net {
                assert!(!s.in_ci, "{}", s.name);
            }
        }
    }

    #[test]
    fn the_two_controller_architectures_run_c3_s_faults_on_c2_and_one_wrong_output_at_a_time() {
        for architecture in [Architecture::Duplex, Architecture::Pair] {
            let clock = find("clock-drift", 1).and_then(|s| s.under(architecture).ok());
            let clock = clock.expect("a clock scenario runs under both");
            assert!(clock
                .steps
                .iter()
                .all(|step| step.fault.target() != Some(Target::Id(3))));
            assert!(clock
                .steps
                .iter()
                .any(|step| step.fault.target() == Some(Target::Id(2))));
            let both = find("c2-both-links-down", 1).and_then(|s| s.under(architecture).ok());
            let alarms = both.and_then(|s| s.network).map(|n| n.controller_alarms);
            assert_eq!(alarms, Some(vec![(1, 2), (2, 1)]));
            assert!(find("wrong-primary", 1).is_some_and(|s| s.under(architecture).is_ok()));
            let two_wrong = find("two-wrong", 1).map(|s| s.under(architecture).is_ok());
            assert_eq!(two_wrong, Some(architecture == Architecture::Duplex));
            // Every scenario it runs has expectations of its own under it.
            for s in named()
                .into_iter()
                .filter_map(|s| s.under(architecture).ok())
            {
                assert!(s.expected_in(architecture).is_ok(), "{}", s.name);
            }
        }
        let voting = find("clock-drift", 1).and_then(|s| s.under(Architecture::Voting).ok());
        assert!(voting.is_some_and(|s| s
            .steps
            .iter()
            .any(|step| step.fault.target() == Some(Target::Id(3)))));
    }

    #[test]
    fn random_schedules_never_overlap_a_partition() {
        for seed in 0..200 {
            let steps = random(seed).steps;
            for pair in steps.windows(2) {
                if involves_everyone(&pair[0].fault) || involves_everyone(&pair[1].fault) {
                    assert!(
                        pair[1].at_ms >= pair[0].at_ms + pair[0].lasts_ms,
                        "seed {seed}"
                    );
                }
            }
        }
    }
}
