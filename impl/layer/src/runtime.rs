//! The voting thread: runs the pure core over DDS. It takes heartbeats and votes from their
//! readers, fires the core's timers, and performs the commands it returns (publish heartbeat,
//! vote and alarms, update the shared status the application reads, LEDs, console, ROS 2
//! status, JSON events). While the core watches command arrivals (the Secondary, F17) it also
//! takes the peers' commands and measures how late they come (`commands_in`, `arrival`).
//!
//! The LEDs go to the bank `leds.backend` names: GPIO lines on a Pi (after a lamp test), or a
//! console line. GPIO that cannot be opened (no chip, a busy line, no permission) is one
//! warning, and the controller goes on with console LEDs: the LEDs help an operator, and a
//! controller without them still votes and commands.
//!
//! Every protocol decision is the core's: when a controller that failed itself leaves
//! (`Command::Exit`, `timing.failed_exit_delay_ms` after a heartbeat announced FAILED; the
//! thread then ends with [`crate::Error::Failed`] and `rl controller` exits to be restarted,
//! crate::failed_exit), how it starts a new life after a stall, a lost carrier or a takeover
//! (`Input::StartAgain`, `Command::NewLife`), and whose round phase it follows
//! (`Command::MoveClock`). The thread detects (a stall, the links), measures (arrivals) and
//! performs.
//!
//! The core's clock (crate::round_clock): milliseconds of the wall clock read once at start,
//! advanced by the monotonic clock, so a wall-clock step while running cannot stall or rush
//! the rounds, and moved to follow the Primary's round phase, so the controllers share round
//! boundaries whether or not their wall clocks agree.

use self::arrival::ArrivalWatch;
pub use self::shared::Options;
pub(crate) use self::shared::Shared;
use crate::config::{Config, LedBackend};
use crate::core::{
    AlarmReason, Command, ControllerId, Core, CoreConfig, Input, Restart, Status, VoteRecord,
};
use crate::dds::{Reader, Session, Writer};
use crate::event::Event;
use crate::failed_exit::Failure;
use crate::leds::{ConsoleLeds, LedPattern};
use crate::link_watch::{LinkWatch, Links, Watched};
use crate::round_clock::RoundClock;
use crate::wire::{AlarmSample, ControllerAlarm, HeartbeatSample, ServoControl, VoteSample};
use rustdds::mio::{Events, Poll, PollOpt, Ready, Token};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;
use tracing::{debug, info, warn};

/// The longest the thread sleeps without looking at its flags (stop, fault).
const FLAG_CHECK_MS: u64 = 100;

const HEARTBEATS: Token = Token(0);
const VOTES: Token = Token(1);
const LINKS: Token = Token(2);
const COMMANDS: Token = Token(3);

struct Endpoints {
    heartbeats_in: Reader<HeartbeatSample>,
    votes_in: Reader<VoteSample>,
    /// Every controller's commands, best effort, to see how they arrive (F17).
    commands_in: Reader<ServoControl>,
    heartbeats_out: Writer<HeartbeatSample>,
    votes_out: Writer<VoteSample>,
    alarms_out: Writer<AlarmSample>,
    ros_status: Option<crate::dds::StatusPublisher>,
    _ros_node: Option<ros2_client::Node>,
}

/// The voting thread; it returns how it ended.
pub(crate) type VotingThread = JoinHandle<Result<(), crate::Error>>;

