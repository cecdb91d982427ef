//! DDS Security (docs/security.md): secured controllers form and vote, an unsecured
//! participant's forged heartbeat and strength-100 command are refused, and a failover still
//! reaches the secured servo; a forged vote, two forged incumbents and garbage datagrams
//! (the forgeries of `forged`) do not reach secured controllers at all; a DATA_FRAG
//! announcing 4 GB (`fragments`, root) is dropped by a secured controller too; with open device topics an unsecured actuator follows secured
//! controllers; a keystore that is missing a file, expired or mismatched stops every command
//! with exit status 2 naming the file.

use crate::adversary::forged::{
    failed_heartbeat_of_c1, flood_with_garbage, forger, impostor_alarms, incumbent_claims,
    keep_forging, outputs_since, reversed_vote_of_c2,
};
use crate::adversary::fragments::{c1_survives, four_gb_attack, warned_once_per_writer};
use crate::support::keys::{keys, keystores};
use crate::support::{rl, tempdir, Cluster};
use rl::procs::{parse_servo_event, ServoEvent};
use rl_layer::core::{Phase, Role};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

const FORM: Duration = Duration::from_secs(20);
const P: Option<Role> = Some(Role::Primary);
const S: Option<Role> = Some(Role::Secondary);
const T: Option<Role> = Some(Role::Tertiary);

/// The same with the device topics left open (`open_device_topics`).
fn open_devices_config(dir: &Path, name: &str, keystore: &Path) -> PathBuf {
    let path = secured_config(dir, name, keystore);
    let text = std::fs::read_to_string(&path).unwrap();
    std::fs::write(&path, format!("{text}open_device_topics = true\n")).unwrap();
    path
}

#[test]
fn with_open_device_topics_an_unsecured_actuator_follows_secured_controllers() {
    const DOMAIN: u16 = 142;
    let dir = tempdir::Dir::new("sec-open");
    let keys_dir = keystores(&dir.0);
    let mut cluster = Cluster::new("sec-open", DOMAIN, "");
    // An unsecured actuator cannot hear the secured heartbeats that name the controllers, so
    // it obeys plain exclusive ownership (`--any-writer`): on the open path the actuator
    // cannot tell a controller from anyone else (docs/security.md).
    cluster
        .fleet
        .start_other("servo", &["servo", "--json", "--any-writer"])
        .unwrap();
    form_secured(&mut cluster, &dir.0, &keys_dir, true);
    // It cannot read the (protected) heartbeats, so it cannot name the controller: it sees a
    // writer at the Primary's strength.
    cluster.wait_for("the unsecured servo follows the Primary at 30", FORM, |c| {
        last_command(c).is_some_and(|(_, strength)| strength == rl_layer::core::Strength(30))
    });
}

/// A configuration naming `keystore`, with a 5 s initialization window: secured discovery
/// (authentication, key exchange) takes about 2 s on loopback, and within the window the
/// three form at once as P=1 S=2 T=3.
fn secured_config(dir: &Path, name: &str, keystore: &Path) -> PathBuf {
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(
        &path,
        format!(
            "[timing]\ninit_window_ms = 5000\n[security]\nkeystore = {:?}\n",
            keystore.display().to_string()
        ),
    )
    .unwrap();
    path
}

fn servo_events<'a>(
    cluster: &'a Cluster,
    source: &'a str,
) -> impl Iterator<Item = ServoEvent> + 'a {
    cluster.lines_from(source).filter_map(parse_servo_event)
}

fn forged_commands(cluster: &Cluster, source: &str) -> usize {
    servo_events(cluster, source)
        .filter(|e| {
            matches!(
                e,
                ServoEvent::Command {
                    strength: rl_layer::core::Strength(100),
                    ..
                }
            )
        })
        .count()
}

