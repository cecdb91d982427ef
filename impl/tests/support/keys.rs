//! Keystores for the secured tests, made by `rl keys` (the native binary) as an operator would.

use super::RL;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Runs `rl keys <args>`, which must succeed.
pub fn keys(args: &[&str]) {
    let output = Command::new(RL).arg("keys").args(args).output().unwrap();
    assert!(
        output.status.success(),
        "rl keys {args:?}: {}",
        String::from_utf8_lossy(&output.stderr)
    );
}

/// A CA in `dir/keys` and keystores for controllers 1-3 and the applications `servo` and
/// `status`; returns `dir/keys`.
pub fn keystores(dir: &Path) -> PathBuf {
    let keys_dir = dir.join("keys");
    let text = keys_dir.to_str().unwrap();
    keys(&["init", "--dir", text]);
    for id in ["1", "2", "3"] {
        keys(&["add", "--dir", text, "--id", id]);
    }
    keys(&["add", "--dir", text, "--app", "servo"]);
    keys(&["add", "--dir", text, "--app", "status"]);
    keys_dir
}
