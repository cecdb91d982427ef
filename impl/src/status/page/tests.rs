use super::*;
use rl_layer::core::types::{Assignment, Holder, Phase, Role};
use rl_layer::core::Heartbeat;
use rl_layer::leds::LedColor::{Green as G, Off as O, Red as R};
use rl_layer::wire::ControllerAlarm;

fn hb(id: ControllerId, role: Option<Role>, ranked: &[ControllerId]) -> Heartbeat {
    let agreed = Assignment::from_ranked(ranked.iter().map(|&id| Holder { id, incarnation: 0 }));
    Heartbeat {
        id,
        incarnation: 0,
        phase: Phase::Steady,
        role,
        strength: role.map(Role::strength),
        agreed: Some(agreed),
        vote: Some(agreed),
        epoch: 1,
        provisional: false,
        established_strength: role.map(Role::strength),
        took_over_from: None,
    }
}

fn lost(reporter: ControllerId, about: ControllerId) -> ControllerAlarm {
    ControllerAlarm {
        reporter,
        reporter_incarnation: 0,
        about,
        about_incarnation: None,
        reason: AlarmReason::Lost,
        raised: true,
    }
}

fn three_steady(board: &mut Board, now: u64) {
    board.heartbeat(hb(1, Some(Role::Primary), &[1, 2, 3]), now);
    board.heartbeat(hb(2, Some(Role::Secondary), &[1, 2, 3]), now);
    board.heartbeat(hb(3, Some(Role::Tertiary), &[1, 2, 3]), now);
}

#[test]
fn leds_follow_roles_and_the_alarms_each_controller_raised() {
    let mut board = Board::default();
    three_steady(&mut board, 0);
    let view = board.view(100, 500);
    assert_eq!(leds_of(&view, 1), Some([G, O, O, G]));
    assert_eq!(leds_of(&view, 2), Some([O, G, O, G]));
    assert_eq!(leds_of(&view, 3), Some([O, O, G, G]));

    // C1 is lost; C2 has raised the alarm, C3 not yet: only C2's LED1 is red.
    board.alarm(&lost(2, 1), Some(1));
    board.heartbeat(hb(2, Some(Role::Secondary), &[1, 2, 3]), 700);
    board.heartbeat(hb(3, Some(Role::Tertiary), &[1, 2, 3]), 700);
    let view = board.view(700, 500);
    assert_eq!(
        leds_of(&view, 1),
        None,
        "a lost controller's LEDs are unknown"
    );
    assert_eq!(leds_of(&view, 2), Some([R, G, O, G]));
    assert_eq!(leds_of(&view, 3), Some([O, O, G, G]));

    // After the re-vote: C2 Primary, C3 Secondary, the vacated Tertiary red.
    board.alarm(&lost(3, 1), Some(2));
    board.heartbeat(hb(2, Some(Role::Primary), &[2, 3]), 900);
    board.heartbeat(hb(3, Some(Role::Secondary), &[2, 3]), 900);
    let view = board.view(900, 500);
    assert_eq!(leds_of(&view, 2), Some([G, O, R, G]));
    assert_eq!(leds_of(&view, 3), Some([O, G, R, G]));
}

#[test]
fn an_impostor_alarm_lights_no_led() {
    let mut board = Board::default();
    three_steady(&mut board, 0);
    let mut alarm = lost(2, 1);
    alarm.reason = AlarmReason::Impostor;
    board.alarm(&alarm, None);
    assert_eq!(leds_of(&board.view(10, 500), 2), Some([O, G, O, G]));
}

#[test]
fn an_input_alarm_a_controller_raised_about_itself_is_in_the_metrics_by_its_reason() {
    let mut board = Board::for_group("nav");
    three_steady(&mut board, 0);
    let mut alarm = lost(1, 1);
    alarm.reason = AlarmReason::InputDisagrees;
    board.alarm(&alarm, None);
    let view = board.view(10, 500);
    let text = metrics::render(&[(&view, &Watch::default())]);
    let line = "rl_controller_alarm{group=\"nav\",about=\"1\",reason=\"input_disagrees\"} 1";
    assert!(text.lines().any(|l| l == line), "no {line:?} in\n{text}");
    let json = serde_json::to_string(&view).expect("the view serializes");
    assert!(json.contains("\"reason\":\"input_disagrees\""), "{json}");
}

