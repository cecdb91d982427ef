//! [`BoardFeed`]: one redundancy group's readers (its heartbeats, controller alarms and network
//! alarms) on the status process's one DDS session, feeding that group's
//! [`Board`]. The configuration's own group reads through the session's own
//! readers; any other group through the library's group readers
//! (`Session::group_heartbeat_reader` and the rest), on the same participant.

use super::Board;
use rl_layer::core::Heartbeat;
use rl_layer::dds::{DdsError, Reader, Session};
use rl_layer::identity::{Admission, Identities};
use rl_layer::wire::{AlarmSample, HeartbeatSample, NetworkAlarmSample};

/// Live inputs of one group's board: its heartbeat and alarm readers.
pub struct BoardFeed {
    heartbeats: Reader<HeartbeatSample>,
    alarms: Reader<AlarmSample>,
    network_alarms: Reader<NetworkAlarmSample>,
    /// Heartbeats in a live controller's name from another participant are not shown
    /// (rl_layer::identity); ids are per group, so each group has its own.
    identities: Identities,
}

impl BoardFeed {
    /// The readers of the session's own group (`dds.group` of its configuration).
    pub fn new(session: &Session) -> Result<BoardFeed, crate::Error> {
        let own = session.config().group.clone();
        BoardFeed::for_group(session, &own)
    }

    /// The readers of group `group` (`""`: the group without a name) on `session`.
    pub fn for_group(session: &Session, group: &str) -> Result<BoardFeed, crate::Error> {
        let dds = |e: DdsError| crate::Error::dds(e);
        let identities = Identities::new(session.timing().peer_deadline_ms);
        if group == session.config().group {
            return Ok(BoardFeed {
                heartbeats: session.heartbeat_reader().map_err(dds)?,
                alarms: session.alarm_reader().map_err(dds)?,
                network_alarms: session.network_alarm_reader().map_err(dds)?,
                identities,
            });
        }
        Ok(BoardFeed {
            heartbeats: session.group_heartbeat_reader(group).map_err(dds)?,
            alarms: session.group_alarm_reader(group).map_err(dds)?,
            network_alarms: session.group_network_alarm_reader(group).map_err(dds)?,
            identities,
        })
    }

    /// Takes in what has arrived, at `now_ms` on the board's clock; returns the heartbeats
    /// taken (for callers that watch changes).
    pub fn update(&mut self, board: &mut Board, now_ms: u64) -> Vec<Heartbeat> {
        let mut heartbeats = Vec::new();
        for received in self.heartbeats.take() {
            let from = rl_layer::dds::participant_key(received.writer);
            let admission = self.identities.heartbeat(
                received.value.id,
                received.value.incarnation,
                from,
                now_ms,
            );
            if !matches!(admission, Admission::Impostor { .. }) {
                heartbeats.push(received.value);
            }
        }
        for heartbeat in &heartbeats {
            board.heartbeat(*heartbeat, now_ms);
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

/// Unix milliseconds of a DDS source timestamp.
fn unix_ms(timestamp: rustdds::Timestamp) -> u64 {
    let ticks = timestamp.to_ticks();
    (ticks >> 32) * 1000 + (((ticks & 0xffff_ffff) * 1000) >> 32)
}
