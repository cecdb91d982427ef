//! The status LEDs: what the four red/green LEDs show (a pure function of what a controller
//! knows) and the banks that show it: a console line, or eight GPIO lines on a Pi ([`gpio`]).
//!
//! The paper's demo wires four two-lead LEDs to each controller: LED1 Primary, LED2 Secondary,
//! LED3 Tertiary (the role LEDs) and LED4 the controller's own status. "A working tracker
//! presents a green LED indicating its role. A red LED indicates a failed unit and role. Off
//! indicates that the corresponding backup role is operational" (or has no unit at all). LED4
//! is the unit's own health, which matters before roles exist and when it fails itself.
//!
//! [`pattern`] computes the four colours from [`LedInputs`], in this order of precedence:
//!
//! | LED | condition | colour |
//! |---|---|---|
//! | role R | this controller holds R and is healthy | green |
//! | role R | this controller holds R and is not healthy | red |
//! | role R | otherwise, `failed_roles[R]` (see [`failed_roles`]) | red |
//! | role R | otherwise: held by an operational peer, or vacant with no failure to account for | off |
//! | LED4 | phase `Failed`, or `own_fault` | red |
//! | LED4 | otherwise (`Initializing`, `Voting`, `Steady`) | green |
//!
//! "Healthy" is LED4's green: not `Failed` and no `own_fault`. A role this controller holds
//! always shows its own state, never a peer's alarm for the same role: once it holds the role,
//! the role is filled again.
//!
//! Which roles count as failed is [`failed_roles`]: a role whose holder in the last agreed
//! assignment has a raised controller alarm (before the re-vote), and, after the re-vote has
//! dropped that holder and promoted the others, one vacant role per alarmed controller, counted
//! from Tertiary up. So a three-controller system that loses one shows a red LED from the
//! moment of the alarm until the alarm is cleared (the unit is back, in the lowest role): first
//! on the failed unit's role, then, after promotion, on the vacated Tertiary.
//!
//! Each LED is two GPIO lines: [`line_values`] maps a colour to them (first pin high = green).

pub mod gpio;

use crate::core::types::{Assignment, ControllerId, Phase, Role, ROLE_COUNT};
use crate::core::Status;
use std::fmt;
use std::io::Write;

/// The colour of one two-lead LED.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum LedColor {
    /// Both leads low: nothing to show (a backup role operational or vacant).
    #[default]
    Off,
    /// A working unit: its role, or LED4 when healthy.
    Green,
    /// A failed unit and role, or LED4 when this controller failed or found a fault.
    Red,
}

impl LedColor {
    /// The colour as the console line and events write it: `off`, `green` or `red`.
    pub fn name(self) -> &'static str {
        match self {
            LedColor::Off => "off",
            LedColor::Green => "green",
            LedColor::Red => "red",
        }
    }
}

impl fmt::Display for LedColor {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The number of LEDs: three role LEDs and the own-status LED.
pub const LED_COUNT: usize = ROLE_COUNT + 1;

/// Index of the own-status LED (LED4) in a [`LedPattern`].
pub const OWN_STATUS_LED: usize = ROLE_COUNT;

/// What the four LEDs show: `[LED1 Primary, LED2 Secondary, LED3 Tertiary, LED4 own status]`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct LedPattern(pub [LedColor; LED_COUNT]);

impl LedPattern {
    /// Every LED off: a bank just opened or being released.
    pub const ALL_OFF: LedPattern = LedPattern([LedColor::Off; LED_COUNT]);
    /// Every LED green: the lamp test's first step.
    pub const ALL_GREEN: LedPattern = LedPattern([LedColor::Green; LED_COUNT]);
    /// Every LED red: the lamp test's second step.
    pub const ALL_RED: LedPattern = LedPattern([LedColor::Red; LED_COUNT]);

    /// The LED of a role (LED1..LED3).
    pub fn role(&self, role: Role) -> LedColor {
        self.0[role.rank()]
    }

    /// LED4, the controller's own status.
    pub fn own(&self) -> LedColor {
        self.0[OWN_STATUS_LED]
    }

    /// The GPIO line values of every LED, in LED order (see [`line_values`]).
    pub fn line_values(&self) -> [[bool; 2]; LED_COUNT] {
        self.0.map(line_values)
    }
}

impl fmt::Display for LedPattern {
    /// `[P:green S:off T:off | own:green]`
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "[P:{} S:{} T:{} | own:{}]",
            self.0[0],
            self.0[1],
            self.0[2],
            self.own()
        )
    }
}

/// The two GPIO line values of one LED, `[green_pin, red_pin]`: driving the first high and the
/// second low lights green, the reverse red, both low is off. Never both high, which would
/// only short the LED's two leads to the same level.
pub fn line_values(color: LedColor) -> [bool; 2] {
    match color {
        LedColor::Off => [false, false],
        LedColor::Green => [true, false],
        LedColor::Red => [false, true],
    }
}

