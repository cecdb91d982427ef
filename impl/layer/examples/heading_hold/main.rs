//! A navigation controller made redundant with RL: docs/api.md walks through it.
//!
//! Each of three copies (`--id 1`, `2`, `3`, on three machines or one) computes the heading to
//! steer from where the boat is and where it must go, and publishes it on `nav/heading`, a
//! topic of its own type. RL votes the copies Primary/Secondary/Tertiary and gives each copy's
//! writer the ownership strength of its role, so a reader of `nav/heading` follows the
//! Primary, and the Secondary within the command deadline when the Primary dies.
//!
//!     cargo run --release -p rl-layer --example heading_hold -- --id 1 --domain 60
//!
//! It runs until Ctrl-C, or exits with status 75 when RL has voted it FAILED (its supervisor
//! restarts it, and it rejoins in the lowest free role).

use rl_layer::api::{AperiodicPolicy, Options, Redundancy, RoleWriter};
use rl_layer::config::Config;
use rl_layer::core::ControllerId;
use rl_layer::event::Event;
use serde::{Deserialize, Serialize};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// The application's own sample type: what its readers (an autopilot) decode.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Heading {
    /// Degrees clockwise from north, 0..360.
    pub degrees: f32,
    /// Which controller computed it (for the reader's log; ownership needs no field).
    pub from_id: u8,
}

/// The topic and its DDS type name, shared with the readers.
pub const HEADING_TOPIC: &str = "nav/heading";
pub const HEADING_TYPE: &str = "nav::Heading";

/// The control law: the bearing from `position` to `waypoint` (x east, y north, metres).
pub fn heading_to(position: (f32, f32), waypoint: (f32, f32)) -> f32 {
    let (east, north) = (waypoint.0 - position.0, waypoint.1 - position.1);
    east.atan2(north).to_degrees().rem_euclid(360.0)
}

/// The boat's position `t` seconds into the run (a stand-in for the GPS every copy reads).
fn position_at(t: f32) -> (f32, f32) {
    (10.0 * t.sin(), 2.0 * t)
}

/// One redundant copy: joins RL as `id`, then writes a heading every 100 ms until `stop` is
/// set or RL stops (FAILED). Returns how RL ended.
pub fn run(config: &Config, id: ControllerId, stop: &AtomicBool) -> Result<(), rl_layer::Error> {
    let rl = Redundancy::start(config, id, Options::default())?;
    let events = rl.events();
    // Republish: RL writes the last heading again before the deadline if this loop is late,
    // so a weaker copy never leaks through to the reader.
    let mut headings: RoleWriter<Heading> =
        rl.role_writer(HEADING_TOPIC, HEADING_TYPE, AperiodicPolicy::Republish)?;
    let started = Instant::now();
    let mut next = started;
    while !stop.load(Ordering::SeqCst) && !rl.is_finished() {
        if Instant::now() >= next {
            let position = position_at(started.elapsed().as_secs_f32());
            let degrees = heading_to(position, (0.0, 1000.0));
            // Ok(false): no role now (forming, FAILED, or stood down), nothing written.
            headings.write(Heading {
                degrees,
                from_id: id,
            })?;
            next += Duration::from_millis(100);
        }
        headings.keep_alive()?;
        // What RL did since the last turn: the role changes are what an operator wants to see.
        for line in events.try_iter() {
            if let Event::Output { role, strength } = line.event {
                eprintln!("C{id}: now {role:?} at strength {strength:?}");
            }
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    // Err(Error::Failed) when RL voted this copy FAILED: exit with its code to be restarted.
    rl.stop()
}

fn main() -> ExitCode {
    let mut args = std::env::args().skip(1);
    let mut id = None;
    let mut config = Config::default();
    while let Some(flag) = args.next() {
        let value = args.next();
        match (flag.as_str(), value.as_deref()) {
            ("--id", Some(value)) => match value.parse::<ControllerId>() {
                Ok(value) if (1..=250).contains(&value) => id = Some(value),
                _ => {
                    eprintln!("heading_hold: --id {value}: must be 1..=250");
                    return ExitCode::from(2);
                }
            },
            ("--domain", Some(value)) => match value.parse() {
                Ok(domain) => config.dds.domain = domain,
                Err(_) => {
                    eprintln!("heading_hold: --domain {value}: must be 0..=232");
                    return ExitCode::from(2);
                }
            },
            _ => {
                eprintln!("usage: heading_hold --id 1..=250 [--domain 0..=232] (at {flag:?})");
                return ExitCode::from(2);
            }
        }
    }
    let Some(id) = id else {
        eprintln!("usage: heading_hold --id 1..=250 [--domain 0..=232]: --id is needed");
        return ExitCode::from(2);
    };
    if let Err(invalid) = config.validate() {
        eprintln!(
            "heading_hold: --domain {}: {}",
            config.dds.domain, invalid.rule
        );
        return ExitCode::from(2);
    }
    let stop = Arc::new(AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        if let Err(error) = signal_hook::flag::register(signal, Arc::clone(&stop)) {
            eprintln!("heading_hold: installing a signal handler: {error}");
            return ExitCode::from(1);
        }
    }
    match run(&config, id, &stop) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("heading_hold: {error}");
            ExitCode::from(error.exit_code())
        }
    }
}

#[cfg(test)]
mod tests;
