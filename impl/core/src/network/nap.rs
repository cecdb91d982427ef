//! The Network Alarm Participant of one controller: heartbeats in, a tick now and then,
//! commands out (publish the network heartbeat on each network, raise or clear an alarm).
//!
//! Every input is followed by an evaluation: the link matrix as of `now_ms`, its conclusion,
//! and the alarm book's hysteresis. So a heartbeat that brings a link back counts from the
//! instant it arrives, and a tick at [`Nap::next_wakeup_ms`] catches every deadline.

use super::alarms::{AlarmBook, AlarmCause, AlarmChange, AlarmSubject, AlarmTiming};
use super::conclude::{conclude, Conclusion};
use super::links::{Hearing, LinkMatrix, Members, Network, NetworkHeartbeat};
use super::observe::Observer;
use crate::types::ControllerId;

/// One monitor's identity and timing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NapConfig {
    /// This controller's id (1..=3).
    pub id: ControllerId,
    /// The like controllers configured (all three, or a duplex pair).
    pub members: Members,
    /// The network heartbeat period (paper: 4 Hz).
    pub period_ms: u64,
    /// A link is Fail after this many periods without its heartbeat (paper: 2).
    pub deadline_periods: u32,
    /// An alarm is raised once its subject has been implicated this long (default one and a
    /// half periods). The links of a failed network miss their deadlines over one period (each
    /// was last heard at its own point of the period), so a conclusion seen meanwhile, while
    /// it settles, must not raise: more than one period.
    pub raise_after_ms: u64,
    /// An alarm clears once its links have been Good this many periods in a row.
    pub clear_after_periods: u32,
}

impl NapConfig {
    /// Controller `id` among all three, with the paper's timing: 250 ms period, deadline two
    /// periods, raise after 375 ms, clear after 4 periods (1 s) of good links. A network that
    /// dies is alarmed within two deadlines (1 s): its links fail within one deadline, the
    /// reports arrive at once (see [`Nap::step`]), and the conclusion holds 375 ms.
    pub fn new(id: ControllerId) -> NapConfig {
        NapConfig {
            id,
            members: Members::ALL,
            period_ms: 250,
            deadline_periods: 2,
            raise_after_ms: 375,
            clear_after_periods: 4,
        }
    }

    /// The link deadline.
    pub fn deadline_ms(&self) -> u64 {
        self.period_ms * u64::from(self.deadline_periods)
    }

    /// The alarms' hysteresis in ms.
    pub fn alarm_timing(&self) -> AlarmTiming {
        AlarmTiming {
            raise_after_ms: self.raise_after_ms,
            clear_after_ms: self.period_ms * u64::from(self.clear_after_periods),
        }
    }
}

/// An input to the monitor.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum NapInput {
    /// A peer's network heartbeat arrived on `received_on` (the network of the participant
    /// that read it, not anything the sender claims).
    Heartbeat {
        /// The network it arrived on.
        received_on: Network,
        /// The heartbeat.
        heartbeat: NetworkHeartbeat,
    },
    /// Time passed (call at [`Nap::next_wakeup_ms`] at the latest).
    Tick,
}

/// What the caller must do.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum NapCommand {
    /// Publish this network heartbeat on `network` (best effort).
    PublishHeartbeat {
        /// The network to publish on.
        network: Network,
        /// The heartbeat.
        heartbeat: NetworkHeartbeat,
    },
    /// Raise a network alarm, or republish it with a new cause (reliable, keyed by subject).
    RaiseAlarm {
        /// What it is about.
        subject: AlarmSubject,
        /// Why.
        cause: AlarmCause,
    },
    /// Clear a network alarm.
    ClearAlarm {
        /// What it was about.
        subject: AlarmSubject,
    },
}

/// The network alarm participant of one controller.
#[derive(Clone, Debug)]
pub struct Nap {
    config: NapConfig,
    observer: Observer,
    alarms: AlarmBook,
    conclusion: Conclusion,
    publish_due_ms: u64,
    /// The row the last heartbeat carried.
    published: Option<Hearing>,
}