#[test]
fn the_watch_counts_commander_changes_and_the_gap() {
    let mut board = Board::default();
    let mut watch = Watch::default();
    three_steady(&mut board, 0);
    watch.follow(&board, 0, 500, 1_000, true);
    assert_eq!(
        watch.commander(),
        Some(Commander {
            id: 1,
            strength: rl_layer::core::Strength(30)
        })
    );
    assert_eq!(
        watch.commander_changes(),
        0,
        "the first commander is no change"
    );
    // C1 falls silent after its heartbeat at 100; C2 commands on.
    board.heartbeat(hb(1, Some(Role::Primary), &[1, 2, 3]), 100);
    for now in [300, 500, 601, 700] {
        board.heartbeat(hb(2, Some(Role::Secondary), &[1, 2, 3]), now);
        watch.follow(&board, now, 500, 1_000 + now, true);
    }
    assert_eq!(
        watch.commander(),
        Some(Commander {
            id: 2,
            strength: rl_layer::core::Strength(20)
        })
    );
    assert_eq!(watch.commander_changes(), 1);
    assert_eq!(watch.last_gap_ms(), Some(501));
    let live = watch.live(&board.view(700, 500), 1_700);
    assert_eq!(live.recent_commander_changes[0].from, Some(1));
    assert_eq!(live.recent_commander_changes[0].to, Some(2));
}

#[test]
fn metrics_are_the_text_format() {
    let mut board = Board::for_group("nav");
    let mut watch = Watch::default();
    three_steady(&mut board, 0);
    watch.heartbeats([1, 1, 2]);
    board.alarm(&lost(2, 3), None);
    let text = metrics::render(&[(&board.view(10, 500), &watch)]);
    for line in [
        "# TYPE rl_strength gauge",
        "rl_strength{group=\"nav\",controller=\"1\"} 30",
        "rl_strength{group=\"nav\",controller=\"3\"} 10",
        "rl_role{group=\"nav\",controller=\"2\",role=\"secondary\"} 1",
        "rl_role{group=\"nav\",controller=\"2\",role=\"primary\"} 0",
        "rl_alive{group=\"nav\",controller=\"3\"} 1",
        "# TYPE rl_heartbeats_seen_total counter",
        "rl_heartbeats_seen_total{group=\"nav\",controller=\"1\"} 2",
        "rl_controller_alarm{group=\"nav\",about=\"3\",reason=\"lost\"} 1",
        "rl_commander_changes_total{group=\"nav\"} 0",
    ] {
        assert!(text.lines().any(|l| l == line), "no {line:?} in\n{text}");
    }
    for line in text.lines().filter(|l| !l.starts_with('#')) {
        assert!(line.starts_with("rl_"), "{line}");
    }
}

#[test]
fn a_silent_controller_exports_no_role_and_no_strength() {
    let mut board = Board::default();
    three_steady(&mut board, 0);
    // C1 falls silent after 0; C2 and C3 go on, C2 now Primary.
    for now in [300, 500, 601] {
        board.heartbeat(hb(2, Some(Role::Primary), &[2, 3]), now);
        board.heartbeat(hb(3, Some(Role::Secondary), &[2, 3]), now);
    }
    let text = metrics::render(&[(&board.view(601, 500), &Watch::default())]);
    let lines: Vec<&str> = text.lines().collect();
    assert!(
        lines.contains(&"rl_alive{group=\"\",controller=\"1\"} 0"),
        "{text}"
    );
    assert!(
        lines.contains(&"rl_role{group=\"\",controller=\"2\",role=\"primary\"} 1"),
        "{text}"
    );
    assert!(
        lines.contains(&"rl_strength{group=\"\",controller=\"2\"} 30"),
        "{text}"
    );
    for line in &lines {
        assert!(
            !(line.starts_with("rl_role{group=\"\",controller=\"1\"")
                || line.starts_with("rl_strength{group=\"\",controller=\"1\"")),
            "the silent C1 still exports {line:?}:\n{text}"
        );
    }
}

#[test]
fn answers_by_path() {
    let idle = Watch::default();
    let unnamed = Board::default().view(0, 500);
    let mut nav = Board::for_group("nav");
    three_steady(&mut nav, 0);
    let nav = nav.view(10, 500);
    let snapshot = Snapshot::of(&[(&unnamed, &idle), (&nav, &idle)], "", 0);
    let get = |path: &str| {
        answer(
            &http::Request {
                head_only: false,
                path: path.into(),
            },
            &snapshot,
        )
    };
    assert_eq!(get("/").status, 200);
    assert_eq!(
        get("/status.json").body,
        br#"{"group":"","controllers":[],"alarms":[],"network_alarms":[]}"#,
        "the configuration's group, as before there were several"
    );
    let groups: serde_json::Value =
        serde_json::from_slice(&get("/groups.json").body).expect("/groups.json is JSON");
    assert_eq!(groups[0], serde_json::to_value(&unnamed).unwrap());
    assert_eq!(groups[1], serde_json::to_value(&nav).unwrap());
    assert_eq!(groups.as_array().map(Vec::len), Some(2));
    let live: serde_json::Value =
        serde_json::from_slice(&get("/live.json").body).expect("/live.json is JSON");
    assert_eq!(live["groups"][1]["status"]["group"], "nav");
    assert_eq!(live["groups"][1]["leds"][0]["leds"][0], "green");
    assert_eq!(get("/metrics").content_type, metrics::CONTENT_TYPE);
    assert_eq!(get("/nope").status, 404);
    assert_eq!(get("/../etc/passwd").status, 404);
}

