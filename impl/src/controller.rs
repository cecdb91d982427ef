//! `rl controller`: one voting controller running the tracker application (the paper's
//! Pixytracker): it reads the camera's `Circle` samples of the configured colour, computes
//! pan/tilt with the original PD law, and writes `pixy/servo_control` through the RL API,
//! which lets the commands out only while the controller holds a role, at its role's strength.
//! Each command also goes out on the voted command topic as this controller's own answer,
//! tagged with the camera frame it answers, for a receiver that votes (`rl servo --vote`,
//! rl_layer::vote_reader). It takes the gimbal's position from the voted commands, so that a
//! takeover is bumpless; until the vote has accepted one in this life, from the commanding
//! controller's own answer to the frame it answered last (without a voted topic, from the
//! commanding controller's commands).
//! Under `architecture = "pair"` it computes every frame's answer twice, in both
//! implementations of the law, and leaves on a mismatch before writing (crate::tracker::lockstep).
//! It cross-checks its own answers with the two others' (rl_layer::cross_check): the odd one
//! out of three at `tracker.odd_limit` frames of one life reports a local fault and leaves.
//!
//! Under systemd it reports readiness once DDS is joined and the voting thread runs, and its
//! loop pings the watchdog while the voting loop also goes round (rl_layer::service).

use crate::cli::{load_config, stop_on_signals};
use crate::tracker::lockstep::Lockstep;
use rl_layer::api::{Options, Redundancy, RoleWriter, VotedWriter};
use rl_layer::config::Config;
use rl_layer::core::types::ControllerId;
use rl_layer::core::Incarnation;
use rl_layer::cross_check::{CrossCheck, Judgement};
use rl_layer::network_monitor::{MonitorOptions, NetworkMonitor};
use rl_layer::service::{LoopProgress, Notifier};
use rl_layer::vote_reader::ServoRule;
use rl_layer::wire::{RawAnswer, ServoControl};
use rustdds::mio::{Events, Poll, PollOpt, Ready, Token};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
use tracing::warn;
use tracking::{Alignment, Tracker};

mod tracking;

/// Arguments of `rl controller`.
#[derive(clap::Args, Debug)]
pub struct ControllerArgs {
    #[command(flatten)]
    pub run: crate::cli::ControllerRunArgs,
    /// Network A: this controller's IPv4 address on it or its interface (`eth0`); with
    /// `--network-b`, RL's traffic goes out on both networks and the network monitor runs
    /// (overrides `[networks] a`).
    #[arg(long, value_name = "ADDR|IFACE", requires = "network_b")]
    pub network_a: Option<String>,
    /// Network B, the same (overrides `[networks] b`).
    #[arg(long, value_name = "ADDR|IFACE", requires = "network_a")]
    pub network_b: Option<String>,
    /// Exit after this many milliseconds (tests and benchmarks).
    #[arg(long, value_name = "MS")]
    pub duration_ms: Option<u64>,
}

const CAMERA: Token = Token(0);

/// Runs `rl controller`.
pub fn run(args: ControllerArgs) -> Result<(), crate::Error> {
    let mut config = load_config(args.run.config.as_deref(), args.run.domain)?;
    if let (Some(a), Some(b)) = (&args.network_a, &args.network_b) {
        config.networks.a = a.clone();
        config.networks.b = b.clone();
        config.validate().map_err(|invalid| {
            crate::Error::Usage(format!(
                "--network-a {a} --network-b {b}: {} = {}: {}",
                invalid.field, invalid.value, invalid.rule
            ))
        })?;
    }
    let stop = stop_on_signals()?;
    let voting_progress = Arc::new(LoopProgress::new());
    let mut notifier = Notifier::new(
        rl_layer::service::watchdog_from_env(),
        Arc::clone(&voting_progress),
    );
    let rl = Redundancy::start(
        &config,
        args.run.id,
        Options {
            json_events: args.run.json_events,
            console_leds: true,
            voting_progress: Some(voting_progress),
        },
    )?;
    let participant = rl.session().participant().clone();
    notifier.watch_dds_loop(move || participant.event_loop_iterations());
    let network_monitor = start_network_monitor(&rl, &config, args.run.id, args.run.json_events)?;
    let result = track(&rl, &config, &stop, args.duration_ms, &mut notifier);
    drop(network_monitor);
    notifier.stopping();
    let stopped = rl.stop();
    result.and(stopped.map_err(crate::Error::from))
}

/// The network monitor, when `[networks]` names both networks (none otherwise).
fn start_network_monitor(
    rl: &Redundancy,
    config: &Config,
    id: ControllerId,
    json_events: bool,
) -> Result<Option<NetworkMonitor>, crate::Error> {
    if !config.networks.configured() {
        return Ok(None);
    }
    let alarms_out = rl
        .session()
        .network_alarm_writer()
        .map_err(crate::Error::dds)?;
    let options = MonitorOptions {
        id,
        incarnation: rl.status().report.incarnation,
        json_events,
    };
    Ok(NetworkMonitor::start(config, options, alarms_out))
}

