//! Real `rl controller` processes over real DDS on loopback: formation, failover, promotion,
//! late joiners, a fourth controller, restarts, SIGSTOP/SIGCONT, malformed samples, bad
//! configuration. Each test has its own DDS domain (201-215) so tests running in parallel
//! never hear each other.

mod support;

use rl::procs::ServoEvent;
use rl_layer::core::{AlarmReason, Phase, Role};
use rl_layer::event::Event;
use std::time::Duration;
use support::Cluster;

const FORM: Duration = Duration::from_secs(15);
const P: Option<Role> = Some(Role::Primary);
const S: Option<Role> = Some(Role::Secondary);
const T: Option<Role> = Some(Role::Tertiary);

fn formed_three(cluster: &mut Cluster) {
    for id in 1..=3 {
        cluster.start(id);
    }
    cluster.wait_for("P=1 S=2 T=3", FORM, |c| {
        c.steady_with(1, P) && c.steady_with(2, S) && c.steady_with(3, T)
    });
}

#[test]
fn three_controllers_form_with_roles_by_id_and_the_servo_follows_the_primary() {
    let mut cluster = Cluster::new("form3", 201, "");
    cluster.start_servo();
    formed_three(&mut cluster);
    cluster.wait_for("servo follows C1", FORM, |c| c.servo_commander() == Some(1));
    let agreed = cluster.status[&2].report.agreed.map(|a| a.to_string());
    assert_eq!(agreed.as_deref(), Some("P=1 S=2 T=3"));
}

#[test]
fn two_controllers_form_as_primary_and_secondary() {
    let mut cluster = Cluster::new("form2", 202, "");
    cluster.start(2);
    cluster.start(1);
    cluster.wait_for("P=1 S=2", FORM, |c| {
        c.steady_with(1, P) && c.steady_with(2, S)
    });
}

#[test]
fn a_single_controller_becomes_primary_after_the_window() {
    let mut cluster = Cluster::new("form1", 203, "");
    cluster.start(3);
    // Alone it cannot tell a dead system from a cut link: its result is provisional and it
    // commands at 15, below the Secondary of any majority (docs/protocol.md, epochs).
    cluster.wait_for("C3 Primary alone at 15", FORM, |c| {
        c.status.get(&3).is_some_and(|s| {
            s.report.phase == Phase::Steady
                && s.report.role == P
                && s.report.provisional
                && s.report.strength == Some(rl_layer::core::PROVISIONAL_PRIMARY_STRENGTH)
        })
    });
}

#[test]
fn kill_9_of_the_primary_hands_the_servo_to_the_secondary_which_is_promoted() {
    let mut cluster = Cluster::new("kill", 204, "");
    cluster.start_servo();
    formed_three(&mut cluster);
    cluster.wait_for("servo follows C1", FORM, |c| c.servo_commander() == Some(1));
    let killed_at = std::time::Instant::now();
    cluster.fleet.kill(1).unwrap();
    cluster.wait_for("servo owner C2", Duration::from_secs(5), |c| {
        c.servo_owner() == Some(2)
    });
    let gap_ms = cluster.servo.iter().rev().find_map(|(_, e)| match e {
        ServoEvent::OwnerChanged {
            from_controller_id: Some(1),
            gap_ms,
            ..
        } => *gap_ms,
        _ => None,
    });
    // Switchover is the command deadline (100 ms) plus a write period, not a re-vote.
    assert!(
        gap_ms.is_some_and(|g| g < 400),
        "gap after the Primary died: {gap_ms:?} ms"
    );
    cluster.wait_for("C2 promoted to 30, C3 to 20", FORM, |c| {
        c.steady_with(2, P) && c.steady_with(3, S)
    });
    let promoted_after = killed_at.elapsed();
    assert!(
        promoted_after < Duration::from_secs(5),
        "{promoted_after:?}"
    );
    for reporter in [2, 3] {
        assert!(
            cluster.events.iter().any(|(_, e)| e.id == reporter
                && e.event
                    == Event::Alarm {
                        about: 1,
                        reason: AlarmReason::Lost,
                        raised: true
                    }),
            "C{reporter} raised an alarm for C1"
        );
    }
    cluster.wait_for("servo follows C2", FORM, |c| c.servo_commander() == Some(2));
}

