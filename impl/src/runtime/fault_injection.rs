//! Test-only fault injection (feature `fault-injection`): heartbeats from the peers named on
//! stdin are dropped on arrival, as if the network lost them one way, each drop logged as a
//! `heartbeat_dropped` event (with `--json-events`); `stall-voting-loop <ms>`
//! blocks the voting loop once for that long, as a hung loop would (the watchdog test).

use std::collections::BTreeSet;
use std::io::BufRead;
use std::sync::Mutex;
use std::time::Duration;

static DROPPED: Mutex<BTreeSet<u8>> = Mutex::new(BTreeSet::new());
static STALL: Mutex<Option<Duration>> = Mutex::new(None);

/// Blocks the calling (voting) thread if a stall was asked for.
pub fn stall() {
    let stall = STALL.lock().unwrap_or_else(|e| e.into_inner()).take();
    if let Some(duration) = stall {
        tracing::warn!("fault injection: voting loop stalled for {duration:?}");
        std::thread::sleep(duration);
    }
}

pub fn dropped(from: u8) -> bool {
    DROPPED
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .contains(&from)
}

/// Reads `drop-heartbeats-from <id>`, `accept-heartbeats-from <id>` and
/// `stall-voting-loop <ms>` lines.
pub fn listen_on_stdin() {
    let _ = std::thread::Builder::new()
        .name("rl-fault-injection".into())
        .spawn(|| {
            for line in std::io::stdin().lock().lines().map_while(Result::ok) {
                let mut words = line.split_whitespace();
                let (Some(verb), Some(id)) = (words.next(), words.next()) else {
                    continue;
                };
                if verb == "stall-voting-loop" {
                    match id.parse::<u64>() {
                        Ok(ms) => {
                            *STALL.lock().unwrap_or_else(|e| e.into_inner()) =
                                Some(Duration::from_millis(ms));
                        }
                        Err(_) => tracing::warn!("fault injection: bad duration in {line:?}"),
                    }
                    continue;
                }
                let Ok(id) = id.parse::<u8>() else {
                    tracing::warn!("fault injection: bad id in {line:?}");
                    continue;
                };
                let mut dropped = DROPPED.lock().unwrap_or_else(|e| e.into_inner());
                match verb {
                    "drop-heartbeats-from" => {
                        dropped.insert(id);
                    }
                    "accept-heartbeats-from" => {
                        dropped.remove(&id);
                    }
                    _ => tracing::warn!("fault injection: unknown command {line:?}"),
                }
                tracing::info!("fault injection: dropping heartbeats from {dropped:?}");
            }
        });
}
