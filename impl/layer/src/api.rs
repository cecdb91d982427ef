//! The RL API: the one small surface an application uses.
//!
//! ```no_run
//! # fn main() -> Result<(), rl_layer::Error> {
//! let config = rl_layer::config::Config::default();
//! let rl = rl_layer::api::Redundancy::start(&config, 1, rl_layer::api::Options::default())?;
//! let mut commands = rl.command_writer()?;
//! loop {
//!     // ... compute a command from the application's inputs ...
//!     let command = rl_layer::wire::ServoControl { pan: 500, tilt: 500, frequency: 60 };
//!     commands.write(command)?; // written only while this controller holds a role,
//!                               // at its role's ownership strength
//!     if rl.status().report.phase == rl_layer::core::Phase::Failed { break; }
//! #   break;
//! }
//! # Ok(()) }
//! ```
//!
//! [`Redundancy::start`] joins DDS and runs the voting core in its own thread (heartbeats,
//! votes, alarms, LEDs, console, the ROS 2 status topic). The application reads the current
//! role and state ([`Redundancy::status`], [`Redundancy::role`]), the raised alarms, reports
//! its own faults ([`Redundancy::report_fault`]), and writes commands through a
//! [`RoleWriter`] whose ownership strength always follows the role, of the command topic or
//! of any topic of its own ([`Redundancy::role_writer`]); what the layer does is pushed to it
//! ([`Redundancy::events`]). For a receiver that votes on the controllers' outputs, each
//! controller also writes its own answer to every input ([`Redundancy::voted_writer`], read
//! with [`Redundancy::vote_feed`]). docs/api.md is the guide.
//!
//! A controller that votes itself FAILED stays FAILED for the rest of its life, so the layer
//! stops by itself `timing.failed_exit_delay_ms` after it failed ([`Redundancy::is_finished`]
//! turns true, [`Redundancy::stop`] returns [`crate::Error::Failed`]); the application should
//! then exit with [`crate::Error::exit_code`] to be restarted (crate::failed_exit).

pub use crate::config::AperiodicPolicy;
use crate::config::Config;
use crate::core::types::{AlarmReason, ControllerId, Role, Strength};
use crate::core::Status;
use crate::dds::{DdsError, Session, StrengthWriter};
pub use crate::dds::{Keying, NoKey, WithKey};
use crate::event::EventLine;
pub use crate::owner_feed::OwnerFeed;
pub use crate::runtime::Options;
use crate::runtime::{self, Shared};
use crate::trust::CommandTrust;
pub use crate::vote_feed::VoteFeed;
use crate::vote_reader::{VoteRule, VoteSettings};
pub use crate::wire::Plain;
use crate::wire::{RawAnswer, ServoControl, Voted, VotedSample, VOTED_SERVO_CONTROL_TYPE_NAME};
use std::sync::atomic::Ordering;
use std::sync::mpsc::Receiver;
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// A running redundancy layer: one controller of the voting group.
pub struct Redundancy {
    shared: Arc<Shared>,
    session: Arc<Session>,
    config: Config,
    thread: Option<JoinHandle<Result<(), crate::Error>>>,
}

impl Redundancy {
    /// Joins the configured DDS domain as controller `id` and starts voting (or, under
    /// `architecture = "duplex" | "pair"`, watching its partner; `id` must then be one of the
    /// two configured).
    pub fn start(
        config: &Config,
        id: ControllerId,
        options: Options,
    ) -> Result<Redundancy, crate::Error> {
        // A duplex or a pair has exactly its two members: another id is a configuration error.
        config
            .check_member(id)
            .map_err(|invalid| crate::config::ConfigError::Invalid {
                source_name: "the configuration".into(),
                invalid,
            })?;
        // On two networks every datagram goes out on both, so losing one loses nothing.
        // With a keystore, secured (checked first: a bad file is named, exit status 2).
        let session = Arc::new(Session::for_config(config)?);
        let (shared, thread) = runtime::spawn(Arc::clone(&session), config.clone(), id, options)?;
        Ok(Redundancy {
            shared,
            session,
            config: config.clone(),
            thread: Some(thread),
        })
    }

