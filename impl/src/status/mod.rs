//! `rl status`: what every controller says about itself, read from the DDS topics (their
//! heartbeats, the controller alarm topic and the network alarm topic), as a live table or
//! one JSON object. Network alarms are transient local: a status started after an alarm was
//! raised still shows it, for as long as its reporter runs.
//!
//! The board is pure (samples and times in, a view out) so the demo and the benchmarks use it
//! too; only [`run`] touches DDS. [`page`] is the same board as a live page over HTTP
//! (`rl status --serve`).

pub mod page;

use rl_layer::core::network::{AlarmSubject, Network};
use rl_layer::core::types::{AlarmReason, ControllerId};
use rl_layer::core::{Heartbeat, SelfReport};
use rl_layer::wire::{Certainty, ControllerAlarm, NetworkAlarm};
use serde::Serialize;
use std::collections::BTreeMap;

/// Arguments of `rl status`.
#[derive(clap::Args, Debug)]
pub struct StatusArgs {
    /// Print one JSON object per refresh instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Listen for a while (1 s and three heartbeat periods; 3 s more with DDS Security), print
    /// once and exit.
    #[arg(long)]
    pub once: bool,
    /// Configuration file (domain, topic names, heartbeat period).
    #[arg(long, value_name = "PATH")]
    pub config: Option<std::path::PathBuf>,
    /// DDS domain id (overrides the configuration).
    #[arg(long, value_name = "D")]
    pub domain: Option<u16>,
    /// Serve the live view over HTTP instead of printing: a page with every controller's
    /// LEDs, /status.json (the --json object) and /metrics (Prometheus). ADDR defaults to
    /// 127.0.0.1:8053, this host only; bind 0.0.0.0:8053 or a LAN address to reach it from
    /// the LAN (no authentication: a trusted network only).
    #[arg(long, value_name = "ADDR", num_args = 0..=1,
          default_missing_value = self::page::DEFAULT_ADDR,
          conflicts_with_all = ["json", "once"])]
    pub serve: Option<String>,
}

/// One controller as the board last heard it: its last self-report (the heartbeat's fields,
/// flattened: id, incarnation, phase, role, strength, agreed, vote) and how long ago.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ControllerView {
    #[serde(flatten)]
    pub report: SelfReport,
    /// Heard within the dead-man deadline.
    pub alive: bool,
    /// Milliseconds since its last heartbeat.
    pub last_heard_ms: u64,
}

/// A raised controller alarm and who raised it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct AlarmView {
    pub about: ControllerId,
    pub reason: AlarmReason,
    pub raised_by: Vec<ControllerId>,
    /// When the first of them raised it (Unix milliseconds, the raising sample's source
    /// timestamp); `null` if no reporter stamped it.
    pub since_ms: Option<u64>,
}

/// A raised network alarm: about `network` as a whole (`controller` null) or controller
/// `controller`'s transceiver on it; how sure and why, as its first reporter says, and who
/// raised it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct NetworkAlarmView {
    pub network: Network,
    pub controller: Option<ControllerId>,
    pub certainty: Certainty,
    pub cause: String,
    pub raised_by: Vec<ControllerId>,
}

/// What `rl status --json` prints.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StatusView {
    /// The redundancy group it shows (`dds.group`; "" for the one group of the domain).
    pub group: String,
    pub controllers: Vec<ControllerView>,
    pub alarms: Vec<AlarmView>,
    pub network_alarms: Vec<NetworkAlarmView>,
}

/// The latest heartbeat per controller and the raised alarms.
#[derive(Clone, Debug, Default)]
pub struct Board {
    /// The redundancy group whose topics feed it.
    group: String,
    heartbeats: BTreeMap<ControllerId, (Heartbeat, u64)>,
    /// (about, reporter, impostor) -> reason, for raised alarms: one protocol alarm per
    /// controller and reporter (Failed replaces Lost), an impostor alarm beside it.
    alarms: BTreeMap<(ControllerId, ControllerId, bool), (AlarmReason, Option<u64>)>,
    /// (subject, reporter) -> how sure and why, for raised network alarms.
    network_alarms: BTreeMap<(AlarmSubject, ControllerId), (Certainty, String)>,
}

impl Board {
    /// An empty board of the redundancy group `group` (`dds.group`).
    pub fn for_group(group: &str) -> Board {
        Board {
            group: group.to_string(),
            ..Board::default()
        }
    }

    pub fn heartbeat(&mut self, heartbeat: Heartbeat, now_ms: u64) {
        self.heartbeats.insert(heartbeat.id, (heartbeat, now_ms));
    }

