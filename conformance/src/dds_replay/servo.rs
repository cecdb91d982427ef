//! The actuator as the servo simulator (`rl servo --json`, DDS exclusive ownership with the
//! command deadline) reports it: every accepted command with the controller behind its
//! writer, placed on the wall clock.
//!
//! The servo stamps its lines with milliseconds since its own start. Its clock is put on the
//! wall clock with the smallest difference seen between a line's arrival (wall clock) and its
//! stamp: the servo's start plus the fastest a line got through the pipe, within about a
//! millisecond of the true time.

use rl::procs::ServoEvent;
use rl_layer::core::ControllerId;
use std::collections::BTreeMap;
use std::fmt::Write as _;

/// The servo's accepted commands so far.
#[derive(Clone, Debug, Default)]
pub struct ServoView {
    /// Wall-clock ms minus servo ms: the smallest seen.
    offset_ms: Option<i64>,
    /// Accepted commands: servo time, and the writer's controller (`None`: no heartbeat named
    /// its participant yet).
    commands: Vec<(u64, Option<ControllerId>)>,
}

/// Who the servo took commands from in a window.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum OwnerSeen {
    /// No command accepted.
    Nobody,
    /// Every accepted command came from this controller.
    One(ControllerId),
    /// Several writers, or one the servo cannot name: commands per controller.
    Unsettled(BTreeMap<Option<ControllerId>, usize>),
}

impl ServoView {
    /// Takes in one servo line that arrived at `arrival_wall_ms`.
    pub fn take(&mut self, arrival_wall_ms: u64, event: &ServoEvent) {
        let t_ms = event.t_ms();
        let offset = arrival_wall_ms as i64 - t_ms as i64;
        self.offset_ms = Some(self.offset_ms.map_or(offset, |o| o.min(offset)));
        if let ServoEvent::Command { controller_id, .. } = event {
            self.commands.push((t_ms, *controller_id));
        }
    }

    /// The servo's time of a wall-clock time, once a line placed its clock.
    fn servo_ms(&self, wall_ms: u64) -> Option<u64> {
        self.offset_ms
            .map(|offset| (wall_ms as i64 - offset).max(0) as u64)
    }

    /// Who the servo accepted commands from in `[from_wall_ms, until_wall_ms)`.
    pub fn owner_between(&self, from_wall_ms: u64, until_wall_ms: u64) -> OwnerSeen {
        let (Some(from), Some(until)) = (self.servo_ms(from_wall_ms), self.servo_ms(until_wall_ms))
        else {
            return OwnerSeen::Nobody;
        };
        let mut counts: BTreeMap<Option<ControllerId>, usize> = BTreeMap::new();
        for (_, controller) in self
            .commands
            .iter()
            .filter(|(t_ms, _)| (from..until).contains(t_ms))
        {
            *counts.entry(*controller).or_default() += 1;
        }
        let mut writers = counts.keys();
        match (writers.next(), writers.next()) {
            (None, _) => OwnerSeen::Nobody,
            (Some(Some(id)), None) => OwnerSeen::One(*id),
            _ => OwnerSeen::Unsettled(counts),
        }
    }
}

/// `C1 x3, C2 x2, an unnamed writer x1`.
pub fn describe_counts(counts: &BTreeMap<Option<ControllerId>, usize>) -> String {
    let mut out = String::new();
    for (controller, count) in counts {
        if !out.is_empty() {
            out.push_str(", ");
        }
        let _ = match controller {
            Some(id) => write!(out, "C{id} x{count}"),
            None => write!(out, "a writer no heartbeat named x{count}"),
        };
    }
    out
}

/// A servo line for the transcript: owner changes only (commands come every 10 ms).
pub fn describe(event: &ServoEvent) -> Option<String> {
    match event {
        ServoEvent::OwnerChanged {
            from_controller_id,
            to_controller_id,
            strength,
            gap_ms,
            ..
        } => {
            let name =
                |id: &Option<ControllerId>| id.map_or("?".to_string(), |id| format!("C{id}"));
            Some(format!(
                "owner {} -> {} (strength {strength}, {} ms without commands)",
                name(from_controller_id),
                name(to_controller_id),
                gap_ms.map_or("-".to_string(), |g| g.to_string())
            ))
        }
        ServoEvent::Expired {
            controller_id,
            late_ms,
            lifespan_ms,
            ..
        } => Some(format!(
            "dropped a command of {} {late_ms} ms late (lifespan {lifespan_ms} ms)",
            controller_id.map_or("?".to_string(), |id| format!("C{id}"))
        )),
        ServoEvent::Command { .. } => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn command(t_ms: u64, controller_id: Option<ControllerId>) -> ServoEvent {
        ServoEvent::Command {
            t_ms,
            writer_guid: "00".into(),
            controller_id,
            strength: rl_layer::core::Strength(30),
            pan: 500,
            tilt: 500,
            frequency: 60,
            late_ms: None,
        }
    }

    #[test]
    fn commands_are_placed_on_the_wall_clock_by_the_fastest_line() {
        let mut view = ServoView::default();
        // Servo started at wall 10_000; lines arrive 1-5 ms after their stamp.
        view.take(10_105, &command(100, Some(1)));
        view.take(10_111, &command(110, Some(1)));
        view.take(10_122, &command(120, Some(2)));
        view.take(10_131, &command(130, Some(2)));
        assert_eq!(view.owner_between(10_100, 10_120), OwnerSeen::One(1));
        assert_eq!(view.owner_between(10_120, 10_140), OwnerSeen::One(2));
        assert_eq!(view.owner_between(10_140, 10_200), OwnerSeen::Nobody);
        let OwnerSeen::Unsettled(counts) = view.owner_between(10_100, 10_140) else {
            panic!("two writers in the window");
        };
        assert_eq!(describe_counts(&counts), "C1 x2, C2 x2");
    }

    #[test]
    fn a_writer_the_servo_cannot_name_is_no_owner() {
        let mut view = ServoView::default();
        view.take(1_000, &command(0, None));
        assert!(matches!(
            view.owner_between(1_000, 1_010),
            OwnerSeen::Unsettled(_)
        ));
        assert_eq!(ServoView::default().owner_between(0, 10), OwnerSeen::Nobody);
    }
}
