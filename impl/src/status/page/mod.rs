//! `rl status --serve`: the operator's live view over HTTP. The status process keeps a
//! [`Board`] per redundancy group as always; this module adds what the page shows beyond
//! `rl status --json` (each controller's four LEDs, computed here with the same pure functions
//! the controllers drive their LEDs with, each group's actuator commander and its changes,
//! heartbeat counts: a [`Watch`] per group) and serves it:
//!
//! - `/` the live page (HTML, CSS and JS inline, polling `/live.json`), a section per group;
//! - `/live.json` what the page draws ([`PageView`]: a [`LiveView`] per group);
//! - `/status.json` exactly the `rl status --json` object of one group, the configuration's
//!   (as before there were several groups: [`Snapshot::of`]);
//! - `/groups.json` that object for every group shown, an array sorted by group;
//! - `/metrics` the Prometheus text exposition of every group ([`metrics`]).
//!
//! The status process builds a [`Snapshot`] (every answer rendered) a few times a second;
//! connection threads only copy it out, so a slow client never holds the boards.

pub mod http;
pub mod metrics;

use super::{Board, StatusView};
use rl_layer::core::types::{AlarmReason, ControllerId, Strength};
use rl_layer::core::Status;
use rl_layer::leds::LedColor;
use serde::Serialize;
use std::collections::{BTreeMap, VecDeque};
use std::sync::{Arc, Mutex};

/// Where `rl status --serve` listens when no address is given: this host only.
pub const DEFAULT_ADDR: &str = "127.0.0.1:8053";

/// How many commander changes the page lists.
const RECENT_CHANGES: usize = 10;

/// One controller's LEDs as the page shows them.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct LedsView {
    pub id: ControllerId,
    /// `[LED1 Primary, LED2 Secondary, LED3 Tertiary, LED4 own status]`, each `green`, `red`
    /// or `off`; `null` when the controller is not heard (its LEDs are unknown).
    pub leds: Option<[&'static str; 4]>,
}

/// A change of the commanding controller, as the status process sees it from heartbeats.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct CommanderChange {
    /// When the status process saw it (Unix milliseconds).
    pub at_ms: u64,
    pub from: Option<ControllerId>,
    pub to: Option<ControllerId>,
    /// From the previous commander's last heartbeat to the change; `null` at the first.
    pub gap_ms: Option<u64>,
}

/// The commanding controller now.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Commander {
    pub id: ControllerId,
    pub strength: Strength,
}

/// What `/live.json` holds: the status object and what the page adds to it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LiveView {
    pub status: StatusView,
    pub leds: Vec<LedsView>,
    pub commander: Option<Commander>,
    pub commander_changes: u64,
    /// The latest first.
    pub recent_commander_changes: Vec<CommanderChange>,
    /// Heartbeats taken in per controller since the status process started.
    pub heartbeats_seen: BTreeMap<ControllerId, u64>,
    /// Each controller's incarnation as decimal text: it is 64 bits and a JavaScript number
    /// holds 53, so the page would show two incarnations that differ in the low bits as one.
    pub incarnations: BTreeMap<ControllerId, String>,
    /// Unix milliseconds of this view.
    pub now_ms: u64,
}

/// The LEDs controller `id` shows, from its last heartbeat and the controller alarms it has
/// raised (its peers' failures): [`rl_layer::leds::pattern_of`] of the status it would report.
/// Impostor alarms are about forged samples, not failed units: they light nothing.
pub fn leds_of(view: &StatusView, id: ControllerId) -> Option<[LedColor; 4]> {
    let controller = view.controllers.iter().find(|c| c.report.id == id)?;
    if !controller.alive {
        return None;
    }
    let alarms: Vec<(ControllerId, AlarmReason)> = view
        .alarms
        .iter()
        .filter(|a| a.reason != AlarmReason::Impostor && a.raised_by.contains(&id))
        .map(|a| (a.about, a.reason))
        .collect();
    let status = Status {
        report: controller.report,
        sees: Vec::new(),
        failed: Vec::new(),
        alarms,
        duplicate_id_heartbeats: 0,
    };
    Some(rl_layer::leds::pattern_of(&status).0)
}

/// What the status process has watched over time: heartbeat counts and commander changes.
#[derive(Clone, Debug, Default)]
pub struct Watch {
    heartbeats_seen: BTreeMap<ControllerId, u64>,
    /// The commander and when the board last heard it (board milliseconds).
    commander: Option<Commander>,
    commander_last_heard_ms: Option<u64>,
    /// `follow` was called before: the commander it found then is no change.
    followed: bool,
    commander_changes: u64,
    recent: VecDeque<CommanderChange>,
    last_gap_ms: Option<u64>,
}

impl Watch {
    /// Counts heartbeats taken in.
    pub fn heartbeats(&mut self, ids: impl IntoIterator<Item = ControllerId>) {
        for id in ids {
            *self.heartbeats_seen.entry(id).or_default() += 1;
        }
    }

    /// Follows the commander on `board` at `now_ms` (board time); `unix_ms` stamps changes.
    /// Before `settled` (every live controller heard) a new commander is no change: the
    /// strongest heard so far is only the first to arrive.
    pub fn follow(
        &mut self,
        board: &Board,
        now_ms: u64,
        alive_within_ms: u64,
        unix_ms: u64,
        settled: bool,
    ) {
        let now = board
            .commander(now_ms, alive_within_ms)
            .and_then(|h| h.strength.map(|strength| Commander { id: h.id, strength }));
        let first = !self.followed;
        self.followed = true;
        if settled && !first && now.map(|c| c.id) != self.commander.map(|c| c.id) {
            let gap_ms = match (self.commander, self.commander_last_heard_ms) {
                (Some(_), Some(heard)) => Some(now_ms.saturating_sub(heard)),
                _ => None,
            };
            self.commander_changes += 1;
            self.last_gap_ms = gap_ms;
            self.recent.push_front(CommanderChange {
                at_ms: unix_ms,
                from: self.commander.map(|c| c.id),
                to: now.map(|c| c.id),
                gap_ms,
            });
            self.recent.truncate(RECENT_CHANGES);
        }
        self.commander = now;
        self.commander_last_heard_ms = now.and_then(|c| board.last_heard_ms(c.id));
    }

