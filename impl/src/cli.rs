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
        with_domain(&mut config, domain)?;
    }
    Ok(config)
}

/// Checks a `--domain` for a run whose controllers start their network monitor (the bench's
/// resource run, on loopback): the monitor's two domains after it must be valid too.
pub fn check_domain_with_networks(domain: u16) -> Result<(), crate::Error> {
    let mut config = Config::default();
    config.networks.a = "127.0.0.1".into();
    config.networks.b = "lo".into();
    with_domain(&mut config, domain)
}

/// The one place a `--domain` is validated: as the configuration's `dds.domain`, so its rules
/// (at most 232; with networks, room for the monitor's two domains) say what is wrong.
fn with_domain(config: &mut Config, domain: u16) -> Result<(), crate::Error> {
    config.dds.domain = domain;
    config
        .validate()
        .map_err(|invalid| crate::Error::Usage(format!("--domain {domain}: {}", invalid.rule)))
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

/// What every controller process takes (`rl controller`, `rl chain nav|act`): which one, its
/// configuration, its events.
#[derive(clap::Args, Debug)]
pub struct ControllerRunArgs {
    /// This controller's id in its group (1, 2, 3; a fourth is ignored by the vote). Roles at
    /// start go by lowest id.
    #[arg(long, value_parser = clap::value_parser!(u8).range(1..=250))]
    pub id: rl_layer::core::ControllerId,
    /// Configuration file (TOML; every field optional, see rl.toml.example).
    #[arg(long, value_name = "PATH")]
    pub config: Option<std::path::PathBuf>,
    /// DDS domain id (overrides the configuration; default 53).
    #[arg(long, value_name = "D")]
    pub domain: Option<u16>,
    /// Print one JSON event per line on stdout (status, output, vote, alarm) instead of
    /// console lines: the record tools and the conformance suite read.
    #[arg(long)]
    pub json_events: bool,
}
