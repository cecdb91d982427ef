//! The host the lab runs on: root, the tools it needs (`ip`, `nft`, `tc`, libfaketime,
//! python3 with the Connext connector), and running system commands with their output
//! checked. Every fault and the LAN itself are built from these commands.

use super::error::LabError;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// libfaketime as Debian's `faketime` package installs it (glibc builds only).
pub const LIBFAKETIME: &str = "/usr/lib/x86_64-linux-gnu/faketime/libfaketime.so.1";

/// The PyPI package the Connext reader needs (as `.ci/run` installs it).
pub const CONNEXT_PACKAGE: &str = "rticonnextdds-connector==1.2.4";

/// Fails unless the lab runs as root.
pub fn require_root() -> Result<(), LabError> {
    // SAFETY: geteuid has no preconditions and no memory effects.
    if unsafe { libc::geteuid() } == 0 {
        Ok(())
    } else {
        Err(LabError::NotRoot)
    }
}

/// A program on PATH, if there is one.
pub fn on_path(program: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|dir| dir.join(program))
        .find(|candidate| candidate.is_file())
}

/// Fails naming the first tool of the lab's that is missing.
pub fn require_tools() -> Result<(), LabError> {
    let tools: [(&str, &'static str, &'static str); 3] = [
        ("ip", "iproute2", "for namespaces, veth pairs and bridges"),
        ("tc", "iproute2", "for the rate-limited link (tbf)"),
        ("nft", "nftables", "for loss, partitions and cuts"),
    ];
    for (tool, package, why) in tools {
        if on_path(tool).is_none() {
            return Err(LabError::MissingTool {
                tool: tool.into(),
                package,
                why,
            });
        }
    }
    if !Path::new(LIBFAKETIME).is_file() {
        return Err(LabError::MissingTool {
            tool: LIBFAKETIME.into(),
            package: "faketime",
            why: "for the clock-offset faults",
        });
    }
    Ok(())
}

/// Whether python3 can import the Connext connector (the second actuator judge).
pub fn connext_available() -> bool {
    Command::new("python3")
        .args(["-c", "import rticonnextdds_connector"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// Runs `program args`, failing with its stderr when it exits non-zero.
pub fn run(program: &str, args: &[&str]) -> Result<(), LabError> {
    run_with_input(program, args, None)
}

/// Runs `program args` with `input` on its stdin (e.g. an nft script).
pub fn run_with_input(program: &str, args: &[&str], input: Option<&str>) -> Result<(), LabError> {
    let mut child = Command::new(program)
        .args(args)
        .stdin(if input.is_some() {
            Stdio::piped()
        } else {
            Stdio::null()
        })
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| LabError::command(program, args, e.to_string()))?;
    if let (Some(text), Some(mut stdin)) = (input, child.stdin.take()) {
        stdin
            .write_all(text.as_bytes())
            .map_err(|e| LabError::command(program, args, e.to_string()))?;
    }
    let output = child
        .wait_with_output()
        .map_err(|e| LabError::command(program, args, e.to_string()))?;
    if output.status.success() {
        Ok(())
    } else {
        let stderr = String::from_utf8_lossy(&output.stderr).trim().to_string();
        let message = match input {
            Some(script) => format!("{stderr}\n(input:\n{script})"),
            None => stderr,
        };
        Err(LabError::command(program, args, message))
    }
}

/// Runs `program args` and returns its stdout; an empty string when it fails (for listing
/// leftovers, where a failure means there is nothing to list).
pub fn stdout_of(program: &str, args: &[&str]) -> String {
    Command::new(program)
        .args(args)
        .stdin(Stdio::null())
        .stderr(Stdio::null())
        .output()
        .map(|o| String::from_utf8_lossy(&o.stdout).into_owned())
        .unwrap_or_default()
}

/// `nft -f -` with `script` inside network namespace `ns`.
pub fn nft(ns: &str, script: &str) -> Result<(), LabError> {
    run_with_input("ip", &["netns", "exec", ns, "nft", "-f", "-"], Some(script))
}
