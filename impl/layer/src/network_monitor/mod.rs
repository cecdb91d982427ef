//! The Network Alarm Participant (NAP) of `rl controller`: the pure monitor
//! (`rl_core::network`) run over two DDS participants, one bound to each network.
//!
//! Every period it publishes the network heartbeat on both networks, feeds what each
//! network's participant reads to the monitor (the network a heartbeat arrived on is the
//! participant's, never a field), and publishes the alarms the monitor raises and clears on
//! the network alarm topic through the controller's own participant, which reaches the others
//! over either network.
//!
//! **A thread of `rl controller`, not a process beside it.** The paper keeps the NAP a separate
//! application so that a NAP fault cannot take the controller down. Here the NAP shares no
//! state with the voting thread but the alarm writer, a failure to bind a network (an address
//! the host does not have yet, a USB adapter still down) is a warning retried every 2 s, and a
//! panic in the monitor is caught and the monitor restarted: the controller votes and commands
//! whatever the NAP does. What a process would add, surviving an abort of the whole process,
//! would not help: then the controller is gone too, and RLCHB reports it. A thread shares the
//! controller's configuration, logging and service supervision, and needs no second
//! participant on both networks to publish its alarms.

mod error;
mod interfaces;
mod report;

pub use error::{MonitorError, Unresolved};
pub use interfaces::{ipv4_addresses, resolve, InterfaceAddress};

use crate::config::{Config, NetworkName, Networks};
use crate::core::network::{Nap, NapCommand, NapConfig, NapInput, Network, Verdict};
use crate::core::types::{ControllerId, Incarnation};
use crate::dds::{mio, NetworkParticipant, ParticipantKey, Writer};
use crate::round_clock::RoundClock;
use crate::wire::NetworkAlarmSample;
use mio::{Events, Poll, PollOpt, Ready, Token};
use report::Reporter;
use std::net::Ipv4Addr;
use std::panic::AssertUnwindSafe;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;
use tracing::{error, info, warn};

/// How long the monitor waits before binding again after a failure.
const RETRY: Duration = Duration::from_secs(2);
/// The longest it sleeps without looking at its stop flag.
const FLAG_CHECK_MS: u64 = 100;

/// Who the monitor reports as, and how.
pub struct MonitorOptions {
    /// This controller's id (1..=250): the reporter of its network alarms.
    pub id: ControllerId,
    /// This controller's current incarnation, carried in its network alarms.
    pub incarnation: Incarnation,
    /// Report on stdout as JSON events (one per line) instead of console lines.
    pub json_events: bool,
}