/// Starts the voting thread of controller `id`.
pub(crate) fn spawn(
    session: Arc<Session>,
    config: Config,
    id: ControllerId,
    options: Options,
) -> Result<(Arc<Shared>, VotingThread), crate::Error> {
    let dds = |e: crate::dds::DdsError| crate::Error::Dds(e.to_string());
    let (ros_node, ros_status) = match session.ros_node(id) {
        Ok(mut node) => match session.status_publisher(&mut node) {
            Ok(publisher) => (Some(node), Some(publisher)),
            Err(error) => {
                warn!("no ROS 2 status topic: {error}");
                (Some(node), None)
            }
        },
        Err(error) => {
            warn!("no ROS 2 node: {error}");
            (None, None)
        }
    };
    #[cfg_attr(not(feature = "fault-injection"), allow(unused_mut))]
    let mut endpoints = Endpoints {
        heartbeats_in: session.heartbeat_reader().map_err(dds)?,
        votes_in: session.vote_reader().map_err(dds)?,
        commands_in: session.command_follower_reader().map_err(dds)?,
        heartbeats_out: session.heartbeat_writer().map_err(dds)?,
        votes_out: session.vote_writer().map_err(dds)?,
        alarms_out: session.alarm_writer().map_err(dds)?,
        ros_status,
        _ros_node: ros_node,
    };
    // Held while discovery goes on (the DDS-level replay's start); what the readers take in
    // meanwhile is not this start's.
    #[cfg(feature = "fault-injection")]
    fault_injection::hold_until_started(&session, id, options.json_events, || {
        let _ = endpoints.heartbeats_in.take();
        let _ = endpoints.commands_in.take();
    });
    // Before the clock starts: the lamp test takes a moment, and the first round must not
    // begin late.
    let leds = led_bank(&config);
    let clock = RoundClock::start();
    // A new incarnation at every start: the start time, with the pid to separate two starts
    // in the same millisecond.
    let incarnation = crate::stall::incarnation(clock.now_ms());
    let timing = &config.timing;
    let core_config = CoreConfig::new(id, incarnation, timing.heartbeat_period_ms, timing.rounds())
        .with_failed_exit_delay_ms(timing.failed_exit_delay_ms)
        .with_architecture(config.core_architecture());
    #[cfg(feature = "mutation")]
    let mutation = mutation_from_environment()?;
    #[cfg(feature = "mutation")]
    let core_config = core_config.with_mutation(mutation);
    let core = Core::new(core_config, clock.now_ms());
    let shared = Arc::new(Shared {
        status: Mutex::new(core.status()),
        alarms: Mutex::new(Vec::new()),
        fault: AtomicBool::new(false),
        silenced: AtomicBool::new(false),
        odd_one_out: Mutex::new(None),
        stop: AtomicBool::new(false),
        loop_clock: crate::stall::LoopClock::new(
            timing.peer_deadline_ms,
            timing.command_deadline_ms,
        ),
        subscribers: Mutex::new(Vec::new()),
        #[cfg(feature = "mutation")]
        mutation,
    });
    let thread_shared = Arc::clone(&shared);
    let mut identities = crate::identity::Identities::new(timing.peer_deadline_ms);
    identities.bind_own(id, session.participant_key());
    let links = LinkWatch::new(Watched::from_config(&config.networks));
    let arrival = ArrivalWatch::new(timing.command_deadline_ms);
    let wait_max_ms = FLAG_CHECK_MS.min(timing.command_deadline_ms / 2).max(1);
    let thread = std::thread::Builder::new()
        .name(format!("rl-voting-{id}"))
        .spawn(move || {
            let shown_status = core.status();
            let mut voting = Voting {
                core,
                clock,
                endpoints,
                shared: thread_shared,
                options,
                leds,
                shown_status,
                shown_leds: LedPattern::ALL_OFF,
                leaving: None,
                events_at_ms: None,
                heartbeat_woke: false,
                delays: heartbeat_delay::HeartbeatDelays::default(),
                links,
                links_woke: false,
                identities,
                impostor_alarms: Vec::new(),
                arrival,
                watching_arrivals: false,
                command_wakes: crate::dds::WakeSwitch::new(),
                deposed: false,
                wait_max_ms,
            };
            voting.run()
        })
        .map_err(|e| crate::Error::io("starting the voting thread", e))?;
    info!(
        id,
        incarnation,
        domain = config.dds.domain,
        "controller started"
    );
    Ok((shared, thread))
}

