//! One attempt's processes and what they printed, and the steps the driver ([`super`]) takes
//! with them: start every process held until all have discovered each other, let each go in
//! its round, apply a round's faults on time (a pause is SIGSTOP, a resume SIGCONT,
//! cuts and pulled cables are [`super::cuts`] on the virtual LAN), wait for and compare a
//! boundary (the faults in `run/faults.rs`). Every
//! observation first checks the processes' health: a process the plan did not kill must
//! still run, and the heartbeat drops logged so far must be the injected ones
//! ([`super::drops`]).

use super::config::{
    RunTiming, DECIDED_BY_MS, DISCOVERY_TIMEOUT, OBSERVE_OFFSET_MS, SETTLE_TIMEOUT,
};
use super::cuts::Cuts;
use super::drops::DropBook;
use super::error::{owner_name, owners_allowed, Failure, Problem};
use super::lives::{self, Life};
use super::plan::{owners, Plan};
use super::processes::{Line, Namespaces, Processes, SERVO};
use super::servo::{describe_counts, OwnerSeen, ServoView};
use super::transcript::Output;
use super::Setup;

mod faults;
use crate::diff::state_diff;
use crate::lab::lan::{Lan, Node};
use crate::record::{describe_event, round_of};
use model::traces::AbstractState;
use model::Action;
use rl::procs::{parse_servo_event, wall_ms};
use rl_layer::core::ControllerId;
use rl_layer::event::{Event, EventLine};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::sync::mpsc::Receiver;
use std::time::{Duration, Instant};

/// What a boundary is compared against: the plan's state, and who may own the actuator
/// ([`super::plan::owners`]: with a tie, any of the strongest).
pub(super) struct Expected {
    pub boundary: usize,
    pub state: AbstractState,
    pub owners: Vec<ControllerId>,
}

impl Expected {
    /// The state to compare with one whose owner is `observed`: with the observed owner if
    /// the model allows it, else with the model's own.
    fn against(&self, observed: Option<ControllerId>) -> AbstractState {
        let mut state = self.state.clone();
        let allowed = match observed {
            Some(id) => self.owners.contains(&id),
            None => self.owners.is_empty(),
        };
        if allowed {
            state.actuator_owner = observed;
        }
        state
    }
}

pub(super) struct Run<'a> {
    pub plan: &'a Plan,
    pub timing: RunTiming,
    processes: Processes,
    lines: Receiver<Line>,
    lives: Vec<Life>,
    servo: ServoView,
    drops: DropBook,
    output: Output,
    /// The real round of the first boundary, once known.
    first_round: Option<u64>,
    /// The cuts and pulled cables in force, on the virtual LAN (if the plan has any).
    cuts: Option<Cuts<'a>>,
    /// The processes started and held, not let go yet, in the order the plan lets them go.
    held: Vec<Held>,
    /// What each held process reported discovered last (its `held` lines).
    discovered: BTreeMap<String, (usize, usize)>,
    /// The processes admitted in this round, to be let go before its heartbeats.
    letting_go: Vec<String>,
    /// The controllers whose link is starved, and the control line for their commands now.
    starved: BTreeMap<ControllerId, String>,
}

/// A controller process started and held before it votes, to be let go in the round the
/// trace starts it.
#[derive(Clone, Debug)]
pub(super) struct Held {
    pub id: ControllerId,
    /// Its number among the processes of its id (0 for the first): its source name.
    pub number: u8,
    pub source: String,
}

/// Every controller process the plan starts, in the order it starts them: the initial
/// controllers, then each join and restart.
fn processes_of(plan: &Plan) -> Vec<Held> {
    let starts = plan
        .rounds
        .iter()
        .flat_map(|r| &r.lifecycle)
        .filter_map(|a| match *a {
            Action::Join { controller } | Action::Restart { controller } => Some(controller),
            _ => None,
        });
    let mut numbers: BTreeMap<ControllerId, u8> = BTreeMap::new();
    plan.initial_up
        .iter()
        .copied()
        .chain(starts)
        .map(|id| {
            let number = numbers.entry(id).or_default();
            let held = Held {
                id,
                number: *number,
                source: lives::source_name(id, *number),
            };
            *number += 1;
            held
        })
        .collect()
}

