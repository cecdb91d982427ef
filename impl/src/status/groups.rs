//! Which redundancy groups `rl status` shows and their boards: [`Selection`] (every group on
//! the domain, or only those named with `--group`) and [`GroupBoards`], one
//! [`Board`] and [`BoardFeed`] per group shown, all on the
//! status process's one DDS session and one clock. Groups appear as discovery finds their
//! controllers' heartbeat writers (`Session::discovered_groups`, re-checked every
//! [`DISCOVERY_EVERY_MS`]); a group once shown stays shown, its controllers then lost.

use super::{Board, BoardFeed, StatusView};
use rl_layer::core::Heartbeat;
use rl_layer::dds::Session;
use std::collections::{BTreeMap, BTreeSet};
use std::time::Instant;

/// How often `rl status` asks discovery which groups are on the domain.
pub const DISCOVERY_EVERY_MS: u64 = 500;

/// Which groups `rl status` shows.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Selection {
    /// The configuration's group (`configured`) and every group discovered on the domain.
    Every { configured: String },
    /// Only these (`--group`), shown from the start whether discovered or not.
    Only(BTreeSet<String>),
}

impl Selection {
    /// The groups shown from the start: the configuration's, or the named ones.
    pub fn initial(&self) -> BTreeSet<String> {
        match self {
            Selection::Every { configured } => BTreeSet::from([configured.clone()]),
            Selection::Only(names) => names.clone(),
        }
    }

    /// The group `/status.json` shows: the configuration's when it is shown, else the first
    /// named one (by name).
    pub fn status_group(&self) -> String {
        match self {
            Selection::Every { configured } => configured.clone(),
            Selection::Only(names) => names.first().cloned().unwrap_or_default(),
        }
    }

    /// The discovered groups to open a board for now: those selected, not shown yet and not
    /// refused before.
    pub fn to_open(
        &self,
        discovered: &BTreeSet<String>,
        shown: &BTreeSet<String>,
        refused: &BTreeSet<String>,
    ) -> Vec<String> {
        let selected = |group: &String| match self {
            Selection::Every { .. } => true,
            Selection::Only(names) => names.contains(group),
        };
        discovered
            .iter()
            .filter(|group| selected(group) && !shown.contains(*group) && !refused.contains(*group))
            .cloned()
            .collect()
    }
}

/// One group shown: its board, its readers, and when its board opened (board time).
struct ShownGroup {
    board: Board,
    feed: BoardFeed,
    opened_ms: u64,
}

/// The boards of every group shown, by group name (so in name order, the unnamed group first).
pub struct GroupBoards {
    // Before the session: the readers go before their participant.
    shown: BTreeMap<String, ShownGroup>,
    /// Discovered groups whose readers could not be created (DDS Security may refuse another
    /// group's topics): reported once, not retried.
    refused: BTreeSet<String>,
    selection: Selection,
    session: Session,
    started: Instant,
    next_discovery_ms: u64,
}

impl GroupBoards {
    /// The boards of `selection`'s initial groups on `session`; their readers are created now
    /// (an error ends `rl status`, as it did for its one group).
    pub fn open(session: Session, selection: Selection) -> Result<GroupBoards, crate::Error> {
        let mut shown = BTreeMap::new();
        for group in selection.initial() {
            let feed = BoardFeed::for_group(&session, &group)?;
            let board = Board::for_group(&group);
            shown.insert(
                group,
                ShownGroup {
                    board,
                    feed,
                    opened_ms: 0,
                },
            );
        }
        Ok(GroupBoards {
            shown,
            refused: BTreeSet::new(),
            selection,
            session,
            started: Instant::now(),
            next_discovery_ms: 0,
        })
    }

    /// Milliseconds since the boards opened: the clock of every board.
    pub fn now_ms(&self) -> u64 {
        u64::try_from(self.started.elapsed().as_millis()).unwrap_or(u64::MAX)
    }

    /// Opens the boards of groups discovered since the last look (at most every
    /// [`DISCOVERY_EVERY_MS`]) and takes in what has arrived; returns the heartbeats taken
    /// per group.
    pub fn update(&mut self) -> BTreeMap<String, Vec<Heartbeat>> {
        let now_ms = self.now_ms();
        if now_ms >= self.next_discovery_ms {
            self.next_discovery_ms = now_ms + DISCOVERY_EVERY_MS;
            self.open_discovered(now_ms);
        }
        self.shown
            .iter_mut()
            .map(|(group, shown)| (group.clone(), shown.feed.update(&mut shown.board, now_ms)))
            .collect()
    }

    /// Opens a board for every newly discovered group selected.
    fn open_discovered(&mut self, now_ms: u64) {
        let discovered = self.session.discovered_groups();
        let shown: BTreeSet<String> = self.shown.keys().cloned().collect();
        for group in self.selection.to_open(&discovered, &shown, &self.refused) {
            match BoardFeed::for_group(&self.session, &group) {
                Ok(feed) => {
                    let board = Board::for_group(&group);
                    let opened_ms = now_ms;
                    self.shown.insert(
                        group,
                        ShownGroup {
                            board,
                            feed,
                            opened_ms,
                        },
                    );
                }
                Err(error) => {
                    eprintln!("rl status: not showing group {group:?}: {error}");
                    self.refused.insert(group);
                }
            }
        }
    }

    /// Every group's board, by group name.
    pub fn boards(&self) -> impl Iterator<Item = &Board> {
        self.shown.values().map(|shown| &shown.board)
    }

    /// Whether group `group`'s board has been open for `listen_ms` at `now_ms` (long enough to
    /// have heard every live controller of it).
    pub fn heard_out(&self, group: &str, now_ms: u64, listen_ms: u64) -> bool {
        self.shown
            .get(group)
            .is_some_and(|shown| now_ms >= shown.opened_ms + listen_ms)
    }

    /// Every group's view at `now_ms`, by group name.
    pub fn views(&self, now_ms: u64, alive_within_ms: u64) -> Vec<StatusView> {
        self.boards()
            .map(|board| board.view(now_ms, alive_within_ms))
            .collect()
    }

    /// The group `/status.json` shows ([`Selection::status_group`]).
    pub fn status_group(&self) -> String {
        self.selection.status_group()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn set(names: &[&str]) -> BTreeSet<String> {
        names.iter().map(|n| n.to_string()).collect()
    }

    #[test]
    fn every_group_discovered_is_shown_once() {
        let every = Selection::Every {
            configured: "nav".into(),
        };
        assert_eq!(every.initial(), set(&["nav"]));
        assert_eq!(every.status_group(), "nav");
        let discovered = set(&["", "act", "nav"]);
        assert_eq!(
            every.to_open(&discovered, &set(&["nav"]), &set(&[])),
            ["", "act"],
            "the unnamed group and act are new; nav is shown already"
        );
        assert_eq!(
            every.to_open(&discovered, &set(&["", "nav"]), &set(&["act"])),
            Vec::<String>::new(),
            "a refused group is not retried"
        );
    }

    #[test]
    fn named_groups_only_are_shown() {
        let only = Selection::Only(set(&["act", "nav"]));
        assert_eq!(only.initial(), set(&["act", "nav"]));
        assert_eq!(only.status_group(), "act", "the first named");
        assert_eq!(
            only.to_open(&set(&["", "act", "ship"]), &set(&["nav"]), &set(&[])),
            ["act"]
        );
    }
}
