//! `rl chain`: the paper's chain of two redundant applications on one RL, one network. A
//! navigation group (`rl chain nav`, three copies) turns the camera's ball into an aim, how far
//! the gimbal must turn, and an actuator group (`rl chain act`, three copies) turns the owning
//! navigation controller's aim into servo commands with the tracker's PD law. Each group votes
//! its own roles (its own `dds.group`); each writes its output with the ownership strength of
//! its role; the actuator controllers follow the navigation group's owner as an actuator
//! follows theirs. Killing either group's Primary moves only that group's output to its
//! Secondary. `rl demo --chain` runs it all on one machine (crate::demo).
//!
//! Both stages are applications of the RL library's public API, as a user's would be:
//! [`nav`] and [`act`].

pub mod act;

pub mod nav;

use rl_layer::core::ControllerId;
use serde::{Deserialize, Serialize};

/// The navigation group's name unless `--nav-group` says otherwise.
pub const NAV_GROUP: &str = "nav";
/// The DDS type name of [`Aim`], which both stages use.
pub const AIM_TYPE: &str = "rl::chain::Aim";

/// The topic the navigation group `nav_group` writes its aims on (`nav/aim`).
pub fn aim_topic(nav_group: &str) -> String {
    format!("{nav_group}/aim")
}

/// What the navigation controllers compute from one camera frame: how far the ball is from
/// the frame's centre, as the tracker's PD law takes it (crate::tracker::errors_of).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Aim {
    /// Pan error, camera units (111 − x).
    pub pan_error: i32,
    /// Tilt error, camera units (y − 126).
    pub tilt_error: i32,
    /// The camera frame it answers: the camera sample's source timestamp (RTPS time, seconds
    /// in the high 32 bits); every navigation controller gives the same frame the same value,
    /// so an actuator controller applies each frame once whichever of them owns the topic and
    /// however often the owner re-publishes it.
    pub frame: u64,
}

/// Arguments of `rl chain`.
#[derive(clap::Args, Debug)]
pub struct ChainArgs {
    #[command(subcommand)]
    pub stage: Stage,
}

/// The two applications of the chain.
#[derive(clap::Subcommand, Debug)]
pub enum Stage {
    /// One navigation controller: camera ball in, aim out (`<group>/aim`), in group `--group`.
    ///
    /// Example: rl chain nav --id 1
    Nav(nav::NavArgs),
    /// One actuator controller: the navigation group's aim in, servo commands out
    /// (`dds.command_topic`), in the configuration's group.
    ///
    /// Example: rl chain act --id 1
    Act(act::ActArgs),
}

/// What both stages take: which copy, the configuration, the events (as `rl controller`).
pub type StageArgs = crate::cli::ControllerRunArgs;

/// Runs `rl chain`.
pub fn run(args: ChainArgs) -> Result<(), crate::Error> {
    match args.stage {
        Stage::Nav(args) => nav::run(args),
        Stage::Act(args) => act::run(args),
    }
}

/// A chain stage's own line beside RL's events (`--json-events`): the actuator controller
/// says whose aim it follows.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "event", rename_all = "snake_case")]
pub enum ChainLine {
    /// The navigation controller whose aims this actuator controller applies changed.
    AimOwner {
        /// This actuator controller.
        id: ControllerId,
        /// The navigation controller it followed (`None`: none yet).
        from: Option<ControllerId>,
        /// The one it follows now (`None`: a writer not yet matched to a controller).
        to: Option<ControllerId>,
    },
}

impl ChainLine {
    /// A stage's line, or `None` for anything else (RL's events, console lines).
    pub fn parse(text: &str) -> Option<ChainLine> {
        serde_json::from_str(text).ok()
    }
}

/// The stage's configuration: the file or the defaults, `--domain`, then `group` as the
/// group (checked as `dds.group` is).
fn stage_config(
    args: &StageArgs,
    group: Option<&str>,
) -> Result<rl_layer::config::Config, crate::Error> {
    let mut config = crate::cli::load_config(args.config.as_deref(), args.domain)?;
    if let Some(group) = group {
        config.dds.group = group.to_string();
        config.validate().map_err(|invalid| {
            crate::Error::Usage(format!(
                "--group {group}: {} = {}: {}",
                invalid.field, invalid.value, invalid.rule
            ))
        })?;
    }
    Ok(config)
}

/// A write that failed is counted and warned about (at the 1st, 2nd, 4th, ... failure) and
/// skipped, as `rl controller` does with its commands: the next frame's output follows within
/// a frame.
fn note_write(written: Result<bool, rl_layer::dds::DdsError>, write_errors: &mut u64, what: &str) {
    if let Err(error) = written {
        *write_errors += 1;
        if write_errors.is_power_of_two() {
            tracing::warn!(write_errors = *write_errors, "{what} not written: {error}");
        }
    }
}

/// Waits for the readers registered with `poll`, at most until the writer's next keep-alive
/// (`due_in`) and 50 ms, so that signals and RL's stop are noticed.
fn wait(
    poll: &rustdds::mio::Poll,
    events: &mut rustdds::mio::Events,
    due_in: Option<std::time::Duration>,
    what: &str,
) -> Result<(), crate::Error> {
    let most = std::time::Duration::from_millis(50);
    match poll.poll(events, Some(due_in.unwrap_or(most).min(most))) {
        Ok(_) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::Interrupted => Ok(()),
        Err(e) => Err(crate::Error::io(format!("waiting for {what}"), e)),
    }
}

/// Starts RL for the stage's copy, runs `application` until it returns (a signal, RL
/// stopped, an error), then stops RL: how either ended (RL's `Failed` exits 75 to be
/// restarted).
fn run_stage(
    args: &StageArgs,
    config: &rl_layer::config::Config,
    application: impl FnOnce(
        &rl_layer::api::Redundancy,
        &std::sync::atomic::AtomicBool,
    ) -> Result<(), crate::Error>,
) -> Result<(), crate::Error> {
    let stop = crate::cli::stop_on_signals()?;
    let options = rl_layer::api::Options {
        json_events: args.json_events,
        console_leds: false,
        voting_progress: None,
    };
    let rl = rl_layer::api::Redundancy::start(config, args.id, options)?;
    let result = application(&rl, &stop);
    let stopped = rl.stop();
    result.and(stopped.map_err(crate::Error::from))
}

/// Milliseconds since `started`, for the owner feeds.
fn elapsed_ms(started: std::time::Instant) -> u64 {
    u64::try_from(started.elapsed().as_millis()).unwrap_or(u64::MAX)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_aim_owner_line_reads_back_and_an_event_line_is_not_one() {
        let line = ChainLine::AimOwner {
            id: 2,
            from: Some(1),
            to: Some(3),
        };
        let text = serde_json::to_string(&line).expect("serializable");
        assert_eq!(
            text, r#"{"event":"aim_owner","id":2,"from":1,"to":3}"#,
            "the documented shape"
        );
        assert_eq!(ChainLine::parse(&text), Some(line));
        assert_eq!(ChainLine::parse(r#"{"event":"output","id":1}"#), None);
        assert_eq!(ChainLine::parse("C1 steady primary"), None);
    }
}
