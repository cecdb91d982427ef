//! The Network Alarm Participant of one controller: heartbeats and named timers in, commands
//! out (publish the network heartbeat on each network, raise or clear an alarm).
//!
//! Every input is followed by an evaluation: the link matrix as of `now_ms`, its conclusion,
//! and the alarm book's hysteresis. So a heartbeat that brings a link back counts from the
//! instant it arrives, and a timer stepped at [`Nap::next_deadline`] catches every deadline.
//! Like the voting core, it names its timers ([`NapTimer`]: the periodic heartbeat, a link's
//! deadline, an alarm's hysteresis) and checks its invariants after every step in debug
//! builds (no timer left due, its own row published as it stands).

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

/// The monitor's timers. When several are due at once they run in this order (it concludes
/// before it speaks); each step evaluates everything due, whichever timer it was given.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum NapTimer {
    /// A link's deadline (or a peer's report's) runs out: the matrix changes by itself.
    LinkDeadline,
    /// An alarm has been implicated, or its links good, long enough: it is raised, republished
    /// with a new cause, or cleared.
    AlarmHysteresis,
    /// The periodic network heartbeat is due.
    Publish,
}

/// When the monitor must next be stepped, and with which timer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NapDeadline {
    /// The instant, on the caller's clock.
    pub at_ms: u64,
    /// The timer that fires then.
    pub timer: NapTimer,
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
    /// A timer fired ([`Nap::due_timer`], [`Nap::next_deadline`]).
    Timer(NapTimer),
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
    /// The instant of the last evaluation: deadlines up to it are taken in.
    evaluated_ms: u64,
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
            evaluated_ms: now_ms,
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
        self.evaluated_ms = self.evaluated_ms.max(now_ms);
        self.debug_check(now_ms);
        commands
    }

    /// Panics (debug builds only) when the monitor breaks an invariant after a step at
    /// `now_ms`: a timer is still due (a deadline would be missed until the next input), or
    /// the row it last published is not its row now (a peer would conclude on a stale row).
    fn debug_check(&self, now_ms: u64) {
        debug_assert!(
            self.next_deadline().at_ms > now_ms,
            "NAP C{}: {:?} still due after a step at {now_ms} ms",
            self.config.id,
            self.next_deadline()
        );
        debug_assert!(
            self.published == Some(self.observer.hearing(now_ms)),
            "NAP C{}: published {:?}, hears {:?} at {now_ms} ms",
            self.config.id,
            self.published,
            self.observer.hearing(now_ms)
        );
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

    /// Its timers with the instant each next fires (a link deadline or an alarm that is not
    /// pending is absent).
    fn timers(&self) -> [(NapTimer, Option<u64>); 3] {
        let evaluated_ms = self.evaluated_ms;
        [
            (
                NapTimer::LinkDeadline,
                self.observer.next_change_ms(evaluated_ms),
            ),
            (
                NapTimer::AlarmHysteresis,
                self.alarms
                    .next_due_ms(self.config.alarm_timing(), evaluated_ms),
            ),
            (NapTimer::Publish, Some(self.publish_due_ms)),
        ]
    }

    /// The timer that runs at `now_ms`, if one is due (the first in [`NapTimer`]'s order).
    pub fn due_timer(&self, now_ms: u64) -> Option<NapTimer> {
        self.timers()
            .into_iter()
            .find(|(_, at_ms)| at_ms.is_some_and(|at_ms| at_ms <= now_ms))
            .map(|(timer, _)| timer)
    }

    /// When the monitor must next be stepped, and which timer fires then: the next
    /// heartbeat, the next link deadline to run out, or the next alarm due.
    pub fn next_deadline(&self) -> NapDeadline {
        let (timer, at_ms) = self
            .timers()
            .into_iter()
            .filter_map(|(timer, at_ms)| at_ms.map(|at_ms| (timer, at_ms)))
            .min_by_key(|&(timer, at_ms)| (at_ms, timer))
            .unwrap_or((NapTimer::Publish, self.publish_due_ms));
        NapDeadline { at_ms, timer }
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
