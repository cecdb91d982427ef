//! What every `rl` command shares on its command line: the configuration it loads (with a
//! `--domain` override, validated like the file), and the signals that stop it.

use rl_layer::config::Config;
use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

/// Loads the configuration named on the command line (defaults without one) and applies a
/// `--domain` override, validating the result.
pub fn load_config(path: Option<&Path>, domain: Option<u16>) -> Result<Config, crate::Error> {
    let mut config = match path {
        Some(path) => Config::load(path)?,
        None => Config::default(),
    };
    if let Some(domain) = domain {
        config.dds.domain = domain;
        config.validate().map_err(|invalid| {
            crate::Error::Usage(format!("--domain {domain}: {}", invalid.rule))
        })?;
    }
    Ok(config)
}

/// SIGINT and SIGTERM set the returned flag.
pub fn stop_on_signals() -> Result<Arc<AtomicBool>, crate::Error> {
    let stop = Arc::new(AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(signal, Arc::clone(&stop))
            .map_err(|e| crate::Error::io("installing a signal handler", e))?;
    }
    Ok(stop)
}
