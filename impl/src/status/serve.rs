//! `rl status --serve`'s loop: every group's board kept fresh, each group's [`Watch`]
//! (heartbeat counts, commander changes) following its own board, and every answer
//! re-rendered into the [`Snapshot`] the HTTP server ([`super::page`]) serves, until a signal.

use super::page::{self, unix_now_ms, Snapshot, Watch};
use super::{GroupBoards, StatusView};
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};

/// How often the snapshot is re-rendered: the page polls every 250 ms, so its lag stays small.
const PUBLISH_EVERY_MS: u64 = 50;

/// Serves `boards` on `addr` until `stop`. A group's commander changes count once its board
/// has listened for `listen_ms` (before, the strongest heard is only the first to arrive).
pub fn serve(
    addr: &str,
    mut boards: GroupBoards,
    alive_within_ms: u64,
    listen_ms: u64,
    stop: &AtomicBool,
) -> Result<(), crate::Error> {
    let published = page::start(addr)?;
    let mut watches: BTreeMap<String, Watch> = BTreeMap::new();
    let unwatched = Watch::default();
    let mut next_publish_ms = 0;
    while !stop.load(Ordering::SeqCst) {
        std::thread::sleep(std::time::Duration::from_millis(10));
        for (group, heard) in boards.update() {
            let watch = watches.entry(group).or_default();
            watch.heartbeats(heard.iter().map(|h| h.id));
        }
        let now = boards.now_ms();
        if now < next_publish_ms {
            continue;
        }
        next_publish_ms = now + PUBLISH_EVERY_MS;
        let unix_ms = unix_now_ms();
        for board in boards.boards() {
            let settled = boards.heard_out(board.group(), now, listen_ms);
            let watch = watches.entry(board.group().to_string()).or_default();
            watch.follow(board, now, alive_within_ms, unix_ms, settled);
        }
        let views = boards.views(now, alive_within_ms);
        let groups = with_watches(&views, &watches, &unwatched);
        let snapshot = Snapshot::of(&groups, &boards.status_group(), unix_ms);
        *published.lock().unwrap_or_else(|e| e.into_inner()) = snapshot;
    }
    Ok(())
}

/// Each view with its group's watch (`unwatched` for a group not watched yet).
fn with_watches<'a>(
    views: &'a [StatusView],
    watches: &'a BTreeMap<String, Watch>,
    unwatched: &'a Watch,
) -> Vec<(&'a StatusView, &'a Watch)> {
    views
        .iter()
        .map(|view| (view, watches.get(&view.group).unwrap_or(unwatched)))
        .collect()
}