    /// The current protocol state: phase, role, strength, agreed result, vote, view, alarms.
    pub fn status(&self) -> Status {
        self.shared.status().clone()
    }

    /// The role this controller holds now.
    pub fn role(&self) -> Option<Role> {
        self.shared.status().report.role
    }

    /// The ownership strength its commands carry now (`None`: it must not command).
    pub fn strength(&self) -> Option<Strength> {
        self.shared.status().report.strength
    }

    /// Controller alarms this controller has raised and not cleared.
    pub fn alarms(&self) -> Vec<(ControllerId, AlarmReason)> {
        self.shared
            .alarms
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }

    /// The application detected its own fault: the controller fails itself (stops commanding
    /// at once, announces FAILED so the others re-vote).
    pub fn report_fault(&self) {
        self.shared.silenced.store(true, Ordering::SeqCst);
        self.shared.fault.store(true, Ordering::SeqCst);
    }

    /// Its cross-check found this controller the odd one out of three (crate::cross_check):
    /// as [`Redundancy::report_fault`], with the reason in the event lines and the log.
    pub fn report_odd_one_out(&self, reason: crate::cross_check::OddOneOut) {
        *self
            .shared
            .odd_one_out
            .lock()
            .unwrap_or_else(|e| e.into_inner()) = Some(reason);
        self.report_fault();
    }

    /// The DDS session (to create the application's own readers on the same participant).
    pub fn session(&self) -> &Session {
        &self.session
    }

    /// A writer of the command topic (`dds.command_topic`, the paper's `pixy/servo_control`)
    /// that carries this controller's role strength, with `tracker.aperiodic`'s policy.
    pub fn command_writer(&self) -> Result<RoleWriter<ServoControl>, crate::Error> {
        let writer = self.session.command_writer(None)?;
        Ok(self.role_writer_over(writer, self.config.tracker.aperiodic))
    }

    /// A writer of the application's own topic `topic` (DDS type name `type_name`, which its
    /// readers must use too) whose ownership strength follows this controller's role, with
    /// the command topic's QoS (exclusive ownership, `timing.command_deadline_ms` deadline).
    /// `K` chooses an unkeyed ([`NoKey`]) or keyed ([`WithKey`]) topic:
    ///
    /// ```no_run
    /// # fn demo(rl: &rl_layer::api::Redundancy) -> Result<(), rl_layer::Error> {
    /// use rl_layer::api::{AperiodicPolicy, RoleWriter};
    /// #[derive(Clone, serde::Serialize)]
    /// struct Heading { degrees: f32 }
    /// let mut headings: RoleWriter<Heading> =
    ///     rl.role_writer("nav/heading", "nav::Heading", AperiodicPolicy::Republish)?;
    /// headings.write(Heading { degrees: 90.0 })?;
    /// # Ok(()) }
    /// ```
    pub fn role_writer<T, K>(
        &self,
        topic: &str,
        type_name: &str,
        policy: AperiodicPolicy,
    ) -> Result<RoleWriter<T, K>, crate::Error>
    where
        T: Clone,
        K: Keying<T>,
    {
        let writer = self.session.strength_writer(topic, type_name, None)?;
        Ok(self.role_writer_over(writer, policy))
    }

    fn role_writer_over<T: Clone, K: Keying<T>>(
        &self,
        writer: StrengthWriter<T, K>,
        policy: AperiodicPolicy,
    ) -> RoleWriter<T, K> {
        let republish = Duration::from_millis(self.config.timing.command_republish_ms);
        // Voting and the duplex bring a doubting owner back below the others (a new life that
        // joins below; the duplex's dwell, A4), so its writer may doubt itself at half the
        // deadline. The pair's owner keeps the deadline (not measured with the earlier bound).
        let doubts_early = self.config.architecture != crate::config::ArchitectureName::Pair;
        let republishes =
            (doubts_early && matches!(policy, AperiodicPolicy::Republish)).then_some(republish);
        let mut writer = writer;
        if republishes.is_some() {
            let gap = crate::dds::qos::command_max_send_gap_ms(&self.config.timing);
            writer.set_max_send_gap(Some(Duration::from_millis(gap)));
        }
        RoleWriter {
            shared: Arc::clone(&self.shared),
            writer,
            policy,
            republish,
            owner_lapse: crate::stall::owner_lapse_bound(
                self.config.timing.command_deadline(),
                republishes,
            ),
            last: None,
        }
    }

