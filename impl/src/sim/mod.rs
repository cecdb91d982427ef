//! Simulators.
pub mod command_feed;
pub mod command_trust;
pub mod gimbal;
pub mod servo;
pub mod shapes;
