//! The two topics shared with the original camera application, matching its IDL exactly:
//! [`ShapeTypeExtended`] on `Circle` (what the camera sees) and [`ServoControl`] on
//! `pixy/servo_control` (what the gimbal is told). Neither is validated beyond CDR: the
//! tracker filters shapes by colour and the camera clamps servo values.

use super::{WireError, WireSample};
use rustdds::Keyed;
use serde::{Deserialize, Serialize};

/// DDS type name of the camera's `Circle` topic.
pub const SHAPE_TYPE_NAME: &str = "ShapeTypeExtended";
/// DDS type name of the command topic.
pub const SERVO_CONTROL_TYPE_NAME: &str = "ServoControl";

/// `enum ShapeFillKind` of the shapes demo; CDR encodes it as a u32 (declaration order).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum ShapeFillKind {
    /// Filled solid (code 0; what `rl shapes` publishes).
    #[default]
    SolidFill,
    /// Outline only (code 1).
    TransparentFill,
    /// Hatched with horizontal lines (code 2).
    HorizontalHatchFill,
    /// Hatched with vertical lines (code 3).
    VerticalHatchFill,
}

/// A shape seen by the camera (`ShapeTypeExtended`, keyed by colour).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShapeTypeExtended {
    /// The shape's colour in capitals, e.g. `YELLOW` (the key; at most 128 bytes in the IDL).
    pub color: String,
    /// Horizontal position in the camera frame, in pixels (the shapes demo's 0..=222).
    pub x: i32,
    /// Vertical position in the camera frame, in pixels (the shapes demo's 0..=252).
    pub y: i32,
    /// The shape's size (a circle's diameter), in pixels.
    pub shapesize: i32,
    /// How the shape is filled (`fillKind` in the IDL).
    pub fill_kind: ShapeFillKind,
    /// The shape's rotation in degrees (the tracker ignores it).
    pub angle: f32,
}

impl Keyed for ShapeTypeExtended {
    type K = String;
    fn key(&self) -> String {
        self.color.clone()
    }
}

impl WireSample for ShapeTypeExtended {
    type Value = ShapeTypeExtended;
    const TYPE_NAME: &'static str = SHAPE_TYPE_NAME;
    /// Any shape is acceptable input; the tracker filters by colour.
    fn decode(self) -> Result<ShapeTypeExtended, WireError> {
        Ok(self)
    }
    fn encode(value: &ShapeTypeExtended) -> ShapeTypeExtended {
        value.clone()
    }
}

/// A gimbal command (`ServoControl`, unkeyed): servo positions 0..1000 and the servo frequency.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct ServoControl {
    /// Pan servo position, 0..1000 (the camera clamps).
    pub pan: u16,
    /// Tilt servo position, 0..1000 (the camera clamps).
    pub tilt: u16,
    /// Servo frequency in Hz (the tracker writes `tracker.servo_frequency_hz`, 1..=1000).
    pub frequency: u16,
}

impl WireSample for ServoControl {
    type Value = ServoControl;
    const TYPE_NAME: &'static str = SERVO_CONTROL_TYPE_NAME;
    /// The camera accepts any value (it clamps), so neither does RL reject one.
    fn decode(self) -> Result<ServoControl, WireError> {
        Ok(self)
    }
    fn encode(value: &ServoControl) -> ServoControl {
        *value
    }
}