    /// The samples of the writer that owns the application's topic `topic` now (the strongest
    /// live controller's, as an actuator arbitrates), for a standby that must continue from
    /// where the owner was (bumpless transfer). This controller's own samples come too: tell
    /// them by their writer's participant (`rl_layer::dds::participant_key(writer)` against
    /// `session().participant_key()`).
    pub fn owner_feed<T>(
        &self,
        topic: &str,
        type_name: &str,
    ) -> Result<OwnerFeed<Plain<T>>, crate::Error>
    where
        T: Clone + serde::de::DeserializeOwned + Send + 'static,
    {
        let heartbeats = self.session.heartbeat_reader()?;
        self.owner_feed_by(heartbeats, topic, type_name)
    }

    /// The samples of the writer that owns group `group`'s topic `topic` now: an application
    /// of this group reading another redundant group's output (the paper's chain: the
    /// actuator controllers steered by the navigation controllers' Primary). Writers are
    /// trusted as that group's live controllers' (from its heartbeats), and the owner is the
    /// strongest of them, as an actuator arbitrates.
    pub fn owner_feed_of_group<T>(
        &self,
        group: &str,
        topic: &str,
        type_name: &str,
    ) -> Result<OwnerFeed<Plain<T>>, crate::Error>
    where
        T: Clone + serde::de::DeserializeOwned + Send + 'static,
    {
        let heartbeats = self.session.group_heartbeat_reader(group)?;
        self.owner_feed_by(heartbeats, topic, type_name)
    }

    /// This controller's writer of the voted topic `topic` (DDS type name `type_name`): its
    /// own instance, keyed by its id, shared ownership (docs/protocol.md, "Output voting at the
    /// receiver"). Each write carries the input it answers; it writes only while this
    /// controller holds a role, never while role-less or FAILED (nor before its role's
    /// strength is granted is it silent, unlike a [`RoleWriter`]: nobody owns a voted topic,
    /// the receiver weighs every answer alike). A voting receiver
    /// ([`Redundancy::vote_feed`], crate::vote_feed) takes a value only when two controllers
    /// agree on it and alarms a dissenting one.
    pub fn voted_writer<T>(
        &self,
        topic: &str,
        type_name: &str,
    ) -> Result<VotedWriter<T>, crate::Error>
    where
        T: Clone + serde::Serialize + Send + 'static,
    {
        let writer = self.session.voted_writer(topic, type_name)?;
        Ok(VotedWriter {
            shared: Arc::clone(&self.shared),
            writer,
            republish: Duration::from_millis(self.config.timing.command_deadline_ms / 2),
            last: None,
        })
    }

    /// The voted writer of the servo commands: `dds.voted_command_topic`, type
    /// `rl::VotedServoControl` (docs/rl.idl).
    pub fn voted_command_writer(&self) -> Result<VotedWriter<ServoControl>, crate::Error> {
        let topic = self.session.config().voted_topic_name();
        self.voted_writer(&topic, VOTED_SERVO_CONTROL_TYPE_NAME)
    }

    /// The vote on this group's voted topic `topic` (DDS type name `type_name`) with `rule`,
    /// read best effort: what a controller that aligns its state to the voted value reads
    /// (a receiver that is no controller opens [`VoteFeed::open`] on its session, reliable).
    pub fn vote_feed<T, R>(
        &self,
        topic: &str,
        type_name: &str,
        rule: R,
        settings: VoteSettings<T>,
    ) -> Result<VoteFeed<T, R>, crate::Error>
    where
        T: Clone + serde::de::DeserializeOwned + Send + 'static,
        R: VoteRule<T>,
    {
        Ok(VoteFeed::following(
            &self.session,
            topic,
            type_name,
            rule,
            settings,
        )?)
    }

