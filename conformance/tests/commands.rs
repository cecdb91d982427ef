//! The conformance suite's two commands read their arguments with clap: a bad one exits 2
//! naming it, and `--help` teaches (what each does, an example); `dds-replay-all --refusals`
//! accounts for every trace it refuses.

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

#[test]
fn dds_replay_all_counts_the_traces_it_refuses_by_reason() {
    let exe = env!("CARGO_BIN_EXE_dds-replay-all");
    let (code, stdout, stderr) = run(exe, &["--refusals"]);
    assert_eq!(code, Some(0), "{stderr}");
    let total = stdout
        .lines()
        .find_map(|l| l.split_once(" traces replayable over DDS, "))
        .and_then(|(_, rest)| rest.split_once(' '))
        .and_then(|(refused, _)| refused.parse::<usize>().ok())
        .unwrap_or_else(|| panic!("no count of refusals in {stdout}"));
    let by_reason: usize = stdout
        .lines()
        .filter_map(|l| l.trim().strip_prefix("refused, "))
        .filter_map(|l| l.rsplit_once(": ")?.1.parse::<usize>().ok())
        .sum();
    let each = stdout.lines().filter(|l| l.contains(" refused: ")).count();
    assert!(total > 0, "{stdout}");
    assert_eq!((by_reason, each), (total, total), "{stdout}");
    // One trace of the paper's variant: refused for that reason alone.
    let traces = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../traces");
    let paper = std::fs::read_dir(traces)
        .expect("traces/ is readable")
        .filter_map(|entry| entry.ok()?.file_name().into_string().ok())
        .find(|name| name.contains("-paper-") && name.ends_with(".jsonl"))
        .expect("traces/ has a trace of the paper's variant");
    let (code, stdout, _) = run(exe, &["--refusals", &paper]);
    assert_eq!(code, Some(0));
    assert!(
        stdout.contains("0 traces replayable over DDS, 1 not replayable"),
        "{stdout}"
    );
    assert!(
        stdout.contains("refused, not a default-variant trace: 1"),
        "{stdout}"
    );
}