/// The `systemctl status` line: `C2 steady primary (strength 30)`; a result agreed without a
/// majority (a controller alone, a side cut off) says `provisional primary (strength 15)`.
fn service_status(rl: &Redundancy) -> String {
    let status = rl.status();
    let role = status.report.role.map_or("no role", |role| role.name());
    let standing = if status.report.provisional {
        "provisional "
    } else {
        ""
    };
    match status.report.strength {
        Some(strength) => format!(
            "C{} {} {standing}{role} (strength {strength})",
            status.report.id, status.report.phase
        ),
        None => format!("C{} {} {role}", status.report.id, status.report.phase),
    }
}

/// The tracker application: camera in, commands out through the RL API.
fn track(
    rl: &Redundancy,
    config: &Config,
    stop: &AtomicBool,
    duration_ms: Option<u64>,
    notifier: &mut Notifier,
) -> Result<(), crate::Error> {
    let dds = |e: rl_layer::dds::DdsError| crate::Error::dds(e);
    let mut camera = rl.session().camera_reader().map_err(dds)?;
    let mut alignment = Alignment::open(rl, config)?;
    let mut outputs = Outputs::open(rl, config)?;
    let poll = Poll::new().map_err(|e| crate::Error::io("creating the event poll", e))?;
    poll.register(&camera, CAMERA, Ready::readable(), PollOpt::edge())
        .map_err(|e| crate::Error::io("registering the camera reader", e))?;
    let mut events = Events::with_capacity(8);
    let mut tracker = Tracker::new(config);
    let republish = Duration::from_millis(config.timing.command_republish_ms);
    let started = Instant::now();
    // The gimbal starts centred; the command is held (re-published before the deadline) so
    // the actuator never falls to a weaker writer while this one lives.
    let mut last_written = started - republish;
    notifier.ready();
    loop {
        if stop.load(Ordering::SeqCst) || rl.is_finished() {
            return Ok(());
        }
        notifier.tick(Instant::now());
        notifier.status(&service_status(rl));
        if duration_ms.is_some_and(|limit| started.elapsed() >= Duration::from_millis(limit)) {
            return Ok(());
        }
        let now_ms = u64::try_from(started.elapsed().as_millis()).unwrap_or(u64::MAX);
        if outputs.follow_life(rl) {
            alignment.voted_in_life = false;
        }
        let aligned = alignment.align(
            rl,
            tracker.pan_tilt.as_mut(),
            tracker.frame,
            now_ms,
            &mut outputs.cross_check,
        );
        tracker.align_second(aligned);
        let mut fresh = false;
        for shape in camera.take() {
            if shape.value.color == config.tracker.color {
                let input = shape.source_timestamp.map_or(0, |t| t.to_ticks());
                let ball = (shape.value.x, shape.value.y);
                let frame = wrong_input(rl, input, ball);
                let gain = pan_gain_percent(rl);
                tracker.answer_frame(frame, gain, &mut alignment, &mut outputs.cross_check);
                fresh = true;
            }
        }
        if fresh || last_written.elapsed() >= republish {
            let frame = (tracker.frame, tracker.frame_digest, tracker.raw);
            outputs.write(rl, frame, tracker.command(), tracker.compare());
            last_written = Instant::now();
        }
        let wait = republish.saturating_sub(last_written.elapsed());
        match poll.poll(&mut events, Some(wait.min(Duration::from_millis(50)))) {
            Ok(_) => {}
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(crate::Error::io("waiting for camera samples", e)),
        }
    }
}

/// The command writers: the exclusive command topic and this controller's instance of the
/// voted one, behind the cross-check of its answers.
struct Outputs {
    commands: RoleWriter<ServoControl>,
    voted: Option<VotedWriter<ServoControl>>,
    write_errors: u64,
    cross_check: CrossCheck<ServoControl, ServoRule>,
    /// The life the cross-check counts in.
    life: Incarnation,
    /// The cross-check found it the odd one out: nothing more is written in this life.
    left: bool,
    /// The wrong output the fault-injection control asked for, as it goes.
    wrong: WrongOutput,
}

impl Outputs {
    fn open(rl: &Redundancy, config: &Config) -> Result<Outputs, crate::Error> {
        Ok(Outputs {
            commands: rl.command_writer()?,
            voted: without_voting_if_refused("writer", rl.voted_command_writer()),
            write_errors: 0,
            cross_check: CrossCheck::new(
                rl.status().report.id,
                ServoRule::default(),
                config.tracker.odd_limit,
            ),
            life: rl.status().report.incarnation,
            left: false,
            wrong: WrongOutput::default(),
        })
    }

