//! # The test kit: real processes and fixtures for RL's tests
//!
//! What the process-level tests of the `rl` command and the library share, in one dev-only
//! crate (it is never a dependency of a shipped crate):
//! - [`rl()`]: the `rl` binary under test;
//! - [`Cluster`]: controllers and a servo as child processes on one DDS domain (the tools'
//!   `rl::procs::Fleet`, whose line reader the demo, the bench and the fault lab use too),
//!   their events collected, bounded waits that report what was seen; [`test_config`];
//! - [`actuators`]: the judges at the actuator (the servo's owner changes, an RTI Connext
//!   reader), counted per controller;
//! - [`keys`]: keystores made by `rl keys`, and the ways a test spoils one;
//! - [`tempdir`]: a test's temporary directory.

pub mod actuators;
mod cluster;
pub mod keys;
pub mod tempdir;

pub use cluster::{test_config, without_terminal_colours, Cluster};

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// The `rl` binary the tests run: nextest's `NEXTEST_BIN_EXE_rl`, or the one beside the test
/// executable (`target/<profile>/rl` for `target/<profile>/deps/<test>`), as cargo builds it
/// for the `rl` package's tests. Panics, saying how to build it, when there is none.
pub fn rl() -> &'static Path {
    static FOUND: OnceLock<PathBuf> = OnceLock::new();
    FOUND.get_or_init(|| {
        if let Some(path) = std::env::var_os("NEXTEST_BIN_EXE_rl") {
            return PathBuf::from(path);
        }
        let exe = std::env::current_exe().unwrap_or_else(|e| panic!("the test's path: {e}"));
        let dir = exe.parent().unwrap_or(Path::new("."));
        let dir = match dir.file_name() {
            Some(name) if name == "deps" => dir.parent().unwrap_or(dir),
            _ => dir,
        };
        let rl = dir.join("rl");
        assert!(
            rl.is_file(),
            "no rl binary at {}: build it (cargo build --release -p rl) or run the tests of \
             the rl package",
            rl.display()
        );
        rl
    })
}
