//! A controller that votes itself FAILED leaves and comes back (paper: "Any unit that does not
//! agree with the two votes of the other controllers will take itself offline and/or
//! restart"). Real controllers over DDS on loopback (domain 228): a one-way heartbeat loss
//! (the `fault-injection` control) outvotes the Tertiary; it must exit with the failed-exit
//! status within the configured delay and say why, and, restarted the way the shipped systemd
//! unit restarts it (same id and configuration, after the unit's `RestartSec`), be back as
//! Tertiary within 3 s while the other two keep their roles.
//!
//! Needs the feature: `cargo test --release -p rl --features fault-injection --test failed_exit`.

#![cfg(feature = "fault-injection")]

mod support;

use rl_layer::core::{Phase, Role};
use rl_layer::event::{Event, EventLine};
use rl_layer::failed_exit::{FailureCause, EXIT_STATUS};
use std::io::Write;
use std::time::{Duration, Instant};
use support::Cluster;

const DOMAIN: u16 = 228;
const FORM: Duration = Duration::from_secs(15);
/// The delay the test configures: long enough to tell "after the delay" from "at once".
const FAILED_EXIT_DELAY_MS: u64 = 400;
/// Scheduling slack on top of the delay: the announcing heartbeat (up to a quarter period
/// after the round end that failed it), leaving DDS, and reading the exit on a busy machine.
const EXIT_MARGIN: Duration = Duration::from_millis(800);
/// "Back within 3 s": from the restarted process's start to its steady Tertiary status.
const BACK_WITHIN: Duration = Duration::from_secs(3);
const P: Option<Role> = Some(Role::Primary);
const S: Option<Role> = Some(Role::Secondary);
const T: Option<Role> = Some(Role::Tertiary);

/// The shipped unit's value of `key=` (the last one wins, as in systemd).
fn unit_setting(key: &str) -> String {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("debian/rl@.service");
    let unit = std::fs::read_to_string(&path).unwrap();
    unit.lines()
        .filter_map(|line| line.strip_prefix(&format!("{key}=")))
        .next_back()
        .unwrap_or_else(|| panic!("{} has no {key}=", path.display()))
        .to_string()
}

/// `RestartSec=` as systemd reads the forms the unit uses (`1s`, `500ms`).
fn restart_delay() -> Duration {
    let text = unit_setting("RestartSec");
    match (text.strip_suffix("ms"), text.strip_suffix('s')) {
        (Some(ms), _) => Duration::from_millis(ms.parse().unwrap()),
        (None, Some(s)) => Duration::from_secs_f64(s.parse().unwrap()),
        (None, None) => Duration::from_secs_f64(text.parse().unwrap()),
    }
}

/// The first event of controller `id` from index `from` on that `matches`, with when it was
/// read.
fn first_event(
    cluster: &Cluster,
    from: usize,
    id: u8,
    matches: impl Fn(&EventLine) -> bool,
) -> Option<(Instant, EventLine)> {
    cluster.events[from..]
        .iter()
        .find(|(_, e)| e.id == id && matches(e))
        .cloned()
}

fn is_failed(event: &EventLine) -> bool {
    event
        .status()
        .is_some_and(|s| s.report.phase == Phase::Failed)
}