    /// A controller alarm raised or cleared; `stamped_ms` is when its reporter wrote it (Unix
    /// milliseconds), if known.
    pub fn alarm(&mut self, alarm: &ControllerAlarm, stamped_ms: Option<u64>) {
        let key = (
            alarm.about,
            alarm.reporter,
            alarm.reason == AlarmReason::Impostor,
        );
        if alarm.raised {
            // A republished alarm keeps the time it was first raised.
            let since_ms = self
                .alarms
                .get(&key)
                .map_or(stamped_ms, |(_, since)| *since);
            self.alarms.insert(key, (alarm.reason, since_ms));
        } else {
            self.alarms.remove(&key);
        }
    }

    pub fn network_alarm(&mut self, alarm: &NetworkAlarm) {
        let key = (alarm.subject, alarm.reporter);
        match alarm.raised {
            Some(certainty) => {
                self.network_alarms
                    .insert(key, (certainty, alarm.cause.clone()));
            }
            None => {
                self.network_alarms.remove(&key);
            }
        }
    }

    /// The latest heartbeat of a controller.
    pub fn latest(&self, id: ControllerId) -> Option<&Heartbeat> {
        self.heartbeats.get(&id).map(|(h, _)| h)
    }

    /// When the board took in controller `id`'s last heartbeat (its `now_ms` then).
    pub fn last_heard_ms(&self, id: ControllerId) -> Option<u64> {
        self.heartbeats.get(&id).map(|(_, at)| *at)
    }

    /// The controllers heard within `alive_within_ms`.
    pub fn alive(&self, now_ms: u64, alive_within_ms: u64) -> impl Iterator<Item = &Heartbeat> {
        self.heartbeats
            .values()
            .filter(move |(_, at)| now_ms.saturating_sub(*at) <= alive_within_ms)
            .map(|(h, _)| h)
    }

    /// The live controller commanding at the highest strength (ties: lowest id).
    pub fn commander(&self, now_ms: u64, alive_within_ms: u64) -> Option<&Heartbeat> {
        self.alive(now_ms, alive_within_ms)
            .filter(|h| h.strength.is_some())
            .min_by_key(|h| (std::cmp::Reverse(h.strength), h.id))
    }

    pub fn view(&self, now_ms: u64, alive_within_ms: u64) -> StatusView {
        let controllers = self
            .heartbeats
            .values()
            .map(|(h, at)| {
                let since = now_ms.saturating_sub(*at);
                ControllerView {
                    report: *h,
                    alive: since <= alive_within_ms,
                    last_heard_ms: since,
                }
            })
            .collect();
        let mut alarms: Vec<AlarmView> = Vec::new();
        for (&(about, reporter, _), &(reason, since_ms)) in &self.alarms {
            match alarms
                .iter_mut()
                .find(|a| a.about == about && a.reason == reason)
            {
                Some(view) => {
                    view.raised_by.push(reporter);
                    view.since_ms = match (view.since_ms, since_ms) {
                        (Some(a), Some(b)) => Some(a.min(b)),
                        (a, b) => a.or(b),
                    };
                }
                None => alarms.push(AlarmView {
                    about,
                    reason,
                    raised_by: vec![reporter],
                    since_ms,
                }),
            }
        }
        let mut network_alarms: Vec<NetworkAlarmView> = Vec::new();
        for (&(subject, reporter), (certainty, cause)) in &self.network_alarms {
            let (network, controller) = match subject {
                AlarmSubject::Network(network) => (network, None),
                AlarmSubject::Transceiver {
                    controller,
                    network,
                } => (network, Some(controller)),
            };
            match network_alarms
                .iter_mut()
                .find(|a| a.network == network && a.controller == controller)
            {
                Some(view) => view.raised_by.push(reporter),
                None => network_alarms.push(NetworkAlarmView {
                    network,
                    controller,
                    certainty: *certainty,
                    cause: cause.clone(),
                    raised_by: vec![reporter],
                }),
            }
        }
        StatusView {
            group: self.group.clone(),
            controllers,
            alarms,
            network_alarms,
        }
    }
}

