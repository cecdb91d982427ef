//! The voting thread: runs the pure core over DDS. It takes heartbeats and votes from their
//! readers, fires the core's timers, and performs the commands it returns (publish heartbeat,
//! vote and alarms, update the shared status the application reads, LEDs, console, ROS 2
//! status, JSON events).
//!
//! The LEDs go to the bank `leds.backend` names: GPIO lines on a Pi (after a lamp test), or a
//! console line. GPIO that cannot be opened (no chip, a busy line, no permission) is one
//! warning, and the controller goes on with console LEDs: the LEDs help an operator, and a
//! controller without them still votes and commands.
//!
//! A controller whose core reports FAILED stops the thread `timing.failed_exit_delay_ms`
//! later, once a heartbeat has announced FAILED, and the thread ends with
//! [`crate::Error::Failed`]: `rl controller` exits to be restarted (crate::failed_exit).
//!
//! The core's clock: milliseconds of the wall clock read once at start, advanced by the
//! monotonic clock. Controllers whose wall clocks agree (NTP) share round boundaries, and a
//! wall-clock step while running cannot stall or rush the rounds.

use crate::api::{Options, Shared};
use crate::config::{Config, LedBackend};
use crate::core::{
    AlarmReason, Command, ControllerId, Core, CoreConfig, Input, Phase, Status, VoteRecord,
};
use crate::dds::{Reader, Session, Writer};
use crate::event::{Event, EventLine};
use crate::failed_exit::{Failure, PendingExit};
use crate::leds::{ConsoleLeds, LedBank, LedPattern};
use crate::wire::{AlarmSample, ControllerAlarm, HeartbeatSample, VoteSample};
use rustdds::mio::{Events, Poll, PollOpt, Ready, Token};
use std::io::Write;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};
use tracing::{info, warn};

/// Milliseconds on the wall clock at start, advanced monotonically.
#[derive(Clone, Copy, Debug)]
pub struct RoundClock {
    started: Instant,
    started_wall_ms: u64,
}

impl RoundClock {
    pub fn start() -> RoundClock {
        let started_wall_ms = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map(|d| d.as_millis() as u64)
            .unwrap_or(0);
        RoundClock {
            started: Instant::now(),
            started_wall_ms,
        }
    }

    pub fn now_ms(&self) -> u64 {
        self.started_wall_ms + self.started.elapsed().as_millis() as u64
    }
}

/// The longest the thread sleeps without looking at its flags (stop, fault).
const FLAG_CHECK_MS: u64 = 100;

const HEARTBEATS: Token = Token(0);
const VOTES: Token = Token(1);

