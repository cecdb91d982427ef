//! The GPIO LED bank: the four two-lead red/green LEDs of a Raspberry Pi controller, eight
//! output lines on a GPIO character device (`/dev/gpiochip0`), driven through `gpiocdev`.
//!
//! Each LED sits across two lines, `[green_pin, red_pin]` (config `leds.pins`, BCM numbers):
//! [`super::line_values`] says which is high. All eight lines are requested together as
//! outputs, low, and every pattern is written with one `set_values` call, so an LED goes
//! from green to red without passing through both-high.
//!
//! The line I/O is behind two small traits, [`GpioChip`] and [`OutputLines`]: [`CdevChip`] is
//! the kernel's character device, and a test can put a fake chip that records line values in
//! its place (no GPIO simulator exists on a build machine). Opening the lines names what went
//! wrong ([`GpioFault`]: no chip, no permission, a line that does not exist or is busy), so
//! the runtime can log one clear line and fall back to the console.
//!
//! [`GpioLeds::lamp_test`] lights every LED green, then red, then switches them off, so a dead
//! LED or a swapped lead shows at start. Dropping the bank switches every LED off before the
//! lines are released, so a stopped controller shows nothing rather than a stale role.

use super::{LedBank, LedError, LedPattern, LED_COUNT};
use gpiocdev::line::{Value, Values};
use std::io::ErrorKind;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The consumer name the kernel shows for the requested lines (`gpioinfo`).
pub const CONSUMER: &str = "rl";

/// How long each colour of the lamp test is shown at start.
pub const LAMP_TEST_STEP: Duration = Duration::from_millis(400);

/// Why the LED lines could not be opened or driven.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum GpioFault {
    /// The configured chip's device file does not exist.
    #[error("no such device (is this a Raspberry Pi? `ls /dev/gpiochip*` lists the chips)")]
    ChipMissing,
    /// The user may not open the chip read-write.
    #[error("permission denied (the user needs read-write access to the chip: group `gpio`)")]
    PermissionDenied,
    /// The device opens but is not a GPIO chip; the text is the kernel's reason.
    #[error("not a GPIO character device ({0})")]
    NotGpioChip(String),
    /// A configured pin is beyond the chip's lines.
    #[error("line {line} does not exist (the chip has lines 0..{line_count})")]
    NoSuchLine {
        /// The pin asked for (BCM number, the chip's line offset).
        line: u32,
        /// How many lines the chip has.
        line_count: u32,
    },
    /// A configured pin is already requested by another consumer.
    #[error("line {line} is busy (used by \"{consumer}\")")]
    LineBusy {
        /// The pin asked for (BCM number, the chip's line offset).
        line: u32,
        /// Who holds it, as the kernel names it (`the kernel` when it gives no name).
        consumer: String,
    },
    /// Any other failure, as `gpiocdev` or the OS describes it.
    #[error("{0}")]
    Other(String),
}

/// A GPIO chip that can hand out output lines.
pub trait GpioChip {
    /// The lines it hands out, released when dropped.
    type Lines: OutputLines;
    /// Requests `offsets` as outputs, all low.
    fn request_outputs(&self, offsets: &[u32]) -> Result<Self::Lines, GpioFault>;
}

/// Requested output lines; dropping them releases them.
pub trait OutputLines: Send {
    /// Sets every listed line at once: `(offset, high)`.
    fn set_values(&mut self, values: &[(u32, bool)]) -> Result<(), GpioFault>;
}

/// The kernel's GPIO character device (uAPI v2, Linux 5.10 and later).
#[derive(Clone, Debug)]
pub struct CdevChip {
    path: PathBuf,
}

impl CdevChip {
    /// The chip at a device path such as `/dev/gpiochip0`; nothing is opened yet.
    pub fn new(path: impl Into<PathBuf>) -> CdevChip {
        CdevChip { path: path.into() }
    }

