//! The bounds as promised, in literal figures, and the refusal of a scenario without them.

use super::*;
use crate::lab::faults::Direction;
use crate::lab::scenario;

#[test]
fn the_settle_bound_is_the_models() {
    let model_bound = model::Config::default().settle_within_rounds;
    assert_eq!(SETTLE_ROUNDS, u64::from(model_bound));
}

#[test]
fn the_gap_bounds_come_from_each_readers_deadline() {
    // rl servo: the 100 ms command deadline, the 10 ms republish period and 20 ms.
    assert_eq!(servo_gap_ms(), 130.0);
    // The Connext reader: its 200 ms deadline, the 10 ms republish period and 20 ms.
    assert_eq!(connext_gap_ms(), 230.0);
}

fn changes(fault: Fault) -> OwnerChanges {
    for_fault(&fault).owner_changes
}

#[test]
fn random_loss_up_to_20_percent_moves_nothing_and_40_percent_at_most_once() {
    let p = Target::Primary;
    assert_eq!(changes(Fault::Loss(p, 5)), OwnerChanges::AtMost(0));
    assert_eq!(
        changes(Fault::Loss(Target::Id(3), 20)),
        OwnerChanges::AtMost(0)
    );
    assert_eq!(changes(Fault::Loss(p, 40)), OwnerChanges::AtMost(1));
    assert_eq!(for_fault(&Fault::Loss(p, 20)).two_at_top_ms, 0.0);
}

#[test]
fn a_flapping_or_starved_link_costs_one_change_for_the_whole_episode() {
    let p = Target::Primary;
    assert_eq!(changes(Fault::Flap(p, 7)), OwnerChanges::AtMost(1));
    assert_eq!(changes(Fault::RateLimit(p, 64)), OwnerChanges::AtMost(1));
}

#[test]
fn a_pulled_cable_is_a_restart_one_change_and_never_two_at_top() {
    let unplugged = for_fault(&Fault::Unplug(Target::Primary));
    assert_eq!(unplugged.owner_changes, OwnerChanges::AtMost(1));
    assert_eq!(unplugged.two_at_top_ms, 0.0);
    assert_eq!(unplugged.silent_ms, 0.0);
}

#[test]
fn splits_cost_one_change_unless_the_actuator_is_split_from_the_primary() {
    let p = Target::Primary;
    let partition = |alone, actuator_with_alone| Fault::Partition {
        alone,
        actuator_with_alone,
    };
    assert_eq!(changes(Fault::Cut(p)), OwnerChanges::AtMost(1));
    assert_eq!(
        changes(Fault::OneWay(p, Direction::In)),
        OwnerChanges::AtMost(1)
    );
    assert_eq!(changes(partition(p, false)), OwnerChanges::AtMost(1));
    // Alone with the Primary: the other side's two writers at the heal.
    assert_eq!(changes(partition(p, true)), OwnerChanges::AtMost(2));
    // Alone with another controller: to it at the fault, then those two.
    assert_eq!(
        changes(partition(Target::Id(3), true)),
        OwnerChanges::AtMost(3)
    );
    // A split is one round at top strength: the heartbeat period.
    assert_eq!(for_fault(&Fault::Cut(p)).two_at_top_ms, 250.0);
}

#[test]
fn one_way_loss_allows_the_minority_grace_at_top_strength() {
    // A round for the new votes to reach the outvoted Primary, then 3 rounds of grace.
    let one_way = for_fault(&Fault::OneWay(Target::Primary, Direction::Out));
    assert_eq!(one_way.two_at_top_ms, 1_000.0);
}

#[test]
fn a_lone_controller_that_may_have_no_writer_may_be_silent_for_a_deadline_and_two_rounds() {
    let alone = |target| Fault::Partition {
        alone: target,
        actuator_with_alone: true,
    };
    assert_eq!(for_fault(&alone(Target::Id(2))).silent_ms, 1_000.0);
    assert_eq!(for_fault(&alone(Target::Primary)).silent_ms, 0.0);
    let expected = for_faults(&[Fault::Kill(Target::Id(2)), alone(Target::Id(2))]);
    assert_eq!(
        (expected.servo_gap_ms, expected.connext_gap_ms),
        (1_130.0, 1_230.0)
    );
}

#[test]
fn each_fault_keeps_its_own_bound_in_a_schedule() {
    let expected = for_faults(&[
        Fault::Loss(Target::Id(3), 20),
        Fault::Kill(Target::Primary),
        Fault::Cut(Target::Id(2)),
    ]);
    let bounds: Vec<OwnerChanges> = expected.faults.iter().map(|f| f.owner_changes).collect();
    assert_eq!(
        bounds,
        [
            OwnerChanges::AtMost(0),
            OwnerChanges::AtMost(1),
            OwnerChanges::AtMost(1)
        ]
    );
    // Each split is a round of its own.
    assert_eq!(expected.two_at_top_ms, 250.0);
    assert_eq!(
        (expected.servo_gap_ms, expected.connext_gap_ms),
        (130.0, 230.0)
    );
}

#[test]
fn a_misspelled_scenario_has_no_expectations() {
    let refused = for_scenario("kill-primray", &[Fault::Kill(Target::Primary)]);
    assert_eq!(
        refused,
        Err(UnknownScenario {
            name: "kill-primray".into()
        })
    );
    let why = refused.map(|_| ()).unwrap_err().to_string();
    assert!(why.contains("\"kill-primray\""), "{why}");
}

#[test]
fn every_named_scenario_has_expectations_for_each_of_its_faults() {
    for s in scenario::named() {
        let faults: Vec<Fault> = s.steps.iter().map(|step| step.fault.clone()).collect();
        let expected = for_scenario(&s.name, &faults);
        assert!(expected.is_ok(), "{}: {expected:?}", s.name);
        let count = expected.map_or(0, |e| e.faults.len());
        assert_eq!(count, s.steps.len(), "{}", s.name);
    }
    assert!(for_scenario("random", &scenario::random(1).faults()).is_ok());
}