#[test]
fn sigstop_sigcont_primary_resumes_commanding() {
    let mut cluster = Cluster::new("sigstop", 205, "");
    cluster.start_servo();
    formed_three(&mut cluster);
    cluster.wait_for("servo follows C1", FORM, |c| c.servo_commander() == Some(1));
    cluster.fleet.pause(1, true).unwrap();
    cluster.wait_for(
        "servo owner C2 while C1 is stopped",
        Duration::from_secs(5),
        |c| c.servo_owner() == Some(2),
    );
    cluster.wait_for("C2 promoted", FORM, |c| c.steady_with(2, P));
    let resumed_from = cluster.events.len();
    cluster.fleet.pause(1, false).unwrap();
    // C1's participant must survive the stop: the others hear it again and clear its alarm.
    cluster.wait_for("C2 and C3 clear the alarm for C1", FORM, |c| {
        [2, 3].iter().all(|&reporter| {
            c.events[resumed_from..].iter().any(|(_, e)| {
                e.id == reporter
                    && matches!(
                        e.event,
                        Event::Alarm {
                            about: 1,
                            raised: false,
                            ..
                        }
                    )
            })
        })
    });
    // One system again: every controller steady, one Primary, the servo following it.
    cluster.wait_for("settled with one Primary", FORM, |c| {
        let steady = c
            .status
            .values()
            .filter(|s| s.report.phase == Phase::Steady)
            .count()
            == 3;
        let primaries: Vec<u8> = c
            .status
            .values()
            .filter(|s| {
                s.report.role == P && s.report.strength == Some(rl_layer::core::Strength(30))
            })
            .map(|s| s.report.id)
            .collect();
        steady && primaries.len() == 1 && c.servo_commander() == primaries.first().copied()
    });
}

#[test]
fn a_late_joiner_comes_in_as_tertiary() {
    let mut cluster = Cluster::new("late", 206, "");
    cluster.start(1);
    cluster.start(2);
    cluster.wait_for("P=1 S=2", FORM, |c| {
        c.steady_with(1, P) && c.steady_with(2, S)
    });
    cluster.start(3);
    cluster.wait_for("C3 Tertiary", FORM, |c| c.steady_with(3, T));
    assert!(cluster.steady_with(1, P) && cluster.steady_with(2, S));
}

#[test]
fn a_fourth_controller_is_ignored() {
    let mut cluster = Cluster::new("fourth", 207, "");
    formed_three(&mut cluster);
    cluster.start(4);
    cluster.wait_for("C4 steady without a role", FORM, |c| c.steady_with(4, None));
    assert!(cluster.steady_with(1, P) && cluster.steady_with(2, S) && cluster.steady_with(3, T));
    assert!(
        !cluster.events.iter().any(|(_, e)| e.id == 4
            && matches!(
                e.event,
                Event::Output {
                    strength: Some(_),
                    ..
                }
            )),
        "C4 never commands"
    );
}

#[test]
fn a_restarted_primary_comes_back_in_the_lowest_role() {
    let mut cluster = Cluster::new("restart", 208, "");
    formed_three(&mut cluster);
    cluster.fleet.kill(1).unwrap();
    cluster.wait_for("P=2 S=3", FORM, |c| {
        c.steady_with(2, P) && c.steady_with(3, S)
    });
    cluster.status.remove(&1);
    let restarted_from = cluster.events.len();
    cluster.start(1);
    // All three at once: C2 and C3 report the rejoin's vote at the same round boundary as C1,
    // but their lines may arrive after C1's.
    cluster.wait_for("C1 back as Tertiary, P=2 S=3", FORM, |c| {
        c.steady_with(1, T) && c.steady_with(2, P) && c.steady_with(3, S)
    });
    // And on the way there nobody commanded in another role: C1 never above Tertiary, C2
    // and C3 never left their roles.
    let expected = |id: u8| [T, P, S][usize::from(id - 1)];
    for (_, line) in &cluster.events[restarted_from..] {
        if let Event::Output { role, .. } = line.event {
            assert!(
                role == expected(line.id) || (line.id == 1 && role.is_none()),
                "C{} commanded as {role:?} after C1's restart",
                line.id
            );
        }
    }
}