    pub fn commander(&self) -> Option<Commander> {
        self.commander
    }

    pub fn commander_changes(&self) -> u64 {
        self.commander_changes
    }

    pub fn last_gap_ms(&self) -> Option<u64> {
        self.last_gap_ms
    }

    pub fn heartbeats_seen(&self) -> &BTreeMap<ControllerId, u64> {
        &self.heartbeats_seen
    }

    /// The page's view of `view`.
    pub fn live(&self, view: &StatusView, unix_ms: u64) -> LiveView {
        let leds = view
            .controllers
            .iter()
            .map(|c| LedsView {
                id: c.report.id,
                leds: leds_of(view, c.report.id).map(|p| p.map(LedColor::name)),
            })
            .collect();
        LiveView {
            status: view.clone(),
            leds,
            commander: self.commander,
            commander_changes: self.commander_changes,
            recent_commander_changes: self.recent.iter().cloned().collect(),
            heartbeats_seen: self.heartbeats_seen.clone(),
            incarnations: view
                .controllers
                .iter()
                .map(|c| (c.report.id, c.report.incarnation.to_string()))
                .collect(),
            now_ms: unix_ms,
        }
    }
}

/// What `/live.json` holds: what the page draws of every group shown, by group name.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PageView {
    pub groups: Vec<LiveView>,
    /// Unix milliseconds of this view.
    pub now_ms: u64,
}

/// Every answer, rendered: what connection threads copy out.
#[derive(Clone, Debug, Default)]
pub struct Snapshot {
    pub status_json: String,
    pub groups_json: String,
    pub live_json: String,
    pub metrics: String,
}

impl Snapshot {
    /// The answers for `groups` (each group's view and watch, by group name); `/status.json`
    /// shows group `status_group` (an empty view of it if it is not among them).
    pub fn of(groups: &[(&StatusView, &Watch)], status_group: &str, unix_ms: u64) -> Snapshot {
        let views: Vec<&StatusView> = groups.iter().map(|(view, _)| *view).collect();
        let empty = StatusView {
            group: status_group.to_string(),
            controllers: Vec::new(),
            alarms: Vec::new(),
            network_alarms: Vec::new(),
        };
        let status = views
            .iter()
            .find(|view| view.group == status_group)
            .copied()
            .unwrap_or(&empty);
        let page = PageView {
            groups: groups
                .iter()
                .map(|(view, watch)| watch.live(view, unix_ms))
                .collect(),
            now_ms: unix_ms,
        };
        Snapshot {
            status_json: json(status),
            groups_json: json(&views),
            live_json: json(&page),
            metrics: metrics::render(groups),
        }
    }
}

/// `value` as JSON, or an object naming why not.
fn json(value: &impl Serialize) -> String {
    serde_json::to_string(value).unwrap_or_else(|e| error_json(&e))
}

fn error_json(error: &serde_json::Error) -> String {
    serde_json::json!({ "error": error.to_string() }).to_string()
}

/// The page, served as is.
const PAGE_HTML: &str = include_str!("page.html");

/// The answer to `request` from `snapshot`.
pub fn answer(request: &http::Request, snapshot: &Snapshot) -> http::Response {
    const JSON: &str = "application/json";
    match request.path.as_str() {
        "/" | "/index.html" => http::Response::ok("text/html; charset=utf-8", PAGE_HTML),
        "/status.json" => http::Response::ok(JSON, snapshot.status_json.clone()),
        "/groups.json" => http::Response::ok(JSON, snapshot.groups_json.clone()),
        "/live.json" => http::Response::ok(JSON, snapshot.live_json.clone()),
        "/metrics" => http::Response::ok(metrics::CONTENT_TYPE, snapshot.metrics.clone()),
        _ => http::Response::error(404),
    }
}

/// Binds `addr` and serves the snapshot from then on; the caller keeps it fresh.
pub fn start(addr: &str) -> Result<Arc<Mutex<Snapshot>>, crate::Error> {
    let listener = std::net::TcpListener::bind(addr)
        .map_err(|e| crate::Error::runtime(format!("rl status --serve {addr}: {e}")))?;
    let bound = listener
        .local_addr()
        .map_or_else(|_| addr.to_string(), |a| a.to_string());
    let snapshot = Arc::new(Mutex::new(Snapshot::default()));
    let shared = Arc::clone(&snapshot);
    let handler = Arc::new(move |request: &http::Request| {
        let current = shared.lock().unwrap_or_else(|e| e.into_inner()).clone();
        answer(request, &current)
    });
    http::serve(listener, handler)
        .map_err(|e| crate::Error::runtime(format!("starting the HTTP server: {e}")))?;
    eprintln!(
        "rl status: serving http://{bound}/ (/status.json, /groups.json, /live.json, /metrics)"
    );
    Ok(snapshot)
}

/// Unix milliseconds now.
pub fn unix_now_ms() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_millis()).unwrap_or(u64::MAX))
}

#[cfg(test)]
mod tests;
