//! Every command that takes `--domain` refuses a bad one at once, with exit status 2 and a
//! message naming it: the same rule everywhere (`rl_layer::config::DOMAIN_MAX`, and room for
//! the network monitor's two domains where it runs).

mod support;

use std::process::Command;
use std::time::{Duration, Instant};

/// `rl <args>`: its exit code and stderr, and how long it took.
fn run(args: &[&str]) -> (Option<i32>, String, Duration) {
    let started = Instant::now();
    let output = Command::new(support::rl())
        .args(args)
        .output()
        .expect("rl runs");
    (
        output.status.code(),
        String::from_utf8_lossy(&output.stderr).into_owned(),
        started.elapsed(),
    )
}

#[test]
fn every_command_refuses_a_domain_past_232_at_once() {
    let commands: [&[&str]; 6] = [
        &["controller", "--id", "1", "--domain", "233"],
        &["shapes", "--domain", "233"],
        &["servo", "--domain", "233"],
        &["status", "--once", "--domain", "233"],
        &["demo", "--domain", "233", "--status-page", "off"],
        &["bench", "--domain", "233"],
    ];
    for args in commands {
        let (code, stderr, took) = run(args);
        assert_eq!(code, Some(2), "rl {}: {stderr}", args.join(" "));
        assert!(
            stderr.contains("--domain 233") && stderr.contains("at most 232"),
            "rl {}: {stderr}",
            args.join(" ")
        );
        assert!(
            took < Duration::from_secs(5),
            "rl {} took {took:?} to refuse",
            args.join(" ")
        );
    }
}

/// The bench starts network monitors, which use the two domains after RL's.
#[test]
fn the_bench_refuses_a_domain_without_room_for_the_network_monitor() {
    let (code, stderr, _) = run(&["bench", "--domain", "231"]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.contains("--domain 231"), "{stderr}");
    assert!(stderr.contains("network monitor"), "{stderr}");
}
