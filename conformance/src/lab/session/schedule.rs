//! The safety phase's schedule: its applies and heals in time order, and a step deferred
//! until the faults it would overlap have healed (`Session::play`).

/// Orders the safety phase's events by time, a heal before an apply at the same time.
pub(super) fn sort_due(due: &mut [(f64, bool, usize)]) {
    due.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
}

/// Moves step `i`, due to apply at `at_ms`, to just after the last heal of the `active`
/// steps, with every later event of the schedule but those heals moved by as much, so the
/// schedule keeps its spacing.
pub(super) fn defer_after_heals(
    due: &mut Vec<(f64, bool, usize)>,
    at_ms: f64,
    i: usize,
    active: &[usize],
) {
    let last_heal = due
        .iter()
        .filter(|(_, apply, k)| !apply && active.contains(k))
        .map(|(at, ..)| *at)
        .fold(at_ms, f64::max);
    let shift = last_heal - at_ms + 1.0;
    for event in due.iter_mut() {
        let heal_of_active = !event.1 && active.contains(&event.2);
        if !heal_of_active {
            event.0 += shift;
        }
    }
    due.push((at_ms + shift, true, i));
    sort_due(due);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_deferred_step_follows_the_active_heals_and_the_rest_keeps_its_spacing() {
        // Step 0 active until 5000; step 1 due at 3000 (heal 4000) is deferred; step 2 at
        // 6000 (heal 7000) moves by as much.
        let mut due = vec![
            (4000.0, false, 1),
            (5000.0, false, 0),
            (6000.0, true, 2),
            (7000.0, false, 2),
        ];
        defer_after_heals(&mut due, 3000.0, 1, &[0]);
        assert_eq!(
            due,
            vec![
                (5000.0, false, 0),
                (5001.0, true, 1),
                (6001.0, false, 1),
                (8001.0, true, 2),
                (9001.0, false, 2),
            ]
        );
    }
}