#[test]
fn malformed_heartbeats_are_dropped_and_nothing_crashes() {
    let mut cluster = Cluster::new("malformed", 209, "");
    formed_three(&mut cluster);
    let config = rl_layer::config::Config {
        dds: rl_layer::config::Dds {
            domain: 209,
            ..Default::default()
        },
        ..Default::default()
    };
    let session = rl_layer::dds::Session::new(&config.dds, &config.timing).unwrap();
    let writer = session.heartbeat_writer().unwrap();
    let mut heartbeats = session.heartbeat_reader().unwrap();
    let garbage = garbage_heartbeats();
    // Garbage written before the controllers have discovered this participant is lost:
    // start once this participant hears all three (discovery runs both ways at once).
    wait_for_heartbeats_from_all(&mut cluster, &mut heartbeats);
    cluster.pump(Duration::from_millis(500));
    // One sample at a time: RustDDS's writer keeps its last sample only (for the whole
    // writer, not per instance), so samples written back to back replace each other unsent.
    const ROUNDS: u64 = 40;
    for _ in 0..ROUNDS {
        for sample in garbage {
            writer.write_sample(sample).unwrap();
            cluster.pump(Duration::from_millis(10));
        }
    }
    // Fresh heartbeats from every controller, sent after the garbage, from the same lives.
    let _ = heartbeats.take();
    let heard = wait_for_heartbeats_from_all(&mut cluster, &mut heartbeats);
    for id in 1..=3 {
        assert_eq!(
            heard.get(&id),
            cluster.status.get(&id).map(|s| &s.report.incarnation),
            "a heartbeat from C{id}'s first life after the garbage"
        );
    }
    // The ninth controller's arrival and loss may cost re-votes; the roles stay.
    cluster.wait_for("P=1 S=2 T=3 again", FORM, |c| {
        c.steady_with(1, P) && c.steady_with(2, S) && c.steady_with(3, T)
    });
    let failed = cluster
        .events
        .iter()
        .find(|(_, e)| e.status().is_some_and(|s| s.report.phase == Phase::Failed));
    assert!(failed.is_none(), "a controller failed itself: {failed:?}");
    for id in 1..=3 {
        let exited = cluster.fleet.exit_status(id).unwrap();
        assert!(exited.is_none(), "C{id} exited: {exited:?}");
        assert!(
            !cluster
                .events
                .iter()
                .any(|(_, e)| e.id == id && matches!(e.event, Event::Stopped { .. })),
            "C{id} still runs"
        );
        // The reader logs its count of dropped samples at every power of two: the garbage
        // reached every controller and was counted, not passed to the core.
        let dropped = most_dropped_logged(&cluster, &format!("C{id}!"));
        eprintln!("C{id} logged {dropped} heartbeats dropped");
        assert!(
            dropped >= 8,
            "C{id} logged {dropped} dropped heartbeats of the {} malformed sent",
            2 * ROUNDS
        );
    }
}

/// Two samples every reader must drop (id 0; unknown phase and role codes, a strength that is
/// no role's), and one valid heartbeat from a ninth controller nobody votes for. None under a
/// live controller's id: heartbeat readers keep the last sample per id, so those would replace
/// that controller's own heartbeats before the reader takes them.
fn garbage_heartbeats() -> [rl_layer::wire::HeartbeatSample; 3] {
    [
        rl_layer::wire::HeartbeatSample {
            from_id: 0,
            ..Default::default()
        },
        rl_layer::wire::HeartbeatSample {
            from_id: 7,
            phase: 200,
            role: 9,
            strength: 77,
            ..Default::default()
        },
        rl_layer::wire::HeartbeatSample {
            from_id: 9,
            phase: 2,
            role: 1,
            strength: 10,
            ..Default::default()
        },
    ]
}

/// The incarnation of controllers 1-3 from their heartbeats that `heartbeats` takes within
/// 3 s (fewer ids when some stay silent).
fn wait_for_heartbeats_from_all(
    cluster: &mut Cluster,
    heartbeats: &mut rl_layer::dds::Reader<rl_layer::wire::HeartbeatSample>,
) -> std::collections::BTreeMap<u8, u64> {
    let mut heard = std::collections::BTreeMap::new();
    let until = std::time::Instant::now() + Duration::from_secs(3);
    while heard.len() < 3 && std::time::Instant::now() < until {
        for heartbeat in heartbeats.take() {
            if (1..=3).contains(&heartbeat.value.id) {
                heard.insert(heartbeat.value.id, heartbeat.value.incarnation);
            }
        }
        cluster.pump(Duration::from_millis(50));
    }
    heard
}