    /// Finds out why the lines cannot be had, in the order an operator would check: the
    /// device, its permissions, that it is a GPIO chip, each line's existence and owner.
    fn diagnose(&self, offsets: &[u32]) -> Result<(), GpioFault> {
        std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .open(&self.path)
            .map_err(|error| match error.kind() {
                ErrorKind::NotFound => GpioFault::ChipMissing,
                ErrorKind::PermissionDenied => GpioFault::PermissionDenied,
                _ => GpioFault::Other(error.to_string()),
            })?;
        let chip = gpiocdev::Chip::from_path(&self.path).map_err(|error| match error {
            gpiocdev::Error::GpioChip(_, kind) => GpioFault::NotGpioChip(kind.to_string()),
            other => GpioFault::Other(other.to_string()),
        })?;
        let line_count = chip
            .info()
            .map_err(|error| GpioFault::NotGpioChip(error.to_string()))?
            .num_lines;
        for &line in offsets {
            if line >= line_count {
                return Err(GpioFault::NoSuchLine { line, line_count });
            }
            let info = chip
                .line_info(line)
                .map_err(|error| GpioFault::Other(format!("line {line}: {error}")))?;
            if info.used {
                let consumer = if info.consumer.is_empty() {
                    "the kernel".to_string()
                } else {
                    info.consumer
                };
                return Err(GpioFault::LineBusy { line, consumer });
            }
        }
        Ok(())
    }
}

impl GpioChip for CdevChip {
    type Lines = CdevLines;

    fn request_outputs(&self, offsets: &[u32]) -> Result<CdevLines, GpioFault> {
        self.diagnose(offsets)?;
        let request = gpiocdev::Request::builder()
            .on_chip(&self.path)
            .with_consumer(CONSUMER)
            .with_lines(offsets)
            .as_output(Value::Inactive)
            .request()
            .map_err(|error| GpioFault::Other(error.to_string()))?;
        Ok(CdevLines { request })
    }
}

/// Lines requested from a [`CdevChip`]; the kernel releases them when this is dropped.
pub struct CdevLines {
    request: gpiocdev::Request,
}

impl OutputLines for CdevLines {
    fn set_values(&mut self, values: &[(u32, bool)]) -> Result<(), GpioFault> {
        let mut line_values = Values::default();
        for &(line, high) in values {
            line_values.set(line, Value::from(high));
        }
        self.request
            .set_values(&line_values)
            .map_err(|error| GpioFault::Other(error.to_string()))
    }
}

/// The four LEDs on eight GPIO lines.
pub struct GpioLeds<L: OutputLines> {
    lines: L,
    chip: String,
    pins: [[u32; 2]; LED_COUNT],
    shown: Option<LedPattern>,
    lamp_test_step: Duration,
}

impl<L: OutputLines> GpioLeds<L> {
    /// Requests the eight lines of `pins` (`[green_pin, red_pin]` per LED) on `chip` as
    /// outputs, every LED off. `chip_name` is what error messages call the chip.
    pub fn open<C: GpioChip<Lines = L>>(
        chip: &C,
        chip_name: &str,
        pins: [[u32; 2]; LED_COUNT],
    ) -> Result<GpioLeds<L>, LedError> {
        let offsets: Vec<u32> = pins.iter().flatten().copied().collect();
        let lines = chip
            .request_outputs(&offsets)
            .map_err(|fault| LedError::Gpio {
                chip: chip_name.to_string(),
                message: format!("cannot request lines {}: {fault}", describe_pins(&pins)),
            })?;
        let mut bank = GpioLeds {
            lines,
            chip: chip_name.to_string(),
            pins,
            shown: None,
            lamp_test_step: LAMP_TEST_STEP,
        };
        bank.drive(LedPattern::ALL_OFF)?;
        Ok(bank)
    }

    /// How long each lamp-test colour stays on (tests use zero).
    pub fn with_lamp_test_step(mut self, step: Duration) -> GpioLeds<L> {
        self.lamp_test_step = step;
        self
    }

    /// The pattern last written, if any.
    pub fn shown(&self) -> Option<LedPattern> {
        self.shown
    }