    /// With the `fault-injection` feature: how the test control asked this controller's
    /// commands to be wrong (`wrong-commands offset <n>|frozen|random|none` on stdin).
    #[cfg(feature = "fault-injection")]
    pub fn injected_output_fault(&self) -> runtime::OutputFault {
        runtime::injected_output_fault()
    }

    /// With the `fault-injection` feature: how the test control asked this controller's
    /// input to be wrong (`wrong-input offset <n>|foreign|none` on stdin).
    #[cfg(feature = "fault-injection")]
    pub fn injected_input_fault(&self) -> runtime::InputFault {
        runtime::injected_input_fault()
    }

    /// With the `mutation` feature: the deliberately broken rule this controller runs
    /// (`RL_MUTATION`), if any; the application reads it for the rules it applies itself (a
    /// lockstep pair's compare before writing).
    #[cfg(feature = "mutation")]
    pub fn mutation(&self) -> Option<crate::core::mutation::Mutation> {
        self.shared.mutation
    }

    /// The owner feed of `topic` whose controllers are those `heartbeats` announce.
    fn owner_feed_by<T>(
        &self,
        heartbeats: crate::dds::Reader<crate::wire::HeartbeatSample>,
        topic: &str,
        type_name: &str,
    ) -> Result<OwnerFeed<Plain<T>>, crate::Error>
    where
        T: Clone + serde::de::DeserializeOwned + Send + 'static,
    {
        let reader = self.session.plain_reader(topic, type_name)?;
        let trust = CommandTrust::new(self.config.timing.peer_deadline_ms, false);
        Ok(OwnerFeed::open_following(
            heartbeats,
            reader,
            self.config.timing.command_deadline_ms,
            trust,
        ))
    }

    /// What the layer does, pushed as it happens: every event line `--json-events` prints
    /// (status and role changes, outputs, votes, alarms raised and cleared, LEDs, a restart,
    /// and `stopped` with the reason when the controller failed itself), from now on. Read
    /// [`Redundancy::status`] first for the state before it; drop the receiver to unsubscribe.
    pub fn events(&self) -> Receiver<EventLine> {
        let (sender, receiver) = std::sync::mpsc::channel();
        self.shared.subscribers().push(sender);
        receiver
    }

    /// The voting thread ended (an error, `stop`, or the controller failed itself and its
    /// `timing.failed_exit_delay_ms` is over).
    pub fn is_finished(&self) -> bool {
        self.thread.as_ref().is_none_or(JoinHandle::is_finished)
    }

    /// Stops the voting thread and returns how it ended: [`crate::Error::Failed`] if it
    /// stopped because the controller failed itself.
    pub fn stop(mut self) -> Result<(), crate::Error> {
        self.shared.stop.store(true, Ordering::SeqCst);
        match self.thread.take() {
            Some(thread) => thread.join().unwrap_or_else(|_| {
                Err(crate::Error::Runtime("the voting thread panicked".into()))
            }),
            None => Ok(()),
        }
    }
}

impl Drop for Redundancy {
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::SeqCst);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

/// A writer of one of the application's topics whose DDS ownership strength follows the
/// controller's role (30/20/10 for Primary/Secondary/Tertiary, 15 provisional, 35 taking over
/// from a late Primary); it writes nothing while the controller holds no role, and drops its DDS
/// writer at once when the role goes down. `K` is [`NoKey`] (one instance, the default) or
/// [`WithKey`] (`T: rustdds::Keyed`: one owner per instance, all moving with the role).
///
/// RustDDS fixes a writer's strength at creation, so a new role means a new DDS writer (a new
/// GUID), handed over so the reader never falls to a weaker controller
/// ([`crate::dds::StrengthWriter`]). The role is read at every [`RoleWriter::write`] and
/// [`RoleWriter::keep_alive`]: call one of them at least every `timing.command_republish_ms`.
pub struct RoleWriter<T, K: Keying<T> = NoKey> {
    shared: Arc<Shared>,
    writer: StrengthWriter<T, K>,
    policy: AperiodicPolicy,
    republish: Duration,
    /// How long its commands as the owner may lapse before it doubts itself
    /// (crate::stall::owner_lapse_bound).
    owner_lapse: Duration,
    /// The last sample the application wrote, and when it last went out (or was offered).
    last: Option<(T, Instant)>,
}

