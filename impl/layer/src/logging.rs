//! Log setup: `tracing`, filtered by `RUST_LOG`, or by default `info,rustdds=warn`: RustDDS
//! is chatty at info level and its discovery chatter would bury the protocol's lines.
//!
//! Under the default filter, a few RustDDS lines that pass the `warn` threshold but mean
//! nothing to an operator ([`RUSTDDS_NOISE`]) are dropped too, by their message: a target
//! filter would also hide the same module's real errors (socket failures, say). A `RUST_LOG`
//! the operator sets replaces the whole default, and then RustDDS's lines show as it logs them.
//! RL's own lines keep their levels either way.
//!
//! Under systemd, whose journal holds stderr (`JOURNAL_STREAM` names that stream), records go
//! to journald natively, each with its priority, so `journalctl -p warning` finds the
//! warnings; everywhere else they go to stderr, in colour only on a terminal.

use std::io::IsTerminal;
use tracing::field::{Field, Visit};
use tracing::{Event, Subscriber};
use tracing_subscriber::layer::{Context, Layer, SubscriberExt};
use tracing_subscriber::util::SubscriberInitExt;
use tracing_subscriber::EnvFilter;

/// The filter used when `RUST_LOG` is not set.
pub const DEFAULT_FILTER: &str = "info,rustdds=warn,ros2_client=error";

/// RustDDS lines hidden under the default filter: `(target prefix, message prefix)`.
pub const RUSTDDS_NOISE: &[(&str, &str)] = &[
    // At ERROR, once per remote participant, as a paused peer resumes: discovery told the
    // event loop of an update to a participant whose entry was gone by the time the loop
    // read it (the lease check removed it), so the loop skips it. The participant's next
    // announcement repeats the update; RL reports the peer's loss and return itself.
    (
        "rustdds::rtps::dp_event_loop",
        "Participant was updated, but DB does not have it",
    ),
    // At WARN for every datagram over 1500 bytes RustDDS sends (an alarm raised or cleared
    // goes out with the discovery data beside it in one message of about 1.8 kB): the
    // datagram is sent all the same, the IP layer fragments it, and a reliable reader has a
    // lost one repaired. Nothing for an operator to act on, once per alarm on the console.
    (
        "rustdds::network::udp_sender",
        "send_to_locator: Message size",
    ),
    (
        "rustdds::network::udp_sender",
        "try_send_to_locator: Message size",
    ),
    (
        "rustdds::network::udp_sender",
        "send_to_multicast_locator_via: Message size",
    ),
    (
        "rustdds::network::udp_sender",
        "try_send_to_multicast_locator_via: Message size",
    ),
];

/// Installs the global subscriber once; later calls do nothing.
pub fn init() {
    let (filter, noise) = match EnvFilter::try_from_default_env() {
        Ok(filter) => (filter, DropNoise::Off),
        Err(_) => (EnvFilter::new(DEFAULT_FILTER), DropNoise::On),
    };
    if stderr_is_journal() {
        if let Ok(journald) = tracing_journald::layer() {
            let _ = tracing_subscriber::registry()
                .with(filter)
                .with(noise)
                .with(journald)
                .try_init();
            return;
        }
        // No journal socket after all (a chroot, say): stderr still reaches the journal.
    }
    let _ = console_subscriber(
        filter,
        noise,
        std::io::stderr,
        std::io::stderr().is_terminal(),
    )
    .try_init();
}

/// The subscriber for plain output: `filter`, then `noise`, then one line per record to
/// `writer`.
fn console_subscriber<W>(
    filter: EnvFilter,
    noise: DropNoise,
    writer: W,
    ansi: bool,
) -> impl Subscriber + Send + Sync
where
    W: for<'w> tracing_subscriber::fmt::MakeWriter<'w> + Send + Sync + 'static,
{
    let lines = tracing_subscriber::fmt::layer()
        .with_writer(writer)
        .with_target(false)
        .with_ansi(ansi);
    tracing_subscriber::registry()
        .with(filter)
        .with(noise)
        .with(lines)
}

/// Whether [`RUSTDDS_NOISE`] is dropped (a layer that vetoes those events).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum DropNoise {
    On,
    Off,
}

impl<S: Subscriber> Layer<S> for DropNoise {
    fn event_enabled(&self, event: &Event<'_>, _context: Context<'_, S>) -> bool {
        if *self == DropNoise::Off {
            return true;
        }
        let mut seen = TargetAndMessage::default();
        event.record(&mut seen);
        // Records from the `log` crate (RustDDS's) carry their target in a field.
        let target = seen
            .log_target
            .as_deref()
            .unwrap_or(event.metadata().target());
        !is_noise(target, &seen.message)
    }
}

/// Whether a record is one of [`RUSTDDS_NOISE`].
fn is_noise(target: &str, message: &str) -> bool {
    RUSTDDS_NOISE
        .iter()
        .any(|(module, start)| target.starts_with(module) && message.starts_with(start))
}

/// The message and (for `log` records) the original target of an event.
#[derive(Default)]
struct TargetAndMessage {
    message: String,
    log_target: Option<String>,
}