#[test]
fn an_unsecured_participant_cannot_forge_heartbeats_or_commands() {
    const DOMAIN: u16 = 140;
    let dir = tempdir::Dir::new("sec-forge");
    let keys_dir = keystores(&dir.0);
    let mut cluster = Cluster::new("sec-forge", DOMAIN, "");
    let servo_config = secured_config(&dir.0, "servo", &keys_dir.join("servo"));
    cluster
        .fleet
        .start_other_configured("servo", &servo_config, &["servo", "--json"])
        .unwrap();
    // The control: an unsecured actuator on the same domain, which the forger can reach,
    // obeying plain exclusive ownership (without `--any-writer` the servo's own check refuses
    // a writer that sends no controller heartbeat, docs/protocol.md "Hostile input").
    cluster
        .fleet
        .start_other("servo-open", &["servo", "--json", "--any-writer"])
        .unwrap();
    form_secured(&mut cluster, &dir.0, &keys_dir, false);
    cluster.wait_for("the secured servo follows C1", FORM, |c| {
        c.servo_commander() == Some(1)
    });

    // The adversary: a participant without DDS Security, writing C1's heartbeat as FAILED
    // and commanding at strength 100, for 4 s (discovery between unsecured participants
    // takes well under a second).
    let config = rl_layer::config::Config {
        dds: rl_layer::config::Dds {
            domain: DOMAIN,
            ..Default::default()
        },
        ..Default::default()
    };
    let session = rl_layer::dds::Session::new(&config.dds, &config.timing).unwrap();
    let heartbeats = session.heartbeat_writer().unwrap();
    let mut commands = session
        .command_writer(Some(rl_layer::core::Strength(100)))
        .unwrap();
    let forged = rl_layer::wire::HeartbeatSample {
        from_id: 1,
        incarnation: u64::MAX / 2,
        phase: rl_layer::wire::PHASE_FAILED,
        ..Default::default()
    };
    let events_before = cluster.events.len();
    let forging_from = Instant::now();
    while forging_from.elapsed() < Duration::from_secs(4) {
        heartbeats.write_sample(forged).unwrap();
        commands
            .write(rl_layer::wire::ServoControl {
                pan: 1,
                tilt: 1,
                frequency: 60,
            })
            .unwrap();
        cluster.pump(Duration::from_millis(25));
    }
    cluster.pump(Duration::from_millis(500));

    // The unsecured actuator took the forged commands: the forger works.
    assert!(
        forged_commands(&cluster, "servo-open") > 0,
        "the unsecured servo saw no forged command; the test proves nothing\n{}",
        cluster.transcript.join("\n")
    );
    // The secured one never saw one and still follows C1.
    assert_eq!(
        forged_commands(&cluster, "servo"),
        0,
        "a forged command reached the secured servo"
    );
    assert_eq!(cluster.servo_commander(), Some(1));
    // No controller moved: every status reported since is the formation's.
    for (_, line) in &cluster.events[events_before..] {
        if let Some(status) = line.status() {
            let expected = [P, S, T][usize::from(line.id) - 1];
            assert!(
                status.report.phase == Phase::Steady && status.report.role == expected,
                "C{} changed under the forgery: {:?} {:?}",
                line.id,
                status.report.phase,
                status.report.role
            );
        }
    }
    for id in 1..=3 {
        assert!(cluster.steady_with(id, [P, S, T][usize::from(id) - 1]));
        assert!(
            cluster.fleet.exit_status(id).unwrap().is_none(),
            "C{id} exited"
        );
    }
    // A secured `rl status` sees the three (after authenticating with each).
    let status_config = secured_config(&dir.0, "status", &keys_dir.join("status"));
    let output = Command::new(rl())
        .args([
            "status",
            "--json",
            "--once",
            "--domain",
            &DOMAIN.to_string(),
        ])
        .arg("--config")
        .arg(&status_config)
        .output()
        .unwrap();
    let board: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    let roles: Vec<(u64, String)> = board["controllers"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            (
                c["id"].as_u64().unwrap(),
                c["role"].as_str().unwrap_or("-").to_string(),
            )
        })
        .collect();
    assert_eq!(
        roles,
        [
            (1, "primary".into()),
            (2, "secondary".into()),
            (3, "tertiary".into())
        ],
        "rl status: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    // A failover still works secured: the Secondary's new writer at 30 (created after the
    // servo was matched) is decoded and followed.
    cluster.fleet.kill(1).unwrap();
    cluster.wait_for("the secured servo follows C2 at 30", FORM, |c| {
        last_command(c) == Some((Some(2), rl_layer::core::Strength(30)))
    });
}

/// Starts secured controllers 1-3 in `cluster`, their configurations in `dir` and keystores
/// in `keys_dir` (the device topics open with `open_devices`), and waits for P=1 S=2 T=3.
fn form_secured(cluster: &mut Cluster, dir: &Path, keys_dir: &Path, open_devices: bool) {
    for id in 1..=3u8 {
        let (name, keystore) = (format!("c{id}"), keys_dir.join(format!("c{id}")));
        let config = if open_devices {
            open_devices_config(dir, &name, &keystore)
        } else {
            secured_config(dir, &name, &keystore)
        };
        cluster
            .fleet
            .start_controller_configured(id, &config, &["--json-events"])
            .unwrap();
    }
    cluster.wait_for("P=1 S=2 T=3, secured", FORM, |c| {
        c.steady_with(1, P) && c.steady_with(2, S) && c.steady_with(3, T)
    });
}

