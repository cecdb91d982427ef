//! The configuration's unit tests: defaults, parsing, every validation rule broken once.

use super::*;
use std::time::Duration;

fn parse(text: &str) -> Result<Config, ConfigError> {
    Config::from_toml_str(text, "rl.toml")
}

/// The error for `text`, which must fail, as the CLI would print it.
fn error_of(text: &str) -> (Option<String>, String) {
    let error = parse(text).unwrap_err();
    (error.field().map(str::to_string), error.to_string())
}

#[test]
fn defaults_are_valid_and_match_the_paper() {
    let config = Config::default();
    config.validate().unwrap();
    assert_eq!(config.timing.heartbeat_period_ms, 250);
    assert_eq!(config.timing.dead_after_rounds(), 2);
    assert_eq!(config.timing.window_rounds(), 40);
    assert_eq!(config.timing.rounds().minority_grace_rounds(), 3);
    assert_eq!(config.timing.command_deadline(), Duration::from_millis(100));
    assert_eq!(
        config.timing.failed_exit_delay(),
        Duration::ZERO,
        "exits at once"
    );
    assert_eq!(config.dds.domain, 53);
}

#[test]
fn failed_exit_delay_parses_and_is_bounded() {
    let config = parse("[timing]\nfailed_exit_delay_ms = 1500\n").unwrap();
    assert_eq!(config.timing.failed_exit_delay_ms, 1500);
    assert_eq!(
        config.timing.failed_exit_delay(),
        Duration::from_millis(1500)
    );
    assert_eq!(
        config.timing,
        Timing {
            failed_exit_delay_ms: 1500,
            ..Timing::default()
        },
        "the other timing fields keep their defaults"
    );
    let longest = parse("[timing]\nfailed_exit_delay_ms = 3600000\n").unwrap();
    assert_eq!(longest.timing.failed_exit_delay_ms, DURATION_MS_MAX);

    let (field, message) = error_of("[timing]\nfailed_exit_delay_ms = 3600001\n");
    assert_eq!(field.as_deref(), Some("timing.failed_exit_delay_ms"));
    assert_eq!(
        message,
        "rl.toml: timing.failed_exit_delay_ms = 3600001: must be at most 3600000 ms (one hour)"
    );
    let (field, message) = error_of("[timing]\nfailed_exit_delay_ms = -5\n");
    assert_eq!(field.as_deref(), Some("timing.failed_exit_delay_ms"));
    assert!(
        message.starts_with("rl.toml:2:24: timing.failed_exit_delay_ms: "),
        "{message}"
    );
    let (field, message) = error_of("[timing]\nfailed_exit_delay_ms = \"soon\"\n");
    assert_eq!(field.as_deref(), Some("timing.failed_exit_delay_ms"));
    assert!(message.contains("invalid type: string"), "{message}");
}

#[test]
fn empty_file_is_the_default() {
    assert_eq!(parse("").unwrap(), Config::default());
    assert_eq!(parse("# nothing\n\n").unwrap(), Config::default());
    assert_eq!(parse("[timing]\n[leds]\n").unwrap(), Config::default());
}

#[test]
fn partial_file_keeps_other_defaults() {
    let config = parse("[timing]\nheartbeat_period_ms = 100\npeer_deadline_ms = 300\n").unwrap();
    assert_eq!(config.timing.heartbeat_period_ms, 100);
    assert_eq!(config.timing.peer_deadline_ms, 300);
    assert_eq!(config.timing.init_window_ms, 10_000);
    assert_eq!(config.timing.dead_after_rounds(), 3);
    assert_eq!(config.timing.window_rounds(), 100);
    assert_eq!(config.timing.rounds().minority_grace_rounds(), 4);
    assert_eq!(config.tracker, Tracker::default());
}

#[test]
fn round_trip_through_toml() {
    let mut config = Config::default();
    config.timing.heartbeat_period_ms = 100;
    config.timing.peer_deadline_ms = 400;
    config.dds.domain = 7;
    config.dds.camera_topic = "Square".into();
    config.tracker.color = "RED".into();
    config.tracker.aperiodic = AperiodicPolicy::PrimaryOnly;
    config.leds.backend = LedBackend::Gpio;
    config.leds.pins = [[1, 2], [3, 4], [5, 6], [7, 8]];
    let text = config.to_toml_string().unwrap();
    assert_eq!(parse(&text).unwrap(), config);
    let defaults = Config::default().to_toml_string().unwrap();
    assert_eq!(parse(&defaults).unwrap(), Config::default());
}

