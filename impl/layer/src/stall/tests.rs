//! The loop clock's tests: stalls, stops with and without SIGCONT, a writer's lapses and
//! doubts, each against a clock marked by hand.

use super::*;

#[test]
fn a_gap_of_the_peer_deadline_is_a_stall_and_a_shorter_one_is_not() {
    let clock = LoopClock::new(40, 20);
    assert_eq!(clock.mark(), None);
    assert!(!clock.stalled());
    std::thread::sleep(Duration::from_millis(10));
    assert_eq!(clock.mark(), None, "10 ms is no stall");
    std::thread::sleep(Duration::from_millis(50));
    assert!(
        clock.stalled(),
        "the writer sees the stall before the loop runs"
    );
    let gap = clock.mark().expect("50 ms is a stall");
    assert!(gap >= Duration::from_millis(40));
    assert!(
        clock.stalled(),
        "still stalled until the loop has restarted the core"
    );
    assert!(clock.mark().is_some(), "and the loop still sees it");
    clock.resumed();
    assert!(!clock.stalled(), "running again");
    assert_eq!(clock.mark(), None);
}

/// (The SIGCONT tests are tests/sigcont_stop.rs: a SIGCONT reaches every clock of the
/// process, so they run in a process of their own.)
/// A loaded host's loop lapses runnable: as far as the scheduler's account goes, as busy
/// as a loop that spins.
fn busy_for(time: Duration) {
    let until = Instant::now() + time;
    while Instant::now() < until {
        std::hint::spin_loop();
    }
}

#[test]
fn a_slow_loop_without_a_sigcont_is_no_stall() {
    let clock = LoopClock::new(10_000, 20);
    assert_eq!(clock.mark(), None);
    busy_for(Duration::from_millis(40));
    assert!(!clock.stalled(), "a loaded host's lapse is not a stop");
    clock.wrote(false);
    assert!(
        !clock.stalled_for_writer(clock.restarts()),
        "a writer that wrote within the deadline was not stopped"
    );
    assert_eq!(
        clock.mark(),
        None,
        "after its settling wait, the loop goes on"
    );
    busy_for(Duration::from_millis(40));
    let started = Instant::now();
    assert!(
        !clock.stalled_for_writer(clock.restarts()),
        "a writer that lapsed with the loop writes once the loop has decided"
    );
    assert!(started.elapsed() >= WRITER_WAIT, "it waited for the loop");
}

#[test]
fn a_held_loop_without_a_sigcont_is_a_stall() {
    let clock = LoopClock::new(10_000, 40);
    assert_eq!(clock.mark(), None, "the account's first reading");
    std::thread::sleep(Duration::from_millis(10));
    assert_eq!(
        clock.mark(),
        None,
        "held 10 ms: the actuator did not notice"
    );
    if held::HeldClock::for_this_thread().is_none() {
        return; // no account here: tests/freeze_stop.rs says so where it matters
    }
    // Off every run queue for a command deadline, as a frozen cgroup is.
    std::thread::sleep(Duration::from_millis(60));
    let gap = clock
        .mark()
        .expect("held 60 ms: a stop the actuator noticed");
    assert!(gap >= Duration::from_millis(60), "{gap:?}");
    assert!(clock.stalled(), "stalled until the loop has restarted");
    clock.resumed();
    assert_eq!(clock.mark(), None);
}

#[test]
fn an_owner_whose_commands_lapsed_doubts_itself_until_the_loop_restarts() {
    let clock = LoopClock::new(10_000, 20);
    assert!(
        !clock.owner_lapsed(Duration::from_millis(20)),
        "nothing written yet: no lapse"
    );
    clock.wrote(false);
    busy_for(Duration::from_millis(30));
    assert!(
        !clock.owner_lapsed(Duration::from_millis(20)),
        "a Secondary's old write is no lapse of the Primary it becomes"
    );
    clock.wrote(true);
    assert!(
        !clock.owner_lapsed(Duration::from_millis(20)),
        "written just now"
    );
    busy_for(Duration::from_millis(30));
    assert!(
        clock.owner_lapsed(Duration::from_millis(20)),
        "30 ms without a command: the actuator moved"
    );
    assert!(clock.stalled(), "and every writer of it goes silent");
    clock.wrote(true);
    clock.wrote(false);
    assert!(
        clock.owner_lapsed(Duration::from_millis(20)),
        "a write meanwhile does not lift the doubt"
    );
    let lapse = clock.mark().expect("the loop restarts at its next mark");
    assert!(lapse >= Duration::from_millis(30), "{lapse:?}");
    assert!(clock.stalled(), "until it has restarted");
    clock.resumed();
    assert!(!clock.stalled());
    assert!(
        !clock.owner_lapsed(Duration::from_millis(20)),
        "the new life has no lapse of its own"
    );
    assert_eq!(clock.mark(), None);
    clock.wrote(true);
    clock.holds_no_role();
    busy_for(Duration::from_millis(30));
    assert!(
        !clock.owner_lapsed(Duration::from_millis(20)),
        "silent without a role: no lapse"
    );
    clock.wrote(true);
    clock.not_the_owner();
    busy_for(Duration::from_millis(30));
    assert!(
        !clock.owner_lapsed(Duration::from_millis(20)),
        "silent in another role: no lapse"
    );
}

#[test]
fn a_voted_answer_between_the_owners_commands_hides_no_lapse() {
    let clock = LoopClock::new(10_000, 20);
    clock.wrote(true);
    clock.wrote(false);
    busy_for(Duration::from_millis(30));
    clock.wrote(false);
    assert!(
        clock.owner_lapsed(Duration::from_millis(20)),
        "the owner's commands lapsed 30 ms, its voted answers written all along"
    );
}

#[test]
fn a_writer_that_read_the_last_lifes_status_writes_nothing() {
    let clock = LoopClock::new(10_000, 20);
    clock.wrote(true);
    // The writer takes the restarts, then reads the status (the Primary's) ...
    let restarts_seen = clock.restarts();
    // ... and, before it looks at the clock, the loop restarts, publishes the new life's
    // status and resumes: all within one of the writer's waiting steps.
    busy_for(Duration::from_millis(30));
    assert!(
        clock.owner_lapsed(Duration::from_millis(20)),
        "the owner's commands lapsed"
    );
    assert!(clock.mark().is_some(), "the loop restarts");
    clock.resumed();
    assert_eq!(clock.restarts(), restarts_seen + 1, "counted once");
    assert!(
        clock.stalled_for_writer(restarts_seen),
        "the status it read is the last life's: it writes nothing"
    );
    assert!(
        !clock.stalled_for_writer(clock.restarts()),
        "with the new life's status it may"
    );
}

#[test]
fn a_republishing_owner_doubts_itself_after_half_the_deadline() {
    let deadline = Duration::from_millis(100);
    let ms = Duration::from_millis;
    assert_eq!(owner_lapse_bound(deadline, Some(ms(10))), ms(50));
    assert_eq!(
        owner_lapse_bound(deadline, Some(ms(40))),
        ms(80),
        "two republications"
    );
    assert_eq!(
        owner_lapse_bound(deadline, Some(ms(90))),
        deadline,
        "never past it"
    );
    assert_eq!(owner_lapse_bound(deadline, None), deadline);
}

#[test]
fn incarnations_grow_with_time() {
    assert!(incarnation(2) > incarnation(1));
}
