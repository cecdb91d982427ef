//! Simulators.
pub mod gimbal;
pub mod servo;
pub mod shapes;