/// The deliberately broken rule named by `RL_MUTATION` (a build with the `mutation` feature
/// only: the conformance suite's DDS-level mutation check runs real controllers with it).
#[cfg(feature = "mutation")]
fn mutation_from_environment() -> Result<Option<crate::core::mutation::Mutation>, crate::Error> {
    use crate::core::mutation::Mutation;
    let Ok(name) = std::env::var("RL_MUTATION") else {
        return Ok(None);
    };
    match Mutation::from_name(&name) {
        Some(mutation) => {
            warn!("running with the deliberately broken rule {name} (RL_MUTATION)");
            Ok(Some(mutation))
        }
        None => Err(crate::Error::Mutation {
            name,
            known: Mutation::ALL.map(Mutation::name).join(", "),
        }),
    }
}

/// The LED bank the configuration names.
enum Leds {
    Console(ConsoleLeds<std::io::Stderr>),
    Gpio(crate::leds::gpio::GpioLeds<crate::leds::gpio::CdevLines>),
}

/// Opens the configured LED bank; GPIO that cannot be had falls back to the console with one
/// warning naming the chip, the lines and the cause.
fn led_bank(config: &Config) -> Leds {
    let console = || Leds::Console(ConsoleLeds::new(std::io::stderr()));
    match config.leds.backend {
        LedBackend::Console => console(),
        LedBackend::Gpio => match crate::leds::gpio::start(&config.leds) {
            Ok(bank) => {
                // In the message, not as fields: `journalctl` shows only the message.
                info!(
                    "status LEDs on GPIO {} lines {} (green,red per LED)",
                    config.leds.chip,
                    crate::leds::gpio::describe_pins(&config.leds.pins)
                );
                Leds::Gpio(bank)
            }
            Err(error) => {
                warn!("status LEDs: {error}; showing them on the console instead");
                console()
            }
        },
    }
}

struct Voting {
    core: Core,
    clock: RoundClock,
    endpoints: Endpoints,
    shared: Arc<Shared>,
    options: Options,
    leds: Leds,
    /// The status last shown (status event, console line, shared status).
    shown_status: Status,
    /// The LEDs last shown.
    shown_leds: LedPattern,
    /// Set when the core says to leave (`Command::Exit`): why it failed itself.
    leaving: Option<Failure>,
    /// While a step's commands are performed: its instant, which its events carry.
    events_at_ms: Option<u64>,
    /// The last wait ended because a heartbeat arrived.
    heartbeat_woke: bool,
    /// How long peers' heartbeats waited on the way (late ones are lost).
    delays: heartbeat_delay::HeartbeatDelays,
    /// Whether this controller's links have a carrier (crate::link_watch).
    links: LinkWatch,
    /// The last wait ended because a link changed.
    links_woke: bool,
    /// Which participant each controller id speaks from (crate::identity).
    identities: crate::identity::Identities,
    /// Ids with an impostor alarm raised.
    impostor_alarms: Vec<ControllerId>,
    /// How each peer's commands arrive (F17), measured while `watching_arrivals`.
    arrival: ArrivalWatch,
    /// The command reader is measured (crate::runtime::commands_in).
    watching_arrivals: bool,
    /// Whether the command reader wakes the loop (registered once, switched after).
    command_wakes: crate::dds::WakeSwitch,
    /// The core asked to start again (a peer took over from this life, F17).
    deposed: bool,
    /// The longest wait for samples: [`FLAG_CHECK_MS`], and at most half the command
    /// deadline, so that a running loop marks its stall clock more often than a command
    /// deadline and a gap that long is a stop or a starved host (crate::stall).
    wait_max_ms: u64,
}