    /// A new life (the layer started it again: resumed, detached, deposed) counts its odd
    /// inputs from zero; returns whether one began.
    fn follow_life(&mut self, rl: &Redundancy) -> bool {
        let life = rl.status().report.incarnation;
        if life == self.life {
            return false;
        }
        self.life = life;
        self.cross_check.new_life();
        self.left = false;
        true
    }

    /// Writes `command`, the answer to camera frame `frame` (its values' digest
    /// `frame_digest`, its raw answer `raw`), on both topics (each only while
    /// this controller may command; on the voted one each new frame's answer, and the same
    /// again only every half deadline) unless the cross-check says leave; failures are
    /// counted and logged sparingly. A lockstep pair's controller first compares the output
    /// with its second implementation's (`compare`), and leaves on a mismatch.
    fn write(
        &mut self,
        rl: &Redundancy,
        (frame, frame_digest, raw): (u64, u64, RawAnswer),
        command: crate::tracker::ServoCommand,
        compare: Option<(&Lockstep, crate::tracker::ServoCommand)>,
    ) {
        let sample = self.wrong.apply(
            rl,
            frame,
            ServoControl {
                pan: command.pan,
                tilt: command.tilt,
                frequency: command.frequency,
            },
        );
        if self.left {
            return;
        }
        let write_first = writes_before_comparing(rl);
        if !write_first && self.leaves_on_mismatch(rl, frame, sample, compare) {
            return;
        }
        let judgement = self.cross_check.answer(frame, frame_digest, raw, sample);
        if let Judgement::Leave(reason) = judgement {
            self.left = true;
            rl.report_odd_one_out(reason);
            return;
        }
        let exclusive = self.commands.write(sample);
        let voted = match self.voted.as_mut() {
            Some(voted) => voted.write_when_due(frame, frame_digest, raw, sample),
            None => Ok(false),
        };
        for written in [exclusive, voted] {
            if let Err(error) = written {
                self.write_errors += 1;
                if self.write_errors.is_power_of_two() {
                    warn!(
                        write_errors = self.write_errors,
                        "command not written: {error}"
                    );
                }
            }
        }
        if write_first {
            self.leaves_on_mismatch(rl, frame, sample, compare);
        }
    }

    /// A lockstep pair's compare (`compare`, none otherwise) of `sample`, the answer to
    /// `frame`, with the second implementation's: on a mismatch this controller leaves the
    /// bus, reports a local fault (FAILED, then exit) and says so.
    fn leaves_on_mismatch(
        &mut self,
        rl: &Redundancy,
        frame: u64,
        sample: ServoControl,
        compare: Option<(&Lockstep, crate::tracker::ServoCommand)>,
    ) -> bool {
        let Some(Err(mismatch)) =
            compare.map(|(lockstep, second)| lockstep.compare(frame, sample, second))
        else {
            return false;
        };
        self.left = true;
        warn!("{mismatch}: leaving the bus");
        rl.report_fault();
        true
    }
}

/// Whether this controller writes each output before its lockstep compare: the deliberately
/// broken order of `RL_MUTATION=write-before-compare` (a `mutation` build only), which the
/// fault lab must catch delivering a wrong command.
#[cfg(feature = "mutation")]
fn writes_before_comparing(rl: &Redundancy) -> bool {
    rl.mutation() == Some(rl_layer::core::mutation::Mutation::WriteBeforeCompare)
}

#[cfg(not(feature = "mutation"))]
fn writes_before_comparing(_: &Redundancy) -> bool {
    false
}

/// The voted topic's endpoint `made`, or none, with a warning, when it cannot be made (a
/// keystore whose permissions predate the voted topic refuses it: `rl keys add` again): the
/// controller then commands on the exclusive topic alone, as before the voted topic.
fn without_voting_if_refused<T>(what: &str, made: Result<T, rl_layer::Error>) -> Option<T> {
    made.inspect_err(|error| {
        warn!("no voted command {what}, commanding on the exclusive topic alone: {error}");
    })
    .ok()
}

/// The wrong output the fault-injection control asks for (`wrong-commands` on stdin), applied
/// to what the tracker computed, as a bug in it would be: the offset on pan, the command it
/// froze at, or random values chosen per frame. A fault asked for takes effect at the next
/// camera frame, as a bug in the computation would: a frame's re-published command stays
/// what it was.
#[derive(Default)]
struct WrongOutput {
    #[cfg(feature = "fault-injection")]
    frame_fault: Option<(u64, rl_layer::runtime::OutputFault)>,
    #[cfg(feature = "fault-injection")]
    frozen_at: Option<ServoControl>,
    /// When the drift asked for began (its rate, and the first frame it applied to).
    #[cfg(feature = "fault-injection")]
    drift_since: Option<(i32, Instant)>,
    /// The drift's offset at the frame it was last applied to.
    #[cfg(feature = "fault-injection")]
    drift_at: Option<(u64, i32)>,
}

