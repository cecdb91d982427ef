//! The benchmark's view of a running fleet, built from the children's JSON lines: each
//! controller's last status, every `output` and `started` event, every report of a steady
//! Primary, and the servo's owner changes.

use crate::procs::{parse_servo_event, Line, ServoEvent};
use rl_layer::core::{ControllerId, Phase, Role, Status, Strength};
use rl_layer::event::{Event, EventLine};
use std::collections::BTreeMap;
use std::sync::mpsc::Receiver;
use std::time::{Duration, Instant};

/// A controller's `output` event: from `t_ms` on (its round clock) it commands at `strength`.
#[derive(Clone, Copy, Debug)]
pub struct Output {
    pub id: ControllerId,
    pub t_ms: u64,
    pub strength: Option<Strength>,
}

/// An owner change at the servo (`owner_changed`).
#[derive(Clone, Copy, Debug)]
pub struct OwnerChange {
    /// Time without commands, measured by the servo's arbiter (`None` for the first owner).
    pub gap_ms: Option<u64>,
    pub from: Option<ControllerId>,
    pub to: Option<ControllerId>,
}

pub struct Watch {
    lines: Receiver<Line>,
    pub status: BTreeMap<ControllerId, Status>,
    pub outputs: Vec<Output>,
    /// `(controller, t_ms)` of every `started` event.
    pub started: Vec<(ControllerId, u64)>,
    /// `(controller, t_ms)` of every status reporting the controller steady as Primary at
    /// the Primary's strength.
    pub steady_primary: Vec<(ControllerId, u64)>,
    pub owner_changes: Vec<OwnerChange>,
    pub owner: Option<ControllerId>,
    /// The camera's frames (`rl shapes --json`): when read, and how far off centre the ball
    /// was (`None`: not seen).
    pub frames: Vec<(Instant, Option<f64>)>,
    /// Every controller alarm raised, in arrival order.
    pub alarms: Vec<AlarmRaised>,
}

/// A controller alarm a controller raised about a peer.
#[derive(Clone, Copy, Debug)]
pub struct AlarmRaised {
    pub by: ControllerId,
    pub about: ControllerId,
    /// When, on the raiser's wall clock (ms since the epoch).
    pub t_ms: u64,
}

impl Watch {
    pub fn new(lines: Receiver<Line>) -> Watch {
        Watch {
            lines,
            status: BTreeMap::new(),
            outputs: Vec::new(),
            started: Vec::new(),
            steady_primary: Vec::new(),
            owner_changes: Vec::new(),
            owner: None,
            frames: Vec::new(),
            alarms: Vec::new(),
        }
    }

    /// Takes in the lines that arrive within `wait`.
    pub fn pump(&mut self, wait: Duration) {
        self.pump_until(Instant::now() + wait);
    }

    /// Takes in the lines that arrive until `until` (returns then, within a millisecond or so).
    pub fn pump_until(&mut self, until: Instant) {
        while let Ok(line) = self
            .lines
            .recv_timeout(until.saturating_duration_since(Instant::now()))
        {
            self.take(&line);
            if Instant::now() >= until {
                break;
            }
        }
    }

    fn take(&mut self, line: &Line) {
        if line.source == "camera" {
            if let Ok(frame) = serde_json::from_str::<crate::sim::shapes::CameraFrame>(&line.text) {
                self.frames.push((line.at, frame.error_px));
            }
        } else if line.source == "servo" {
            if let Some(ServoEvent::OwnerChanged {
                gap_ms,
                from_controller_id,
                to_controller_id,
                ..
            }) = parse_servo_event(&line.text)
            {
                self.owner = to_controller_id;
                self.owner_changes.push(OwnerChange {
                    gap_ms,
                    from: from_controller_id,
                    to: to_controller_id,
                });
            }
        } else if let Some(line) = EventLine::parse(&line.text) {
            match line.event {
                Event::Status { status } => {
                    let report = &status.report;
                    if report.phase == Phase::Steady
                        && report.role == Some(Role::Primary)
                        && report.strength == Some(Role::Primary.strength())
                    {
                        self.steady_primary.push((line.id, line.t_ms));
                    }
                    self.status.insert(line.id, *status);
                }
                Event::Output { strength, .. } => self.outputs.push(Output {
                    id: line.id,
                    t_ms: line.t_ms,
                    strength,
                }),
                Event::Started => self.started.push((line.id, line.t_ms)),
                Event::Alarm {
                    about,
                    raised: true,
                    ..
                } => self.alarms.push(AlarmRaised {
                    by: line.id,
                    about,
                    t_ms: line.t_ms,
                }),
                _ => {}
            }
        }
    }

    /// The tracking errors of the frames read in `from..to`, and how many frames lost the ball.
    pub fn tracking_errors(&self, from: Instant, to: Instant) -> (Vec<f64>, usize) {
        let window: Vec<Option<f64>> = self
            .frames
            .iter()
            .filter(|(at, _)| (from..to).contains(at))
            .map(|(_, error)| *error)
            .collect();
        let unseen = window.iter().filter(|e| e.is_none()).count();
        (window.into_iter().flatten().collect(), unseen)
    }

    /// Pumps until `done` holds (true) or `timeout` passes (false).
    pub fn wait(&mut self, timeout: Duration, mut done: impl FnMut(&Watch) -> bool) -> bool {
        let until = Instant::now() + timeout;
        while !done(self) {
            if Instant::now() >= until {
                return false;
            }
            self.pump(Duration::from_millis(10));
        }
        true
    }

    /// The steady controller holding `role`.
    pub fn holder(&self, role: Role) -> Option<ControllerId> {
        self.status
            .values()
            .find(|s| s.report.phase == Phase::Steady && s.report.role == Some(role))
            .map(|s| s.report.id)
    }

    /// Whether controllers 1-3 are steady and commanding as one group: one Primary, one
    /// Secondary, one Tertiary. (Alone, each is a steady provisional Primary: with DDS
    /// Security, discovery can outlast a short initialization window, and the group forms by
    /// merging a moment later.)
    pub fn formed(&self) -> bool {
        let mut roles: Vec<Option<Role>> = [1, 2, 3]
            .iter()
            .filter_map(|id| self.status.get(id))
            .filter(|s| s.report.phase == Phase::Steady && s.report.strength.is_some())
            .map(|s| s.report.role)
            .collect();
        roles.sort();
        roles
            == [
                Some(Role::Primary),
                Some(Role::Secondary),
                Some(Role::Tertiary),
            ]
    }

    /// Whether every one of `ids` is steady and commanding.
    pub fn all_steady(&self, ids: &[ControllerId]) -> bool {
        ids.iter().all(|id| {
            self.status
                .get(id)
                .is_some_and(|s| s.report.phase == Phase::Steady && s.report.strength.is_some())
        })
    }
}