impl Voting {
    fn run(&mut self) -> Result<(), crate::Error> {
        let poll = Poll::new().map_err(|e| crate::Error::io("creating the event poll", e))?;
        let register = |reader: &dyn rustdds::mio::Evented, token| {
            poll.register(reader, token, Ready::readable(), PollOpt::edge())
                .map_err(|e| crate::Error::io("registering a DDS reader", e))
        };
        register(&self.endpoints.heartbeats_in, HEARTBEATS)?;
        register(&self.endpoints.votes_in, VOTES)?;
        if let Some(fd) = self.links.fd() {
            register(&rustdds::mio::unix::EventedFd(&fd), LINKS)?;
        }
        let mut events = Events::with_capacity(16);
        self.event(Event::Started);
        #[cfg(feature = "fault-injection")]
        fault_injection::listen_on_stdin();
        let progress = self.options.voting_progress.clone();
        let mut failed = None;
        while !self.shared.stop.load(Ordering::SeqCst) {
            if let Some(progress) = &progress {
                progress.mark();
            }
            if let Some(stalled) = self.shared.loop_clock.mark() {
                let stalled_ms = u64::try_from(stalled.as_millis()).unwrap_or(u64::MAX);
                self.start_again(Restart::Stalled { stalled_ms });
                // Only now that the silent status is in place may the writer follow it.
                self.shared.loop_clock.resumed();
            }
            match self.links.changed(self.links_woke) {
                Some(Links::Detached) if !self.start_again(Restart::Detached) => {
                    warn!("every link lost its carrier; going on as before")
                }
                Some(Links::Detached) => {}
                Some(Links::Attached) => info!("a link has its carrier again"),
                None => {}
            }
            #[cfg(feature = "fault-injection")]
            fault_injection::stall();
            // Samples first: a heartbeat sent before a round boundary belongs to the round
            // that ends there (one sent after it ends that round first: heartbeat_delay.rs).
            self.take_samples();
            self.follow_arrivals(&poll)?;
            self.take_commands();
            if self.shared.fault.swap(false, Ordering::SeqCst) {
                self.report_odd_one_out();
                self.step(Input::LocalFault);
            }
            self.fire_due_timers();
            if let Some(failure) = self.leaving.take() {
                failed = Some(failure);
                break;
            }
            let now_ms = self.clock.now_ms();
            let wait_ms = self
                .core
                .next_deadline()
                .at_ms
                .saturating_sub(now_ms)
                .min(self.wait_max_ms);
            match poll.poll(&mut events, Some(Duration::from_millis(wait_ms))) {
                Ok(_) => {
                    self.heartbeat_woke = events.iter().any(|e| e.token() == HEARTBEATS);
                    self.links_woke = events.iter().any(|e| e.token() == LINKS);
                }
                // SIGSTOP/SIGCONT interrupts the wait: not an error.
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(crate::Error::io("waiting for DDS samples", e)),
            }
        }
        match failed {
            Some(failure) => {
                self.event(Event::stopped_failed(&failure));
                Err(crate::Error::Failed(Box::new(failure)))
            }
            None => {
                self.event(Event::stopped());
                Ok(())
            }
        }
    }

    /// Back from a stall (crate::stall), cut off at its own links (crate::link_watch), or
    /// deposed (F17): the core starts a new life, silent, with what the readers hold now.
    /// Whether it did (under the `StayWhenUnplugged` mutation a lost carrier changes nothing).
    fn start_again(&mut self, cause: Restart) -> bool {
        let now_ms = self.clock.now_ms();
        let incarnation = crate::stall::incarnation(now_ms);
        let commands = self
            .core
            .step(Input::StartAgain { cause, incarnation }, now_ms);
        let started = !commands.is_empty();
        for command in commands {
            self.perform(command);
        }
        started
    }

    /// The core started a new life: say why, and show its silent status.
    fn new_life(&mut self, cause: Restart) {
        let id = self.core.config().id;
        let why = match cause {
            Restart::Stalled { stalled_ms } => {
                format!("C{id} did not run or command for {stalled_ms} ms (stopped or starved)")
            }
            Restart::Detached => format!(
                "C{id}'s links have all lost their carrier (a pulled cable, a dead switch port)"
            ),
            Restart::Deposed => format!(
                "C{id}'s commands reached its peers late (a starved link?) and its Secondary \
                 took over"
            ),
        };
        warn!(
            "{why}: starting again as a new incarnation, silent until it has heard a round and \
             joined below the others"
        );
        self.event(match cause {
            Restart::Stalled { stalled_ms } => Event::Resumed { stalled_ms },
            Restart::Detached => Event::Detached,
            Restart::Deposed => Event::Deposed,
        });
        self.show(self.core.status());
    }

