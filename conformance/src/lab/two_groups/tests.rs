use super::*;

#[test]
fn the_groups_differ_in_name_topic_and_restart() {
    let [nav, act] = GROUPS;
    assert_ne!(nav.name, act.name);
    assert_eq!(
        nav.config(),
        "[dds]\ngroup = \"nav\"\ncommand_topic = \"nav/servo_control\"\n"
    );
    assert_ne!(nav.command_topic(), act.command_topic());
    // The monitor judge tells the groups' C1s apart by when each comes back.
    assert_ne!(nav.restart_after_ms, act.restart_after_ms);
}

#[test]
fn each_group_is_judged_by_kill_primarys_bounds_and_a_dead_controllers_alarms() {
    let kill = [Fault::Kill(Target::Id(KILLED))];
    let kill_primary = [Fault::Kill(Target::Primary)];
    assert_eq!(
        expect::for_scenario(NAME, &kill),
        expect::for_scenario("kill-primary", &kill_primary)
    );
    let network = network_alarms::for_scenario(NAME);
    let network = network.as_ref();
    assert_eq!(network.map(|n| n.alarms.len()), Some(0));
    assert_eq!(
        network.and_then(|n| n.conclusion_allows),
        Some(rl_layer::core::network::Finding::ControllerDown(KILLED))
    );
    assert_eq!(
        network.map(|n| n.controller_alarms.clone()),
        Some(vec![(2, KILLED), (3, KILLED)])
    );
}

#[test]
fn it_is_in_neither_matrix() {
    assert!(super::super::scenario::named()
        .iter()
        .all(|s| s.name != NAME));
}