/// The running monitor; stops when dropped.
pub struct NetworkMonitor {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl NetworkMonitor {
    /// Starts the monitor if `config.networks` names both networks (`None` otherwise).
    /// `alarms_out` is a network alarm writer of the controller's own participant.
    pub fn start(
        config: &Config,
        options: MonitorOptions,
        alarms_out: Writer<NetworkAlarmSample>,
    ) -> Option<NetworkMonitor> {
        config.networks.pair()?;
        let stop = Arc::new(AtomicBool::new(false));
        let thread_stop = Arc::clone(&stop);
        let config = config.clone();
        let reporter = Reporter {
            id: options.id,
            incarnation: options.incarnation,
            json_events: options.json_events,
            alarms_out,
        };
        let thread = std::thread::Builder::new()
            .name("network-monitor".into())
            .spawn(move || supervise(&config, &reporter, &thread_stop))
            .map_err(|error| error!("network monitor not started: {error}"))
            .ok()?;
        Some(NetworkMonitor {
            stop,
            thread: Some(thread),
        })
    }
}

impl Drop for NetworkMonitor {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

/// Sleeps `duration` in short steps; false if asked to stop meanwhile.
fn sleep_unless_stopped(duration: Duration, stop: &AtomicBool) -> bool {
    let step = Duration::from_millis(FLAG_CHECK_MS);
    let mut left = duration;
    while !left.is_zero() {
        if stop.load(Ordering::SeqCst) {
            return false;
        }
        let now = left.min(step);
        std::thread::sleep(now);
        left -= now;
    }
    !stop.load(Ordering::SeqCst)
}

/// Binds and runs the monitor until stopped: a bind failure is retried, a panic restarts it.
fn supervise(config: &Config, reporter: &Reporter, stop: &AtomicBool) {
    let mut last_problem = String::new();
    while !stop.load(Ordering::SeqCst) {
        let outcome = std::panic::catch_unwind(AssertUnwindSafe(|| {
            let participants = bind(config)?;
            last_problem.clear();
            monitor(config, reporter, stop, participants)
        }));
        let problem = match outcome {
            Ok(Ok(())) => return,
            Ok(Err(problem)) => problem.to_string(),
            Err(_) => MonitorError::Panicked.to_string(),
        };
        // A problem that persists (an interface still down) is logged once, not every 2 s.
        if problem != last_problem {
            warn!(
                "network monitor: {problem}; retrying every {} s",
                RETRY.as_secs()
            );
            last_problem = problem;
        }
        if !sleep_unless_stopped(RETRY, stop) {
            return;
        }
    }
}

/// The two networks' participants, A then B, with the addresses they are bound to.
fn bind(config: &Config) -> Result<[(Ipv4Addr, NetworkParticipant); 2], MonitorError> {
    let (name_a, name_b) = config.networks.pair().ok_or(MonitorError::NotConfigured)?;
    let addresses = ipv4_addresses().map_err(MonitorError::Addresses)?;
    let domains = Networks::monitor_domains(config.dds.domain);
    let deadline_ms =
        config.networks.heartbeat_period_ms * u64::from(config.networks.deadline_periods);
    let bind_one = |network: Network, name: &NetworkName, domain: u16| {
        let address = resolve(name, &addresses)
            .map_err(|problem| MonitorError::Unresolved { network, problem })?;
        let participant = NetworkParticipant::bind(
            domain,
            address,
            &config.dds.grouped().network_heartbeat_topic,
            deadline_ms,
        )
        .map_err(|source| MonitorError::Bind {
            network,
            address,
            source,
        })?;
        info!("network monitor: network {network} on {address} ({name}), DDS domain {domain}");
        Ok((address, participant))
    };
    Ok([
        bind_one(Network::A, &name_a, domains[0])?,
        bind_one(Network::B, &name_b, domains[1])?,
    ])
}

/// The monitor's loop over bound participants, until stopped.
fn monitor(
    config: &Config,
    reporter: &Reporter,
    stop: &AtomicBool,
    mut participants: [(Ipv4Addr, NetworkParticipant); 2],
) -> Result<(), MonitorError> {
    let clock = RoundClock::start();
    let nap_config = NapConfig {
        period_ms: config.networks.heartbeat_period_ms,
        deadline_periods: config.networks.deadline_periods,
        raise_after_ms: config.networks.raise_after_ms,
        clear_after_periods: config.networks.clear_after_periods,
        members: config.core_architecture().network_members(),
        ..NapConfig::new(reporter.id)
    };
    let mut nap = Nap::new(nap_config, clock.now_ms());
    let own: Vec<ParticipantKey> = participants
        .iter()
        .map(|(_, p)| crate::dds::participant_key(p.guid()))
        .collect();
    let poll_error = |doing| move |source| MonitorError::Poll { doing, source };
    let poll = Poll::new().map_err(poll_error("creating the event poll"))?;
    for (index, (_, participant)) in participants.iter().enumerate() {
        poll.register(
            &participant.heartbeats_in,
            Token(index),
            Ready::readable(),
            PollOpt::edge(),
        )
        .map_err(poll_error("registering a network heartbeat reader"))?;
    }
    let mut events = Events::with_capacity(8);
    let mut shown: Option<Verdict> = None;
    while !stop.load(Ordering::SeqCst) {
        let now_ms = clock.now_ms();
        let mut commands = due_timers(&mut nap, now_ms);
        for (network, (_, participant)) in Network::ALL.into_iter().zip(participants.iter_mut()) {
            for received in participant.heartbeats_in.take() {
                // RustDDS may hand a participant its own samples: they say nothing of a link.
                if own.contains(&crate::dds::participant_key(received.writer)) {
                    continue;
                }
                let input = NapInput::Heartbeat {
                    received_on: network,
                    heartbeat: received.value,
                };
                commands.extend(nap.step(input, now_ms));
            }
        }
        for command in commands {
            match command {
                NapCommand::PublishHeartbeat { network, heartbeat } => {
                    let (_, participant) = &participants[network.index()];
                    if let Err(error) = participant.heartbeats_out.write(&heartbeat) {
                        warn!("network heartbeat on {network} not published: {error}");
                    }
                }
                NapCommand::RaiseAlarm { subject, cause } => {
                    reporter.alarm(subject, Some(&cause), now_ms);
                }
                NapCommand::ClearAlarm { subject } => reporter.alarm(subject, None, now_ms),
            }
        }
        if shown.as_ref() != Some(&nap.conclusion().verdict) {
            reporter.conclusion(nap.conclusion(), now_ms);
            shown = Some(nap.conclusion().verdict.clone());
        }
        let wait_ms = nap
            .next_deadline()
            .at_ms
            .saturating_sub(clock.now_ms())
            .clamp(1, FLAG_CHECK_MS);
        match poll.poll(&mut events, Some(Duration::from_millis(wait_ms))) {
            Ok(_) => {}
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(poll_error("waiting for network heartbeats")(e)),
        }
    }
    Ok(())
}

/// Steps every timer of `nap` due at `now_ms`; the commands, in order.
fn due_timers(nap: &mut Nap, now_ms: u64) -> Vec<NapCommand> {
    let mut commands = Vec::new();
    while let Some(timer) = nap.due_timer(now_ms) {
        commands.extend(nap.step(NapInput::Timer(timer), now_ms));
    }
    commands
}
