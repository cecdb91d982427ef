//! Log setup: `tracing` to stderr, filtered by `RUST_LOG` (default `info,rustdds=warn`:
//! RustDDS is chatty at info level and its discovery chatter would bury the protocol's lines).

use tracing_subscriber::EnvFilter;

/// The filter used when `RUST_LOG` is not set.
pub const DEFAULT_FILTER: &str = "info,rustdds=warn,ros2_client=error";

/// Installs the global subscriber once; later calls do nothing.
pub fn init() {
    let filter =
        EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new(DEFAULT_FILTER));
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_target(false)
        .try_init();
}