impl Nap {
    /// A monitor starting at `now_ms`; its first heartbeats are due at once.
    pub fn new(config: NapConfig, now_ms: u64) -> Nap {
        let config = NapConfig {
            period_ms: config.period_ms.max(1),
            deadline_periods: config.deadline_periods.max(1),
            ..config
        };
        let observer = Observer::new(config.id, config.members, config.deadline_ms(), now_ms);
        let conclusion = conclude(&observer.matrix(now_ms), config.members, config.id);
        Nap {
            config,
            observer,
            alarms: AlarmBook::new(),
            conclusion,
            publish_due_ms: now_ms,
            published: None,
        }
    }

    /// Its identity and timing.
    pub fn config(&self) -> &NapConfig {
        &self.config
    }

    /// Feeds one input at `now_ms`; returns the commands to perform, in order.
    ///
    /// Heartbeats go out every period and also at once when this monitor's own row changes
    /// (a link it hears failed or came back): the other monitors learn of it without waiting
    /// up to a period, so every monitor's conclusion settles as soon as the links' own
    /// deadlines have run out.
    pub fn step(&mut self, input: NapInput, now_ms: u64) -> Vec<NapCommand> {
        let mut commands = Vec::new();
        if let NapInput::Heartbeat {
            received_on,
            heartbeat,
        } = input
        {
            self.observer.hear(received_on, &heartbeat, now_ms);
        }
        let periodic = now_ms >= self.publish_due_ms;
        if periodic || self.published != Some(self.observer.hearing(now_ms)) {
            self.publish(now_ms, periodic, &mut commands);
        }
        self.conclusion = conclude(
            &self.observer.matrix(now_ms),
            self.config.members,
            self.config.id,
        );
        let changes = self
            .alarms
            .update(&self.conclusion, self.config.alarm_timing(), now_ms);
        commands.extend(changes.into_iter().map(|change| match change {
            AlarmChange::Raise { subject, cause } => NapCommand::RaiseAlarm { subject, cause },
            AlarmChange::Clear { subject } => NapCommand::ClearAlarm { subject },
        }));
        commands
    }

    /// The same heartbeat on both networks; a periodic one schedules the next a period on (a
    /// caller that fell behind publishes once, not once per missed period).
    fn publish(&mut self, now_ms: u64, periodic: bool, commands: &mut Vec<NapCommand>) {
        let heartbeat = NetworkHeartbeat {
            from: self.config.id,
            hearing: self.observer.hearing(now_ms),
        };
        self.published = Some(heartbeat.hearing);
        for network in Network::ALL {
            commands.push(NapCommand::PublishHeartbeat { network, heartbeat });
        }
        if !periodic {
            return;
        }
        self.publish_due_ms += self.config.period_ms;
        if self.publish_due_ms <= now_ms {
            self.publish_due_ms = now_ms + self.config.period_ms;
        }
    }

    /// When to tick next (after `now_ms`): the next heartbeat, the next deadline to run out,
    /// or the next alarm due.
    pub fn next_wakeup_ms(&self, now_ms: u64) -> u64 {
        let publish_ms = self.publish_due_ms.max(now_ms + 1);
        [
            self.observer.next_change_ms(now_ms),
            self.alarms.next_due_ms(self.config.alarm_timing(), now_ms),
        ]
        .into_iter()
        .flatten()
        .fold(publish_ms, u64::min)
    }

    /// The conclusion of the last evaluation.
    pub fn conclusion(&self) -> &Conclusion {
        &self.conclusion
    }

    /// The link matrix as of `now_ms`.
    pub fn matrix(&self, now_ms: u64) -> LinkMatrix {
        self.observer.matrix(now_ms)
    }

    /// The alarms raised, with the cause last published.
    pub fn raised_alarms(&self) -> impl Iterator<Item = (AlarmSubject, &AlarmCause)> {
        self.alarms.raised()
    }

    /// Heartbeats dropped so far: from this controller's own id (another process configured
    /// with it) or from a controller not configured.
    pub fn ignored_heartbeats(&self) -> u64 {
        self.observer.ignored_heartbeats()
    }
}