    fn fire_due_timers(&mut self) {
        while let Some(timer) = self.core.due_timer(self.clock.now_ms()) {
            self.step(Input::Timer(timer));
        }
    }

    /// Tells the core when `heartbeat`, whose arrival woke the loop, arrived: where the
    /// round boundaries will be, also while the clock holds still after a move back. The core
    /// answers with a clock move when it came from the peer whose phase this controller
    /// follows, off its expected place in the round (rl-core's `phase`).
    fn follow_phase(&mut self, heartbeat: &crate::core::Heartbeat) {
        let arrived_ms = self.clock.unheld_ms();
        for command in self
            .core
            .step(Input::HeartbeatArrival(*heartbeat), arrived_ms)
        {
            self.perform(command);
        }
    }

    /// Moves the round clock as the core asked, to follow `following`'s phase.
    fn move_clock(&mut self, by_ms: i64, following: ControllerId) {
        self.clock.shift(by_ms);
        // Moved forward across a boundary: that round ends before this heartbeat, which
        // arrived in the next one.
        self.fire_due_timers();
        // A newcomer's first move, or clocks that drifted apart: worth a line. Jitter
        // corrections are small.
        let period_ms = self.core.config().heartbeat_period_ms;
        if by_ms.unsigned_abs() >= period_ms / 8 {
            info!(
                "round phase moved by {by_ms} ms to follow C{following} ({} ms in all)",
                self.clock.moved_ms()
            );
        } else {
            debug!("round phase moved by {by_ms} ms to follow C{following}");
        }
    }

    /// Drains both readers (edge-triggered: whatever woke the poll).
    fn take_samples(&mut self) {
        let heartbeats = self.endpoints.heartbeats_in.take();
        // Only a heartbeat whose arrival woke the loop arrived now (a wake-up can come late:
        // the timeout finds what arrived without one): the newest of those sets the phase.
        let on_time = std::mem::take(&mut self.heartbeat_woke).then_some(heartbeats.len());
        for (number, heartbeat) in (1..).zip(heartbeats) {
            #[cfg(feature = "fault-injection")]
            if fault_injection::dropped(heartbeat.value.id) {
                // Logged: an injected loss must be told apart from a real one.
                self.event(Event::HeartbeatDropped {
                    from: heartbeat.value.id,
                });
                continue;
            }
            if !self.admit_heartbeat(&heartbeat) || !self.place_in_its_round(&heartbeat) {
                continue;
            }
            if on_time == Some(number) {
                self.follow_phase(&heartbeat.value);
            }
            self.step(Input::Heartbeat(heartbeat.value));
        }
        for vote in self.endpoints.votes_in.take() {
            if self.admit_vote(&vote) {
                self.step(Input::Vote(vote.value));
            }
        }
        self.clear_silent_impostors();
    }

    fn step(&mut self, input: Input) {
        let now = self.clock.now_ms();
        let commands = self.core.step(input, now);
        // Before the step's events go out: an application told of a new role (Redundancy::
        // events) that writes at once must find its writer at the new role's strength. (A
        // step's commands do not change the core: a new life waits for the end of the step.)
        let status = self.core.status();
        *self.shared.status() = status.clone();
        // The step's events carry the step's instant, the core's: a FAILED status then says
        // when the core failed, which its exit delay counts from.
        self.events_at_ms = Some(now);
        let mut failures = Vec::new();
        for command in commands {
            match command {
                Command::Failed { .. } => failures.push(command),
                command => self.perform(command),
            }
        }
        self.show(status);
        // Under the FAILED console line the step's status printed.
        for failure in failures {
            self.perform(failure);
        }
        self.events_at_ms = None;
        // After the old life's last status went out, so the record shows where it ended.
        if std::mem::take(&mut self.deposed) {
            self.start_again(Restart::Deposed);
        }
    }