#[cfg(feature = "fault-injection")]
impl WrongOutput {
    fn apply(&mut self, rl: &Redundancy, frame: u64, sample: ServoControl) -> ServoControl {
        use rl_layer::runtime::OutputFault;
        let fault = match self.frame_fault {
            Some((at, fault)) if at == frame => fault,
            _ => {
                let fault = rl.injected_output_fault();
                self.frame_fault = Some((frame, fault));
                fault
            }
        };
        if fault != OutputFault::Frozen {
            self.frozen_at = None;
        }
        let drift_rate = match fault {
            OutputFault::Drift(rate) => Some(rate),
            _ => None,
        };
        if self.drift_since.map(|(rate, _)| rate) != drift_rate {
            self.drift_since = drift_rate.map(|rate| (rate, Instant::now()));
        }
        match fault {
            // A wrong gain is the law's, applied as it steps (Tracker::answer_frame).
            OutputFault::None | OutputFault::Gain(_) => sample,
            OutputFault::Offset(offset) => {
                let pan = (i32::from(sample.pan) + offset).clamp(0, 1000);
                ServoControl {
                    pan: u16::try_from(pan).unwrap_or(sample.pan),
                    ..sample
                }
            }
            OutputFault::Drift(rate) => {
                // Fixed at the frame's first answer: a re-publication repeats it.
                let since = self
                    .drift_since
                    .map_or(0.0, |(_, at)| at.elapsed().as_secs_f64());
                let grown = (f64::from(rate) * since).clamp(-1000.0, 1000.0) as i32;
                let offset = match self.drift_at {
                    Some((at, offset)) if at == frame => offset,
                    _ => {
                        self.drift_at = Some((frame, grown));
                        grown
                    }
                };
                let pan = (i32::from(sample.pan) + offset).clamp(0, 1000);
                ServoControl {
                    pan: u16::try_from(pan).unwrap_or(sample.pan),
                    ..sample
                }
            }
            OutputFault::Frozen => *self.frozen_at.get_or_insert(sample),
            OutputFault::Random => {
                // The same frame always gets the same values, so a re-publication repeats it.
                let bits = splitmix64(frame ^ u64::from(rl.status().report.id));
                ServoControl {
                    pan: (bits % 1001) as u16,
                    tilt: ((bits >> 32) % 1001) as u16,
                    ..sample
                }
            }
        }
    }
}

/// Without the fault-injection control: `sample` as it is.
#[cfg(not(feature = "fault-injection"))]
impl WrongOutput {
    fn apply(&mut self, _: &Redundancy, _: u64, sample: ServoControl) -> ServoControl {
        sample
    }
}

/// The camera frame `input` with the ball at `ball` as the fault-injection control asks the
/// tracker to read it (`wrong-input` on stdin): the ball's x off by an offset, or another
/// camera's frame (an input the group never has, one tick after the group's, the ball 40 px
/// away).
#[cfg(feature = "fault-injection")]
fn wrong_input(rl: &Redundancy, input: u64, ball: (i32, i32)) -> (u64, (i32, i32)) {
    use rl_layer::runtime::InputFault;
    match rl.injected_input_fault() {
        InputFault::None => (input, ball),
        InputFault::Offset(offset) => (input, (ball.0.saturating_add(offset), ball.1)),
        InputFault::Foreign => (input.wrapping_add(1), (ball.0.saturating_add(40), ball.1)),
    }
}

/// The pan gain the fault-injection control asks the law to step with, in percent of its own
/// (`wrong-commands gain <percent>`: a wrong law; 100: right).
#[cfg(feature = "fault-injection")]
fn pan_gain_percent(rl: &Redundancy) -> i64 {
    match rl.injected_output_fault() {
        rl_layer::runtime::OutputFault::Gain(percent) => i64::from(percent),
        _ => 100,
    }
}

/// Without the fault-injection control: the law's own gain.
#[cfg(not(feature = "fault-injection"))]
fn pan_gain_percent(_: &Redundancy) -> i64 {
    100
}

/// Without the fault-injection control: the frame as it came.
#[cfg(not(feature = "fault-injection"))]
fn wrong_input(_: &Redundancy, input: u64, ball: (i32, i32)) -> (u64, (i32, i32)) {
    (input, ball)
}

/// SplitMix64's output function: well-mixed bits from a counter.
#[cfg(feature = "fault-injection")]
fn splitmix64(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}
