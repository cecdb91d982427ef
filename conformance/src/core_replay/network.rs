//! Real cores on a simulated clock and network, stepped by model actions (the mapping is in
//! the parent module's header). Every input that reaches a core is logged with the commands
//! it returned, so a transcript shows what the core did, not what the trace says.

use super::{Problem, DELIVERY_OFFSET_MS, PERIOD_MS, START_OFFSET_MS};
use crate::abstraction::{self, IncarnationNumbers, Observed};
use model::traces::AbstractState;
use model::{Action, Life};
use rl_layer::core::types::{Arrival, TAKEOVER_STRENGTH};
use rl_layer::core::{
    Command, ControllerId, Core, CoreConfig, Heartbeat, Input, Restart, Rounds, Timer,
};
use std::collections::{BTreeMap, BTreeSet};

/// Why a core was stepped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cause {
    /// One of its timers fired.
    Timer(Timer),
    /// A peer's heartbeat was delivered.
    HeartbeatFrom(ControllerId),
    /// It started (a new life).
    Started,
    /// How a peer's commands arrive changed (F17).
    Arrival(ControllerId, Arrival),
}

/// One input to one core and the commands it returned.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Emitted {
    pub cause: Cause,
    pub commands: Vec<Command>,
}

/// What each core did during one step, by controller id, in order.
pub type StepLog = BTreeMap<ControllerId, Vec<Emitted>>;

/// Every command a core emitted during the step, in order.
pub fn commands_of(log: &[Emitted]) -> Vec<Command> {
    log.iter()
        .flat_map(|e| e.commands.iter().cloned())
        .collect()
}

/// Adjusts each core's configuration before it starts.
pub type Configure = dyn Fn(CoreConfig) -> CoreConfig;

/// One controller id's slot in the simulated system.
#[derive(Clone, Debug)]
struct Slot {
    id: ControllerId,
    life: Life,
    /// The model's incarnation number of its current or last life.
    incarnation: u8,
    /// The running core, while `life` is up.
    core: Option<Core>,
    /// The stopped core, while `life` is paused: told `Input::StartAgain` at the resume (it
    /// goes on as it was only under the `KeepIncarnationOnResume` mutation).
    paused: Option<Core>,
}

/// Real cores on a simulated clock and network, stepped by model actions.
pub struct CoreNetwork<'a> {
    rounds: Rounds,
    configure: &'a Configure,
    /// The current round: the model's rounds ended so far.
    round: u64,
    slots: Vec<Slot>,
    /// Links whose heartbeat is lost this round, as (from, to).
    lost: BTreeSet<(ControllerId, ControllerId)>,
    /// Controllers cut off from their peers (every heartbeat to and from them lost).
    isolated: BTreeSet<ControllerId>,
    /// Of the cut-off controllers, those whose cable is out: the actuator does not hear them.
    unplugged: BTreeSet<ControllerId>,
    /// Controllers whose links are starved: their commands reach their peers late (F17).
    starved: BTreeSet<ControllerId>,
    /// Of the starved controllers, those whose command deadline the actuator missed: it does
    /// not count their writers until a late sample arrives.
    lagging: BTreeSet<ControllerId>,
    /// The actuator over the cores' command writers (see [`Actuator`]).
    actuator: Actuator,
    pub(super) numbers: IncarnationNumbers,
}

/// The actuator as DDS exclusive ownership runs it over the cores' command writers: the
/// model's rule (`model::protocol::actuator::next_owner`), the environment the cores command,
/// not part of the implementation under test. A writer the core created in a step is
/// undiscovered until the trace's `DiscoverWriter` or the round's end; the core's retiring
/// writer stays visible for that round; ties go by the trace's `TieBreak` order.
#[derive(Clone, Debug, Default)]
struct Actuator {
    owner: Option<ControllerId>,
    /// Bit `model::state::link_bit(a, b)`: at equal strength `a`'s writers beat `b`'s.
    tie_order: u16,
    undiscovered: BTreeSet<ControllerId>,
}