#[test]
fn forged_votes_incumbents_and_garbage_do_not_reach_secured_controllers() {
    const DOMAIN: u16 = 143;
    let dir = tempdir::Dir::new("sec-votes");
    let keys_dir = keystores(&dir.0);
    let mut cluster = Cluster::new("sec-votes", DOMAIN, "");
    form_secured(&mut cluster, &dir.0, &keys_dir, false);
    // The control: an unsecured participant that hears what the forgers write (and nothing
    // from the secured controllers, whose discovery it cannot join).
    let witness = forger(DOMAIN);
    let mut heard_votes = witness.vote_reader().unwrap();
    let mut heard_heartbeats = witness.heartbeat_reader().unwrap();
    // The forgeries of the unsecured tests, all at once: C1 FAILED, C1 and C2 as incumbents
    // of a newer epoch agreeing on C3, and C2 voting the reverse order; two participants.
    let forgers = [forger(DOMAIN), forger(DOMAIN)];
    let heartbeat_writers: Vec<_> = forgers
        .iter()
        .map(|f| f.heartbeat_writer().unwrap())
        .collect();
    let votes = forgers[0].vote_writer().unwrap();
    let claims = incumbent_claims(&cluster);
    let failed = failed_heartbeat_of_c1(&cluster);
    let vote = reversed_vote_of_c2(&cluster);
    let since = Instant::now();
    let mut heartbeats = Vec::new();
    let mut forged_votes = 0;
    keep_forging(&mut cluster, || {
        for (writer, claim) in heartbeat_writers.iter().zip(&claims) {
            writer.write(claim).unwrap();
        }
        heartbeat_writers[0].write(&failed).unwrap();
        votes.write(&vote).unwrap();
        // The witness keeps the latest sample per writer: take them as they come.
        heartbeats.extend(heard_heartbeats.take());
        forged_votes += heard_votes.take().len();
    });
    let sent = flood_with_garbage(&mut cluster, DOMAIN);

    assert!(
        heartbeats.len() > 10 && forged_votes > 10,
        "the unsecured witness heard {} heartbeats and {forged_votes} votes: the forgers reach \
         nobody and the test proves nothing",
        heartbeats.len()
    );
    assert!(
        heartbeats.iter().all(|h| forgers
            .iter()
            .any(|f| f.participant_guid().prefix == h.writer.prefix)),
        "an unsecured participant heard a secured controller's heartbeat"
    );
    assert!(sent > 10_000, "only {sent} garbage datagrams sent");
    // The secured controllers never heard a forged sample: no impostor alarm (which
    // unsecured controllers raise, `forged`), no role moved, nobody left.
    assert_eq!(
        outputs_since(&cluster, since),
        Vec::<String>::new(),
        "a role moved"
    );
    for id in 1..=3 {
        assert_eq!(
            impostor_alarms(&cluster, id, true, since),
            Vec::<u8>::new(),
            "a forged sample about C{id} reached a secured controller"
        );
        assert!(
            cluster.steady_with(id, [P, S, T][usize::from(id) - 1]),
            "{}",
            cluster.describe()
        );
        assert!(
            cluster.fleet.exit_status(id).unwrap().is_none(),
            "C{id} exited"
        );
    }
}

/// Participant discovery (SPDP) is unauthenticated even with DDS Security (a participant
/// must be heard before it can authenticate), so its reader takes fragments from anyone:
/// the size bound of the vendored RustDDS (fix 5), not security, stops the 4 GB sample.
#[test]
#[ignore = "needs root (a memory cgroup limiting the attacked controller to 256 MB)"]
fn a_data_frag_announcing_4_gb_is_dropped_by_a_secured_controller() {
    const DOMAIN: u16 = 144;
    let dir = tempdir::Dir::new("sec-fragments");
    let keys_dir = keystores(&dir.0);
    let configs = [1, 2, 3]
        .map(|id| secured_config(&dir.0, &format!("c{id}"), &keys_dir.join(format!("c{id}"))));
    let stderr = c1_survives(four_gb_attack("sec-fragments-4gb", DOMAIN, Some(configs)));
    warned_once_per_writer(&stderr);
}

