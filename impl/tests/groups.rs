//! Two redundancy groups on one DDS domain (166), as the paper's navigation and actuator
//! controllers share one network: real `rl controller` processes, ids 1-3 in each group, each
//! group commanding its own topic read by its own `rl servo`. Neither group hears the other's
//! heartbeats, votes or alarms, and when both Primaries die at once each group's actuator
//! changes owner once, to its own Secondary.

mod support;

use rl_layer::core::Role;
use rl_layer::event::Event;
use std::time::{Duration, Instant};
use support::actuators::{owner_changes, servo_owners};
use support::Cluster;

const DOMAIN: u16 = 166;

fn group(name: &str) -> Cluster {
    let mut cluster = Cluster::new(
        &format!("group-{name}"),
        DOMAIN,
        &format!("[dds]\ngroup = \"{name}\"\ncommand_topic = \"{name}/servo_control\""),
    );
    for id in 1..=3 {
        cluster.start(id);
    }
    cluster.start_servo();
    cluster
}

fn formed(cluster: &Cluster) -> bool {
    cluster.steady_with(1, Some(Role::Primary))
        && cluster.steady_with(2, Some(Role::Secondary))
        && cluster.steady_with(3, Some(Role::Tertiary))
        && cluster.servo_owner() == Some(1)
}

/// What the other group's samples would cause, had they been heard: a second controller
/// with the same id (duplicate-id heartbeats, impostor alarms) or a member beyond three.
fn heard_no_other_group(cluster: &Cluster, name: &str) {
    for status in cluster.status.values() {
        assert_eq!(
            status.duplicate_id_heartbeats, 0,
            "{name}: C{} heard another controller with its id",
            status.report.id
        );
    }
    for (_, line) in &cluster.events {
        if let Event::Alarm { about, reason, .. } = &line.event {
            panic!("{name}: C{} alarmed about C{about} ({reason:?})", line.id);
        }
    }
}

/// The last stderr lines of each controller of `cluster`, for a failure to say what each
/// heard.
fn controller_logs(cluster: &Cluster) -> String {
    let mut logs = Vec::new();
    for id in 1..=3 {
        let source = format!("C{id}!");
        let lines: Vec<&str> = cluster.lines_from(&source).collect();
        let tail = &lines[lines.len().saturating_sub(15)..];
        logs.extend(tail.iter().map(|line| format!("{source} {line}")));
    }
    logs.join("\n")
}

#[test]
fn two_groups_on_one_domain_fail_over_apart() {
    let mut nav = group("nav");
    let mut act = group("act");
    let until = Instant::now() + Duration::from_secs(30);
    while !(formed(&nav) && formed(&act)) {
        assert!(
            Instant::now() < until,
            "not both formed: nav [{}], act [{}]\n--- act's controllers' logs ---\n{}",
            nav.describe(),
            act.describe(),
            controller_logs(&act)
        );
        nav.pump(Duration::from_millis(50));
        act.pump(Duration::from_millis(50));
    }
    // A few more rounds for any cross-talk to show.
    nav.pump(Duration::from_secs(2));
    act.pump(Duration::from_secs(2));
    heard_no_other_group(&nav, "nav");
    heard_no_other_group(&act, "act");

    let killed = Instant::now();
    nav.fleet.kill(1).expect("kill nav's C1");
    act.fleet.kill(1).expect("kill act's C1");
    for (cluster, name) in [(&mut nav, "nav"), (&mut act, "act")] {
        cluster.wait_for(
            &format!("{name}: C2 Primary, C3 Secondary, the servo on C2"),
            Duration::from_secs(15),
            |c| {
                c.steady_with(2, Some(Role::Primary))
                    && c.steady_with(3, Some(Role::Secondary))
                    && c.servo_owner() == Some(2)
            },
        );
    }
    // Counted by the writer's participant, as every actuator test counts: C2 re-creating its
    // writer at 30 after the promotion is the same controller, not another owner.
    for (cluster, name) in [(&nav, "nav"), (&act, "act")] {
        let changes = owner_changes(servo_owners(&cluster.servo, cluster.started));
        let kill_ms = killed.duration_since(cluster.started).as_secs_f64() * 1000.0;
        let since_kill: Vec<_> = changes.iter().filter(|c| c.at_ms >= kill_ms).collect();
        assert_eq!(
            since_kill.len(),
            1,
            "{name}: one owner change after the kill: {:?}",
            since_kill
                .iter()
                .map(|c| (&c.from, &c.to, c.at_ms))
                .collect::<Vec<_>>()
        );
    }
}
