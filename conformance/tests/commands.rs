//! The conformance suite's two commands read their arguments with clap: a bad one exits 2
//! naming it, and `--help` teaches (what each does, an example).

use std::process::Command;

fn run(exe: &str, args: &[&str]) -> (Option<i32>, String, String) {
    let output = Command::new(exe)
        .args(args)
        .output()
        .expect("the command runs");
    (
        output.status.code(),
        String::from_utf8_lossy(&output.stdout).into_owned(),
        String::from_utf8_lossy(&output.stderr).into_owned(),
    )
}

#[test]
fn validate_run_names_a_bad_argument_and_teaches() {
    let exe = env!("CARGO_BIN_EXE_validate-run");
    let (code, _, stderr) = run(exe, &["--bogus", "dir"]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.contains("--bogus"), "{stderr}");
    let (code, _, stderr) = run(exe, &[]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.contains("<DIR>"), "{stderr}");
    let (code, stdout, _) = run(exe, &["--help"]);
    assert_eq!(code, Some(0));
    assert!(stdout.contains("Example: validate-run"), "{stdout}");
}

#[test]
fn dds_replay_all_names_a_bad_argument_and_teaches() {
    let exe = env!("CARGO_BIN_EXE_dds-replay-all");
    let (code, _, stderr) = run(exe, &["--bogus"]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.contains("--bogus"), "{stderr}");
    let (code, _, stderr) = run(exe, &["--mutation"]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.contains("--mutation"), "{stderr}");
    let (code, stdout, _) = run(exe, &["--help"]);
    assert_eq!(code, Some(0));
    assert!(stdout.contains("Example: dds-replay-all"), "{stdout}");
}
