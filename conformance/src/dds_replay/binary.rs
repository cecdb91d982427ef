//! The `rl` binary the replay runs: the workspace build's own, beside the program or test that
//! replays (`target/<profile>/rl`). It must have the `fault-injection` feature (the heartbeat
//! drop control on stdin, each drop logged) and the `mutation` feature (the deliberately
//! broken rules, inert unless `RL_MUTATION` names one). The workspace's test command builds
//! it so (`--all-features`): one build of `rl` serves every test, the lab and the replay,
//! where the replay used to build a second one of its own.

use super::error::BinaryError;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

/// The features the replay needs in its `rl`.
pub const FEATURES: [&str; 2] = ["fault-injection", "mutation"];

/// What builds an `rl` the replay can run, for the error that says it is missing.
pub const BUILD_COMMAND: &str =
    "cargo build --release -p rl --features fault-injection,mutation (or the workspace's test command, with --all-features)";

/// The `rl` beside this program (found and checked once per process).
pub fn fault_injection_rl() -> Result<PathBuf, BinaryError> {
    static FOUND: OnceLock<Result<PathBuf, BinaryError>> = OnceLock::new();
    FOUND.get_or_init(find).clone()
}

fn find() -> Result<PathBuf, BinaryError> {
    let exe = std::env::current_exe().map_err(|e| BinaryError::NoExe(e.to_string()))?;
    let rl = beside(&exe);
    if !rl.is_file() {
        return Err(BinaryError::Missing { path: rl });
    }
    let output =
        Command::new(&rl)
            .arg("--version")
            .output()
            .map_err(|e| BinaryError::Unrunnable {
                path: rl.clone(),
                message: e.to_string(),
            })?;
    let version = String::from_utf8_lossy(&output.stdout).trim().to_string();
    let built_with = features_of(&version);
    let missing: Vec<&str> = FEATURES
        .into_iter()
        .filter(|feature| !built_with.contains(feature))
        .collect();
    if !output.status.success() || !missing.is_empty() {
        return Err(BinaryError::Features {
            path: rl,
            version,
            missing: missing.join(", "),
        });
    }
    Ok(rl)
}

/// `target/release/rl` for `target/release/deps/dds_replay-…` (a test) and for
/// `target/release/dds-replay-all` (a program) alike.
fn beside(exe: &Path) -> PathBuf {
    let dir = exe.parent().unwrap_or(Path::new("."));
    let dir = match dir.file_name() {
        Some(name) if name == "deps" => dir.parent().unwrap_or(dir),
        _ => dir,
    };
    dir.join("rl")
}

/// The features `rl --version` names: `rl 0.1.0 (features: fault-injection, mutation)`.
fn features_of(version: &str) -> Vec<&str> {
    version
        .split_once("(features: ")
        .and_then(|(_, rest)| rest.split_once(')'))
        .map(|(list, _)| list.split(", ").map(str::trim).collect())
        .unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_test_and_a_program_find_the_same_rl() {
        let test = beside(Path::new("/w/target/release/deps/dds_replay-0123abcd"));
        let program = beside(Path::new("/w/target/release/dds-replay-all"));
        assert_eq!(test, PathBuf::from("/w/target/release/rl"));
        assert_eq!(program, test);
    }

    #[test]
    fn features_are_read_from_the_version_line() {
        assert_eq!(
            features_of("rl 0.1.0 (features: fault-injection, mutation, security)"),
            vec!["fault-injection", "mutation", "security"]
        );
        assert_eq!(features_of("rl 0.1.0 (features: none)"), vec!["none"]);
        // An older rl's plain version names no feature: it is refused.
        assert!(features_of("rl 0.1.0").is_empty());
    }
}