    fn perform(&mut self, command: Command) {
        match command {
            Command::PublishHeartbeat(heartbeat) => {
                if let Err(error) = self.endpoints.heartbeats_out.write(&heartbeat) {
                    warn!("heartbeat not sent: {error}");
                }
                // The ROS 2 status goes out with every heartbeat too, so a ROS 2 tool that
                // starts late sees it within a period.
                let status = self.core.status();
                self.publish_ros_status(&status);
            }
            Command::PublishVote(record) => {
                self.event(Event::Vote { vote: record.vote });
                self.write_vote(record);
            }
            Command::SetOutput { role, strength } => {
                self.event(Event::Output { role, strength });
            }
            Command::RaiseAlarm { about, reason } => self.alarm(about, reason, true),
            Command::ClearAlarm { about, reason } => self.alarm(about, reason, false),
            Command::RoundEndsMissed { rounds } => self.fell_behind(rounds),
            // After the step's other commands: the new life replaces the core.
            Command::StartAgain => self.deposed = true,
            Command::NewLife { cause } => self.new_life(cause),
            Command::MoveClock { by_ms, following } => self.move_clock(by_ms, following),
            // A warning: stderr shows it under the FAILED line; `journalctl -p warning` too.
            Command::Failed {
                failure,
                exit_in_ms,
            } => warn!("{}", crate::failed_exit::notice(&failure, exit_in_ms)),
            Command::Exit(failure) => self.leaving = Some(failure),
        }
    }

    fn write_vote(&self, record: VoteRecord) {
        if let Err(error) = self.endpoints.votes_out.write(&record) {
            warn!("vote not published: {error}");
        }
    }

    fn alarm(&mut self, about: ControllerId, reason: AlarmReason, raised: bool) {
        let alarm = ControllerAlarm {
            reporter: self.core.config().id,
            reporter_incarnation: self.core.config().incarnation,
            about,
            about_incarnation: None,
            reason,
            raised,
        };
        {
            let mut alarms = self.shared.alarms.lock().unwrap_or_else(|e| e.into_inner());
            // One protocol alarm per controller (Failed replaces Lost); an impostor alarm is
            // about someone else's samples and stands beside it.
            let impostor = |r: AlarmReason| r == AlarmReason::Impostor;
            alarms.retain(|(about, r)| {
                *about != alarm.about || impostor(*r) != impostor(alarm.reason)
            });
            if alarm.raised {
                alarms.push((alarm.about, alarm.reason));
            }
        }
        let verb = if alarm.raised { "RAISED" } else { "cleared" };
        let line = format!(
            "C{}: alarm {verb}: controller C{} {:?}",
            alarm.reporter, alarm.about, alarm.reason
        );
        self.console(&line);
        self.event(Event::Alarm {
            about: alarm.about,
            reason: alarm.reason,
            raised: alarm.raised,
        });
        if let Err(error) = self.endpoints.alarms_out.write(&alarm) {
            warn!("alarm not published: {error}");
        }
    }
}

mod arrival;
mod commands_in;
#[cfg(feature = "fault-injection")]
mod fault_injection;

#[cfg(feature = "fault-injection")]
pub use fault_injection::{InputFault, OutputFault};

/// With the `fault-injection` feature: how the test control asked the application's commands
/// to be wrong (`wrong-commands ...` on stdin).
#[cfg(feature = "fault-injection")]
pub fn injected_output_fault() -> OutputFault {
    fault_injection::output_fault()
}

/// With `fault-injection`: how the test control asked the input to be wrong (`wrong-input`).
#[cfg(feature = "fault-injection")]
pub fn injected_input_fault() -> InputFault {
    fault_injection::input_fault()
}
mod heartbeat_delay;
mod impostors;
mod output;
mod shared;