#[test]
fn an_outvoted_controller_exits_with_its_status_and_is_back_as_tertiary_after_a_restart() {
    let restart_sec = restart_delay();
    assert!(
        unit_setting("RestartForceExitStatus")
            .split_whitespace()
            .any(|status| status == EXIT_STATUS.to_string()),
        "the unit restarts on exit status {EXIT_STATUS}"
    );
    let extra = format!("failed_exit_delay_ms = {FAILED_EXIT_DELAY_MS}");
    let mut cluster = Cluster::new("failedexit", DOMAIN, &extra);
    cluster.start(1);
    cluster.start(2);
    let (_, mut c3_control) = cluster
        .fleet
        .start_controller_piped(3, "C3", &["--json-events"])
        .unwrap();
    cluster.wait_for("P=1 S=2 T=3", FORM, |c| {
        c.steady_with(1, P) && c.steady_with(2, S) && c.steady_with(3, T)
    });
    let formed_from = cluster.events.len();

    // C3 stops hearing C1: it re-votes without C1, alone against C1 and C2, who mark it
    // FAILED. When it hears C1 again, their agreeing votes outvote its own.
    writeln!(c3_control, "drop-heartbeats-from 1").unwrap();
    cluster.wait_for("C1 and C2 mark C3 FAILED", FORM, |c| {
        [1, 2]
            .iter()
            .all(|id| c.status.get(id).is_some_and(|s| s.failed.contains(&3)))
    });
    writeln!(c3_control, "accept-heartbeats-from 1").unwrap();
    cluster.wait_for("C3 votes itself FAILED", FORM, |c| {
        first_event(c, formed_from, 3, is_failed).is_some()
    });
    let (failed_seen, failed_event) = first_event(&cluster, formed_from, 3, is_failed).unwrap();

    // It exits by itself, with the status, after the delay.
    let exit = loop {
        cluster.pump(Duration::from_millis(5));
        if let Some(exit) = cluster.fleet.exit_status(3).unwrap() {
            break exit;
        }
        assert!(
            failed_seen.elapsed() < Duration::from_secs(10),
            "C3 still runs 10 s after failing itself\n{}",
            cluster.transcript.join("\n")
        );
    };
    let exited = Instant::now();
    let exited_after = exited.duration_since(failed_seen);
    cluster.pump(Duration::from_millis(200));
    assert_eq!(exit.code(), Some(i32::from(EXIT_STATUS)), "{exit:?}");
    let limit = Duration::from_millis(FAILED_EXIT_DELAY_MS) + EXIT_MARGIN;
    assert!(
        exited_after <= limit,
        "C3 exited {exited_after:?} after failing (limit {limit:?})"
    );
    check_it_said_why(&cluster, formed_from, &failed_event);

    // Restarted as systemd restarts it: the same id and configuration, RestartSec later.
    std::thread::sleep(restart_sec.saturating_sub(exited.elapsed()));
    cluster.status.remove(&3);
    let restarted_from = cluster.events.len();
    let restarted = Instant::now();
    let (_, _control) = cluster
        .fleet
        .start_controller_piped(3, "C3#1", &["--json-events"])
        .unwrap();
    cluster.wait_for("C3 back as Tertiary", FORM, |c| c.steady_with(3, T));
    let (back_seen, _) = first_event(&cluster, restarted_from, 3, |e| {
        e.status().is_some_and(|s| {
            s.report.phase == Phase::Steady
                && s.report.role == T
                && s.report.strength == Some(rl_layer::core::Strength(10))
        })
    })
    .unwrap();
    let back_after = back_seen.duration_since(restarted);
    println!(
        "C3 exited {exited_after:?} after failing (delay {FAILED_EXIT_DELAY_MS} ms); restarted \
         after RestartSec={restart_sec:?}, steady Tertiary {back_after:?} after its start"
    );
    assert!(
        back_after <= BACK_WITHIN,
        "C3 back as Tertiary {back_after:?} after its restart"
    );
    cluster.wait_for("P=1 S=2 T=3 again", FORM, |c| {
        c.steady_with(1, P) && c.steady_with(2, S) && c.steady_with(3, T)
    });
    check_the_others_kept_their_roles(&cluster, formed_from);
}

/// Before it exited: the `stopped` event with the reason, the FAILED LEDs, and the log lines
/// that say why and with which status.
fn check_it_said_why(cluster: &Cluster, from: usize, failed: &EventLine) {
    let (_, stopped) = first_event(cluster, from, 3, |e| {
        matches!(e.event, Event::Stopped { .. })
    })
    .expect("a stopped event from C3");
    assert_eq!(
        stopped.event,
        Event::Stopped {
            reason: Some(FailureCause::Outvoted),
            disagreed_with: vec![1, 2],
            exit_status: Some(EXIT_STATUS),
        }
    );
    assert_eq!(stopped.incarnation, failed.incarnation);
    let waited_ms = stopped.t_ms - failed.t_ms;
    assert!(
        waited_ms >= FAILED_EXIT_DELAY_MS,
        "stopped {waited_ms} ms after failing, before the configured delay"
    );
    let leds = cluster.events[from..]
        .iter()
        .filter(|(_, e)| e.id == 3 && e.incarnation == failed.incarnation)
        .filter_map(|(_, e)| match &e.event {
            Event::Leds { leds } => Some(leds.clone()),
            _ => None,
        })
        .next_back();
    assert!(
        leds.as_deref().is_some_and(|l| l.ends_with("own:red]")),
        "the LEDs C3 showed last: {leds:?}"
    );
    let log: Vec<&str> = cluster.lines_from("C3!").collect();
    let says = |words: &str| log.iter().any(|line| line.contains(words));
    assert!(
        says(&format!(
            "C3 voted itself FAILED: outvoted by C1, C2 (they voted P=1 S=2 T=-, it voted \
             P=1 S=2 T=3); exits in {FAILED_EXIT_DELAY_MS} ms with status {EXIT_STATUS} to be \
             restarted"
        )),
        "C3's log:\n{}",
        log.join("\n")
    );
    assert!(
        says(&format!(
            "rl: C3 voted itself FAILED: outvoted by C1, C2 (they voted P=1 S=2 T=-, it voted \
             P=1 S=2 T=3); exits with status {EXIT_STATUS} to be restarted"
        )),
        "C3's log:\n{}",
        log.join("\n")
    );
}

/// From the formation on, C1 commanded and reported only as Primary and C2 only as
/// Secondary.
fn check_the_others_kept_their_roles(cluster: &Cluster, from: usize) {
    for (_, line) in &cluster.events[from..] {
        let expected = match line.id {
            1 => P,
            2 => S,
            _ => continue,
        };
        let role = match &line.event {
            Event::Output { role, .. } => *role,
            Event::Status { status } => status.report.role,
            _ => continue,
        };
        assert_eq!(role, expected, "C{} left its role: {line:?}", line.id);
    }
}
