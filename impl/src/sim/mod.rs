//! Simulators.
pub mod servo;
pub mod shapes;