/// The highest `dropped=N` a controller's stderr reported for invalid heartbeats.
fn most_dropped_logged(cluster: &Cluster, source: &str) -> u64 {
    cluster
        .lines_from(source)
        .filter(|line| line.contains("dropped invalid sample") && line.contains("heartbeat"))
        .filter_map(|line| {
            let count = line.split("dropped=").nth(1)?;
            count.split_whitespace().next()?.parse::<u64>().ok()
        })
        .max()
        .unwrap_or(0)
}

fn run_rl(args: &[&str]) -> std::process::Output {
    std::process::Command::new(support::rl())
        .args(args)
        .output()
        .expect("run rl")
}

#[test]
fn bad_configuration_exits_2_naming_the_field() {
    let dir = support::tempdir::Dir::new("badconfig");
    let cases = [
        (
            "[timing]\npeer_deadline_ms = 300\n",
            "timing.peer_deadline_ms",
        ),
        ("[timin]\n", "timin"),
        ("[dds]\ndomain = \"x\"\n", "dds.domain"),
        (
            "[timing]\nheartbeat_period_ms = 0\n",
            "timing.heartbeat_period_ms",
        ),
    ];
    for (text, field) in cases {
        let path = dir.0.join("bad.toml");
        std::fs::write(&path, text).unwrap();
        let out = run_rl(&[
            "controller",
            "--id",
            "1",
            "--config",
            path.to_str().unwrap(),
        ]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{text:?}: {stderr}");
        assert!(
            stderr.contains(field),
            "{text:?}: message names {field}: {stderr}"
        );
        assert!(!stderr.contains("panicked"), "{stderr}");
    }
    let missing = run_rl(&[
        "controller",
        "--id",
        "1",
        "--config",
        "/nonexistent/rl.toml",
    ]);
    assert_eq!(missing.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&missing.stderr).contains("/nonexistent/rl.toml"));
    let bad_id = run_rl(&["controller", "--id", "0"]);
    assert_eq!(bad_id.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad_id.stderr).contains("--id"));
    // 233 is the first domain whose RTPS ports pass 65535; every command refuses it before
    // joining DDS.
    let commands: [&[&str]; 4] = [
        &["controller", "--id", "1"],
        &["servo", "--duration-ms", "3000"],
        &["shapes", "--duration-ms", "3000"],
        &["status", "--once"],
    ];
    for command in commands {
        let bad_domain = run_rl(&[command, &["--domain", "233"]].concat());
        let stderr = String::from_utf8_lossy(&bad_domain.stderr);
        assert_eq!(
            bad_domain.status.code(),
            Some(2),
            "rl {command:?}: {stderr}"
        );
        assert!(
            stderr.contains("--domain 233"),
            "rl {command:?} names --domain: {stderr}"
        );
    }
}

