//! The `rl` binary the replay runs: built with the `fault-injection` feature (the heartbeat
//! drop control on stdin, each drop logged) and the `mutation` feature (the deliberately
//! broken rules, inert unless `RL_MUTATION` names one), into a target directory of its own.

use super::error::BuildError;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::Instant;

/// The features the replay's `rl` is built with.
pub const FEATURES: &str = "fault-injection,mutation";

/// Builds `rl` with [`FEATURES`] into `<workspace>/target/fault-injection` (a target
/// directory of its own, so the workspace's `target/release/rl` is not rebuilt back and
/// forth), once per process; returns the binary.
pub fn fault_injection_rl() -> Result<PathBuf, BuildError> {
    static BUILT: OnceLock<Result<PathBuf, BuildError>> = OnceLock::new();
    BUILT.get_or_init(build).clone()
}

fn build() -> Result<PathBuf, BuildError> {
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
    let workspace = manifest.parent().unwrap_or(manifest);
    let target_dir = workspace.join("target").join("fault-injection");
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_string());
    let command = format!(
        "cargo build --release -p rl --features {FEATURES} --target-dir {}",
        target_dir.display()
    );
    println!("{command} (once; the first build takes a few minutes)");
    let started = Instant::now();
    let output = std::process::Command::new(&cargo)
        .current_dir(workspace)
        .args(["build", "--release", "-p", "rl", "--features", FEATURES])
        .arg("--target-dir")
        .arg(&target_dir)
        .output()
        .map_err(|e| BuildError::Cargo {
            cargo: cargo.clone(),
            message: e.to_string(),
        })?;
    if !output.status.success() {
        let stderr = String::from_utf8_lossy(&output.stderr);
        let tail: Vec<&str> = stderr.lines().rev().take(30).collect();
        return Err(BuildError::Failed {
            command,
            status: output.status.to_string(),
            tail: tail.into_iter().rev().collect::<Vec<_>>().join("\n"),
        });
    }
    let exe = target_dir.join("release").join("rl");
    if !exe.is_file() {
        return Err(BuildError::Missing { path: exe });
    }
    println!(
        "built {} in {:.1} s",
        exe.display(),
        started.elapsed().as_secs_f64()
    );
    Ok(exe)
}
