//! Keystores for the secured tests, made by `rl keys` (the native binary) as an operator would,
//! and the ways the tests spoil one.

use std::path::{Path, PathBuf};
use std::process::Command;

/// Runs `rl keys <args>`, which must succeed.
pub fn keys(args: &[&str]) {
    let output = Command::new(crate::rl())
        .arg("keys")
        .args(args)
        .output()
        .unwrap();
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

/// Alters the signed governance document `keystore/governance.p7s` after signing (join access
/// control turned off): its signature no longer matches, which RL and OpenSSL must both see.
pub fn alter_governance(keystore: &Path) -> PathBuf {
    let path = keystore.join("governance.p7s");
    let text = std::fs::read_to_string(&path).unwrap();
    let altered = text.replace(
        "<enable_join_access_control>true",
        "<enable_join_access_control>false",
    );
    assert_ne!(altered, text, "{}: nothing to alter", path.display());
    std::fs::write(&path, altered).unwrap();
    path
}
