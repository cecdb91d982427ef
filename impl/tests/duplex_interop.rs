//! Interop for the simple duplex on DDS domain 177: an RTI Connext reader with the paper's QoS
//! (exclusive ownership, reliable, 200 ms deadline; `tests/interop/connext_reader.py`) follows
//! a duplex's owner as it follows the voting group's (`actuator_switches.rs`): the Primary; the
//! Standby after the Primary's `kill -9`, within the deadline and two re-publish periods; and
//! the Primary again when it returns (the paper's preemption). Two owner changes in all, at
//! the Connext reader and at `rl servo` alike.
//!
//! Ignored by default, as the other Connext tests: it needs PyPI `rticonnextdds-connector`
//! (`.ci/run` installs it).

mod support;

use std::time::{Duration, Instant};
use support::actuators::{
    owner_changes, require_peer, servo_owners, ConnextReader, Life, Lives,
    CONNEXT_LIVELINESS_CHECK_MS, CONNEXT_PACKAGE,
};
use support::Cluster;

const DOMAIN: u16 = 177;
const CONNEXT_DEADLINE_MS: u64 = 200;
const STEP: Duration = Duration::from_secs(30);

struct Duplex {
    cluster: Cluster,
    lives: Lives,
    connext: ConnextReader,
}

impl Duplex {
    fn now_ms(&self) -> f64 {
        self.cluster.started.elapsed().as_secs_f64() * 1000.0
    }

    /// Pumps until the Connext reader has followed `life` for `window_ms`; panics with what
    /// both readers saw after `STEP`.
    fn until_connext_follows(&mut self, life: Life, window_ms: f64) {
        let until = Instant::now() + STEP;
        loop {
            self.cluster.pump(Duration::from_millis(20));
            self.connext.pump();
            self.lives.listen();
            let now_ms = self.now_ms();
            let follows = self
                .lives
                .participant(life)
                .is_some_and(|p| self.connext.follows(p, now_ms, window_ms));
            if follows {
                return;
            }
            assert!(
                Instant::now() < until && self.connext.running(),
                "the Connext reader does not follow {life}: {}\nconnext owners: {:?}",
                self.cluster.describe(),
                self.named(self.connext.owners(0))
            );
        }
    }

    fn named(&self, owners: Vec<(f64, String)>) -> Vec<(u64, String)> {
        owners
            .into_iter()
            .map(|(at_ms, p)| (at_ms as u64, self.lives.name(&p)))
            .collect()
    }
}

#[test]
#[ignore = "needs python3 with rticonnextdds-connector (pip install rticonnextdds-connector==1.2.4)"]
fn the_connext_reader_follows_a_duplex_owner_through_a_kill_and_the_return() {
    require_peer("rticonnextdds_connector", CONNEXT_PACKAGE);
    let mut cluster = Cluster::with_head("duplex-connext", DOMAIN, "architecture = \"duplex\"\n");
    let lives = Lives::new(DOMAIN);
    cluster.start_servo();
    cluster.start(1);
    cluster.start(2);
    let connext = ConnextReader::start(
        DOMAIN,
        CONNEXT_DEADLINE_MS,
        CONNEXT_LIVELINESS_CHECK_MS,
        cluster.started,
    );
    let mut duplex = Duplex {
        cluster,
        lives,
        connext,
    };
    let c1 = Life { id: 1, life: 1 };
    duplex.until_connext_follows(c1, 1000.0);
    let judged_from_ms = duplex.now_ms();

    duplex.cluster.fleet.kill(1).expect("kill C1");
    duplex.until_connext_follows(Life { id: 2, life: 1 }, 500.0);
    // Restarted once the Standby has noticed: after the heartbeat deadline.
    std::thread::sleep(Duration::from_millis(600));
    duplex.cluster.start(1);
    duplex.until_connext_follows(Life { id: 1, life: 2 }, 1000.0);

    for (judge, owners) in [
        ("connext", duplex.connext.owners(0)),
        (
            "rl servo",
            servo_owners(&duplex.cluster.servo, duplex.cluster.started),
        ),
    ] {
        let changes: Vec<(String, String)> = owner_changes(owners)
            .into_iter()
            .filter(|change| change.at_ms > judged_from_ms)
            .map(|change| {
                (
                    duplex.lives.name(&change.from),
                    duplex.lives.name(&change.to),
                )
            })
            .collect();
        eprintln!("{judge}: owner changes {changes:?}");
        let expected =
            [("C1", "C2"), ("C2", "C1#2")].map(|(from, to)| (from.to_string(), to.to_string()));
        assert_eq!(
            changes, expected,
            "{judge}: the kill's switch and the return's"
        );
    }
}
