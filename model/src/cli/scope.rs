//! The scopes `model`'s commands take: the role model's configuration flags ([`Scope`]) and
//! the output model's ([`OutputScope`]), each turned into the library's configuration with
//! the bounds checked.

use clap::Args;
use model::config::ConfigError;
use model::outputs::{CrossCheck, OutputConfig, OutputConfigError, OutputMutation};
use model::{Config, Fix, Mutation, Variant};

/// The configuration to check (defaults: docs/model.md).
#[derive(Args, Clone)]
pub struct Scope {
    /// Controllers that start the system together (the first k of them, for every k).
    #[arg(long, default_value_t = 3)]
    controllers: u8,
    /// Further controllers that only join a running system.
    #[arg(long, default_value_t = 1)]
    late_joiners: u8,
    /// Crashes in total over a run.
    #[arg(long, default_value_t = 1)]
    crashes: u8,
    /// Restarts in total over a run.
    #[arg(long, default_value_t = 1)]
    restarts: u8,
    /// Heartbeats that may be lost in total over a run (0 = reliable heartbeats).
    #[arg(long, default_value_t = 1)]
    lost_heartbeats: u8,
    /// Pauses (SIGSTOP, a stall: the process resumes with its memory) over a run.
    #[arg(long, default_value_t = 0)]
    pauses: u8,
    /// Cuts of one controller from its peers (the actuator still hears it) over a run.
    #[arg(long, default_value_t = 0)]
    cuts: u8,
    /// Starved links of one controller (a rate limit: late, partly dropped datagrams) over a
    /// run (F17).
    #[arg(long, default_value_t = 0)]
    starvations: u8,
    /// Slowed processes of one controller (starved of CPU: it runs, late; its heartbeats
    /// miss rounds until it heals) over a run (F18).
    #[arg(long, default_value_t = 0)]
    slowdowns: u8,
    /// Late heartbeats of slowed controllers over a run: how long a slowdown lasts (with
    /// `--gray`: 4, both peers' dead-man deadline).
    #[arg(long)]
    late_heartbeats: Option<u8>,
    /// A pause may end without the controller noticing it stopped, within its peers'
    /// dead-man deadline (F18).
    #[arg(long)]
    unnoticed_stalls: bool,
    /// A slowed controller may also hear its peers late or sleep through a round's end (a
    /// slowed receiver; with `--gray` or `--slowdowns`, F18).
    #[arg(long)]
    slowed_receivers: bool,
    /// The scope of a controller that comes back: 3 controllers, one pause and one cut, no
    /// crash or lost heartbeat (overrides the fault flags).
    #[arg(long, conflicts_with_all = ["full", "gray"])]
    returns: bool,
    /// The scope of a slowed process: 3 controllers, one slowdown, no crash or lost
    /// heartbeat (overrides the fault flags; F18).
    #[arg(long, conflicts_with = "full")]
    gray: bool,
    /// Which rules: the corrected default, or the paper's text read literally (every fix of
    /// docs/findings.md reverted).
    #[arg(long, value_enum, default_value_t = Variant::Default)]
    variant: Variant,
    /// Take one fix of docs/findings.md out of the default rules (repeatable): its finding's
    /// counterexample comes back.
    #[arg(long, value_enum)]
    revert: Vec<Fix>,
    /// The larger configuration: 4 controllers started together, 2 crashes, 2 restarts.
    #[arg(long)]
    full: bool,
    /// A deliberately broken rule, to see the checker catch it.
    #[arg(long, value_enum, hide = true)]
    mutation: Option<Mutation>,
}

impl Scope {
    pub fn config(&self) -> Result<Config, ConfigError> {
        let base = if self.full {
            Config::full()
        } else if self.returns {
            Config::returns()
        } else if self.gray {
            let gray = Config::gray();
            Config {
                max_late_heartbeats: self.late_heartbeats.unwrap_or(gray.max_late_heartbeats),
                slowed_receivers: self.slowed_receivers,
                ..gray
            }
        } else {
            Config {
                founders: self.controllers,
                late_joiners: self.late_joiners,
                max_crashes: self.crashes,
                max_restarts: self.restarts,
                max_pauses: self.pauses,
                max_isolations: self.cuts,
                max_starvations: self.starvations,
                max_slowdowns: self.slowdowns,
                max_late_heartbeats: self.late_heartbeats.unwrap_or(0),
                unnoticed_stalls: self.unnoticed_stalls,
                slowed_receivers: self.slowed_receivers,
                max_lost_heartbeats: self.lost_heartbeats,
                ..Config::default()
            }
        };
        let config = Config {
            variant: self.variant,
            reverted: {
                let mut fixes = self.revert.clone();
                fixes.sort();
                fixes.dedup();
                fixes
            },
            mutation: self.mutation,
            ..base
        };
        config.validate()?;
        Ok(config)
    }
}

/// The output-voting model (docs/protocol.md, "Output voting"), with `--outputs`.
#[derive(Args, Clone)]
pub struct OutputScope {
    /// Check or explore the output-voting model instead of the role model: controllers whose
    /// commands go wrong while their heartbeats stay correct, a voting receiver, an
    /// exclusive-ownership receiver and the controllers' cross-check.
    #[arg(long, conflicts_with_all = [
        "controllers", "late_joiners", "crashes", "restarts", "lost_heartbeats", "pauses",
        "cuts", "starvations", "slowdowns", "late_heartbeats", "unnoticed_stalls", "slowed_receivers", "returns", "gray", "variant",
        "revert", "full", "mutation",
    ])]
    pub outputs: bool,
    /// Output model: faults that may begin over a run, 0 to 2 (2: finding O1, two wrong
    /// controllers that agree).
    #[arg(long, requires = "outputs", default_value_t = 1)]
    wrong: u8,
    /// Output model: two wrong controllers never send the same wrong value (the fail-safe
    /// hold).
    #[arg(long, requires = "outputs")]
    disagreeing: bool,
    /// Output model: how a controller counts the inputs at which it was the odd one out
    /// (consecutive: finding O2).
    #[arg(long, requires = "outputs", value_enum, default_value_t = CrossCheck::Cumulative)]
    cross_check: CrossCheck,
    /// Output model: N, the odd-one-out inputs after which a controller leaves (K = N).
    #[arg(long, requires = "outputs", default_value_t = 2)]
    odd_limit: u8,
    /// Output model: a deliberately broken rule, to see the checker catch it.
    #[arg(long, requires = "outputs", value_enum, hide = true)]
    output_mutation: Option<OutputMutation>,
}

impl OutputScope {
    pub fn config(&self) -> Result<OutputConfig, OutputConfigError> {
        let config = OutputConfig {
            max_wrong: self.wrong,
            wrong_values_differ: self.disagreeing,
            cross_check: self.cross_check,
            odd_limit: self.odd_limit,
            mutation: self.output_mutation,
        };
        config.validate()?;
        Ok(config)
    }
}