    /// Writes all eight lines for `pattern` in one call.
    fn drive(&mut self, pattern: LedPattern) -> Result<(), LedError> {
        let values: Vec<(u32, bool)> = self
            .pins
            .iter()
            .zip(pattern.line_values())
            .flat_map(|(pins, levels)| pins.iter().copied().zip(levels))
            .collect();
        match self.lines.set_values(&values) {
            Ok(()) => {
                self.shown = Some(pattern);
                Ok(())
            }
            Err(fault) => {
                // Unknown after a failed write: the next pattern is written in full.
                self.shown = None;
                Err(LedError::Gpio {
                    chip: self.chip.clone(),
                    message: format!("cannot set lines {}: {fault}", describe_pins(&self.pins)),
                })
            }
        }
    }
}

impl<L: OutputLines> LedBank for GpioLeds<L> {
    fn show(&mut self, pattern: LedPattern) -> Result<(), LedError> {
        if self.shown == Some(pattern) {
            return Ok(());
        }
        self.drive(pattern)
    }

    fn lamp_test(&mut self) -> Result<(), LedError> {
        for pattern in [LedPattern::ALL_GREEN, LedPattern::ALL_RED] {
            self.drive(pattern)?;
            std::thread::sleep(self.lamp_test_step);
        }
        self.drive(LedPattern::ALL_OFF)
    }
}

impl<L: OutputLines> Drop for GpioLeds<L> {
    fn drop(&mut self) {
        // A stopped controller must not go on showing a role; the lines are released after.
        if let Err(error) = self.drive(LedPattern::ALL_OFF) {
            tracing::warn!("LEDs not switched off: {error}");
        }
    }
}

/// `20,21 7,8 24,23 15,14`: the pins of each LED, green first.
pub fn describe_pins(pins: &[[u32; 2]; LED_COUNT]) -> String {
    pins.iter()
        .map(|[green, red]| format!("{green},{red}"))
        .collect::<Vec<_>>()
        .join(" ")
}

/// Opens the configured LEDs on the kernel's chip and runs the lamp test.
pub fn start(leds: &crate::config::Leds) -> Result<GpioLeds<CdevLines>, LedError> {
    let chip = CdevChip::new(Path::new(&leds.chip));
    let mut bank = GpioLeds::open(&chip, &leds.chip, leds.pins)?;
    bank.lamp_test()?;
    Ok(bank)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_chip_is_named_with_its_lines() {
        let chip = CdevChip::new("/nonexistent/gpiochip7");
        let error = GpioLeds::open(
            &chip,
            "/nonexistent/gpiochip7",
            [[20, 21], [7, 8], [24, 23], [15, 14]],
        )
        .err()
        .expect("no chip there");
        assert_eq!(
            error.to_string(),
            "GPIO /nonexistent/gpiochip7: cannot request lines 20,21 7,8 24,23 15,14: no such \
             device (is this a Raspberry Pi? `ls /dev/gpiochip*` lists the chips)"
        );
    }

    #[test]
    fn a_device_that_is_no_gpio_chip_is_refused() {
        let chip = CdevChip::new("/dev/null");
        let fault = chip.request_outputs(&[20, 21]).err().expect("not a chip");
        assert_eq!(
            fault,
            GpioFault::NotGpioChip("is not a GPIO character device".into())
        );
        let file = CdevChip::new("/proc/self/status");
        assert!(matches!(
            file.request_outputs(&[20]),
            Err(GpioFault::NotGpioChip(_)) | Err(GpioFault::PermissionDenied)
        ));
    }

    #[test]
    fn faults_say_what_to_check() {
        assert_eq!(
            GpioFault::LineBusy {
                line: 14,
                consumer: "serial0".into()
            }
            .to_string(),
            "line 14 is busy (used by \"serial0\")"
        );
        assert_eq!(
            GpioFault::NoSuchLine {
                line: 60,
                line_count: 54
            }
            .to_string(),
            "line 60 does not exist (the chip has lines 0..54)"
        );
        assert!(GpioFault::PermissionDenied
            .to_string()
            .contains("group `gpio`"));
    }
}
