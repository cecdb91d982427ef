//! The traffic each controller sends and receives, measured where nothing else is counted:
//! each controller is alone in its namespace, so the host side of its two links (one per
//! net) carries exactly its packets. `lab traffic` forms a system under an architecture, lets
//! discovery's burst pass, and reads the links' kernel counters across a fault-free window
//! (docs/architectures.md's traffic row).

use super::error::LabError;
use super::lan::{Lan, Net, Node};
use super::session::{Session, Setup};
use serde::Serialize;
use std::path::Path;
use std::time::{Duration, Instant};

/// After formation, before counting: the discovery of late readers and the first status
/// bursts are over.
const SETTLE_BEFORE_COUNTING: Duration = Duration::from_secs(3);

/// One controller's traffic over the window, both nets together, per second.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ControllerTraffic {
    pub id: u8,
    pub sent_bytes_per_s: f64,
    pub sent_packets_per_s: f64,
    pub received_bytes_per_s: f64,
    pub received_packets_per_s: f64,
}

/// A link's kernel counters, as the host side sees them.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Counters {
    rx_bytes: u64,
    rx_packets: u64,
    tx_bytes: u64,
    tx_packets: u64,
}

/// Forms a system with `setup`, then measures every controller's traffic over `window`.
pub fn measure(setup: &Setup, window: Duration) -> Result<Vec<ControllerTraffic>, LabError> {
    let mut session = Session::start(setup)?;
    session.pump(SETTLE_BEFORE_COUNTING)?;
    let ids = super::architecture::controller_ids(setup.architecture);
    let read_all = |session: &Session| -> Result<Vec<Counters>, LabError> {
        ids.iter()
            .map(|id| node_counters(session.lan(), *id))
            .collect()
    };
    let before = read_all(&session)?;
    let started = Instant::now();
    session.pump(window)?;
    let after = read_all(&session)?;
    let seconds = started.elapsed().as_secs_f64();
    let dead = session.dead();
    session.stop()?;
    if !dead.is_empty() {
        return Err(LabError::Command {
            command: "lab traffic".into(),
            message: format!(
                "a controller stopped during the window: {}",
                dead.join(", ")
            ),
        });
    }
    Ok(ids
        .iter()
        .zip(before.iter().zip(&after))
        .map(|(id, (before, after))| per_second(*id, before, after, seconds))
        .collect())
}

/// The traffic of controller `id` between two readings `seconds` apart. The host side's
/// receive counters are what the controller sent.
fn per_second(id: u8, before: &Counters, after: &Counters, seconds: f64) -> ControllerTraffic {
    let rate = |later: u64, earlier: u64| later.saturating_sub(earlier) as f64 / seconds;
    ControllerTraffic {
        id,
        sent_bytes_per_s: rate(after.rx_bytes, before.rx_bytes),
        sent_packets_per_s: rate(after.rx_packets, before.rx_packets),
        received_bytes_per_s: rate(after.tx_bytes, before.tx_bytes),
        received_packets_per_s: rate(after.tx_packets, before.tx_packets),
    }
}

/// Controller `id`'s two links' counters, added.
fn node_counters(lan: &Lan, id: u8) -> Result<Counters, LabError> {
    let mut total = Counters::default();
    for net in Net::BOTH {
        let link = lan.link(Node::Controller(id), net);
        let dir = Path::new("/sys/class/net").join(&link).join("statistics");
        let read = |name: &str| -> Result<u64, LabError> {
            let path = dir.join(name);
            let text = std::fs::read_to_string(&path).map_err(|e| LabError::output(&path, e))?;
            text.trim().parse().map_err(|_| LabError::Command {
                command: format!("read {}", path.display()),
                message: format!("not a counter: {:?}", text.trim()),
            })
        };
        total.rx_bytes += read("rx_bytes")?;
        total.rx_packets += read("rx_packets")?;
        total.tx_bytes += read("tx_bytes")?;
        total.tx_packets += read("tx_packets")?;
    }
    Ok(total)
}

/// The Markdown table of `traffic` (kB/s and packets/s, sent and received).
pub fn table(traffic: &[ControllerTraffic]) -> String {
    let mut text = String::from(
        "| controller | sent, kB/s | sent, packets/s | received, kB/s | received, packets/s |\n|---|---|---|---|---|\n",
    );
    for t in traffic {
        text.push_str(&format!(
            "| C{} | {:.1} | {:.0} | {:.1} | {:.0} |\n",
            t.id,
            t.sent_bytes_per_s / 1000.0,
            t.sent_packets_per_s,
            t.received_bytes_per_s / 1000.0,
            t.received_packets_per_s
        ));
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn what_the_host_side_received_is_what_the_controller_sent() {
        let before = Counters {
            rx_bytes: 1000,
            rx_packets: 10,
            tx_bytes: 5000,
            tx_packets: 50,
        };
        let after = Counters {
            rx_bytes: 21_000,
            rx_packets: 210,
            tx_bytes: 45_000,
            tx_packets: 450,
        };
        let t = per_second(2, &before, &after, 10.0);
        assert_eq!(t.sent_bytes_per_s, 2000.0);
        assert_eq!(t.sent_packets_per_s, 20.0);
        assert_eq!(t.received_bytes_per_s, 4000.0);
        assert_eq!(t.received_packets_per_s, 40.0);
        assert!(table(&[t]).contains("| C2 | 2.0 | 20 | 4.0 | 40 |"));
    }
}
