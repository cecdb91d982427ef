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
    #[default]
    SolidFill,
    TransparentFill,
    HorizontalHatchFill,
    VerticalHatchFill,
}

/// A shape seen by the camera (`ShapeTypeExtended`, keyed by colour).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShapeTypeExtended {
    pub color: String,
    pub x: i32,
    pub y: i32,
    pub shapesize: i32,
    pub fill_kind: ShapeFillKind,
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
    pub pan: u16,
    pub tilt: u16,
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