/// What a controller knows that the LEDs show.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LedInputs {
    /// Where this controller is in the protocol.
    pub phase: Phase,
    /// The role this controller commands with now, if any.
    pub own_role: Option<Role>,
    /// Roles whose unit has failed and is not replaced yet; index = role rank. Usually
    /// computed by [`failed_roles`].
    pub failed_roles: [bool; ROLE_COUNT],
    /// This controller detected a fault of its own (it is about to fail itself, or its
    /// software check failed).
    pub own_fault: bool,
}

impl LedInputs {
    /// Healthy = LED4 green: not failed and no fault of its own.
    pub fn healthy(&self) -> bool {
        self.phase != Phase::Failed && !self.own_fault
    }
}

/// The LEDs for what a controller knows; the module header has the table.
pub fn pattern(inputs: &LedInputs) -> LedPattern {
    let healthy = inputs.healthy();
    let health_color = if healthy {
        LedColor::Green
    } else {
        LedColor::Red
    };
    let mut colors = [LedColor::Off; LED_COUNT];
    for role in Role::ALL {
        colors[role.rank()] = if inputs.own_role == Some(role) {
            health_color
        } else if inputs.failed_roles[role.rank()] {
            LedColor::Red
        } else {
            LedColor::Off
        };
    }
    colors[OWN_STATUS_LED] = health_color;
    LedPattern(colors)
}

/// The LEDs for what a controller reports of itself and its peers ([`Status`]).
pub fn pattern_of(status: &Status) -> LedPattern {
    let alarmed: Vec<ControllerId> = status.alarms.iter().map(|(id, _)| *id).collect();
    pattern(&LedInputs {
        phase: status.report.phase,
        own_role: status.report.role,
        failed_roles: failed_roles(status.report.agreed.as_ref(), &alarmed),
        own_fault: false,
    })
}

/// Which roles show a failed unit, from the last agreed assignment and the controllers with a
/// raised controller alarm (lost or FAILED, not yet cleared):
///
/// - a role whose agreed holder is alarmed is failed (the re-vote has not dropped it yet);
/// - each alarmed controller that holds no agreed role has vacated one: that many vacant
///   roles are failed, counted from Tertiary up (promotion leaves the hole at the bottom).
///
/// An alarm is cleared when its controller comes back, so a returning unit turns its red off.
/// A vacant role with no alarm to account for (a system started with fewer than three) is not
/// failed: its LED is off.
pub fn failed_roles(agreed: Option<&Assignment>, alarmed: &[ControllerId]) -> [bool; ROLE_COUNT] {
    let mut failed = [false; ROLE_COUNT];
    let slots = agreed.map(|assignment| assignment.0).unwrap_or_default();
    let mut unplaced = 0;
    let mut counted: Vec<ControllerId> = Vec::with_capacity(alarmed.len());
    for &id in alarmed {
        // The same controller alarmed twice (lost, then FAILED) is one failed unit.
        if counted.contains(&id) {
            continue;
        }
        counted.push(id);
        match slots
            .iter()
            .position(|slot| slot.is_some_and(|h| h.id == id))
        {
            Some(rank) => failed[rank] = true,
            None => unplaced += 1,
        }
    }
    for rank in (0..ROLE_COUNT).rev() {
        if unplaced == 0 {
            break;
        }
        if slots[rank].is_none() {
            failed[rank] = true;
            unplaced -= 1;
        }
    }
    failed
}

/// Why an LED bank could not show a pattern.
#[derive(Debug, thiserror::Error)]
pub enum LedError {
    /// Writing the console line failed.
    #[error("cannot write the LED line: {0}")]
    Io(#[from] std::io::Error),
    /// A GPIO chip or line could not be opened or driven.
    #[error("GPIO {chip}: {message}")]
    Gpio {
        /// The GPIO character device, as configured (`leds.chip`).
        chip: String,
        /// What failed, with the pins involved.
        message: String,
    },
}

/// Something that shows a [`LedPattern`]: a console line, GPIO lines, a test recorder.
pub trait LedBank {
    /// Shows the pattern. Banks may skip a pattern equal to the one already shown.
    fn show(&mut self, pattern: LedPattern) -> Result<(), LedError>;

