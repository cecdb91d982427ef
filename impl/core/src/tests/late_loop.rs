//! A loop that fell behind: one round end for the boundaries it missed, and the record of it.

use super::*;

fn missed(commands: &[Command]) -> Vec<u64> {
    commands
        .iter()
        .filter_map(|c| match c {
            Command::RoundEndsMissed { rounds } => Some(*rounds),
            _ => None,
        })
        .collect()
}

/// Fires every timer due at `now_ms`, as a loop that wakes then does.
fn wake(core: &mut Core, now_ms: u64) -> Vec<Command> {
    let mut out = Vec::new();
    while let Some(timer) = core.due_timer(now_ms) {
        out.extend(core.step(Input::Timer(timer), now_ms));
    }
    out
}

#[test]
fn a_round_end_run_rounds_late_names_the_round_ends_it_stands_for() {
    let mut c = formed_c(3);
    assert_eq!(missed(&advance(&mut c, 1000)), Vec::<u64>::new());
    // Late within its own round (the boundary of 1250 ended at 1320): none missed.
    assert_eq!(missed(&wake(&mut c, 1320)), Vec::<u64>::new());
    // The loop sleeps to 2071: the boundaries of 1500, 1750 and 2000 passed, one round end
    // runs for them, standing for two more. The next is due at the next boundary.
    assert_eq!(c.due_timer(2071), Some(Timer::RoundEnd));
    assert_eq!(missed(&wake(&mut c, 2071)), vec![2]);
    assert_ne!(c.due_timer(2249), Some(Timer::RoundEnd));
    assert_eq!(c.due_timer(2250), Some(Timer::RoundEnd));
    assert_eq!(
        missed(&wake(&mut c, 2250)),
        Vec::<u64>::new(),
        "on time again"
    );
}
