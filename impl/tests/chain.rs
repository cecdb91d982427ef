//! The paper's chain as `rl demo --chain` runs it (DDS domain 227): three navigation
//! controllers (`rl chain nav`, group `nav`) aim from the camera's ball, three actuator
//! controllers (`rl chain act`, the domain's unnamed group) command the servo from the
//! navigation Primary's aims. The demo kills the navigation Primary, then the actuator
//! Primary, restarting each. Judged from the recordings it keeps:
//! - the navigation kill moves every actuator controller's aims to the navigation
//!   Secondary, once, and the servo's owner not at all;
//! - the actuator kill moves the servo to the actuator Secondary, once;
//! - the camera on the gimbal keeps the ball near the centre (the aims reach the servo).

mod support;

use rl::chain::ChainLine;
use rl::procs::{parse_servo_event, ServoEvent};
use rl::sim::shapes::CameraFrame;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use support::rl;
const DOMAIN: &str = "227";

fn lines(dir: &Path, name: &str) -> Vec<String> {
    let path = dir.join(format!("{name}.log"));
    std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .lines()
        .map(str::to_string)
        .collect()
}

/// Runs the demo to its end (two kills) and returns its timeline.
fn run_demo(dir: &Path) -> String {
    let mut child = Command::new(rl())
        .args(["demo", "--chain", "--cycles", "2", "--kill-every-s", "3"])
        .args(["--down-s", "2", "--status-page", "off", "--domain", DOMAIN])
        .arg("--record")
        .arg(dir)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("rl demo --chain starts");
    let until = Instant::now() + Duration::from_secs(90);
    loop {
        if let Some(status) = child.try_wait().expect("waitable") {
            let output = child.wait_with_output().expect("its output");
            let timeline = String::from_utf8_lossy(&output.stdout).to_string();
            assert!(status.success(), "rl demo --chain: {status}\n{timeline}");
            return timeline;
        }
        if Instant::now() > until {
            let _ = child.kill();
            let output = child.wait_with_output().expect("its output");
            panic!(
                "rl demo --chain did not end within 90 s:\n{}",
                String::from_utf8_lossy(&output.stdout)
            );
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// The (from, to) controller of every aim owner change an actuator controller reported.
fn aim_owner_changes(dir: &Path, act: u8) -> Vec<(Option<u8>, Option<u8>)> {
    lines(dir, &format!("act-C{act}"))
        .iter()
        .filter_map(|line| ChainLine::parse(line))
        .map(|ChainLine::AimOwner { from, to, .. }| (from, to))
        .collect()
}

#[test]
fn the_chain_follows_each_groups_primary_and_keeps_the_ball_centred() {
    let dir = support::tempdir::Dir::new("chain");
    let timeline = run_demo(&dir.0);
    println!("{timeline}");
    let kills: Vec<&str> = timeline.lines().filter(|l| l.contains("kill -9")).collect();
    assert_eq!(kills.len(), 2, "two kills: {kills:?}");
    assert!(kills[0].contains("kill -9 nav C1"), "{kills:?}");
    assert!(kills[1].contains("kill -9 act C1"), "{kills:?}");

    // C2 and C3 of the actuator group live throughout: their aims came from the navigation
    // C1, then, once, from its Secondary C2.
    for act in [2, 3] {
        assert_eq!(
            aim_owner_changes(&dir.0, act),
            [(None, Some(1)), (Some(1), Some(2))],
            "act C{act}: whose aims it applied"
        );
    }

    // The servo: act C1 first, then once act C2 (a change of writer within one controller,
    // at its promotion to strength 30, is not a change of controller).
    let owners: Vec<Option<u8>> = lines(&dir.0, "servo")
        .iter()
        .filter_map(|line| match parse_servo_event(line) {
            Some(ServoEvent::OwnerChanged {
                from_controller_id,
                to_controller_id,
                ..
            }) if from_controller_id != to_controller_id => Some(to_controller_id),
            _ => None,
        })
        .collect();
    assert_eq!(owners, [Some(1), Some(2)], "the servo's owners");

    // Tracking: once formed (2 s in), the ball stays near the centre through both kills.
    let errors: Vec<f64> = lines(&dir.0, "camera")
        .iter()
        .filter_map(|line| serde_json::from_str::<CameraFrame>(line).ok())
        .filter(|frame| frame.t_ms >= 2000)
        .filter_map(|frame| frame.error_px)
        .collect();
    assert!(errors.len() > 100, "{} frames with the ball", errors.len());
    let mut sorted = errors.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];
    println!(
        "tracking error from 2 s: median {median:.1} px, worst {:.1} px, {} frames",
        sorted[sorted.len() - 1],
        sorted.len()
    );
    assert!(
        median < 25.0,
        "the ball is tracked: median {median:.1} px off centre"
    );
}