impl<'a> Run<'a> {
    /// An attempt on loopback, or on `lan` (one namespace per node) if given.
    pub fn new(
        plan: &'a Plan,
        setup: &Setup,
        timing: RunTiming,
        config: &std::path::Path,
        lan: Option<&'a Lan>,
    ) -> Self {
        let namespaces = lan.map(|lan| Namespaces {
            controllers: crate::lab::lan::CONTROLLER_IDS
                .iter()
                .map(|&id| (id, lan.ns(Node::Controller(id))))
                .collect(),
            servo: lan.ns(Node::Actuator),
        });
        let (processes, lines) = Processes::new(
            setup.exe,
            config,
            setup.domain,
            setup.mutation.as_deref(),
            namespaces,
        );
        Run {
            cuts: lan.map(Cuts::new),
            plan,
            timing,
            processes,
            lines,
            lives: Vec::new(),
            servo: ServoView::default(),
            drops: DropBook::default(),
            output: Output::default(),
            first_round: None,
            held: processes_of(plan),
            discovered: BTreeMap::new(),
            letting_go: Vec::new(),
            starved: BTreeMap::new(),
        }
    }

    pub fn period_ms(&self) -> u64 {
        self.timing.rounds.period_ms
    }

    /// The servo and every controller process of the plan, held; returns once all have
    /// discovered each other (each knows a heartbeat writer and reader of every controller
    /// process, and the servo's reader).
    pub fn start_held(&mut self) -> Result<(), Failure> {
        if let Err(source) = self.processes.start_servo() {
            let what = "rl servo --json".to_string();
            return Err(self.failure(false, Problem::Spawn { what, source }));
        }
        for index in 0..self.held.len() {
            let Held { id, ref source, .. } = self.held[index];
            let source = source.clone();
            if let Err(source) = self.processes.start_controller(id, &source) {
                let what = format!("rl controller --id {id}");
                return Err(self.failure(false, Problem::Spawn { what, source }));
            }
        }
        // Every controller process has a heartbeat writer and reader, the servo a reader, and
        // each counts its own.
        let needed = (self.held.len(), self.held.len() + 1);
        let deadline = Instant::now() + DISCOVERY_TIMEOUT;
        loop {
            self.pump(Duration::from_millis(5));
            let all = self.held.iter().all(|h| {
                self.discovered
                    .get(&h.source)
                    .is_some_and(|&(writers, readers)| writers >= needed.0 && readers >= needed.1)
            });
            if all {
                return Ok(());
            }
            self.check_exits(round_of(wall_ms(), self.period_ms()))?;
            if Instant::now() >= deadline {
                let counts = self
                    .held
                    .iter()
                    .map(|h| match self.discovered.get(&h.source) {
                        Some((writers, readers)) => format!("{} {writers}/{readers}", h.source),
                        None => format!("{} none", h.source),
                    })
                    .collect::<Vec<_>>()
                    .join(", ");
                let timeout = DISCOVERY_TIMEOUT;
                let problem = Problem::NotDiscovered {
                    timeout,
                    counts,
                    writers: needed.0,
                    readers: needed.1,
                };
                return Err(self.failure(true, problem));
            }
        }
    }

    /// Real round `start`: round 0's faults, and the trace's initial controllers let go
    /// with round 0's starts; boundary 1 is the next.
    pub fn start(&mut self, start: u64) -> Result<(), Failure> {
        let plan = self.plan;
        self.first_round = Some(start + 1);
        for &id in &plan.initial_up {
            self.admit(id, start)?;
        }
        // One that crashes in round 0 runs until then: let go now, before the others (held
        // until +55, they throw its first heartbeat away, as the model's crash loses it).
        for action in &plan.rounds[0].lifecycle {
            if let Action::Crash { controller } = *action {
                let pending = self.letting_go.iter().position(|source| {
                    lives::of_process_mut(&mut self.lives, source)
                        .is_some_and(|l| l.log.id == controller)
                });
                if let Some(index) = pending {
                    let source = self.letting_go.remove(index);
                    self.let_go_now(&source, start)?;
                    // Until it has said it runs, within the round's first tens of ms.
                    let deadline = Instant::now() + Duration::from_millis(40);
                    while Instant::now() < deadline
                        && !lives::of_process_mut(&mut self.lives, &source)
                            .is_some_and(|l| l.stamped)
                    {
                        self.pump(Duration::from_millis(1));
                    }
                }
            }
        }
        self.apply(&plan.rounds[0], start)?;
        self.resume_within_round(&plan.rounds[0], start)
    }

    /// Boundary `k` as compared in the lockstep, where round `k`'s faults were applied at its
    /// start: the owner is the one through the round, after its crashes.
    pub fn expected_in_lockstep(&self, k: usize) -> Expected {
        let mut state = self.plan.expected(k);
        let owners = self.plan.owners_in_round[k].clone();
        state.actuator_owner = owners.first().copied();
        Expected {
            boundary: k,
            state,
            owners,
        }
    }

    /// Boundary `k` as waited for: no faults in the rounds it is observed in.
    pub fn expected_at_rest(&self, k: usize) -> Expected {
        Expected {
            boundary: k,
            state: self.plan.expected(k),
            owners: owners(&self.plan.boundaries[k]),
        }
    }