#[test]
fn metrics_of_several_groups_describe_each_family_once() {
    let mut nav = Board::for_group("nav");
    let mut act = Board::for_group("act");
    three_steady(&mut nav, 0);
    three_steady(&mut act, 0);
    // act's C1 is lost: C2 raised the alarm and commands.
    act.alarm(&lost(2, 1), None);
    act.heartbeat(hb(2, Some(Role::Primary), &[2, 3]), 700);
    act.heartbeat(hb(3, Some(Role::Secondary), &[2, 3]), 700);
    nav.heartbeat(hb(1, Some(Role::Primary), &[1, 2, 3]), 700);
    let (mut nav_watch, mut act_watch) = (Watch::default(), Watch::default());
    nav_watch.heartbeats([1, 1, 2]);
    act_watch.heartbeats([2]);
    nav_watch.follow(&nav, 700, 500, 0, true);
    act_watch.follow(&act, 700, 500, 0, true);
    let (nav_view, act_view) = (nav.view(700, 500), act.view(700, 500));
    let text = metrics::render(&[(&act_view, &act_watch), (&nav_view, &nav_watch)]);

    let families: Vec<&str> = text
        .lines()
        .filter_map(|l| l.strip_prefix("# TYPE "))
        .filter_map(|l| l.split(' ').next())
        .collect();
    let unique: std::collections::BTreeSet<&str> = families.iter().copied().collect();
    assert_eq!(
        families.len(),
        unique.len(),
        "a TYPE line repeated:\n{text}"
    );
    assert_eq!(families.len(), 12, "{text}");
    for family in &families {
        let helps = text
            .lines()
            .filter(|l| l.starts_with(&format!("# HELP {family} ")))
            .count();
        assert_eq!(helps, 1, "{family}'s HELP\n{text}");
        // A family's samples follow its TYPE line, before the next family's HELP.
        let type_at = text.find(&format!("# TYPE {family} ")).unwrap_or(0);
        let block_end = text[type_at..]
            .find("\n# HELP ")
            .map_or(text.len(), |end| type_at + end);
        let outside = text[..type_at]
            .lines()
            .chain(text[block_end..].lines())
            .filter(|l| l.starts_with(&format!("{family}{{")))
            .count();
        assert_eq!(
            outside, 0,
            "{family}'s samples are not all under its TYPE\n{text}"
        );
    }
    for line in [
        "rl_role{group=\"nav\",controller=\"1\",role=\"primary\"} 1",
        "rl_role{group=\"act\",controller=\"2\",role=\"primary\"} 1",
        "rl_alive{group=\"act\",controller=\"1\"} 0",
        "rl_alive{group=\"nav\",controller=\"1\"} 1",
        "rl_heartbeats_seen_total{group=\"nav\",controller=\"1\"} 2",
        "rl_heartbeats_seen_total{group=\"act\",controller=\"2\"} 1",
        "rl_controller_alarm{group=\"act\",about=\"1\",reason=\"lost\"} 1",
        "rl_commander{group=\"nav\"} 1",
        "rl_commander{group=\"act\"} 2",
        "rl_commander_changes_total{group=\"act\"} 0",
        "rl_commander_changes_total{group=\"nav\"} 0",
    ] {
        assert!(text.lines().any(|l| l == line), "no {line:?} in\n{text}");
    }
    assert!(
        !text.contains("rl_controller_alarm{group=\"nav\""),
        "nav raised no alarm\n{text}"
    );
}

#[test]
fn incarnations_reach_the_page_exactly() {
    // Two incarnations 1 apart above 2^53: as JavaScript numbers they would be one.
    let mut board = Board::default();
    let mut first = hb(1, Some(Role::Primary), &[1, 2]);
    first.incarnation = 117_671_640_260_879_741;
    let mut second = hb(2, Some(Role::Secondary), &[1, 2]);
    second.incarnation = 117_671_640_260_879_742;
    board.heartbeat(first, 0);
    board.heartbeat(second, 0);
    let live = Watch::default().live(&board.view(10, 500), 1_000);
    let json = serde_json::to_value(&live).expect("a live view serializes");
    assert_eq!(json["incarnations"]["1"], "117671640260879741");
    assert_eq!(json["incarnations"]["2"], "117671640260879742");
}