    /// Lights every LED in each colour briefly at start-up so a dead LED or a swapped lead
    /// shows before it matters. Banks a person cannot look at do nothing.
    fn lamp_test(&mut self) -> Result<(), LedError> {
        Ok(())
    }
}

/// The console bank: one line `LEDs [P:green S:off T:off | own:green]` each time the pattern
/// changes, so a log shows every change and nothing else.
#[derive(Debug)]
pub struct ConsoleLeds<W: Write> {
    out: W,
    shown: Option<LedPattern>,
}

impl<W: Write> ConsoleLeds<W> {
    /// A bank writing its lines to `out`, nothing shown yet.
    pub fn new(out: W) -> ConsoleLeds<W> {
        ConsoleLeds { out, shown: None }
    }

    /// The pattern last written, if any.
    pub fn shown(&self) -> Option<LedPattern> {
        self.shown
    }

    /// The writer back, with everything written to it.
    pub fn into_inner(self) -> W {
        self.out
    }
}

impl ConsoleLeds<std::io::Stdout> {
    /// The console bank on standard output.
    pub fn stdout() -> ConsoleLeds<std::io::Stdout> {
        ConsoleLeds::new(std::io::stdout())
    }
}

impl<W: Write> LedBank for ConsoleLeds<W> {
    fn show(&mut self, pattern: LedPattern) -> Result<(), LedError> {
        if self.shown == Some(pattern) {
            return Ok(());
        }
        writeln!(self.out, "LEDs {pattern}")?;
        self.out.flush()?;
        // Only after a successful write, so a failed line is written again next time.
        self.shown = Some(pattern);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::types::Holder;
    use LedColor::{Green as G, Off as O, Red as R};

    const HEALTHY_PHASES: [Phase; 3] = [Phase::Initializing, Phase::Voting, Phase::Steady];

    fn inputs(
        phase: Phase,
        own_role: Option<Role>,
        failed_roles: [bool; 3],
        own_fault: bool,
    ) -> LedInputs {
        LedInputs {
            phase,
            own_role,
            failed_roles,
            own_fault,
        }
    }

    #[test]
    fn pattern_table() {
        use Phase::*;
        use Role::*;
        const NONE_FAILED: [bool; 3] = [false; 3];
        #[rustfmt::skip]
        let table: &[(LedInputs, [LedColor; 4])] = &[
            // Before roles exist: only LED4.
            (inputs(Initializing, None, NONE_FAILED, false), [O, O, O, G]),
            (inputs(Voting, None, NONE_FAILED, false), [O, O, O, G]),
            // A working controller: green on its own role, backups operational = off.
            (inputs(Steady, Some(Primary), NONE_FAILED, false), [G, O, O, G]),
            (inputs(Steady, Some(Secondary), NONE_FAILED, false), [O, G, O, G]),
            (inputs(Steady, Some(Tertiary), NONE_FAILED, false), [O, O, G, G]),
            // An incumbent keeps commanding (and its green) during a re-vote.
            (inputs(Voting, Some(Secondary), NONE_FAILED, false), [O, G, O, G]),
            // A spare beyond three holds no role.
            (inputs(Steady, None, NONE_FAILED, false), [O, O, O, G]),
            // A peer failed: red on its role until the role is refilled.
            (inputs(Steady, Some(Secondary), [true, false, false], false), [R, G, O, G]),
            (inputs(Voting, Some(Primary), [false, false, true], false), [G, O, R, G]),
            (inputs(Steady, Some(Primary), [false, true, true], false), [G, R, R, G]),
            // Holding the role refills it: own state wins over a peer's alarm.
            (inputs(Steady, Some(Primary), [true, false, false], false), [G, O, O, G]),
            // This controller failed itself: red on its role and on LED4.
            (inputs(Failed, Some(Primary), NONE_FAILED, false), [R, O, O, R]),
            (inputs(Failed, None, NONE_FAILED, false), [O, O, O, R]),
            (inputs(Steady, Some(Tertiary), NONE_FAILED, true), [O, O, R, R]),
            (inputs(Initializing, None, NONE_FAILED, true), [O, O, O, R]),
            (inputs(Failed, None, [false, false, true], false), [O, O, R, R]),
        ];
        for (row, (inputs, expected)) in table.iter().enumerate() {
            assert_eq!(
                pattern(inputs),
                LedPattern(*expected),
                "row {row}: {inputs:?}"
            );
        }
    }

    #[test]
    fn led4_follows_health_in_every_phase() {
        for phase in HEALTHY_PHASES {
            let healthy = inputs(phase, None, [false; 3], false);
            assert_eq!(pattern(&healthy).own(), G, "{phase:?}");
            let faulty = inputs(phase, None, [false; 3], true);
            assert_eq!(pattern(&faulty).own(), R, "{phase:?}");
        }
        assert_eq!(
            pattern(&inputs(Phase::Failed, None, [false; 3], false)).own(),
            R
        );
    }

    fn holder(id: ControllerId) -> Holder {
        Holder { id, incarnation: 1 }
    }

    fn agreed(ids: &[ControllerId]) -> Assignment {
        Assignment::from_ranked(ids.iter().copied().map(holder))
    }

    #[test]
    fn failed_roles_table() {
        #[rustfmt::skip]
        let table: &[(Option<Assignment>, &[ControllerId], [bool; 3])] = &[
            // No agreement yet, no alarm.
            (None, &[], [false, false, false]),
            // Three working controllers.
            (Some(agreed(&[1, 2, 3])), &[], [false, false, false]),
            // Started with two: the vacant Tertiary is absent, not failed.
            (Some(agreed(&[1, 2])), &[], [false, false, false]),
            // Primary 1 lost, before the re-vote: its role is red.
            (Some(agreed(&[1, 2, 3])), &[1], [true, false, false]),
            (Some(agreed(&[1, 2, 3])), &[3], [false, false, true]),
            // After the re-vote promoted 2 and 3: the vacated Tertiary is red.
            (Some(agreed(&[2, 3])), &[1], [false, false, true]),
            // Two failures after the re-vote: Secondary and Tertiary vacated.
            (Some(agreed(&[3])), &[1, 2], [false, true, true]),
            // One re-voted away, one still in its role.
            (Some(agreed(&[2, 3])), &[1, 3], [false, true, true]),
            // The same controller alarmed twice is one failure.
            (Some(agreed(&[2, 3])), &[1, 1], [false, false, true]),
            // More alarms than vacant roles: every vacancy red, nothing else.
            (Some(agreed(&[2, 3, 4])), &[1, 5], [false, false, false]),
            (Some(agreed(&[2])), &[1, 3, 4], [false, true, true]),
            // No agreement yet but alarms (a controller failed during initialization).
            (None, &[2], [false, false, true]),
        ];
        for (row, (assignment, alarmed, expected)) in table.iter().enumerate() {
            assert_eq!(
                failed_roles(assignment.as_ref(), alarmed),
                *expected,
                "row {row}: {assignment:?} {alarmed:?}"
            );
        }
    }

    #[test]
    fn line_values_table() {
        assert_eq!(line_values(LedColor::Off), [false, false]);
        assert_eq!(line_values(LedColor::Green), [true, false]);
        assert_eq!(line_values(LedColor::Red), [false, true]);
        assert_eq!(
            LedPattern([G, R, O, G]).line_values(),
            [[true, false], [false, true], [false, false], [true, false]]
        );
    }

    #[test]
    fn pattern_display_and_accessors() {
        let shown = LedPattern([G, O, R, G]);
        assert_eq!(shown.to_string(), "[P:green S:off T:red | own:green]");
        assert_eq!(shown.role(Role::Primary), G);
        assert_eq!(shown.role(Role::Tertiary), R);
        assert_eq!(shown.own(), G);
        assert_eq!(
            LedPattern::ALL_OFF.to_string(),
            "[P:off S:off T:off | own:off]"
        );
    }

    #[test]
    fn console_prints_only_changes() {
        let mut console = ConsoleLeds::new(Vec::new());
        let steps = [
            LedPattern([O, O, O, G]),
            LedPattern([O, O, O, G]),
            LedPattern([G, O, O, G]),
            LedPattern([G, O, O, G]),
            LedPattern([G, O, O, G]),
            LedPattern([G, O, R, G]),
            LedPattern([G, O, O, G]),
        ];
        for step in steps {
            console.show(step).unwrap();
        }
        console.lamp_test().unwrap();
        assert_eq!(console.shown(), Some(LedPattern([G, O, O, G])));
        let text = String::from_utf8(console.into_inner()).unwrap();
        assert_eq!(
            text,
            "LEDs [P:off S:off T:off | own:green]\n\
             LEDs [P:green S:off T:off | own:green]\n\
             LEDs [P:green S:off T:red | own:green]\n\
             LEDs [P:green S:off T:off | own:green]\n"
        );
    }

    /// A writer that fails until told otherwise.
    struct Flaky {
        fail: bool,
        written: Vec<u8>,
    }

    impl Write for Flaky {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            if self.fail {
                return Err(std::io::Error::other("disk full"));
            }
            self.written.extend_from_slice(buf);
            Ok(buf.len())
        }

        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn console_write_failure_is_reported_and_retried() {
        let mut console = ConsoleLeds::new(Flaky {
            fail: true,
            written: Vec::new(),
        });
        let error = console.show(LedPattern::ALL_RED).unwrap_err();
        assert_eq!(error.to_string(), "cannot write the LED line: disk full");
        assert_eq!(console.shown(), None);
        console.out.fail = false;
        console.show(LedPattern::ALL_RED).unwrap();
        assert_eq!(
            String::from_utf8(console.into_inner().written).unwrap(),
            "LEDs [P:red S:red T:red | own:red]\n"
        );
    }
}