impl<T: Clone, K: Keying<T>> RoleWriter<T, K> {
    /// Writes `sample` if this controller may write now; returns whether it was written. The
    /// sample is kept for [`RoleWriter::keep_alive`] either way.
    pub fn write(&mut self, sample: T) -> Result<bool, DdsError> {
        self.last = Some((sample.clone(), Instant::now()));
        self.write_if_allowed(Some(sample))
    }

    /// Follows the role without new data: drops or re-creates the DDS writer for the current
    /// role and, with [`AperiodicPolicy::Republish`], writes the last sample again once
    /// `timing.command_republish_ms` has passed since it last went out, so the reader's
    /// deadline never lets a weaker writer through on an aperiodic topic (paper, "Exclusive
    /// Ownership on aperiodic topics"). Returns whether it wrote.
    pub fn keep_alive(&mut self) -> Result<bool, DdsError> {
        let due = match (&self.last, self.policy) {
            (Some((_, at)), AperiodicPolicy::Republish) => at.elapsed() >= self.republish,
            _ => false,
        };
        if !due {
            self.write_if_allowed(None)?;
            return Ok(false);
        }
        let sample = self.last.as_mut().map(|(sample, at)| {
            *at = Instant::now();
            sample.clone()
        });
        self.write_if_allowed(sample)
    }

    /// How long until [`RoleWriter::keep_alive`] would write again (zero: now; `None`: it
    /// never republishes under this policy, or nothing was written yet).
    pub fn keep_alive_due_in(&self) -> Option<Duration> {
        match (&self.last, self.policy) {
            (Some((_, at)), AperiodicPolicy::Republish) => {
                Some(self.republish.saturating_sub(at.elapsed()))
            }
            _ => None,
        }
    }

    /// Sets the DDS writer's strength from the current role and policy, then writes `sample`
    /// (if any) when there is a writer.
    fn write_if_allowed(&mut self, sample: Option<T>) -> Result<bool, DdsError> {
        // Taken before the status: a restart after it makes that status the last life's.
        let restarts_seen = self.shared.loop_clock.restarts();
        let (role, strength) = {
            let status = self.shared.status();
            (status.report.role, status.report.strength)
        };
        let allowed = match self.policy {
            AperiodicPolicy::Republish | AperiodicPolicy::Periodic => strength,
            AperiodicPolicy::PrimaryOnly => strength.filter(|_| role == Some(Role::Primary)),
        };
        if strength.is_none() {
            self.shared.loop_clock.holds_no_role();
        }
        // Back from a stop before the voting loop has noticed: what the status says is stale
        // (a new Primary commands meanwhile), so the writer goes and nothing is written.
        // A reported fault silences it at once, before the voting loop fails it.
        // The Primary beside weaker writers whose commands lapsed for a deadline has lost the
        // actuator to the next of them: it must not take it back (crate::stall).
        let owner_beside_others = role == Some(Role::Primary)
            && matches!(
                self.policy,
                AperiodicPolicy::Republish | AperiodicPolicy::Periodic
            );
        if !owner_beside_others {
            self.shared.loop_clock.not_the_owner();
        }
        // Its DDS writer stopped after a gap in its sends: the actuator may have moved to the
        // next writer, and the owner's next command would take it back, so it doubts itself
        // as after a lapse (crate::dds::StrengthWriter::set_max_send_gap).
        let silent = || {
            self.shared.loop_clock.stalled_for_writer(restarts_seen)
                || self.shared.silenced.load(Ordering::SeqCst)
                || (owner_beside_others
                    && (self.shared.loop_clock.owner_lapsed(self.owner_lapse)
                        || (self.writer.stopped_after_gap()
                            && self.shared.loop_clock.owner_stopped(self.owner_lapse))))
        };
        let allowed = allowed.filter(|_| !silent());
        self.writer.set_strength(allowed)?;
        let written = match sample {
            Some(sample) => self.writer.write(sample)?,
            None => false,
        };
        if written {
            self.shared.loop_clock.wrote(owner_beside_others);
        }
        Ok(written)
    }

