//! The table `rl status` prints without `--json`: one table per redundancy group, each under
//! a `group NAME` header (`group (unnamed)` for the group without a name), in the order given
//! (`rl status` gives them sorted by name). Text only: the views come from the boards.

use super::view::StatusView;

/// How the table names the group without a name (`dds.group = ""`).
pub const UNNAMED_GROUP: &str = "(unnamed)";

/// The tables of several groups, one after the other with a blank line between.
pub fn render_tables(views: &[StatusView]) -> String {
    views
        .iter()
        .map(render_table)
        .collect::<Vec<_>>()
        .join("\n")
}

/// The table of one group: its header, a line per controller, then its alarms.
pub fn render_table(view: &StatusView) -> String {
    let group = if view.group.is_empty() {
        UNNAMED_GROUP
    } else {
        &view.group
    };
    let mut out = format!("group {group}\n");
    out.push_str("ID  PHASE         ROLE       STRENGTH  AGREED              HEARD\n");
    for view in &view.controllers {
        let c = &view.report;
        let role = c.role.map(|r| r.name()).unwrap_or("-");
        let strength = c
            .strength
            .map(|s| s.to_string())
            .unwrap_or_else(|| "-".into());
        let heard = if view.alive {
            format!("{} ms ago", view.last_heard_ms)
        } else {
            format!("LOST ({} ms)", view.last_heard_ms)
        };
        out.push_str(&format!(
            "C{:<2} {:<13} {:<10} {:<9} {:<19} {}\n",
            c.id,
            c.phase.name(),
            role,
            strength,
            c.agreed.map_or("-".to_string(), |a| a.to_string()),
            heard
        ));
    }
    render_alarms(view, &mut out);
    out
}

/// The controller and network alarm lines of `view`.
fn render_alarms(view: &StatusView, out: &mut String) {
    if view.alarms.is_empty() {
        out.push_str("alarms: none\n");
    }
    for a in &view.alarms {
        let by: Vec<String> = a.raised_by.iter().map(|id| format!("C{id}")).collect();
        let since = a.since_ms.map_or(String::new(), |ms| {
            format!("; since {} UTC", clock_time(ms))
        });
        out.push_str(&format!(
            "ALARM C{} {:?} (raised by {}{since})\n",
            a.about,
            a.reason,
            by.join(", ")
        ));
    }
    if view.network_alarms.is_empty() {
        out.push_str("network alarms: none\n");
    }
    for a in &view.network_alarms {
        let by: Vec<String> = a.raised_by.iter().map(|id| format!("C{id}")).collect();
        let subject = match a.controller {
            None => format!("network {}", a.network),
            Some(id) => format!("C{id}'s transceiver on network {}", a.network),
        };
        out.push_str(&format!(
            "NETWORK ALARM {subject}: {} ({}; raised by {})\n",
            a.cause,
            a.certainty.name(),
            by.join(", ")
        ));
    }
}

/// `HH:MM:SS` of a Unix time in milliseconds (UTC).
fn clock_time(unix_ms: u64) -> String {
    let seconds = (unix_ms / 1000) % 86_400;
    format!(
        "{:02}:{:02}:{:02}",
        seconds / 3600,
        (seconds / 60) % 60,
        seconds % 60
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::status::Board;
    use rl_layer::core::network::{AlarmSubject, Network};
    use rl_layer::core::types::{AlarmReason, Assignment, Holder, Phase, Role};
    use rl_layer::core::Heartbeat;
    use rl_layer::wire::{Certainty, ControllerAlarm, NetworkAlarm};

    fn primary(id: u8) -> Heartbeat {
        let agreed = Assignment::from_ranked([Holder { id, incarnation: 0 }]);
        Heartbeat {
            id,
            incarnation: 0,
            phase: Phase::Steady,
            role: Some(Role::Primary),
            strength: Some(Role::Primary.strength()),
            agreed: Some(agreed),
            vote: Some(agreed),
            epoch: 1,
            provisional: false,
            established_strength: Some(Role::Primary.strength()),
            took_over_from: None,
        }
    }

    #[test]
    fn alarms_show_who_raised_them_and_since_when() {
        let mut board = Board::default();
        let lost = |reporter, since| {
            let alarm = ControllerAlarm {
                reporter,
                reporter_incarnation: 0,
                about: 1,
                about_incarnation: None,
                reason: AlarmReason::Lost,
                raised: true,
            };
            (alarm, Some(since))
        };
        assert!(render_table(&board.view(0, 500)).contains("alarms: none"));
        for (alarm, since) in [lost(2, 5_000), lost(3, 3_000)] {
            board.alarm(&alarm, since);
        }
        board.network_alarm(&NetworkAlarm {
            reporter: 1,
            reporter_incarnation: 0,
            subject: AlarmSubject::Network(Network::B),
            raised: Some(Certainty::Concluded),
            cause: "network B failed".into(),
        });
        let table = render_table(&board.view(0, 500));
        assert!(
            table.contains("ALARM C1 Lost (raised by C2, C3; since 00:00:03 UTC)"),
            "{table}"
        );
        assert!(
            table.contains("NETWORK ALARM network B: network B failed (concluded; raised by C1)"),
            "{table}"
        );
    }

    #[test]
    fn each_group_has_its_table_under_its_header() {
        let mut unnamed = Board::default();
        unnamed.heartbeat(primary(1), 0);
        let mut nav = Board::for_group("nav");
        nav.heartbeat(primary(2), 0);
        let text = render_tables(&[unnamed.view(10, 500), nav.view(10, 500)]);
        let headers: Vec<&str> = text.lines().filter(|l| l.starts_with("group ")).collect();
        assert_eq!(headers, ["group (unnamed)", "group nav"], "{text}");
        let (first, second) = text.split_once("group nav\n").expect("nav's header");
        assert!(first.contains("C1 ") && !first.contains("C2 "), "{text}");
        assert!(second.contains("C2 ") && !second.contains("C1 "), "{text}");
    }
}
