//! The `[leds]` section: which LED bank shows the status, and the GPIO chip and pins of the
//! four two-lead LEDs.

use super::error::{check, quoted, InvalidValue};
use serde::{Deserialize, Serialize};

/// Which LED bank shows the status.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LedBackend {
    /// One console line whenever the LEDs change.
    Console,
    /// Eight GPIO lines (Raspberry Pi).
    Gpio,
}

/// Status LEDs: four two-lead red/green LEDs, each across two BCM GPIO pins.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Leds {
    /// Where the LEDs are shown: a console line (the default) or GPIO lines.
    pub backend: LedBackend,
    /// GPIO character device.
    pub chip: String,
    /// `[green_pin, red_pin]` per LED: LED1 Primary, LED2 Secondary, LED3 Tertiary, LED4 own
    /// status. Driving the first pin high and the second low lights green.
    pub pins: [[u32; 2]; 4],
}

impl Default for Leds {
    fn default() -> Leds {
        Leds {
            backend: LedBackend::Console,
            chip: "/dev/gpiochip0".into(),
            pins: [[20, 21], [7, 8], [24, 23], [15, 14]],
        }
    }
}

impl Leds {
    /// Checks that the chip is named and that all eight pins are distinct.
    pub fn validate(&self) -> Result<(), InvalidValue> {
        check(
            !self.chip.is_empty(),
            "leds.chip",
            quoted(&self.chip),
            || "must name a GPIO character device, like \"/dev/gpiochip0\"".to_string(),
        )?;
        // One line driven by two LEDs would light neither correctly.
        let pins: Vec<(usize, u32)> = self
            .pins
            .iter()
            .enumerate()
            .flat_map(|(led, pair)| pair.iter().map(move |pin| (led, *pin)))
            .collect();
        for (index, (led, pin)) in pins.iter().enumerate() {
            if let Some((other_led, _)) = pins[..index].iter().find(|(_, other)| other == pin) {
                let place = if other_led == led {
                    format!("twice by LED{}", led + 1)
                } else {
                    format!("by LED{} and LED{}", other_led + 1, led + 1)
                };
                return Err(InvalidValue::new(
                    "leds.pins",
                    format!("{:?}", self.pins),
                    format!("pins must be distinct, but pin {pin} is used {place}"),
                ));
            }
        }
        Ok(())
    }
}