impl<'a> CoreNetwork<'a> {
    /// The cores of a trace's initial state, started together inside round 0.
    pub fn start(
        config: &model::Config,
        initial: &AbstractState,
        configure: &'a Configure,
    ) -> Result<CoreNetwork<'a>, Problem> {
        let mut network = CoreNetwork {
            rounds: Rounds {
                dead_after_rounds: u32::from(config.dead_after_rounds),
                window_rounds: u32::from(config.window_rounds),
            },
            configure,
            round: 0,
            slots: Vec::new(),
            lost: BTreeSet::new(),
            isolated: BTreeSet::new(),
            unplugged: BTreeSet::new(),
            starved: BTreeSet::new(),
            lagging: BTreeSet::new(),
            actuator: Actuator::default(),
            numbers: IncarnationNumbers::new(),
        };
        for (index, c) in initial.controllers.iter().enumerate() {
            if usize::from(c.id) != index + 1 {
                return Err(Problem::Unsupported(format!(
                    "controller {} listed at position {}",
                    c.id,
                    index + 1
                )));
            }
            network.slots.push(Slot {
                id: c.id,
                life: Life::NotStarted,
                incarnation: c.incarnation,
                core: None,
                paused: None,
            });
            match c.life {
                Life::Up => network.start_core(c.id, c.incarnation)?,
                Life::Down => network.slots[index].life = Life::Down,
                Life::NotStarted => {}
                Life::Paused => {
                    return Err(Problem::Unsupported(format!(
                        "C{} is paused in the initial state",
                        c.id
                    )))
                }
            }
        }
        network.arbitrate();
        Ok(network)
    }

    /// The current round's boundary (its start).
    fn boundary_ms(&self) -> u64 {
        self.round * PERIOD_MS
    }

    fn slot_mut(&mut self, id: ControllerId) -> Result<&mut Slot, Problem> {
        let index = usize::from(id).wrapping_sub(1);
        self.slots.get_mut(index).ok_or_else(|| {
            Problem::Unsupported(format!(
                "the action names C{id}, which the trace does not have"
            ))
        })
    }

    fn live_core(&mut self, id: ControllerId) -> Result<&mut Core, Problem> {
        self.slot_mut(id)?
            .core
            .as_mut()
            .ok_or_else(|| Problem::Timing(format!("C{id} is not running")))
    }

    fn start_core(&mut self, id: ControllerId, incarnation: u8) -> Result<(), Problem> {
        let rounds = self.rounds;
        let start_ms = self.boundary_ms() + START_OFFSET_MS;
        // The implementation's incarnation is the model's number, so holders map one to one.
        let stamp = u64::from(incarnation);
        let number = self.numbers.started(id, stamp);
        if number != incarnation {
            return Err(Problem::Timing(format!(
                "C{id} starts its life #{incarnation}, but it is its start number {number}"
            )));
        }
        let config = (self.configure)(CoreConfig::new(id, stamp, PERIOD_MS, rounds));
        let slot = self.slot_mut(id)?;
        slot.life = Life::Up;
        slot.incarnation = incarnation;
        slot.core = Some(Core::new(config, start_ms));
        self.forget_last_life(id);
        Ok(())
    }

    /// A new life of `id`: the losses of its last life end, and its writers have new GUIDs,
    /// so their tie order is not known yet.
    fn forget_last_life(&mut self, id: ControllerId) {
        self.lost.retain(|&(from, to)| from != id && to != id);
        for other in self.slots.iter().map(|slot| slot.id) {
            let links = model::state::link_bit(id, other) | model::state::link_bit(other, id);
            self.actuator.tie_order &= !links;
        }
    }

    /// `Input::StartAgain` to a running core at `now_ms`, as the runtime sends it after a
    /// stall, a lost carrier or a takeover from it, with the next incarnation; whether the
    /// core started a new life (it does not under the `KeepIncarnationOnResume` and
    /// `StayWhenUnplugged` mutations).
    fn start_again(
        &mut self,
        id: ControllerId,
        cause: Restart,
        now_ms: u64,
    ) -> Result<bool, Problem> {
        let next = self.slot_mut(id)?.incarnation.saturating_add(1);
        let stamp = u64::from(next);
        let commands = self.live_core(id)?.step(
            Input::StartAgain {
                cause,
                incarnation: stamp,
            },
            now_ms,
        );
        if commands.is_empty() {
            return Ok(false);
        }
        let number = self.numbers.started(id, stamp);
        if number != next {
            return Err(Problem::Timing(format!(
                "C{id} starts its life #{next}, but it is its start number {number}"
            )));
        }
        self.slot_mut(id)?.incarnation = next;
        self.forget_last_life(id);
        Ok(true)
    }

    /// What an observer sees of every controller, in id order.
    pub fn observed(&self) -> Vec<Observed> {
        self.slots
            .iter()
            .map(|slot| match (&slot.core, slot.life) {
                (Some(core), _) => Observed::Up(Box::new(core.status())),
                (None, Life::Down) => Observed::Down {
                    incarnation: u64::from(slot.incarnation),
                },
                (None, Life::Paused) => Observed::Paused {
                    incarnation: u64::from(slot.incarnation),
                },
                (None, _) => Observed::NotStarted,
            })
            .collect()
    }

    /// The abstract state of the cores, with the actuator's owner.
    pub fn observe(&self) -> Result<AbstractState, Problem> {
        let mut state = abstraction::abstract_state(&self.observed(), &self.numbers)
            .map_err(Problem::Abstraction)?;
        state.actuator_owner = self.actuator.owner;
        Ok(state)
    }

    /// Each running core's command strength.
    fn outputs(&self) -> BTreeMap<ControllerId, Option<u8>> {
        self.slots
            .iter()
            .filter_map(|slot| {
                slot.core
                    .as_ref()
                    .map(|core| (slot.id, core.state().output.map(abstraction::strength)))
            })
            .collect()
    }

    /// Performs one model action; returns what each core did.
    pub fn apply(&mut self, action: Action) -> Result<StepLog, Problem> {
        let before = self.outputs();
        if action == Action::Tick {
            // The writers created last round are established now (the model's timing
            // assumption: discovery within a round).
            self.actuator.undiscovered.clear();
        }
        let log = self.perform(action)?;
        for (id, output) in self.outputs() {
            if before.get(&id) != Some(&output) {
                // A takeover moves to the writer the runtime keeps ready, which every reader
                // knows already (F17).
                let ready = matches!(action, Action::Starve { .. })
                    && output == Some(abstraction::strength(TAKEOVER_STRENGTH));
                match output {
                    Some(_) if !ready => self.actuator.undiscovered.insert(id),
                    _ => self.actuator.undiscovered.remove(&id),
                };
            }
        }
        self.arbitrate();
        Ok(log)
    }

    /// The actuator's owner after a step: the model's rule over the visible writers.
    fn arbitrate(&mut self) {
        let writers: Vec<(ControllerId, u8)> = self
            .slots
            .iter()
            .filter(|slot| !self.unplugged.contains(&slot.id) && !self.lagging.contains(&slot.id))
            .filter_map(|slot| {
                let state = slot.core.as_ref()?.state();
                let newest = state
                    .output
                    .filter(|_| !self.actuator.undiscovered.contains(&slot.id));
                newest
                    .max(state.writer.retiring)
                    .map(|strength| (slot.id, abstraction::strength(strength)))
            })
            .collect();
        if let Some(to) = model::protocol::actuator::next_owner(
            &writers,
            self.actuator.owner,
            self.actuator.tie_order,
        ) {
            self.actuator.owner = Some(to);
        }
    }

    fn perform(&mut self, action: Action) -> Result<StepLog, Problem> {
        let mut log = StepLog::new();
        match action {
            Action::Tick => self.tick(&mut log)?,
            Action::LoseHeartbeat { from, to } => {
                self.lost.insert((from, to));
            }
            // The gray process faults are judged on processes (the fault lab); the trace set
            // has none of them.
            Action::Slow { .. }
            | Action::LateHeartbeat { .. }
            | Action::HearLate { .. }
            | Action::Oversleep { .. }
            | Action::Thaw { .. } => {
                return Err(Problem::Unsupported(format!(
                    "{action}: a gray process fault, judged by the fault lab, not replayed on cores"
                )));
            }
            Action::ExpireWindow { controller } => {
                let boundary = self.boundary_ms();
                let core = self.live_core(controller)?;
                let due = core.next_deadline();
                if due.timer != Timer::WindowExpiry || due.at_ms > boundary {
                    return Err(Problem::Timing(format!(
                        "C{controller}'s initialization window is not due at the round \
                         boundary ({boundary} ms; its next timer is {:?} at {} ms)",
                        due.timer, due.at_ms
                    )));
                }
                let commands = core.step(Input::Timer(due.timer), due.at_ms);
                log.insert(
                    controller,
                    vec![Emitted {
                        cause: Cause::Timer(due.timer),
                        commands,
                    }],
                );
            }
            Action::Crash { controller } => {
                let slot = self.slot_mut(controller)?;
                slot.core = None;
                slot.life = Life::Down;
                self.lost
                    .retain(|&(from, to)| from != controller && to != controller);
            }
            // A stall restarts the controller as a new incarnation when it resumes (the
            // runtime's stall detection, impl/layer/src/stall.rs; the model's F12).
            Action::Restart { controller } => {
                let next = self.slot_mut(controller)?.incarnation.saturating_add(1);
                self.start_core(controller, next)?;
                log.insert(controller, vec![started()]);
            }
            // The runtime finds its loop stalled for a peer deadline and tells the core to
            // start again (impl/layer/src/stall.rs; the model's F12).
            Action::Resume { controller } => {
                let slot = self.slot_mut(controller)?;
                let core = slot.paused.take().ok_or_else(|| {
                    Problem::Timing(format!("C{controller} resumes but was not paused"))
                })?;
                slot.core = Some(core);
                slot.life = Life::Up;
                // Stopped for at least a peer deadline: what the runtime restarts after.
                let stalled_ms = u64::from(self.rounds.dead_after_rounds) * PERIOD_MS;
                let now_ms = self.boundary_ms() + START_OFFSET_MS;
                if self.start_again(controller, Restart::Stalled { stalled_ms }, now_ms)? {
                    log.insert(controller, vec![started()]);
                }
            }
            Action::Pause { controller } => {
                let slot = self.slot_mut(controller)?;
                slot.paused = slot.core.take();
                slot.life = Life::Paused;
            }
            Action::Isolate { controller } => {
                self.isolated.insert(controller);
            }
            // The runtime sees its carrier go and starts again as a new incarnation
            // (impl/layer/src/link_watch.rs; the model's F16).
            Action::Unplug { controller } => {
                self.isolated.insert(controller);
                self.unplugged.insert(controller);
                let now_ms = self.boundary_ms() + START_OFFSET_MS;
                if self.start_again(controller, Restart::Detached, now_ms)? {
                    log.insert(controller, vec![started()]);
                }
            }
            Action::Heal { controller } => {
                self.isolated.remove(&controller);
                self.unplugged.remove(&controller);
                self.lagging.remove(&controller);
                // A starved link drained: its commands arrive on time again.
                if self.starved.remove(&controller) {
                    self.arrivals(&mut log);
                }
            }
            // The runtime measures how each peer's commands arrive (impl/layer/src/runtime/
            // arrival.rs): the starved controller's late, every other's on time.
            Action::Starve { controller } => {
                self.starved.insert(controller);
                self.arrivals(&mut log);
            }
            Action::Lag { controller } => {
                self.lagging.insert(controller);
            }
            Action::CatchUp { controller } => {
                self.lagging.remove(&controller);
            }
            Action::DiscoverWriter { controller } => {
                self.actuator.undiscovered.remove(&controller);
            }
            Action::TieBreak { to } => {
                if let Some(owner) = self.actuator.owner {
                    self.actuator.tie_order |= model::state::link_bit(to, owner);
                }
                self.actuator.owner = Some(to);
            }
            Action::Join { controller } => {
                self.start_core(controller, 0)?;
                log.insert(controller, vec![started()]);
            }
            Action::DeliverVotes { to } => {
                return Err(Problem::Unsupported(format!(
                    "votes delivered to C{to}: durable-vote delivery exists only in the paper \
                     variant"
                )));
            }
        }
        Ok(log)
    }

    /// Every live core learns how each live peer's commands arrive: late from a starved
    /// controller, then on time from the others (a Tertiary's command arriving on time after
    /// the Primary's late one is what lets a Secondary take over).
    fn arrivals(&mut self, log: &mut StepLog) {
        let at_ms = self.boundary_ms() + DELIVERY_OFFSET_MS;
        let live: Vec<ControllerId> = self
            .slots
            .iter()
            .filter(|slot| slot.core.is_some())
            .map(|slot| slot.id)
            .collect();
        let mut order: Vec<(ControllerId, Arrival)> = live
            .iter()
            .filter(|id| self.starved.contains(id))
            .map(|id| (*id, Arrival::Late))
            .collect();
        order.extend(
            live.iter()
                .filter(|id| !self.starved.contains(id))
                .map(|id| (*id, Arrival::OnTime)),
        );
        for slot in &mut self.slots {
            let to = slot.id;
            let Some(core) = slot.core.as_mut() else {
                continue;
            };
            for &(from, arrival) in order.iter().filter(|(from, _)| *from != to) {
                let commands = core.step(Input::Commands { from, arrival }, at_ms);
                if !commands.is_empty() {
                    log.entry(to).or_default().push(Emitted {
                        cause: Cause::Arrival(from, arrival),
                        commands,
                    });
                }
            }
        }
    }

    /// The end of a round: heartbeats out at the send slot, delivered, then the round ends.
    fn tick(&mut self, log: &mut StepLog) -> Result<(), Problem> {
        let boundary = self.boundary_ms();
        let round_end = boundary + PERIOD_MS;
        let mut heartbeats: BTreeMap<ControllerId, Heartbeat> = BTreeMap::new();
        for slot in &mut self.slots {
            let Some(core) = slot.core.as_mut() else {
                continue;
            };
            let id = slot.id;
            if core.next_deadline().timer == Timer::WindowExpiry {
                return Err(Problem::Timing(format!(
                    "C{id}'s initialization window is due, but the model ends the round \
                     without it expiring"
                )));
            }
            let send_slot = boundary + core.config().heartbeat_offset_ms();
            let emitted = log.entry(id).or_default();
            while core.next_deadline().at_ms <= send_slot {
                let due = core.next_deadline();
                let commands = core.step(Input::Timer(due.timer), due.at_ms);
                for command in &commands {
                    if let Command::PublishHeartbeat(heartbeat) = command {
                        heartbeats.insert(id, *heartbeat);
                    }
                }
                emitted.push(Emitted {
                    cause: Cause::Timer(due.timer),
                    commands,
                });
            }
            if !heartbeats.contains_key(&id) {
                return Err(Problem::Timing(format!(
                    "C{id} published no heartbeat by its send slot ({send_slot} ms)"
                )));
            }
        }
        let lost = &self.lost;
        let isolated = &self.isolated;
        for slot in &mut self.slots {
            let Some(core) = slot.core.as_mut() else {
                continue;
            };
            let to = slot.id;
            let emitted = log.entry(to).or_default();
            for (&from, heartbeat) in &heartbeats {
                let cut = isolated.contains(&from) || isolated.contains(&to);
                if from != to && !lost.contains(&(from, to)) && !cut {
                    let commands =
                        core.step(Input::Heartbeat(*heartbeat), boundary + DELIVERY_OFFSET_MS);
                    // Deliveries are shown only when they make the core do something.
                    if !commands.is_empty() {
                        emitted.push(Emitted {
                            cause: Cause::HeartbeatFrom(from),
                            commands,
                        });
                    }
                }
            }
        }
        let mut deposed = Vec::new();
        for slot in &mut self.slots {
            let Some(core) = slot.core.as_mut() else {
                continue;
            };
            let due = core.next_deadline();
            if due.at_ms != round_end || due.timer != Timer::RoundEnd {
                return Err(Problem::Timing(format!(
                    "C{}'s next timer is {:?} at {} ms, but the round ends at {round_end} ms",
                    slot.id, due.timer, due.at_ms
                )));
            }
            let commands = core.step(Input::Timer(Timer::RoundEnd), round_end);
            if commands.contains(&Command::StartAgain) {
                deposed.push(slot.id);
            }
            log.entry(slot.id).or_default().push(Emitted {
                cause: Cause::Timer(Timer::RoundEnd),
                commands,
            });
        }
        self.lost.clear();
        self.round += 1;
        // A peer took over from it (F17): it starts again as a new incarnation at the round's
        // end, as the runtime does on `Command::StartAgain`.
        for id in deposed {
            if self.start_again(id, Restart::Deposed, round_end)? {
                log.entry(id).or_default().push(started());
            }
        }
        Ok(())
    }
}

fn started() -> Emitted {
    Emitted {
        cause: Cause::Started,
        commands: Vec::new(),
    }
}