/// The table `rl status` prints.
pub fn render_table(view: &StatusView) -> String {
    let mut out = String::new();
    if !view.group.is_empty() {
        out.push_str(&format!("group {}\n", view.group));
    }
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
    out
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

/// Unix milliseconds of a DDS source timestamp.
fn unix_ms(timestamp: rustdds::Timestamp) -> u64 {
    let ticks = timestamp.to_ticks();
    (ticks >> 32) * 1000 + (((ticks & 0xffff_ffff) * 1000) >> 32)
}

/// Live inputs of the board: the heartbeat and controller alarm readers of one session.
pub struct BoardFeed {
    heartbeats: rl_layer::dds::Reader<rl_layer::wire::HeartbeatSample>,
    alarms: rl_layer::dds::Reader<rl_layer::wire::AlarmSample>,
    network_alarms: rl_layer::dds::Reader<rl_layer::wire::NetworkAlarmSample>,
    /// Heartbeats in a live controller's name from another participant are not shown
    /// (rl_layer::identity).
    identities: rl_layer::identity::Identities,
    started: std::time::Instant,
}

impl BoardFeed {
    pub fn new(session: &rl_layer::dds::Session) -> Result<BoardFeed, crate::Error> {
        let dds = |e: rl_layer::dds::DdsError| crate::Error::dds(e);
        Ok(BoardFeed {
            heartbeats: session.heartbeat_reader().map_err(dds)?,
            alarms: session.alarm_reader().map_err(dds)?,
            network_alarms: session.network_alarm_reader().map_err(dds)?,
            identities: rl_layer::identity::Identities::new(session.timing().peer_deadline_ms),
            started: std::time::Instant::now(),
        })
    }

    /// Milliseconds since the feed started.
    pub fn now_ms(&self) -> u64 {
        self.started.elapsed().as_millis() as u64
    }

    /// Takes in what has arrived; returns the heartbeats (for callers that watch changes).
    pub fn update(&mut self, board: &mut Board) -> Vec<Heartbeat> {
        let now = self.now_ms();
        let mut heartbeats = Vec::new();
        for received in self.heartbeats.take() {
            let from = rl_layer::dds::participant_key(received.writer);
            let admission =
                self.identities
                    .heartbeat(received.value.id, received.value.incarnation, from, now);
            if !matches!(admission, rl_layer::identity::Admission::Impostor { .. }) {
                heartbeats.push(received.value);
            }
        }
        for heartbeat in &heartbeats {
            board.heartbeat(*heartbeat, now);
        }
        for alarm in self.alarms.take() {
            board.alarm(&alarm.value, alarm.source_timestamp.map(unix_ms));
        }
        for alarm in self.network_alarms.take() {
            board.network_alarm(&alarm.value);
        }
        heartbeats
    }
}

/// Runs `rl status`.
pub fn run(args: StatusArgs) -> Result<(), crate::Error> {
    let config = crate::cli::load_config(args.config.as_deref(), args.domain)?;
    let stop = crate::cli::stop_on_signals()?;
    let session = rl_layer::dds::Session::for_config(&config)?;
    let mut feed = BoardFeed::new(&session)?;
    let mut board = Board::for_group(&config.dds.group);
    let period_ms = config.timing.heartbeat_period_ms;
    let alive_within_ms = config.timing.peer_deadline_ms;
    // Discovery plus a few heartbeats: enough to hear every live controller.
    // Secured, discovery first authenticates and exchanges keys with every participant
    // (about 2 s on loopback, docs/security.md): listen that much longer.
    let authentication_ms = if config.security.enabled() { 3000 } else { 0 };
    let listen_ms = 1000 + 3 * period_ms + authentication_ms;
    if let Some(addr) = args.serve {
        return serve(&addr, feed, board, alive_within_ms, listen_ms, &stop);
    }
    let refresh_ms = 500;
    let mut next_print_ms = if args.once { listen_ms } else { refresh_ms };
    loop {
        std::thread::sleep(std::time::Duration::from_millis(20));
        feed.update(&mut board);
        let now = feed.now_ms();
        if now < next_print_ms {
            if stop.load(std::sync::atomic::Ordering::SeqCst) {
                return Ok(());
            }
            continue;
        }
        next_print_ms = now + refresh_ms;
        let view = board.view(now, alive_within_ms);
        if args.json {
            let line = serde_json::to_string(&view)
                .map_err(|e| crate::Error::runtime(format!("status JSON: {e}")))?;
            println!("{line}");
        } else {
            if !args.once {
                // Clear the screen and home the cursor: a live table.
                print!("\x1b[2J\x1b[H");
            }
            print!("{}", render_table(&view));
        }
        use std::io::Write;
        let _ = std::io::stdout().flush();
        if args.once || stop.load(std::sync::atomic::Ordering::SeqCst) {
            return Ok(());
        }
    }
}

/// `rl status --serve`: the board kept fresh and published to the HTTP server
/// ([`self::page`]) until a signal.
fn serve(
    addr: &str,
    mut feed: BoardFeed,
    mut board: Board,
    alive_within_ms: u64,
    listen_ms: u64,
    stop: &std::sync::atomic::AtomicBool,
) -> Result<(), crate::Error> {
    use self::page::{unix_now_ms, Snapshot, Watch};
    let published = self::page::start(addr)?;
    let mut watch = Watch::default();
    // The page polls every 250 ms: a fresh snapshot every 50 ms keeps its lag small.
    let refresh_ms = 50;
    let mut next_publish_ms = 0;
    while !stop.load(std::sync::atomic::Ordering::SeqCst) {
        std::thread::sleep(std::time::Duration::from_millis(10));
        let heard = feed.update(&mut board);
        watch.heartbeats(heard.iter().map(|h| h.id));
        let now = feed.now_ms();
        if now < next_publish_ms {
            continue;
        }
        next_publish_ms = now + refresh_ms;
        let unix_ms = unix_now_ms();
        watch.follow(&board, now, alive_within_ms, unix_ms, now >= listen_ms);
        let snapshot = Snapshot::of(&board.view(now, alive_within_ms), &watch, unix_ms);
        *published.lock().unwrap_or_else(|e| e.into_inner()) = snapshot;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rl_layer::core::types::{Assignment, Holder, Phase, Role};

    fn hb(from: ControllerId, role: Option<Role>) -> Heartbeat {
        let agreed = Assignment::from_ranked([1, 2, 3].map(|id| Holder { id, incarnation: 0 }));
        Heartbeat {
            id: from,
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

    #[test]
    fn the_view_lists_controllers_and_marks_the_silent_ones_lost() {
        let mut board = Board::default();
        board.heartbeat(hb(1, Some(Role::Primary)), 1000);
        board.heartbeat(hb(2, Some(Role::Secondary)), 1500);
        let view = board.view(1700, 500);
        assert_eq!(view.controllers.len(), 2);
        assert!(!view.controllers[0].alive, "700 ms silent > 500 ms");
        assert!(view.controllers[1].alive);
        assert_eq!(board.commander(1700, 500).map(|h| h.id), Some(2));
        let json = serde_json::to_value(&view).unwrap();
        assert_eq!(json["controllers"][1]["role"], "secondary");
        assert_eq!(json["controllers"][1]["strength"], 20);
        let agreed: Assignment = serde_json::from_value(json["controllers"][1]["agreed"].clone())
            .expect("the agreed result reads back as an assignment");
        assert_eq!(agreed.to_string(), "P=1 S=2 T=3");
    }

    #[test]
    fn an_alarm_stays_raised_until_every_reporter_clears_it() {
        let mut board = Board::default();
        let alarm = |reporter, raised| ControllerAlarm {
            reporter,
            reporter_incarnation: 0,
            about: 1,
            about_incarnation: None,
            reason: AlarmReason::Lost,
            raised,
        };
        board.alarm(&alarm(2, true), Some(5_000));
        board.alarm(&alarm(3, true), Some(3_000));
        assert_eq!(board.view(0, 500).alarms[0].raised_by, vec![2, 3]);
        assert_eq!(
            board.view(0, 500).alarms[0].since_ms,
            Some(3_000),
            "the first raise"
        );
        assert!(render_table(&board.view(0, 500)).contains("since 00:00:03 UTC"));
        board.alarm(&alarm(2, false), None);
        assert_eq!(board.view(0, 500).alarms[0].raised_by, vec![3]);
        board.alarm(&alarm(3, false), None);
        assert!(board.view(0, 500).alarms.is_empty());
        assert!(render_table(&board.view(0, 500)).contains("alarms: none"));
    }

    #[test]
    fn network_alarms_are_grouped_by_subject_and_cleared_per_reporter() {
        let mut board = Board::default();
        let alarm = |reporter, subject, raised: Option<Certainty>| NetworkAlarm {
            reporter,
            reporter_incarnation: 0,
            subject,
            raised,
            cause: raised.map_or(String::new(), |_| "network B failed".into()),
        };
        let net_b = AlarmSubject::Network(Network::B);
        let c2_a = AlarmSubject::Transceiver {
            controller: 2,
            network: Network::A,
        };
        board.network_alarm(&alarm(1, net_b, Some(Certainty::Concluded)));
        board.network_alarm(&alarm(3, net_b, Some(Certainty::Concluded)));
        board.network_alarm(&alarm(1, c2_a, Some(Certainty::Suspected)));
        let view = board.view(0, 500);
        assert_eq!(view.network_alarms.len(), 2);
        assert_eq!(view.network_alarms[0].raised_by, vec![1, 3]);
        assert_eq!(view.network_alarms[1].controller, Some(2));
        let table = render_table(&view);
        assert!(
            table.contains(
                "NETWORK ALARM network B: network B failed (concluded; raised by C1, C3)"
            ),
            "{table}"
        );
        let json = serde_json::to_value(&view).unwrap();
        assert_eq!(json["network_alarms"][0]["network"], "B");
        assert_eq!(
            json["network_alarms"][0]["controller"],
            serde_json::Value::Null
        );
        assert_eq!(json["network_alarms"][1]["certainty"], "suspected");
        for reporter in [1, 3] {
            board.network_alarm(&alarm(reporter, net_b, None));
        }
        board.network_alarm(&alarm(1, c2_a, None));
        let view = board.view(0, 500);
        assert!(view.network_alarms.is_empty());
        assert!(render_table(&view).contains("network alarms: none"));
    }
}