struct Endpoints {
    heartbeats_in: Reader<HeartbeatSample>,
    votes_in: Reader<VoteSample>,
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
    let endpoints = Endpoints {
        heartbeats_in: session.heartbeat_reader().map_err(dds)?,
        votes_in: session.vote_reader().map_err(dds)?,
        heartbeats_out: session.heartbeat_writer().map_err(dds)?,
        votes_out: session.vote_writer().map_err(dds)?,
        alarms_out: session.alarm_writer().map_err(dds)?,
        ros_status,
        _ros_node: ros_node,
    };
    // Before the clock starts: the lamp test takes a moment, and the first round must not
    // begin late.
    let leds = led_bank(&config);
    let clock = RoundClock::start();
    // A new incarnation at every start: the start time, with the pid to separate two starts
    // in the same millisecond.
    let incarnation = crate::stall::incarnation(clock.now_ms());
    let timing = &config.timing;
    let core_config = CoreConfig::new(id, incarnation, timing.heartbeat_period_ms, timing.rounds());
    #[cfg(feature = "mutation")]
    let core_config = core_config.with_mutation(mutation_from_environment()?);
    let core = Core::new(core_config, clock.now_ms());
    let shared = Arc::new(Shared {
        status: Mutex::new(core.status()),
        alarms: Mutex::new(Vec::new()),
        fault: AtomicBool::new(false),
        stop: AtomicBool::new(false),
        loop_clock: crate::stall::LoopClock::new(timing.peer_deadline_ms),
    });
    let thread_shared = Arc::clone(&shared);
    let failed_exit_delay_ms = config.timing.failed_exit_delay_ms;
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
                failed_exit_delay_ms,
                pending_exit: None,
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
    /// How long it stays up after failing itself (`timing.failed_exit_delay_ms`).
    failed_exit_delay_ms: u64,
    /// Set when the core reported FAILED: why, and when the thread stops.
    pending_exit: Option<PendingExit>,
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
                self.start_again(stalled);
                // Only now that the silent status is in place may the writer follow it.
                self.shared.loop_clock.resumed();
            }
            #[cfg(feature = "fault-injection")]
            fault_injection::stall();
            // Samples first: a heartbeat that arrived before a round boundary belongs to the
            // round that ends there.
            self.take_samples();
            if self.shared.fault.swap(false, Ordering::SeqCst) {
                self.step(Input::LocalFault);
            }
            while let Some(timer) = self.core.due_timer(self.clock.now_ms()) {
                self.step(Input::Timer(timer));
            }
            let now_ms = self.clock.now_ms();
            if let Some(exit) = self.pending_exit.take_if(|exit| exit.is_due(now_ms)) {
                failed = Some(exit.failure);
                break;
            }
            let exit_wait_ms = self.pending_exit.as_ref().and_then(|e| e.wait_ms(now_ms));
            let wait_ms = self
                .core
                .next_deadline()
                .at_ms
                .saturating_sub(now_ms)
                .min(exit_wait_ms.unwrap_or(FLAG_CHECK_MS))
                .min(FLAG_CHECK_MS);
            match poll.poll(&mut events, Some(Duration::from_millis(wait_ms))) {
                Ok(_) => {}
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

    /// Back from a stall (crate::stall): start again as a new incarnation, silent, with what
    /// the readers hold now.
    fn start_again(&mut self, stalled: Duration) {
        let now_ms = self.clock.now_ms();
        let old = *self.core.config();
        let config = CoreConfig {
            incarnation: crate::stall::incarnation(now_ms),
            ..old
        };
        warn!(
            "C{} did not run for {} ms (stopped or starved): starting again as a new \
             incarnation, silent until it has heard a round and joined below the others",
            config.id,
            stalled.as_millis()
        );
        self.core = Core::new(config, now_ms);
        self.pending_exit = None;
        self.event(Event::Resumed {
            stalled_ms: u64::try_from(stalled.as_millis()).unwrap_or(u64::MAX),
        });
        self.show(self.core.status());
    }

    /// Drains both readers (edge-triggered: whatever woke the poll).
    fn take_samples(&mut self) {
        for heartbeat in self.endpoints.heartbeats_in.take() {
            #[cfg(feature = "fault-injection")]
            if fault_injection::dropped(heartbeat.value.id) {
                // Logged: an injected loss must be told apart from a real one.
                self.event(Event::HeartbeatDropped {
                    from: heartbeat.value.id,
                });
                continue;
            }
            self.step(Input::Heartbeat(heartbeat.value));
        }
        for vote in self.endpoints.votes_in.take() {
            self.step(Input::Vote(vote.value));
        }
    }

    fn step(&mut self, input: Input) {
        let now = self.clock.now_ms();
        let vote_before = self.core.state().vote;
        let local_fault = input == Input::LocalFault;
        for command in self.core.step(input, now) {
            self.perform(command);
        }
        self.show(self.core.status());
        if self.pending_exit.is_none() && self.core.state().phase == Phase::Failed {
            let failure = Failure::observe(self.core.state(), vote_before, local_fault);
            // The delay counts from after the FAILED status went out.
            self.failed(failure, self.clock.now_ms());
        }
    }

    /// The core has just reported FAILED: say why, and when it exits.
    fn failed(&mut self, failure: Failure, now_ms: u64) {
        let exit = PendingExit::new(failure, now_ms, self.failed_exit_delay_ms);
        // A warning: the terminal (stderr) shows it under the FAILED console line, and
        // `journalctl -p warning` finds it.
        warn!("{}", exit.notice(now_ms));
        self.pending_exit = Some(exit);
    }

    /// What a person sees follows the status: the status event and console line when it
    /// changed, the LEDs when their pattern did.
    fn show(&mut self, status: Status) {
        let leds = crate::leds::pattern_of(&status);
        if leds != self.shown_leds {
            self.shown_leds = leds;
            self.show_leds(leds);
        }
        if status == self.shown_status {
            return;
        }
        if status.duplicate_id_heartbeats > self.shown_status.duplicate_id_heartbeats {
            warn!(
                "another controller is using id {} (its heartbeats are ignored; check --id)",
                status.report.id
            );
        }
        self.console(&crate::console::console_line(&status));
        self.status(status.clone());
        self.shown_status = status;
    }

    fn show_leds(&mut self, pattern: LedPattern) {
        let shown = match &mut self.leds {
            Leds::Gpio(bank) => Some(bank.show(pattern)),
            Leds::Console(console) if self.options.console_leds && !self.options.json_events => {
                Some(console.show(pattern))
            }
            Leds::Console(_) => None,
        };
        if let Some(Err(error)) = shown {
            warn!("LEDs: {error}");
        }
        self.event(Event::Leds {
            leds: pattern.to_string(),
        });
    }

    /// A line for the operator: on stdout, or in the log when stdout carries JSON events.
    fn console(&self, line: &str) {
        if self.options.json_events {
            info!("{line}");
        } else {
            println!("{line}");
        }
    }

    fn perform(&mut self, command: Command) {
        match command {
            Command::PublishHeartbeat(heartbeat) => {
                if let Err(error) = self.endpoints.heartbeats_out.write(&heartbeat) {
                    warn!("heartbeat not sent: {error}");
                }
                if heartbeat.phase == Phase::Failed {
                    if let Some(exit) = &mut self.pending_exit {
                        exit.announced();
                    }
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
            alarms.retain(|(about, _)| *about != alarm.about);
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

    fn publish_ros_status(&self, status: &Status) {
        if let Some(ros) = &self.endpoints.ros_status {
            if let Ok(text) = serde_json::to_string(status) {
                if let Err(error) = ros.publish(&text) {
                    warn!("ROS 2 status not published: {error}");
                }
            }
        }
    }

    fn status(&mut self, status: Status) {
        self.publish_ros_status(&status);
        self.event(Event::Status {
            status: status.clone(),
        });
        *self.shared.status() = status;
    }

    /// One JSON event line on stdout (with `--json-events`): the record of what it did.
    fn event(&self, event: Event) {
        if !self.options.json_events {
            return;
        }
        let line = EventLine {
            t_ms: self.clock.now_ms(),
            id: self.core.config().id,
            incarnation: self.core.config().incarnation,
            event,
        };
        let mut out = std::io::stdout().lock();
        let _ = writeln!(out, "{}", line.to_json());
        let _ = out.flush();
    }
}

/// Test-only fault injection (feature `fault-injection`): heartbeats from the peers named on
/// stdin are dropped on arrival, as if the network lost them one way, each drop logged as a
/// `heartbeat_dropped` event (with `--json-events`); `stall-voting-loop <ms>`
/// blocks the voting loop once for that long, as a hung loop would (the watchdog test).
#[cfg(feature = "fault-injection")]
mod fault_injection {
    use std::collections::BTreeSet;
    use std::io::BufRead;
    use std::sync::Mutex;
    use std::time::Duration;

    static DROPPED: Mutex<BTreeSet<u8>> = Mutex::new(BTreeSet::new());
    static STALL: Mutex<Option<Duration>> = Mutex::new(None);

    /// Blocks the calling (voting) thread if a stall was asked for.
    pub fn stall() {
        let stall = STALL.lock().unwrap_or_else(|e| e.into_inner()).take();
        if let Some(duration) = stall {
            tracing::warn!("fault injection: voting loop stalled for {duration:?}");
            std::thread::sleep(duration);
        }
    }

    pub fn dropped(from: u8) -> bool {
        DROPPED
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .contains(&from)
    }

    /// Reads `drop-heartbeats-from <id>`, `accept-heartbeats-from <id>` and
    /// `stall-voting-loop <ms>` lines.
    pub fn listen_on_stdin() {
        let _ = std::thread::Builder::new()
            .name("rl-fault-injection".into())
            .spawn(|| {
                for line in std::io::stdin().lock().lines().map_while(Result::ok) {
                    let mut words = line.split_whitespace();
                    let (Some(verb), Some(id)) = (words.next(), words.next()) else {
                        continue;
                    };
                    if verb == "stall-voting-loop" {
                        match id.parse::<u64>() {
                            Ok(ms) => {
                                *STALL.lock().unwrap_or_else(|e| e.into_inner()) =
                                    Some(Duration::from_millis(ms));
                            }
                            Err(_) => tracing::warn!("fault injection: bad duration in {line:?}"),
                        }
                        continue;
                    }
                    let Ok(id) = id.parse::<u8>() else {
                        tracing::warn!("fault injection: bad id in {line:?}");
                        continue;
                    };
                    let mut dropped = DROPPED.lock().unwrap_or_else(|e| e.into_inner());
                    match verb {
                        "drop-heartbeats-from" => {
                            dropped.insert(id);
                        }
                        "accept-heartbeats-from" => {
                            dropped.remove(&id);
                        }
                        _ => tracing::warn!("fault injection: unknown command {line:?}"),
                    }
                    tracing::info!("fault injection: dropping heartbeats from {dropped:?}");
                }
            });
    }
}
