//! Simulators.
pub mod command_trust;
pub mod servo;
pub mod shapes;