impl Visit for TargetAndMessage {
    fn record_str(&mut self, field: &Field, value: &str) {
        match field.name() {
            "message" => self.message = value.to_string(),
            "log.target" => self.log_target = Some(value.to_string()),
            _ => {}
        }
    }

    fn record_debug(&mut self, field: &Field, value: &dyn std::fmt::Debug) {
        match field.name() {
            "message" => self.message = format!("{value:?}"),
            "log.target" => self.log_target = Some(format!("{value:?}")),
            _ => {}
        }
    }
}

/// Whether stderr is the journal stream systemd connected (`JOURNAL_STREAM=<dev>:<inode>`,
/// compared with stderr itself, as systemd.exec(5) advises: a child that inherited the
/// variable but writes elsewhere keeps plain stderr).
pub fn stderr_is_journal() -> bool {
    let Ok(value) = std::env::var("JOURNAL_STREAM") else {
        return false;
    };
    let Some((device, inode)) = parse_journal_stream(&value) else {
        return false;
    };
    let mut stat = std::mem::MaybeUninit::<libc::stat>::uninit();
    // SAFETY: fstat writes a `stat` into the buffer it is given, and only reads the fd.
    if unsafe { libc::fstat(libc::STDERR_FILENO, stat.as_mut_ptr()) } != 0 {
        return false;
    }
    // SAFETY: fstat returned 0, so it filled the buffer.
    let stat = unsafe { stat.assume_init() };
    // dev_t and ino_t are not u64 on every target.
    #[allow(clippy::unnecessary_cast)]
    let same = stat.st_dev as u64 == device && stat.st_ino as u64 == inode;
    same
}

/// `"<device>:<inode>"`, both decimal.
fn parse_journal_stream(value: &str) -> Option<(u64, u64)> {
    let (device, inode) = value.trim().split_once(':')?;
    Some((device.parse().ok()?, inode.parse().ok()?))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::{Arc, Mutex};

    #[test]
    fn journal_stream_is_device_colon_inode() {
        assert_eq!(parse_journal_stream("8:12345"), Some((8, 12345)));
        assert_eq!(parse_journal_stream("8:12345\n"), Some((8, 12345)));
        assert_eq!(parse_journal_stream("8"), None);
        assert_eq!(parse_journal_stream("a:b"), None);
    }

    /// Everything written, shared with the test.
    #[derive(Clone, Default)]
    struct Captured(Arc<Mutex<Vec<u8>>>);

    impl std::io::Write for Captured {
        fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
            self.0.lock().unwrap().extend_from_slice(bytes);
            Ok(bytes.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    impl Captured {
        fn text(&self) -> String {
            String::from_utf8(self.0.lock().unwrap().clone()).unwrap()
        }
    }

    /// What the console shows of RustDDS's noise, a real RustDDS error and RL's own lines,
    /// logged the way each is (RustDDS through the `log` crate), under `filter`.
    fn console_output(filter: &str, noise: DropNoise) -> String {
        let captured = Captured::default();
        let writer = captured.clone();
        let subscriber =
            console_subscriber(EnvFilter::new(filter), noise, move || writer.clone(), false);
        {
            // Also installs the `log` bridge, as `init` does.
            let _default = subscriber.set_default();
            let noisy = "rustdds::rtps::dp_event_loop";
            log::error!(target: noisy, "Participant was updated, but DB does not have it. Strange.");
            log::error!(target: noisy, "Cannot send to socket: broken");
            log::info!(target: "rustdds::discovery", "participant cleanup - deleting proxy");
            let sender = "rustdds::network::udp_sender";
            log::warn!(target: sender, "send_to_locator: Message size = 1808");
            log::warn!(target: sender, "send_to_multicast_locator_via: Message size = 1808");
            log::error!(target: sender, "send_to_locator: send failed: refused");
            tracing::warn!("C1: heartbeat not sent: no route");
            tracing::info!("C1 steady primary (30)");
        }
        captured.text()
    }

    #[test]
    fn rustdds_noise_stays_below_the_default_level_and_rl_keeps_its_lines() {
        let shown = console_output(DEFAULT_FILTER, DropNoise::On);
        assert!(!shown.contains("DB does not have it"), "{shown}");
        assert!(!shown.contains("participant cleanup"), "{shown}");
        assert!(!shown.contains("Message size"), "{shown}");
        assert!(shown.contains("ERROR Cannot send to socket"), "{shown}");
        // The same module's real failures still show.
        assert!(
            shown.contains("ERROR send_to_locator: send failed"),
            "{shown}"
        );
        assert!(shown.contains("WARN C1: heartbeat not sent"), "{shown}");
        assert!(shown.contains("INFO C1 steady primary"), "{shown}");
    }

    #[test]
    fn an_operator_filter_shows_rustdds_as_it_logs() {
        let shown = console_output("info", DropNoise::Off);
        assert!(shown.contains("ERROR Participant was updated"), "{shown}");
        assert!(
            shown.contains("WARN send_to_locator: Message size = 1808"),
            "{shown}"
        );
        assert!(shown.contains("participant cleanup"), "{shown}");
    }
}