    /// Waits until `expected` is observed at `times` consecutive boundaries; returns the real
    /// round of the last.
    pub fn await_state(&mut self, expected: &Expected, times: u64) -> Result<u64, Failure> {
        let deadline = Instant::now() + SETTLE_TIMEOUT;
        let mut run = 0;
        let mut real = round_of(wall_ms(), self.period_ms());
        loop {
            self.sleep_until(real * self.period_ms() + OBSERVE_OFFSET_MS);
            let (observed, owner) = self.observe(real)?;
            let settled = !matches!(owner, OwnerSeen::Unsettled(_));
            if settled && observed == expected.against(observed.actuator_owner) {
                run += 1;
                if run >= times {
                    return Ok(real);
                }
            } else {
                run = 0;
                if Instant::now() >= deadline {
                    let k = expected.boundary;
                    let last = self.plan.last();
                    let what = if k == last {
                        "the settled end"
                    } else {
                        "quiescent, faults follow"
                    };
                    let model = expected.against(observed.actuator_owner);
                    let mut diff = state_diff("processes", "the processes'", &model, &observed);
                    if let OwnerSeen::Unsettled(counts) = owner {
                        let _ = writeln!(diff, "  the servo: {}", describe_counts(&counts));
                    }
                    let timeout = SETTLE_TIMEOUT;
                    let problem = Problem::NotReached {
                        boundary: k,
                        last,
                        what,
                        timeout,
                        real,
                        diff,
                    };
                    return Err(self.failure(false, problem));
                }
            }
            real += 1;
        }
    }

    /// Compares the boundary observed in real round `real` with `expected`.
    pub fn compare(
        &mut self,
        expected: &Expected,
        real: u64,
        how: &'static str,
    ) -> Result<(), Failure> {
        let (observed, owner) = self.observe(real)?;
        if let OwnerSeen::Unsettled(counts) = owner {
            let problem = Problem::OwnerUnsettled {
                boundary: expected.boundary,
                real,
                from_ms: self.timing.owner_from_ms,
                until_ms: OBSERVE_OFFSET_MS,
                expected: expected.owners.clone(),
                commands: describe_counts(&counts),
            };
            return Err(self.failure(false, problem));
        }
        let model = expected.against(observed.actuator_owner);
        if observed == model {
            return Ok(());
        }
        let mut diff = state_diff("processes", "the processes'", &model, &observed);
        if observed.actuator_owner != model.actuator_owner {
            let _ = writeln!(
                diff,
                "  (the owner is the servo's: every command it accepted {}-{} ms into the \
                 round came from {}; the model allows {})",
                self.timing.owner_from_ms,
                OBSERVE_OFFSET_MS,
                owner_name(observed.actuator_owner),
                owners_allowed(&expected.owners)
            );
        }
        let problem = Problem::StateDiffers {
            boundary: expected.boundary,
            last: self.plan.last(),
            how,
            real,
            since_first: real - self.first_round.unwrap_or(real),
            diff,
        };
        Err(self.failure(false, problem))
    }

    /// The controllers' reports at the boundary of real round `real`, with the servo's owner
    /// in the round's owner window; the processes' health checked first.
    fn observe(&mut self, real: u64) -> Result<(AbstractState, OwnerSeen), Failure> {
        self.check_exits(real)?;
        let period_ms = self.period_ms();
        let dead_after_rounds = u64::from(self.timing.rounds.dead_after_rounds);
        if let Err(problem) = self
            .drops
            .check(&self.lives, real, period_ms, dead_after_rounds)
        {
            return Err(self.failure(false, problem));
        }
        let count = self.plan.boundaries[0].controllers.len();
        let mut observed = lives::observe(&self.lives, count, real, period_ms, DECIDED_BY_MS)
            .map_err(|e| self.failure(false, e.into()))?;
        let boundary_ms = real * period_ms;
        let owner = self.servo.owner_between(
            boundary_ms + self.timing.owner_from_ms,
            boundary_ms + OBSERVE_OFFSET_MS,
        );
        observed.actuator_owner = match owner {
            OwnerSeen::One(id) => Some(id),
            OwnerSeen::Nobody | OwnerSeen::Unsettled(_) => None,
        };
        Ok((observed, owner))
    }

    /// A process that exited without the plan killing it is a failure.
    fn check_exits(&mut self, real: u64) -> Result<(), Failure> {
        let exited = self.processes.exited();
        let Some((source_name, status)) = exited.into_iter().next() else {
            return Ok(());
        };
        // Its last lines may still be in the pipe.
        self.pump(Duration::from_millis(100));
        let tail = self.output.process_tail(&source_name);
        let problem = Problem::ProcessExited {
            source_name,
            status,
            real,
            tail,
        };
        Err(self.failure(false, problem))
    }

