//! A heartbeat probe: one RustDDS participant, created inside a network namespace, that
//! publishes a small best-effort sample every period on one topic and records every sample it
//! takes from that topic (who sent it, over which net the sender meant it, and when).
//!
//! The participant is created on a thread that first joined the host's namespace with
//! `setns(CLONE_NEWNET)`; RustDDS's own threads are spawned from it and inherit the namespace,
//! so its sockets and its view of the interfaces are the host's.

use super::lan::Net;
use rustdds::{
    policy::{History, Reliability},
    DomainParticipantBuilder, QosPolicyBuilder, TopicKind,
};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fs::File;
use std::net::Ipv4Addr;
use std::os::fd::AsRawFd;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

/// What a probe publishes.
#[derive(Serialize, Deserialize, Debug, Clone, Copy)]
struct Beat {
    host: u8,
    /// 0 for net A, 1 for net B: the net the sending participant stands for.
    net: u8,
    seq: u32,
}

fn net_code(net: Net) -> u8 {
    match net {
        Net::A => 0,
        Net::B => 1,
    }
}

fn net_of(code: u8) -> Net {
    if code == 0 {
        Net::A
    } else {
        Net::B
    }
}

/// How to build one probe.
#[derive(Clone, Debug)]
pub struct ProbeConfig {
    /// The namespace (host) to run in.
    pub ns: String,
    pub host: u8,
    /// The net this participant stands for (a label in its samples).
    pub net: Net,
    pub domain: u16,
    pub topic: String,
    /// `DomainParticipantBuilder::with_only_networks([addr])` when set.
    pub only_networks: Option<Ipv4Addr>,
    /// `DomainParticipantBuilder::send_on_every_interface(true)` when set.
    pub every_interface: bool,
    pub period: Duration,
    /// Whether the participant also reads the topic (RL's heartbeats: yes) and writes it.
    pub reads: bool,
    pub writes: bool,
}

/// One sample taken by a probe.
#[derive(Clone, Copy, Debug)]
pub struct Heard {
    pub at: Instant,
    pub from_host: u8,
    pub from_net: Net,
}

/// A running probe; stopped (and its participant dropped) by [`Probe::stop`] or on drop.
pub struct Probe {
    pub config: ProbeConfig,
    stop: Arc<AtomicBool>,
    log: Arc<Mutex<Vec<Heard>>>,
    handle: Option<JoinHandle<()>>,
}

fn enter_namespace(ns: &str) {
    let file = File::open(format!("/run/netns/{ns}")).unwrap();
    // SAFETY: setns(2) on a valid fd changes only this thread's network namespace.
    let rc = unsafe { libc::setns(file.as_raw_fd(), libc::CLONE_NEWNET) };
    assert_eq!(
        rc,
        0,
        "setns into {ns}: {}",
        std::io::Error::last_os_error()
    );
}

fn run_probe(config: ProbeConfig, stop: Arc<AtomicBool>, log: Arc<Mutex<Vec<Heard>>>) {
    enter_namespace(&config.ns);
    let mut builder = DomainParticipantBuilder::new(config.domain);
    if let Some(addr) = config.only_networks {
        builder = builder.with_only_networks([addr]);
    }
    let participant = builder
        .send_on_every_interface(config.every_interface)
        .build()
        .unwrap();
    let qos = QosPolicyBuilder::new()
        .reliability(Reliability::BestEffort)
        .history(History::KeepLast { depth: 1 })
        .build();
    let topic = participant
        .create_topic(
            config.topic.clone(),
            "napx::Beat".to_string(),
            &qos,
            TopicKind::NoKey,
        )
        .unwrap();
    let publisher = participant.create_publisher(&qos).unwrap();
    let subscriber = participant.create_subscriber(&qos).unwrap();
    let writer = config.writes.then(|| {
        publisher
            .create_datawriter_no_key_cdr::<Beat>(&topic, None)
            .unwrap()
    });
    // An unkeyed topic is one instance: the reader keeps enough history for every sender's
    // beats between two takes.
    let reader_qos = QosPolicyBuilder::new()
        .reliability(Reliability::BestEffort)
        .history(History::KeepLast { depth: 64 })
        .build();
    let mut reader = config.reads.then(|| {
        subscriber
            .create_datareader_no_key_cdr::<Beat>(&topic, Some(reader_qos))
            .unwrap()
    });
    let mut seq = 0;
    while !stop.load(Ordering::Relaxed) {
        let beat = Beat {
            host: config.host,
            net: net_code(config.net),
            seq,
        };
        if let Some(writer) = &writer {
            writer.write(beat, None).unwrap();
        }
        seq += 1;
        let deadline = Instant::now() + config.period;
        while Instant::now() < deadline {
            while let Some(Ok(Some(sample))) = reader.as_mut().map(|r| r.take_next_sample()) {
                let beat = sample.into_value();
                log.lock().unwrap().push(Heard {
                    at: Instant::now(),
                    from_host: beat.host,
                    from_net: net_of(beat.net),
                });
            }
            thread::sleep(Duration::from_millis(5));
        }
    }
}

impl Probe {
    pub fn start(config: ProbeConfig) -> Probe {
        let stop = Arc::new(AtomicBool::new(false));
        let log = Arc::new(Mutex::new(Vec::new()));
        let handle = {
            let (config, stop, log) = (config.clone(), stop.clone(), log.clone());
            thread::Builder::new()
                .name(format!("probe h{} {:?}", config.host, config.net))
                .spawn(move || run_probe(config, stop, log))
                .unwrap()
        };
        Probe {
            config,
            stop,
            log,
            handle: Some(handle),
        }
    }

    /// Samples taken in `[from, to)`, counted per sender (host, net), own samples excluded.
    pub fn heard_between(&self, from: Instant, to: Instant) -> BTreeMap<(u8, Net), usize> {
        let mut counts = BTreeMap::new();
        for heard in self.log.lock().unwrap().iter() {
            let own = heard.from_host == self.config.host && heard.from_net == self.config.net;
            if !own && heard.at >= from && heard.at < to {
                *counts.entry((heard.from_host, heard.from_net)).or_insert(0) += 1;
            }
        }
        counts
    }

    /// The longest silence from `host` (any net) within `[from, to]`, edges included.
    pub fn longest_gap_from(&self, host: u8, from: Instant, to: Instant) -> Duration {
        let log = self.log.lock().unwrap();
        let mut times: Vec<Instant> = vec![from];
        times.extend(
            log.iter()
                .filter(|h| h.from_host == host && h.at >= from && h.at <= to)
                .map(|h| h.at),
        );
        times.push(to);
        times
            .windows(2)
            .map(|w| w[1] - w[0])
            .max()
            .unwrap_or_default()
    }

    fn halt(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(handle) = self.handle.take() {
            if let Err(panic) = handle.join() {
                if !thread::panicking() {
                    std::panic::resume_unwind(panic);
                }
            }
        }
    }
}

impl Drop for Probe {
    fn drop(&mut self) {
        self.halt();
    }
}