/// The controller and strength of the last command the secured servo accepted.
fn last_command(cluster: &Cluster) -> Option<(Option<u8>, rl_layer::core::Strength)> {
    cluster.servo.iter().rev().find_map(|(_, e)| match e {
        ServoEvent::Command {
            controller_id,
            strength,
            ..
        } => Some((*controller_id, *strength)),
        _ => None,
    })
}

/// Runs `rl <args> --config <config> --domain 141` and returns its exit code and stderr.
fn run_rl(args: &[&str], config: &Path) -> (Option<i32>, String) {
    let output = Command::new(rl())
        .args(args)
        .arg("--config")
        .arg(config)
        .arg("--domain")
        .arg("141")
        .output()
        .unwrap();
    (
        output.status.code(),
        String::from_utf8_lossy(&output.stderr).into_owned(),
    )
}

/// Copies keystore `from` to a fresh directory `to`, for a test to break.
fn copy_keystore(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        std::fs::copy(entry.path(), to.join(entry.file_name())).unwrap();
    }
}

#[test]
fn a_missing_expired_or_mismatched_keystore_file_exits_2_naming_it() {
    let dir = tempdir::Dir::new("sec-files");
    let keys_dir = keystores(&dir.0);
    let text = keys_dir.to_str().unwrap();
    // Controller 4's certificate expired in 2020.
    keys(&[
        "add",
        "--dir",
        text,
        "--id",
        "4",
        "--not-before",
        "2020-01-01",
        "--days",
        "30",
    ]);
    // A second CA, whose controller 1 is a stranger to the first.
    let other_dir = dir.0.join("other");
    keys(&["init", "--dir", other_dir.to_str().unwrap()]);
    keys(&["add", "--dir", other_dir.to_str().unwrap(), "--id", "1"]);

    let broken = |name: &str, from: &str, change: &dyn Fn(&Path)| -> PathBuf {
        let keystore = dir.0.join(name);
        copy_keystore(&keys_dir.join(from), &keystore);
        change(&keystore);
        keystore
    };
    let c1 = keys_dir.join("c1");
    let cases: Vec<(&str, PathBuf, &str, &str)> = vec![
        (
            "missing certificate",
            broken("missing", "c1", &|k| {
                std::fs::remove_file(k.join("cert.pem")).unwrap()
            }),
            "cert.pem",
            "cannot read",
        ),
        (
            "expired certificate",
            keys_dir.join("c4"),
            "cert.pem",
            "expired",
        ),
        (
            "another controller's key",
            broken("wrong-key", "c2", &|k| {
                std::fs::copy(c1.join("key.pem"), k.join("key.pem")).unwrap();
            }),
            "key.pem",
            "is not the key of",
        ),
        (
            "another controller's permissions",
            broken("wrong-permissions", "c2", &|k| {
                std::fs::copy(c1.join("permissions.p7s"), k.join("permissions.p7s")).unwrap();
            }),
            "permissions.p7s",
            "grants CN=rl-controller-1",
        ),
        (
            "a certificate from another CA",
            broken("other-ca", "c1", &|k| {
                for file in ["cert.pem", "key.pem"] {
                    std::fs::copy(other_dir.join("c1").join(file), k.join(file)).unwrap();
                }
            }),
            "cert.pem",
            "was not issued by the CA",
        ),
        (
            "permissions signed by another CA",
            broken("other-ca-permissions", "c1", &|k| {
                std::fs::copy(
                    other_dir.join("c1/permissions.p7s"),
                    k.join("permissions.p7s"),
                )
                .unwrap();
            }),
            "permissions.p7s",
            "not the CA's",
        ),
        (
            "an altered governance document",
            broken("altered-governance", "c1", &|k| {
                crate::support::keys::alter_governance(k);
            }),
            "governance.p7s",
            "altered",
        ),
    ];
    for (what, keystore, file, problem) in cases {
        let config = secured_config(&dir.0, "broken", &keystore);
        let named = keystore.join(file).display().to_string();
        let commands: [&[&str]; 4] = [
            &["controller", "--id", "1", "--duration-ms", "3000"],
            &["status", "--json", "--once"],
            &["servo", "--duration-ms", "3000"],
            &["shapes", "--duration-ms", "3000"],
        ];
        for args in commands {
            let (code, stderr) = run_rl(args, &config);
            assert_eq!(
                code,
                Some(2),
                "{what}: rl {args:?} exited {code:?}: {stderr}"
            );
            assert!(
                stderr.contains(&named) && stderr.contains(problem),
                "{what}: rl {args:?} should name {named} ({problem}): {stderr}"
            );
        }
        eprintln!("{what}: {}", run_rl(commands[0], &config).1.trim());
    }
}
