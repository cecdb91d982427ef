//! `rl status`: what every controller of every redundancy group on the domain says about
//! itself, read from the DDS topics (their heartbeats, the controller alarm topic and the
//! network alarm topic), as live tables or JSON lines, or served as a live page
//! (`rl status --serve`, [`page`]). Network alarms are transient local: a status started after
//! an alarm was raised still shows it, for as long as its reporter runs.
//!
//! The parts, each in its module:
//! - [`view`]: the `--json` object of one group ([`StatusView`]), the stable interface;
//! - [`board`]: [`Board`], one group's samples in and its view out, pure (the demo and the
//!   benchmarks use it too);
//! - [`feed`]: [`BoardFeed`], one group's readers feeding its board;
//! - [`groups`]: [`GroupBoards`], a board per group shown, and which groups ([`Selection`]:
//!   the configuration's and every one discovered, or `--group`'s);
//! - [`table`]: the text tables; [`serve`](mod@serve) the `--serve` loop; [`page`] the page,
//!   its JSON and the Prometheus metrics.
//!
//! This file has the command line and the printing loop.

pub mod board;
pub mod feed;
pub mod groups;
pub mod page;
pub mod serve;
pub mod table;
pub mod view;

pub use board::Board;
pub use feed::BoardFeed;
pub use groups::{GroupBoards, Selection};
pub use table::{render_table, render_tables};
pub use view::{AlarmView, ControllerView, NetworkAlarmView, StatusView};

use rl_layer::config::{Config, Dds};
use std::sync::atomic::{AtomicBool, Ordering};

/// Arguments of `rl status`.
#[derive(clap::Args, Debug)]
pub struct StatusArgs {
    /// Print JSON instead of tables: per refresh one line per group, sorted by group name,
    /// each the object a single group printed before (with its `group` field).
    #[arg(long)]
    pub json: bool,
    /// Listen for a while (1 s and three heartbeat periods from when each group shown was
    /// found; 3 s more with DDS Security), print once and exit.
    #[arg(long)]
    pub once: bool,
    /// Configuration file (domain, topic names, heartbeat period).
    #[arg(long, value_name = "PATH")]
    pub config: Option<std::path::PathBuf>,
    /// DDS domain id (overrides the configuration).
    #[arg(long, value_name = "D")]
    pub domain: Option<u16>,
    /// Show only redundancy group NAME (`dds.group`; `--group ""` the group without a name);
    /// repeat it for several. Without it: the configuration's group and every group
    /// discovered on the domain while it runs.
    #[arg(long = "group", value_name = "NAME")]
    pub groups: Vec<String>,
    /// Serve the live view over HTTP instead of printing: a page with every group's
    /// controllers and their LEDs, /status.json (the --json object of the configuration's
    /// group), /groups.json (every group's) and /metrics (Prometheus). ADDR defaults to
    /// 127.0.0.1:8053, this host only; bind 0.0.0.0:8053 or a LAN address to reach it from
    /// the LAN (no authentication: a trusted network only).
    #[arg(long, value_name = "ADDR", num_args = 0..=1,
          default_missing_value = self::page::DEFAULT_ADDR,
          conflicts_with_all = ["json", "once"])]
    pub serve: Option<String>,
}

/// Runs `rl status`.
pub fn run(args: StatusArgs) -> Result<(), crate::Error> {
    let config = crate::cli::load_config(args.config.as_deref(), args.domain)?;
    let selection = selection_of(&args.groups, &config)?;
    let stop = crate::cli::stop_on_signals()?;
    let session = rl_layer::dds::Session::for_config(&config)?;
    let boards = GroupBoards::open(session, selection)?;
    let alive_within_ms = config.timing.peer_deadline_ms;
    // Discovery plus a few heartbeats: enough to hear every live controller of a group.
    // Secured, discovery first authenticates and exchanges keys with every participant
    // (about 2 s on loopback, docs/security.md): listen that much longer.
    let authentication_ms = if config.security.enabled() { 3000 } else { 0 };
    let listen_ms = 1000 + 3 * config.timing.heartbeat_period_ms + authentication_ms;
    if let Some(addr) = &args.serve {
        return serve::serve(addr, boards, alive_within_ms, listen_ms, &stop);
    }
    print_views(&args, boards, alive_within_ms, listen_ms, &stop)
}

/// Which groups to show: `--group`'s (each checked as `dds.group` is), or every one.
fn selection_of(named: &[String], config: &Config) -> Result<Selection, crate::Error> {
    if named.is_empty() {
        return Ok(Selection::Every {
            configured: config.dds.group.clone(),
        });
    }
    for name in named {
        let dds = Dds {
            group: name.clone(),
            ..config.dds.clone()
        };
        dds.validate().map_err(|invalid| {
            crate::Error::Usage(format!("--group {name:?}: {}", invalid.rule))
        })?;
    }
    Ok(Selection::Only(named.iter().cloned().collect()))
}

/// Prints every group's table or JSON line each refresh (with `--once`: once, after every
/// group shown has been listened to for `listen_ms`) until `stop`.
fn print_views(
    args: &StatusArgs,
    mut boards: GroupBoards,
    alive_within_ms: u64,
    listen_ms: u64,
    stop: &AtomicBool,
) -> Result<(), crate::Error> {
    let refresh_ms = 500;
    let mut next_print_ms = if args.once { listen_ms } else { refresh_ms };
    loop {
        std::thread::sleep(std::time::Duration::from_millis(20));
        boards.update();
        let now = boards.now_ms();
        let heard_out = || {
            boards
                .boards()
                .all(|b| boards.heard_out(b.group(), now, listen_ms))
        };
        if now < next_print_ms || (args.once && !heard_out()) {
            if stop.load(Ordering::SeqCst) {
                return Ok(());
            }
            continue;
        }
        next_print_ms = now + refresh_ms;
        let views = boards.views(now, alive_within_ms);
        if args.json {
            for view in &views {
                let line = serde_json::to_string(view)
                    .map_err(|e| crate::Error::runtime(format!("status JSON: {e}")))?;
                println!("{line}");
            }
        } else {
            if !args.once {
                // Clear the screen and home the cursor: live tables.
                print!("\x1b[2J\x1b[H");
            }
            print!("{}", render_tables(&views));
        }
        use std::io::Write;
        let _ = std::io::stdout().flush();
        if args.once || stop.load(Ordering::SeqCst) {
            return Ok(());
        }
    }
}