    /// Takes in what the processes printed, waiting up to `wait` for the first line.
    fn pump(&mut self, wait: Duration) {
        let mut first = true;
        loop {
            let line = if first {
                self.lines.recv_timeout(wait).ok()
            } else {
                self.lines.try_recv().ok()
            };
            first = false;
            let Some(line) = line else {
                break;
            };
            self.take(line);
        }
    }

    fn take(&mut self, line: Line) {
        let period_ms = self.period_ms();
        let round = round_of(line.wall_ms, period_ms);
        let relative = self.first_round.map_or(String::new(), |f| {
            format!(" ({:+})", round as i64 - f as i64)
        });
        let shown = if line.source == SERVO {
            parse_servo_event(&line.text).map_or(Some(line.text.clone()), |event| {
                self.servo.take(line.wall_ms, &event);
                super::servo::describe(&event)
            })
        } else if let Some(event) = EventLine::parse(&line.text) {
            if let Event::Held {
                heartbeat_writers,
                heartbeat_readers,
            } = event.event
            {
                let counts = (heartbeat_writers, heartbeat_readers);
                self.discovered.insert(line.source.clone(), counts);
            }
            let is_leds = matches!(event.event, Event::Leds { .. });
            let shown = (!is_leds).then(|| describe_event(&event, None));
            // A held line comes before the process's life: no incarnation yet.
            let life = match event.event {
                Event::Held { .. } => None,
                _ => lives::of_process_mut(&mut self.lives, &line.source),
            };
            if let Some(life) = life {
                if !life.stamped {
                    life.log.incarnation = event.incarnation;
                    life.stamped = true;
                }
                if event.incarnation == life.log.incarnation {
                    life.log.events.push(event);
                } else {
                    // The process went on as a new incarnation (after a stall, a lost carrier,
                    // or deposed). One that began with a boundary's decisions (deposed, which
                    // it learns at a round's end) is that boundary's: as if started in the
                    // round before.
                    let at_boundary = event.t_ms % period_ms < DECIDED_BY_MS;
                    let started = if at_boundary {
                        round_of(event.t_ms, period_ms).saturating_sub(1)
                    } else {
                        round
                    };
                    // A life after a resume is that round's, however soon after the
                    // boundary its first line comes.
                    let started = life.resumed_round.map_or(started, |r| started.max(r));
                    let mut next = life.next_incarnation(event.incarnation, started, line.wall_ms);
                    next.log.events.push(event);
                    self.lives.push(next);
                }
            }
            shown
        } else {
            Some(super::transcript::without_terminal_colours(&line.text))
        };
        if let Some(shown) = shown {
            let source = &line.source;
            let text = format!("{} round {round}{relative} {source}: {shown}", line.wall_ms);
            self.output.show(text);
        }
        self.output.keep(&line.source, &line.text);
    }

    pub fn sleep_until(&mut self, target_ms: u64) {
        loop {
            let now = wall_ms();
            if now >= target_ms {
                self.pump(Duration::ZERO);
                return;
            }
            self.pump(Duration::from_millis((target_ms - now).min(20)));
        }
    }

    /// A problem with the run's context: the plan, the processes, their last lines.
    pub fn failure(&self, retry: bool, problem: Problem) -> Failure {
        let mut context = String::new();
        let _ = writeln!(context, "\n  plan: {}", self.plan.describe());
        let lives: Vec<String> = self
            .lives
            .iter()
            .map(|l| {
                let killed = l
                    .killed_round
                    .map_or(String::new(), |k| format!(", killed round {k}"));
                format!(
                    "{} (started round {}{killed})",
                    l.log.source, l.spawned_round
                )
            })
            .collect();
        let _ = writeln!(context, "  processes: {}, servo", lives.join(", "));
        let _ = writeln!(
            context,
            "  --- the last {} lines the processes printed (wall ms, round, rounds since \
             boundary 1; leds events and servo commands left out) ---",
            super::transcript::TAIL_LINES
        );
        for line in self.output.transcript_tail() {
            let _ = writeln!(context, "  {line}");
        }
        Failure {
            problem,
            retry,
            context,
        }
    }

    /// Stops every process (SIGTERM, then SIGKILL) and takes in their last lines.
    pub fn stop(&mut self) {
        self.processes.stop_all();
        // The LAN outlives the attempt: the next one starts with every link whole.
        if let Some(cuts) = self.cuts.as_mut() {
            cuts.heal_all();
        }
        self.pump(Duration::from_millis(200));
    }

    pub fn output(&self) -> &Output {
        &self.output
    }
}
