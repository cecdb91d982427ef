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
use crate::tracker::{control_law, ControlLaw};
use rl_layer::api::{Options, Redundancy, RoleWriter, VoteFeed, VotedWriter};
use rl_layer::config::{ArchitectureName, Config};
use rl_layer::core::types::ControllerId;
use rl_layer::core::Incarnation;
use rl_layer::cross_check::{CrossCheck, Judgement};
use rl_layer::network_monitor::{MonitorOptions, NetworkMonitor};
use rl_layer::owner_feed::OwnerFeed;
use rl_layer::service::{LoopProgress, Notifier};
use rl_layer::vote_reader::{ServoRule, VoteEvent, VoteSettings};
use rl_layer::wire::{ServoControl, VOTED_SERVO_CONTROL_TYPE_NAME};
use rustdds::mio::{Events, Poll, PollOpt, Ready, Token};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
use tracing::warn;

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
    let mut outputs = Outputs {
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
    };
    let poll = Poll::new().map_err(|e| crate::Error::io("creating the event poll", e))?;
    poll.register(&camera, CAMERA, Ready::readable(), PollOpt::edge())
        .map_err(|e| crate::Error::io("registering the camera reader", e))?;
    let mut events = Events::with_capacity(8);
    let mut pan_tilt = control_law(config.tracker.law, config.tracker.servo_frequency_hz);
    // A lockstep pair's controller runs the other implementation beside it and compares.
    let mut lockstep = (config.architecture == ArchitectureName::Pair)
        .then(|| Lockstep::beside(config.tracker.law, config.tracker.servo_frequency_hz));
    let republish = Duration::from_millis(config.timing.command_republish_ms);
    let started = Instant::now();
    // The gimbal starts centred; the command is held (re-published before the deadline) so
    // the actuator never falls to a weaker writer while this one lives.
    let mut last_written = started - republish;
    // The camera frame the commands answer (its source timestamp), for the voted topic.
    let mut frame: u64 = 0;
    // Its answer to that frame: a re-publication repeats it. The tracker's state, aligned to
    // the group since, is for the next frame; a re-publication computed from it would be a
    // second, different answer to the same frame (two wrong values per frame from a wrong
    // controller at an exclusive reader, where the model bounds wrong answers per input).
    let mut answer = None;
    // The second implementation's answer to the same frame (a lockstep pair only).
    let mut second_answer = None;
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
            pan_tilt.as_mut(),
            frame,
            now_ms,
            &mut outputs.cross_check,
        );
        if let (Some((pan, tilt)), Some(lockstep)) = (aligned, lockstep.as_mut()) {
            lockstep.align(pan, tilt);
        }
        let mut fresh = None;
        for shape in camera.take() {
            if shape.value.color == config.tracker.color {
                let input = shape.source_timestamp.map_or(0, |t| t.to_ticks());
                let skipped = alignment.before_frame(
                    input,
                    frame,
                    pan_tilt.as_mut(),
                    &mut outputs.cross_check,
                );
                if let (Some((pan, tilt)), Some(lockstep)) = (skipped, lockstep.as_mut()) {
                    lockstep.align(pan, tilt);
                }
                fresh = Some(pan_tilt.update(shape.value.x, shape.value.y));
                second_answer = lockstep
                    .as_mut()
                    .map(|lockstep| lockstep.update(shape.value.x, shape.value.y));
                frame = input;
                answer = fresh;
            }
        }
        if fresh.is_some() || last_written.elapsed() >= republish {
            let command = answer.unwrap_or_else(|| pan_tilt.command());
            let compare = lockstep.as_ref().zip(second_answer);
            outputs.write(rl, frame, command, compare);
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

/// Bumpless transfer: where the tracker takes the gimbal's position from. From the voted
/// topic's accepted commands (every controller, the commanding one too), so that a controller
/// computing wrong commands does not pull the others' state after it; until the vote has
/// accepted a command in this life (formation, a new life), from the owner's voted answer to
/// the frame it answered last while another controller commands (without a voted topic, the
/// owner's commands; crate::tracker, `align`). Once the vote has
/// worked, never from the owner again in this life: without a majority (two wrong that
/// disagree) the owner may be a wrong Primary, and a correct controller aligned to it would
/// agree with it at the next frame, making a wrong majority and the other wrong one the odd
/// one out. It keeps its own state then, which is the group's while all compute alike.
struct Alignment {
    owner_commands: OwnerFeed<ServoControl>,
    own_participant: rl_layer::dds::ParticipantKey,
    votes: Option<VoteFeed<ServoControl, ServoRule>>,
    /// The vote accepted a command in this life.
    voted_in_life: bool,
    /// The peers' answers on the voted topic, by input and controller, the newest
    /// [`ANSWERS_KEPT`] inputs: before the vote works, the owner's answer to the frame this
    /// controller answered last is where it takes the gimbal's position from.
    answers:
        std::collections::BTreeMap<u64, std::collections::BTreeMap<ControllerId, ServoControl>>,
    /// The vote's accepted answers to inputs this controller has not answered yet, the newest
    /// [`ANSWERS_KEPT`]: a loaded controller hears the others' answers to a frame before the
    /// frame itself, and taking that position first would step twice for the frame (its answer
    /// then unlike the group's, and its state too, frame after frame while it lags). Applied
    /// once it has answered that input, or, for an input it never got (a lost frame), before
    /// it answers the next one.
    accepted_ahead: std::collections::BTreeMap<u64, ServoControl>,
}

/// Inputs whose answers [`Alignment`] keeps.
const ANSWERS_KEPT: usize = 8;

impl Alignment {
    fn open(rl: &Redundancy, config: &Config) -> Result<Alignment, crate::Error> {
        let dds = |e: rl_layer::dds::DdsError| crate::Error::dds(e);
        // The commanding controller's commands, to follow while standing by.
        let owner_commands = OwnerFeed::open(
            rl.session(),
            rl.session().command_follower_reader().map_err(dds)?,
            config.timing.command_deadline_ms,
            config.timing.peer_deadline_ms,
        )
        .map_err(dds)?;
        let votes = rl.vote_feed(
            &config.dds.voted_topic_name(),
            VOTED_SERVO_CONTROL_TYPE_NAME,
            ServoRule::default(),
            VoteSettings::holding(config.timing.command_deadline_ms),
        );
        let votes = without_voting_if_refused("reader", votes);
        Ok(Alignment {
            owner_commands,
            own_participant: rl.session().participant_key(),
            votes,
            voted_in_life: false,
            answers: std::collections::BTreeMap::new(),
            accepted_ahead: std::collections::BTreeMap::new(),
        })
    }

    /// Before it answers camera frame `input` (having answered `frame` last): when the vote
    /// accepted an input between the two (a frame lost to this controller), the group's
    /// position at the newest of them is where it steps from. Returns that position, if any.
    fn before_frame(
        &mut self,
        input: u64,
        frame: u64,
        pan_tilt: &mut dyn ControlLaw,
        cross_check: &mut CrossCheck<ServoControl, ServoRule>,
    ) -> Option<(u16, u16)> {
        let later = self.accepted_ahead.split_off(&input);
        let skipped = std::mem::replace(&mut self.accepted_ahead, later);
        let (&skipped_input, command) = skipped.range(frame.saturating_add(1)..).next_back()?;
        pan_tilt.align(command.pan, command.tilt);
        cross_check.aligned(skipped_input);
        Some((command.pan, command.tilt))
    }

    /// Aligns `pan_tilt` to what arrived: a voted command for the frame it last answered
    /// (`frame`; one for an older frame would set it back, and one for a frame it has not
    /// answered yet waits for it, [`Alignment::before_frame`]), else, until the vote has worked
    /// in this life, the owner's command. The answers that arrived go to `cross_check`, and so
    /// does the alignment. Returns the position it aligned to, if it did.
    fn align(
        &mut self,
        rl: &Redundancy,
        pan_tilt: &mut dyn ControlLaw,
        frame: u64,
        now_ms: u64,
        cross_check: &mut CrossCheck<ServoControl, ServoRule>,
    ) -> Option<(u16, u16)> {
        let owner = self.owner_commands.take(rl.session(), now_ms);
        let mut voted = None;
        if let Some(votes) = self.votes.as_mut() {
            let answers = &mut self.answers;
            let events = votes.take_seeing(now_ms, |answer| {
                cross_check.peer_answer(answer.from, answer.input, answer.value);
                answers
                    .entry(answer.input)
                    .or_default()
                    .insert(answer.from, answer.value);
            });
            while self.answers.len() > ANSWERS_KEPT {
                self.answers.pop_first();
            }
            for event in events {
                if let VoteEvent::Accepted {
                    input,
                    value,
                    agreeing,
                } = event
                {
                    if agreeing.len() >= rl_layer::core::types::ROLE_COUNT {
                        cross_check.all_agreed();
                    }
                    self.voted_in_life = true;
                    if input > frame {
                        self.accepted_ahead.insert(input, value);
                    }
                    voted = (input == frame).then_some((input, value)).or(voted);
                }
            }
            while self.accepted_ahead.len() > ANSWERS_KEPT {
                self.accepted_ahead.pop_first();
            }
        }
        // An acceptance that came ahead of its frame, now answered.
        if let Some(value) = self.accepted_ahead.remove(&frame) {
            voted = voted.or(Some((frame, value)));
        }
        self.accepted_ahead = self.accepted_ahead.split_off(&frame);
        match (voted, owner) {
            (Some((input, command)), _) => {
                pan_tilt.align(command.pan, command.tilt);
                cross_check.aligned(input);
                Some((command.pan, command.tilt))
            }
            (None, Some((command, writer)))
                if !self.voted_in_life
                    && rl_layer::dds::participant_key(writer) != self.own_participant =>
            {
                // Not in step for the cross-check. With a voted topic, the owner's own answer
                // to the frame this controller answered last: the exclusive topic does not say
                // which frame its command answers, and a command answering a frame this
                // controller has not taken yet would have it step twice for that frame (two
                // standbys doing so agree with each other and not with a right Primary).
                let command = match self.votes {
                    Some(_) => {
                        let owner = self.owner_commands.controller_of(writer)?;
                        *self.answers.get(&frame)?.get(&owner)?
                    }
                    None => command,
                };
                pan_tilt.align(command.pan, command.tilt);
                Some((command.pan, command.tilt))
            }
            _ => None,
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

    /// Writes `command`, the answer to camera frame `frame`, on both topics (each only while
    /// this controller may command; on the voted one each new frame's answer, and the same
    /// again only every half deadline) unless the cross-check says leave; failures are
    /// counted and logged sparingly. A lockstep pair's controller first compares the output
    /// with its second implementation's (`compare`), and leaves on a mismatch.
    fn write(
        &mut self,
        rl: &Redundancy,
        frame: u64,
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
        if let Some(Err(mismatch)) =
            compare.map(|(lockstep, second)| lockstep.compare(frame, sample, second))
        {
            self.left = true;
            warn!("{mismatch}: leaving the bus");
            rl.report_fault();
            return;
        }
        if let Judgement::Leave(reason) = self.cross_check.answer(frame, sample) {
            self.left = true;
            rl.report_odd_one_out(reason);
            return;
        }
        let exclusive = self.commands.write(sample);
        let voted = match self.voted.as_mut() {
            Some(voted) => voted.write_when_due(frame, sample),
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
    }
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
        match fault {
            OutputFault::None => sample,
            OutputFault::Offset(offset) => {
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

/// SplitMix64's output function: well-mixed bits from a counter.
#[cfg(feature = "fault-injection")]
fn splitmix64(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}