    /// The strength of the DDS writer now (`None`: no writer).
    pub fn strength(&self) -> Option<Strength> {
        self.writer.strength()
    }

    /// The name of the topic it writes.
    pub fn topic_name(&self) -> String {
        self.writer.topic_name()
    }
}

/// This controller's writer of a voted topic (see [`Redundancy::voted_writer`]): each sample is
/// its own answer to one input, keyed by its id, written only while it holds a role.
pub struct VotedWriter<T: Clone> {
    shared: Arc<Shared>,
    writer: crate::dds::Writer<VotedSample<T>>,
    /// How long [`VotedWriter::write_when_due`] lets pass without a write: half the command
    /// deadline.
    republish: Duration,
    /// The input last written, and when.
    last: Option<(u64, Instant)>,
}

impl<T: Clone + 'static> VotedWriter<T> {
    /// Writes `value` as this controller's answer to `input` (the application's tag of the
    /// input it computed from: the tracker's is the camera sample's source timestamp), with
    /// `input_digest`, the digest of the input's values as it received them
    /// ([`crate::wire::input_digest`]; 0: none) and `raw`, its raw answer before alignment
    /// ([`RawAnswer`]; [`RawAnswer::NONE`]: none), if this controller holds a role now (and is
    /// not FAILED); returns whether it was written. Write at least once per command deadline
    /// (again with the same input while no new input comes), so a receiver keeps counting
    /// this controller.
    pub fn write(
        &mut self,
        input: u64,
        input_digest: u64,
        raw: RawAnswer,
        value: T,
    ) -> Result<bool, DdsError> {
        // Taken before the status, as RoleWriter::write_if_allowed does.
        let restarts_seen = self.shared.loop_clock.restarts();
        let (id, role_held) = {
            let report = &self.shared.status().report;
            let failed = report.phase == crate::core::Phase::Failed;
            (report.id, report.role.is_some() && !failed)
        };
        // Back from a stop before the voting loop has noticed, the role is stale: silent.
        let silenced = self.shared.silenced.load(Ordering::SeqCst);
        if !role_held || silenced || self.shared.loop_clock.stalled_for_writer(restarts_seen) {
            return Ok(false);
        }
        let answer = Voted {
            from: id,
            input,
            input_digest,
            raw,
            value,
        };
        self.writer.write(&answer)?;
        self.shared.loop_clock.wrote(false);
        self.last = Some((input, Instant::now()));
        Ok(true)
    }

    /// As [`VotedWriter::write`], but only when `input` is not the one last written or half
    /// a command deadline has passed since the last write: for an application that offers its
    /// output more often than its inputs change (the tracker re-publishes every
    /// `command_republish_ms` on the exclusive topic), so that a receiver hears each new answer
    /// at once and a live controller at least twice per deadline, without the re-publications.
    pub fn write_when_due(
        &mut self,
        input: u64,
        input_digest: u64,
        raw: RawAnswer,
        value: T,
    ) -> Result<bool, DdsError> {
        let due = self
            .last
            .is_none_or(|(last, at)| last != input || at.elapsed() >= self.republish);
        if !due {
            return Ok(false);
        }
        self.write(input, input_digest, raw, value)
    }

    /// The name of the topic it writes.
    pub fn topic_name(&self) -> &str {
        self.writer.topic_name()
    }
}