#[test]
fn status_once_json_lists_the_controllers_and_exits() {
    let mut cluster = Cluster::new("status", 210, "");
    formed_three(&mut cluster);
    let out = run_rl(&["status", "--json", "--once", "--domain", "210"]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    let view: serde_json::Value = serde_json::from_str(text.trim()).expect("one JSON object");
    let controllers = view["controllers"].as_array().expect("controllers");
    let roles: Vec<(u64, String, u64)> = controllers
        .iter()
        .map(|c| {
            (
                c["id"].as_u64().unwrap(),
                c["role"].as_str().unwrap_or("-").to_string(),
                c["strength"].as_u64().unwrap_or(0),
            )
        })
        .collect();
    assert_eq!(
        roles,
        vec![
            (1, "primary".into(), 30),
            (2, "secondary".into(), 20),
            (3, "tertiary".into(), 10)
        ]
    );
    assert!(view["alarms"].as_array().is_some_and(|a| a.is_empty()));
}

#[test]
fn a_status_started_after_an_alarm_shows_it_with_who_raised_it_and_since_when() {
    let mut cluster = Cluster::new("late-status", 214, "");
    formed_three(&mut cluster);
    cluster.fleet.kill(3).unwrap();
    let killed_ms = rl::procs::wall_ms();
    cluster.wait_for("C1 and C2 raise Lost about C3", FORM, |c| {
        [1, 2].iter().all(|&by| {
            c.events.iter().any(|(_, e)| {
                e.id == by
                    && matches!(
                        e.event,
                        Event::Alarm {
                            about: 3,
                            reason: AlarmReason::Lost,
                            raised: true
                        }
                    )
            })
        })
    });
    // Started only now: the alarm topic is transient local, so it hears the active alarms.
    let out = run_rl(&["status", "--json", "--once", "--domain", "214"]);
    assert_eq!(out.status.code(), Some(0));
    let view: serde_json::Value =
        serde_json::from_str(String::from_utf8_lossy(&out.stdout).trim()).expect("one object");
    let alarms = view["alarms"].as_array().expect("alarms");
    assert_eq!(alarms.len(), 1, "{view}");
    assert_eq!(alarms[0]["about"], 3);
    assert_eq!(alarms[0]["reason"], "lost");
    assert_eq!(alarms[0]["raised_by"], serde_json::json!([1, 2]));
    let since_ms = alarms[0]["since_ms"].as_u64().expect("since_ms");
    assert!(
        since_ms >= killed_ms && since_ms < killed_ms + 5_000,
        "raised at {since_ms}, C3 killed at {killed_ms}"
    );
    let table = run_rl(&["status", "--once", "--domain", "214"]);
    let table = String::from_utf8_lossy(&table.stdout);
    assert!(
        table.contains("ALARM C3 Lost (raised by C1, C2; since "),
        "{table}"
    );
}

/// A heartbeat that waited in a queue past the end of the round it was sent in says what its
/// sender decided rounds ago: every controller drops it as lost (the model delivers a
/// heartbeat in its round or never) and logs `heartbeat_late`; the same sender's heartbeats
/// sent on time are taken. The ninth controller's heartbeats go out right after C1's, so
/// inside every controller's round, and one of them carries a stamp 600 ms old.
#[test]
fn a_heartbeat_sent_rounds_before_it_arrives_is_dropped_as_late() {
    let mut cluster = Cluster::new("late", 215, "");
    formed_three(&mut cluster);
    let config = rl_layer::config::Config {
        dds: rl_layer::config::Dds {
            domain: 215,
            ..Default::default()
        },
        ..Default::default()
    };
    let session = rl_layer::dds::Session::new(&config.dds, &config.timing).unwrap();
    let writer = session.heartbeat_writer().unwrap();
    let mut heartbeats = session.heartbeat_reader().unwrap();
    wait_for_heartbeats_from_all(&mut cluster, &mut heartbeats);
    const ROUNDS: usize = 16;
    const QUEUED_ROUND: usize = 10;
    const QUEUED_MS: u64 = 600;
    let mut round = 0;
    let until = std::time::Instant::now() + Duration::from_secs(10);
    while round < ROUNDS && std::time::Instant::now() < until {
        cluster.pump(Duration::from_millis(5));
        if !heartbeats.take().iter().any(|h| h.value.id == 1) {
            continue;
        }
        let stamp = rl_layer::wire::sender_clock_ms();
        let sent_ms = if round == QUEUED_ROUND {
            stamp - QUEUED_MS
        } else {
            stamp
        };
        writer
            .write_sample(rl_layer::wire::HeartbeatSample {
                from_id: 9,
                incarnation: 1,
                phase: rl_layer::wire::PHASE_INITIALIZING,
                sent_ms,
                ..Default::default()
            })
            .unwrap();
        round += 1;
    }
    assert_eq!(round, ROUNDS, "C1's heartbeats stopped");
    cluster.pump(Duration::from_millis(500));
    for id in 1..=3 {
        let late: Vec<u64> = cluster
            .events
            .iter()
            .filter_map(|(_, e)| match e.event {
                Event::HeartbeatLate { from: 9, waited_ms } if e.id == id => Some(waited_ms),
                _ => None,
            })
            .collect();
        eprintln!("C{id} dropped the ninth's heartbeats that waited {late:?} ms");
        assert!(
            late.iter().any(|&waited_ms| waited_ms >= QUEUED_MS - 50),
            "C{id} took the heartbeat stamped {QUEUED_MS} ms before it was written: {late:?}"
        );
        // Those written at once arrive within the round they were written in.
        assert!(
            late.iter().all(|&waited_ms| waited_ms >= 150),
            "C{id} dropped on-time heartbeats as late: {late:?}"
        );
    }
}
