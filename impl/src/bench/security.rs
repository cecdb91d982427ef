//! `rl bench --security`: the cost of DDS Security. The first deadline's failover run and the
//! resource run are repeated with every participant secured (keystores made by `rl keys` code
//! in the bench's temporary directory), right after the unsecured runs of the same
//! invocation, and each figure is given as secured over unsecured.

use super::failover::FailoverResult;
use super::resources::ResourceResult;
use super::stats::SplitMix64;
use super::{BenchArgs, BenchError, Setup};
use serde::Serialize;

/// The secured runs and the ratios secured / unsecured.
#[derive(Clone, Debug, Serialize)]
pub struct SecurityComparison {
    pub failover: FailoverResult,
    pub resources: ResourceResult,
    pub gap_p50_ratio: f64,
    pub gap_max_ratio: f64,
    pub promotion_p50_ratio: f64,
    pub cpu_ratio: f64,
    pub rss_ratio: f64,
}

fn ratio(secured: f64, unsecured: f64) -> f64 {
    if unsecured > 0.0 {
        secured / unsecured
    } else {
        f64::NAN
    }
}

/// Keystores for controllers 1-3 and the applications `servo` and `camera` under `dir`.
#[cfg(feature = "security")]
fn make_keystores(dir: &std::path::Path) -> Result<std::path::PathBuf, BenchError> {
    use rl_layer::security::{documents::Grantee, keys};
    let keys_dir = dir.join("keys");
    let dds = rl_layer::config::Dds::default();
    let failed = |e: keys::KeysError| {
        BenchError::io("making keystores", std::io::Error::other(e.to_string()))
    };
    keys::init(&keys_dir, &dds, keys::Validity::from_now(1)).map_err(failed)?;
    let grantees = [
        Grantee::Controller(1),
        Grantee::Controller(2),
        Grantee::Controller(3),
        Grantee::Application("servo".into()),
        Grantee::Application("camera".into()),
    ];
    for grantee in &grantees {
        keys::add(&keys_dir, &dds, grantee, keys::Validity::from_now(1)).map_err(failed)?;
    }
    Ok(keys_dir)
}

#[cfg(not(feature = "security"))]
fn make_keystores(_dir: &std::path::Path) -> Result<std::path::PathBuf, BenchError> {
    Err(BenchError::io(
        "--security",
        std::io::Error::other("this rl was built without the `security` feature"),
    ))
}

/// Repeats the failover run at `unsecured.deadline_ms` and the resource run, secured.
pub fn compare(
    setup: &Setup,
    unsecured: &FailoverResult,
    unsecured_resources: &ResourceResult,
    args: &BenchArgs,
    phases: &mut SplitMix64,
) -> Result<SecurityComparison, BenchError> {
    let keystores = make_keystores(&setup.dir)?;
    let secured_setup = Setup {
        exe: setup.exe.clone(),
        dir: setup.dir.clone(),
        domain: setup.domain,
        heartbeat_period_ms: setup.heartbeat_period_ms,
        keystores: Some(keystores),
        laws: setup.laws.clone(),
    };
    eprintln!("rl bench: the same runs with DDS Security");
    let failover =
        super::failover::failover(&secured_setup, unsecured.deadline_ms, args.kills, phases)?;
    let resources = super::resources::resources(&secured_setup, args.resources_s)?;
    Ok(SecurityComparison {
        gap_p50_ratio: ratio(failover.gap_ms.p50, unsecured.gap_ms.p50),
        gap_max_ratio: ratio(failover.gap_ms.max, unsecured.gap_ms.max),
        promotion_p50_ratio: ratio(failover.promotion_ms.p50, unsecured.promotion_ms.p50),
        cpu_ratio: ratio(
            resources.cpu_percent_of_one_core,
            unsecured_resources.cpu_percent_of_one_core,
        ),
        rss_ratio: ratio(
            resources.rss_kb_max as f64,
            unsecured_resources.rss_kb_max as f64,
        ),
        failover,
        resources,
    })
}