#[test]
fn example_file_is_the_defaults() {
    let text = include_str!("../../../rl.toml.example");
    assert_eq!(parse(text).unwrap(), Config::default());
    // Uncommenting every field must still give the defaults: the example says them all.
    let uncommented: String = text
        .lines()
        .map(|line| {
            line.strip_prefix("# ")
                .filter(|setting| {
                    setting.split_once(" = ").is_some_and(|(key, _)| {
                        key.chars().all(|c| c.is_ascii_lowercase() || c == '_')
                    })
                })
                .unwrap_or(line)
        })
        .collect::<Vec<_>>()
        .join("\n");
    assert_eq!(parse(&uncommented).unwrap(), Config::default());
    let default_text = Config::default().to_toml_string().unwrap();
    for line in default_text.lines().filter(|l| l.contains(" = ")) {
        let key = line.split(" = ").next().unwrap();
        assert!(
            uncommented
                .lines()
                .any(|l| l.starts_with(&format!("{key} = "))),
            "rl.toml.example lacks {key}"
        );
    }
}

#[test]
fn load_reads_a_file_and_names_it() {
    let dir = std::env::temp_dir().join(format!("rl-config-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("rl.toml");
    std::fs::write(&path, "[dds]\ndomain = 9\n").unwrap();
    assert_eq!(Config::load(&path).unwrap().dds.domain, 9);
    std::fs::write(&path, "[dds]\ndomain = 999\n").unwrap();
    let message = Config::load(&path).unwrap_err().to_string();
    assert!(message.starts_with(&format!("{}: dds.domain = 999: ", path.display())));
    let missing = dir.join("missing.toml");
    let error = Config::load(&missing).unwrap_err();
    assert!(matches!(error, ConfigError::Read { .. }));
    assert!(error
        .to_string()
        .starts_with(&format!("{}: cannot read", missing.display())));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_brief_example_message() {
    let (field, message) = error_of("[timing]\npeer_deadline_ms = 300\n");
    assert_eq!(field.as_deref(), Some("timing.peer_deadline_ms"));
    assert_eq!(
        message,
        "rl.toml: timing.peer_deadline_ms = 300: must be a whole number of heartbeat \
         periods (250 ms) and at least 2 of them"
    );
}

#[test]
fn parse_errors_name_the_field_and_place() {
    let (field, message) = error_of("timin = 3\n");
    assert_eq!(field.as_deref(), Some("timin"));
    assert_eq!(
        message,
        "rl.toml:1:1: unknown field `timin`, expected one of `architecture`, `timing`, `dds`, `tracker`, `leds`, `networks`, `security`, `duplex`, `pair`"
    );

    let (field, message) = error_of("[timing]\nheartbeat = 250\n");
    assert_eq!(field.as_deref(), Some("timing.heartbeat"));
    assert!(
        message.starts_with("rl.toml:2:1: unknown field `timing.heartbeat`, expected one of"),
        "{message}"
    );

    let (field, message) = error_of("[timin]\nheartbeat_period_ms = 250\n");
    assert_eq!(field.as_deref(), Some("timin"));
    assert!(
        message.starts_with("rl.toml:1:2: unknown field `timin`"),
        "{message}"
    );

    let (field, message) = error_of("[timing]\nheartbeat_period_ms = \"fast\"\n");
    assert_eq!(field.as_deref(), Some("timing.heartbeat_period_ms"));
    assert!(
        message.starts_with("rl.toml:2:23: timing.heartbeat_period_ms: invalid type: string"),
        "{message}"
    );

    let (field, message) = error_of("[dds]\ndomain = -1\n");
    assert_eq!(field.as_deref(), Some("dds.domain"));
    assert!(
        message.starts_with("rl.toml:2:10: dds.domain: "),
        "{message}"
    );

    let (field, message) = error_of("[tracker]\naperiodic = \"sometimes\"\n");
    assert_eq!(field.as_deref(), Some("tracker.aperiodic"));
    assert!(message.contains("unknown variant `sometimes`"), "{message}");

    let (field, message) = error_of("[leds]\npins = [[1, 2], [3, 4], [5, 6]]\n");
    assert_eq!(field.as_deref(), Some("leds.pins"));
    assert!(message.starts_with("rl.toml:2:8: leds.pins: "), "{message}");

    let (field, message) = error_of("[timing\n");
    assert_eq!(field, None);
    assert_eq!(
        message,
        "rl.toml:1:8: invalid table header; expected `.`, `]`"
    );
}

/// Each rule, broken once: (file text, field named, words the message must contain).
const RULE_BREAKS: &[(&str, &str, &str)] = &[
    (
        "[timing]\nheartbeat_period_ms = 9",
        "timing.heartbeat_period_ms",
        "between 10 and 10000",
    ),
    (
        "[timing]\nheartbeat_period_ms = 10001",
        "timing.heartbeat_period_ms",
        "between 10 and 10000",
    ),
    (
        "[timing]\npeer_deadline_ms = 250",
        "timing.peer_deadline_ms",
        "at least 2 of them",
    ),
    (
        "[timing]\npeer_deadline_ms = 600",
        "timing.peer_deadline_ms",
        "whole number",
    ),
    (
        "[timing]\npeer_deadline_ms = 0",
        "timing.peer_deadline_ms",
        "at least 2",
    ),
    (
        "[timing]\npeer_deadline_ms = 3600250",
        "timing.peer_deadline_ms",
        "at most 3600000",
    ),
    (
        "[timing]\ninit_window_ms = 10100",
        "timing.init_window_ms",
        "whole number",
    ),
    (
        "[timing]\ninit_window_ms = 250",
        "timing.init_window_ms",
        "at least timing.peer_deadline_ms (500 ms)",
    ),
    (
        "[timing]\ncommand_deadline_ms = 0\ncommand_republish_ms = 0",
        "timing.command_deadline_ms",
        "at least 1",
    ),
    (
        "[timing]\ncommand_republish_ms = 0",
        "timing.command_republish_ms",
        "at least 1 ms",
    ),
    (
        "[timing]\ncommand_republish_ms = 100",
        "timing.command_republish_ms",
        "less than timing.command_deadline_ms (100 ms)",
    ),
    (
        "[timing]\nfailed_exit_delay_ms = 3600001",
        "timing.failed_exit_delay_ms",
        "at most 3600000",
    ),
    (
        "[timing]\ncommand_deadline_ms = 10",
        "timing.command_republish_ms",
        "less than timing.command_deadline_ms (10 ms)",
    ),
    ("[dds]\ndomain = 233", "dds.domain", "at most 232"),
    (
        "[dds]\nheartbeat_topic = \"\"",
        "dds.heartbeat_topic",
        "non-empty",
    ),
    (
        "[dds]\nvote_topic = \"rl vote\"",
        "dds.vote_topic",
        "without whitespace",
    ),
    (
        "[dds]\ncontroller_alarm_topic = \"a\\tb\"",
        "dds.controller_alarm_topic",
        "without whitespace",
    ),
    (
        "[dds]\nnetwork_alarm_topic = \" \"",
        "dds.network_alarm_topic",
        "non-empty",
    ),
    (
        "[dds]\ncommand_topic = \"\"",
        "dds.command_topic",
        "non-empty",
    ),
    (
        "[dds]\ncamera_topic = \"Circle \"",
        "dds.camera_topic",
        "without whitespace",
    ),
    (
        "[dds]\ncamera_topic = \"rl/vote\"",
        "dds.camera_topic",
        "must differ from dds.vote_topic",
    ),
    (
        "[dds]\nros_namespace = \"rl\"",
        "dds.ros_namespace",
        "absolute ROS 2 namespace",
    ),
    (
        "[dds]\nros_namespace = \"/rl/\"",
        "dds.ros_namespace",
        "ROS 2 namespace",
    ),
    (
        "[dds]\nros_namespace = \"/1rl\"",
        "dds.ros_namespace",
        "ROS 2 namespace",
    ),
    ("[dds]\ngroup = \"nav/a\"", "dds.group", "letters, digits"),
    (
        "[dds]\ngroup = \"1nav\"",
        "dds.group",
        "not starting with a digit",
    ),
    (
        "[dds]\ngroup = \"nav unit\"",
        "dds.group",
        "letters, digits",
    ),
    (
        "[tracker]\ncolor = \"\"",
        "tracker.color",
        "uppercase letters",
    ),
    (
        "[tracker]\ncolor = \"yellow\"",
        "tracker.color",
        "uppercase letters",
    ),
    (
        "[tracker]\ncolor = \"RED' OR 1=1\"",
        "tracker.color",
        "uppercase letters",
    ),
    (
        "[tracker]\nservo_frequency_hz = 0",
        "tracker.servo_frequency_hz",
        "between 1 and 1000",
    ),
    (
        "[tracker]\nservo_frequency_hz = 1001",
        "tracker.servo_frequency_hz",
        "between 1 and 1000",
    ),
    (
        "[tracker]\nodd_limit = 101",
        "tracker.odd_limit",
        "at most 100",
    ),
    ("[leds]\nchip = \"\"", "leds.chip", "GPIO character device"),
    (
        "[leds]\npins = [[1, 2], [3, 4], [5, 6], [7, 1]]",
        "leds.pins",
        "pin 1 is used by LED1 and LED4",
    ),
    (
        "[leds]\npins = [[1, 2], [3, 3], [5, 6], [7, 8]]",
        "leds.pins",
        "pin 3 is used twice by LED2",
    ),
];

#[test]
fn every_rule_is_enforced_with_the_field_named() {
    for (text, field, words) in RULE_BREAKS {
        let error = parse(text).unwrap_err();
        assert!(
            matches!(error, ConfigError::Invalid { .. }),
            "{text}: {error}"
        );
        assert_eq!(error.field(), Some(*field), "{text}");
        let message = error.to_string();
        assert!(
            message.starts_with(&format!("rl.toml: {field} = ")),
            "{message}"
        );
        assert!(message.contains(words), "{text}: {message} lacks {words:?}");
    }
}

#[test]
fn boundary_values_are_accepted() {
    for text in [
        "[timing]\nheartbeat_period_ms = 10\npeer_deadline_ms = 20\ninit_window_ms = 30\n\
         command_deadline_ms = 2\ncommand_republish_ms = 1",
        "[timing]\nheartbeat_period_ms = 10000\npeer_deadline_ms = 20000\ninit_window_ms = 30000",
        "[timing]\npeer_deadline_ms = 3599750\ninit_window_ms = 3600000",
        "[dds]\ndomain = 232",
        "[dds]\ndomain = 0\nros_namespace = \"/\"",
        "[dds]\nros_namespace = \"/robots/_rl_1\"",
        "[tracker]\ncolor = \"Y\"\nservo_frequency_hz = 1",
        "[tracker]\nservo_frequency_hz = 1000",
    ] {
        if let Err(error) = parse(text) {
            panic!("{text:?} rejected: {error}");
        }
    }
    let config = parse("[timing]\npeer_deadline_ms = 3500000\ninit_window_ms = 3600000").unwrap();
    assert_eq!(config.timing.dead_after_rounds(), 14_000);
    assert_eq!(config.timing.window_rounds(), 14_400);
}

#[test]
fn networks_are_addresses_or_interfaces_both_or_neither() {
    let config = parse("[networks]\na = \"10.201.1.2\"\nb = \"eth1\"").unwrap();
    assert_eq!(
        config.networks.pair(),
        Some((
            NetworkName::Address("10.201.1.2".parse().unwrap()),
            NetworkName::Interface("eth1".into())
        ))
    );
    assert_eq!(Config::default().networks.pair(), None);
    assert!(!Config::default().networks.configured());
    for (text, field, rule) in [
        ("[networks]\na = \"eth0\"", "networks.b", "must be set too"),
        ("[networks]\nb = \"eth1\"", "networks.a", "must be set too"),
        (
            "[networks]\na = \"eth0\"\nb = \"eth0\"",
            "networks.b",
            "must differ",
        ),
        (
            "[networks]\na = \"10.0.0.300\"\nb = \"eth1\"",
            "networks.a",
            "IPv4 address",
        ),
        (
            "[networks]\na = \"eth0\"\nb = \"a name far too long\"",
            "networks.b",
            "interface name",
        ),
        (
            "[networks]\nheartbeat_period_ms = 5",
            "networks.heartbeat_period_ms",
            "10..=10000",
        ),
        (
            "[networks]\ndeadline_periods = 0",
            "networks.deadline_periods",
            "1..=100",
        ),
        (
            "[dds]\ndomain = 231\n[networks]\na = \"eth0\"\nb = \"eth1\"",
            "dds.domain",
            "next two domains",
        ),
    ] {
        let (got_field, message) = error_of(text);
        assert_eq!(got_field.as_deref(), Some(field), "{text}: {message}");
        assert!(message.contains(rule), "{text}: {message}");
    }
}

#[test]
fn security_names_its_field() {
    let config = parse("[security]\nkeystore = \"/etc/rl/keys\"");
    if cfg!(feature = "security") {
        let config = config.unwrap();
        assert!(config.security.enabled());
        assert!(!config.security.open_device_topics);
    } else {
        let message = config.unwrap_err().to_string();
        assert!(
            message.contains("security.keystore") && message.contains("`security` feature"),
            "{message}"
        );
    }
    assert!(!Config::default().security.enabled());
    let (field, message) = error_of("[security]\nopen_device_topics = true");
    assert_eq!(
        field.as_deref(),
        Some("security.open_device_topics"),
        "{message}"
    );
    assert!(message.contains("security.keystore set"), "{message}");
}

#[test]
fn a_group_names_rls_topics_and_the_ros_namespace_and_nothing_else() {
    let plain = crate::config::Dds::default();
    assert_eq!(plain.grouped(), plain, "no group: the names as configured");
    let nav = parse("[dds]\ngroup = \"nav\"")
        .expect("a valid group")
        .dds
        .grouped();
    assert_eq!(nav.heartbeat_topic, "rl/nav/controller_heartbeat");
    assert_eq!(nav.vote_topic, "rl/nav/vote");
    assert_eq!(nav.controller_alarm_topic, "rl/nav/controller_alarm");
    assert_eq!(nav.network_alarm_topic, "rl/nav/network_alarm");
    assert_eq!(nav.network_heartbeat_topic, "rl/nav/network_heartbeat");
    assert_eq!(nav.ros_namespace, "/rl/nav");
    // The application's topics are its own.
    assert_eq!(nav.command_topic, plain.command_topic);
    assert_eq!(nav.voted_command_topic, plain.voted_command_topic);
    assert_eq!(nav.camera_topic, plain.camera_topic);
    let flat = parse("[dds]\ngroup = \"g2\"\nvote_topic = \"votes\"\nros_namespace = \"/\"")
        .expect("valid")
        .dds
        .grouped();
    assert_eq!(flat.vote_topic, "g2/votes");
    assert_eq!(flat.ros_namespace, "/g2");
    assert!(flat.validate().is_ok(), "grouped names are valid names");
}

#[test]
fn a_heartbeat_topic_names_its_group_and_nothing_else_does() {
    let plain = crate::config::Dds::default();
    for group in ["", "nav", "act_2", "_x"] {
        let topic = plain.of_group(group).heartbeat_topic;
        assert_eq!(
            plain.group_of_heartbeat_topic(&topic).as_deref(),
            Some(group),
            "{topic}"
        );
    }
    for topic in [
        "rl/vote",
        "rl/nav/vote",
        "rl/a/b/controller_heartbeat",
        "rl/1nav/controller_heartbeat",
        "rl//controller_heartbeat",
        "other/nav/controller_heartbeat",
        "rl/nav/controller_heartbeat/x",
    ] {
        assert_eq!(plain.group_of_heartbeat_topic(topic), None, "{topic}");
    }
    // A heartbeat topic without a path: the group goes in front.
    let flat = parse("[dds]\nheartbeat_topic = \"beats\"")
        .expect("valid")
        .dds;
    assert_eq!(flat.of_group("g").heartbeat_topic, "g/beats");
    assert_eq!(
        flat.group_of_heartbeat_topic("g/beats").as_deref(),
        Some("g")
    );
    assert_eq!(flat.group_of_heartbeat_topic("beats").as_deref(), Some(""));
    assert_eq!(flat.group_of_heartbeat_topic("g/h/beats"), None);
}

#[test]
fn the_voted_command_topic_follows_the_command_topic_unless_named() {
    assert_eq!(
        Config::default().dds.voted_topic_name(),
        "pixy/servo_control_voted"
    );
    let act = parse("[dds]\ngroup = \"act\"\ncommand_topic = \"act/servo\"").unwrap();
    assert_eq!(act.dds.grouped().voted_topic_name(), "act/servo_voted");
    let named = parse("[dds]\nvoted_command_topic = \"votes/servo\"").unwrap();
    assert_eq!(named.dds.voted_topic_name(), "votes/servo");
    let clash = parse("[dds]\nvoted_command_topic = \"Circle\"").unwrap_err();
    assert!(clash.to_string().contains("dds.camera_topic"), "{clash}");
}
