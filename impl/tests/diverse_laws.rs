//! Diverse implementations of the control law on DDS domain 157: C1 and C3 run the original
//! integer law, C2 the floating-point one (`tracker.law = "float"`). They form as ever, the
//! camera on the gimbal keeps the ball near the centre, and when the Primary dies C2 takes the
//! servo over, once, and the tracking goes on under its law.

mod support;

use rl::sim::shapes::CameraFrame;
use rl_layer::core::Role;
use std::time::{Duration, Instant};
use support::actuators::{owner_changes, servo_owners};
use support::Cluster;

/// The camera's tracking errors (pixels off centre) printed since `from`.
fn tracking_errors_px(cluster: &Cluster, from: Instant) -> Vec<f64> {
    let from_ms = from.duration_since(cluster.started).as_millis() as u64;
    // The camera's own clock starts a little after the cluster's: frames from a second after
    // `from` on its clock are surely after `from`.
    cluster
        .lines_from("camera")
        .filter_map(|line| serde_json::from_str::<CameraFrame>(line).ok())
        .filter(|frame| frame.t_ms >= from_ms + 1000)
        .filter_map(|frame| frame.error_px)
        .collect()
}

fn median(mut values: Vec<f64>) -> f64 {
    assert!(!values.is_empty(), "no frames with the ball");
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

#[test]
fn controllers_with_two_different_laws_form_track_and_fail_over() {
    let mut cluster = Cluster::new("diverse-laws", 157, "");
    let base = cluster
        .fleet
        .config()
        .expect("a configuration")
        .to_path_buf();
    let float = base.with_file_name("float.toml");
    let text = std::fs::read_to_string(&base).expect("the base configuration");
    std::fs::write(&float, format!("{text}\n[tracker]\nlaw = \"float\"\n")).expect("written");
    cluster.start(1);
    cluster
        .fleet
        .start_controller_configured(2, &float, &["--json-events"])
        .expect("start C2 on the float law");
    cluster.start(3);
    cluster.start_servo();
    cluster
        .fleet
        .start_other("camera", &["shapes", "--json"])
        .expect("start the camera");
    cluster.wait_for(
        "P=C1 S=C2 T=C3, the servo on C1",
        Duration::from_secs(20),
        |c| {
            c.steady_with(1, Some(Role::Primary))
                && c.steady_with(2, Some(Role::Secondary))
                && c.steady_with(3, Some(Role::Tertiary))
                && c.servo_owner() == Some(1)
        },
    );
    // The gimbal catches the ball (it starts centred, the ball anywhere on its path).
    cluster.pump(Duration::from_secs(2));
    let tracking_from = Instant::now();
    cluster.pump(Duration::from_secs(3));
    let before = median(tracking_errors_px(&cluster, tracking_from));

    let killed = Instant::now();
    cluster.fleet.kill(1).expect("kill C1");
    cluster.wait_for(
        "C2 Primary, the servo on C2",
        Duration::from_secs(10),
        |c| c.steady_with(2, Some(Role::Primary)) && c.servo_owner() == Some(2),
    );
    cluster.pump(Duration::from_secs(3));
    let after = median(tracking_errors_px(&cluster, killed));
    println!("tracking error, median: {before:.1} px under C1's integer law, {after:.1} px after C2's float law took over");
    assert!(
        before < 25.0,
        "tracked under the integer law: {before:.1} px"
    );
    assert!(after < 25.0, "tracked under the float law: {after:.1} px");

    let kill_ms = killed.duration_since(cluster.started).as_secs_f64() * 1000.0;
    let changes = owner_changes(servo_owners(&cluster.servo, cluster.started));
    let since_kill: Vec<_> = changes.iter().filter(|c| c.at_ms >= kill_ms).collect();
    assert_eq!(
        since_kill.len(),
        1,
        "one owner change after the kill: {:?}",
        since_kill
            .iter()
            .map(|c| (&c.from, &c.to, c.at_ms))
            .collect::<Vec<_>>()
    );
}
