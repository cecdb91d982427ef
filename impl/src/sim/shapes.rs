//! `rl shapes`: the camera simulator. It publishes `Circle` samples (`ShapeTypeExtended`, as
//! the original PixyShapes camera application and the RTI Shapes Demo do): the YELLOW ball the
//! trackers follow, plus RED and BLUE circles on fixed paths so the colour filter has something
//! to reject.
//!
//! The camera sits on the pan-tilt gimbal (crate::sim::gimbal): it reads `pixy/servo_control`
//! as the real pan-tilt does (the owner's commands, rl_layer::owner_feed), moves its
//! rate-limited servos, and sees the ball where it is relative to where the gimbal points. So
//! the trackers close the loop and keep the ball near the centre, through failovers. With
//! `--json` it prints one line per frame: where it saw the ball and how far off centre
//! ([`CameraFrame`]), the tracking error `rl demo` and `rl bench` report. `--open-loop` moves
//! the YELLOW circle on a fixed path in the frame instead, whatever the gimbal does; `--vote`
//! makes the gimbal follow the vote on the voted command topic (rl_layer::vote_feed: a command
//! two controllers agree on) instead of the exclusive topic's owner.
//!
//! Positions stay inside the shapes application's range, x 0..222 and y 0..252, and every
//! path is a pure function of time, so runs are reproducible.

use crate::sim::gimbal::{ball, error_px, Gimbal};
use crate::Error;
use rl_layer::dds::Session;
use rl_layer::owner_feed::OwnerFeed;
use rl_layer::vote_feed::VoteFeed;
use rl_layer::vote_reader::{ServoRule, VoteEvent, VoteSettings};
use rl_layer::wire::{ServoControl, ShapeFillKind, ShapeTypeExtended};
use std::f64::consts::TAU;
use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

/// The camera simulator: publishes a YELLOW circle moving on a path, plus RED and BLUE ones.
#[derive(Clone, Debug, clap::Args)]
pub struct ShapesArgs {
    /// Configuration file (rl.toml) for the domain and the camera topic name.
    #[arg(long, value_name = "PATH")]
    pub config: Option<PathBuf>,
    /// DDS domain id (overrides the configuration).
    #[arg(long, value_name = "D")]
    pub domain: Option<u16>,
    /// Samples per second of each circle.
    #[arg(long, value_name = "HZ", default_value_t = 30.0)]
    pub rate_hz: f64,
    /// Exit after this many milliseconds (default: run until SIGINT/SIGTERM).
    #[arg(long, value_name = "MS")]
    pub duration_ms: Option<u64>,
    /// Move the YELLOW circle on a fixed path in the frame, ignoring the gimbal's commands.
    #[arg(long)]
    pub open_loop: bool,
    /// The gimbal follows the vote on the voted command topic (a command two controllers
    /// agree on, rl_layer::vote_reader, holding without a majority) instead of the exclusive
    /// command topic's owner.
    #[arg(long, conflicts_with = "open_loop")]
    pub vote: bool,
    /// Print one JSON line per frame (`{"event":"frame",...}`: where the ball was seen, how far
    /// off centre, where the gimbal points) instead of the start and stop lines.
    #[arg(long)]
    pub json: bool,
}

/// One frame of `rl shapes --json`.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "event", rename = "frame")]
pub struct CameraFrame {
    /// Milliseconds since the camera started.
    pub t_ms: u64,
    /// Where the YELLOW ball is in the frame; `null` when the camera does not see it.
    pub x: Option<i32>,
    pub y: Option<i32>,
    /// Distance of the ball from the frame centre (111, 126) in pixels; `null` if not seen.
    pub error_px: Option<f64>,
    /// Where the gimbal's servos are (0..=1000).
    pub pan: f64,
    pub tilt: f64,
}

/// The shapes application's drawing area.
pub const X_MAX: i32 = 222;
pub const Y_MAX: i32 = 252;
/// Circle diameter.
pub const SHAPE_SIZE: i32 = 30;

/// The circles published: colour and path.
pub const COLORS: [&str; 3] = ["YELLOW", "RED", "BLUE"];

/// Where the circle of `color` is at `t_s` seconds. The YELLOW path is a 3:2 Lissajous curve
/// (one full figure every 12 s) around the centre (111, 126) that the tracker aims at; RED
/// circles the centre; BLUE sweeps left and right across the bottom.
pub fn position(color: &str, t_s: f64) -> (i32, i32) {
    let (cx, cy) = (f64::from(X_MAX) / 2.0, f64::from(Y_MAX) / 2.0);
    let (x, y) = match color {
        "YELLOW" => (
            cx + 90.0 * (TAU * t_s / 4.0).sin(),
            cy + 100.0 * (TAU * t_s / 6.0 + 0.5).sin(),
        ),
        "RED" => (
            cx + 60.0 * (TAU * t_s / 5.0).cos(),
            cy + 60.0 * (TAU * t_s / 5.0).sin(),
        ),
        _ => (
            cx + 100.0 * (TAU * t_s / 8.0).sin(),
            f64::from(Y_MAX) - 20.0,
        ),
    };
    // `as` saturates; the clamp keeps rounding from leaving the area.
    (
        (x.round() as i32).clamp(0, X_MAX),
        (y.round() as i32).clamp(0, Y_MAX),
    )
}

/// The sample of `color` at `t_s`.
pub fn shape(color: &str, t_s: f64) -> ShapeTypeExtended {
    let (x, y) = position(color, t_s);
    ShapeTypeExtended {
        color: color.to_string(),
        x,
        y,
        shapesize: SHAPE_SIZE,
        fill_kind: ShapeFillKind::SolidFill,
        angle: 0.0,
    }
}

/// Publishes the circles until SIGINT/SIGTERM or `--duration-ms`.
pub fn run(args: ShapesArgs) -> Result<(), Error> {
    if !(args.rate_hz.is_finite() && args.rate_hz > 0.0 && args.rate_hz <= 1000.0) {
        return Err(Error::Usage(format!(
            "--rate-hz: {} is not in (0, 1000]",
            args.rate_hz
        )));
    }
    let config = crate::cli::load_config(args.config.as_deref(), args.domain)?;
    let stop = crate::cli::stop_on_signals()?;
    let keystore = rl_layer::security::keystore_of(&config)?;
    let session = Session::with_keystore(&config.dds, &config.timing, false, keystore.as_ref())
        .map_err(Error::dds)?;
    let writer = session.camera_writer().map_err(Error::dds)?;
    let mut feed = GimbalCommands::open(&args, &session)?;
    let mut gimbal = Gimbal::default();
    if !args.json {
        println!(
            "shapes: publishing {} circles on {} (domain {}) at {} Hz, {}",
            COLORS.join(", "),
            config.dds.camera_topic,
            config.dds.domain,
            args.rate_hz,
            match (args.open_loop, args.vote) {
                (true, _) => "YELLOW on a fixed path",
                (false, false) => "seen from the gimbal (closed loop)",
                (false, true) => "seen from the gimbal following the voted commands (closed loop)",
            }
        );
    }

    let period = Duration::from_secs_f64(1.0 / args.rate_hz);
    let start = Instant::now();
    let mut next = start;
    let mut published: u64 = 0;
    while !stop.load(Ordering::Relaxed) {
        let elapsed = start.elapsed();
        if args
            .duration_ms
            .is_some_and(|limit| elapsed >= Duration::from_millis(limit))
        {
            break;
        }
        let t_s = elapsed.as_secs_f64();
        let t_ms = u64::try_from(elapsed.as_millis()).unwrap_or(u64::MAX);
        let yellow = see_yellow(&mut feed, &mut gimbal, &session, t_s, t_ms, period);
        for color in COLORS {
            let sample = match (color, yellow) {
                ("YELLOW", None) => continue,
                ("YELLOW", Some((x, y))) => ShapeTypeExtended {
                    x,
                    y,
                    ..shape(color, t_s)
                },
                _ => shape(color, t_s),
            };
            writer.write(&sample).map_err(Error::dds)?;
        }
        // A closed stdout (the reader left) ends the camera.
        if args.json && !print_frame(t_ms, yellow, &gimbal) {
            return Ok(());
        }
        published += 1;
        // Fixed-rate schedule; after a stall, resume from now rather than bursting.
        next += period;
        let now = Instant::now();
        if next > now {
            std::thread::sleep(next - now);
        } else {
            next = now;
        }
    }
    if !args.json {
        println!("shapes: stopped after {published} rounds");
    }
    Ok(())
}

/// What the gimbal follows.
enum GimbalCommands {
    /// The exclusive command topic's owner, as the camera application's pan-tilt does.
    Owner(OwnerFeed<ServoControl>),
    /// The vote on the voted command topic (`--vote`).
    Vote(VoteFeed<ServoControl, ServoRule>),
}

impl GimbalCommands {
    /// What `args` ask the gimbal to follow: nothing with `--open-loop`.
    fn open(args: &ShapesArgs, session: &Session) -> Result<Option<GimbalCommands>, Error> {
        let deadline_ms = session.timing().command_deadline_ms;
        Ok(match (args.open_loop, args.vote) {
            (true, _) => None,
            (false, false) => Some(GimbalCommands::Owner(
                OwnerFeed::open(
                    session,
                    session.command_reader().map_err(Error::dds)?,
                    deadline_ms,
                    session.timing().peer_deadline_ms,
                )
                .map_err(Error::dds)?,
            )),
            (false, true) => Some(GimbalCommands::Vote(crate::sim::vote_mutated(
                VoteFeed::servo_commands(
                    session,
                    ServoRule::default(),
                    VoteSettings::holding(deadline_ms),
                )
                .map_err(Error::dds)?,
            )?)),
        })
    }

    /// The newest command to move to, if one came since the last call.
    fn newest(&mut self, session: &Session, t_ms: u64) -> Option<ServoControl> {
        match self {
            GimbalCommands::Owner(feed) => feed.take(session, t_ms).map(|(command, _)| command),
            GimbalCommands::Vote(feed) => {
                let mut decided = feed.take(t_ms).into_iter().filter_map(|event| match event {
                    VoteEvent::Accepted { value, .. } => Some(value),
                    // Holding keeps the last accepted command; a safe one is gone to.
                    VoteEvent::NoMajority { value, .. } => value,
                    VoteEvent::Dissent { .. } => None,
                });
                decided.next_back()
            }
        }
    }
}

/// Where the camera sees the YELLOW ball this frame: on its fixed path (open loop), or from
/// the gimbal after `period` of servo motion toward the newest command it follows.
fn see_yellow(
    feed: &mut Option<GimbalCommands>,
    gimbal: &mut Gimbal,
    session: &Session,
    t_s: f64,
    t_ms: u64,
    period: Duration,
) -> Option<(i32, i32)> {
    let Some(feed) = feed else {
        return Some(position("YELLOW", t_s));
    };
    if let Some(command) = feed.newest(session, t_ms) {
        gimbal.command(command.pan, command.tilt);
    }
    gimbal.advance(period.as_secs_f64());
    gimbal.sees(ball(t_s))
}

/// One `--json` frame line on stdout; false once stdout is closed.
fn print_frame(t_ms: u64, yellow: Option<(i32, i32)>, gimbal: &Gimbal) -> bool {
    use std::io::Write;
    let frame = CameraFrame {
        t_ms,
        x: yellow.map(|(x, _)| x),
        y: yellow.map(|(_, y)| y),
        error_px: yellow.map(error_px),
        pan: gimbal.pan,
        tilt: gimbal.tilt,
    };
    let Ok(line) = serde_json::to_string(&frame) else {
        return true;
    };
    let mut out = std::io::stdout().lock();
    writeln!(out, "{line}").and_then(|()| out.flush()).is_ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_path_stays_inside_the_drawing_area() {
        for color in COLORS {
            for step in 0..2400 {
                let (x, y) = position(color, f64::from(step) * 0.01);
                assert!(
                    (0..=X_MAX).contains(&x) && (0..=Y_MAX).contains(&y),
                    "{color} {x},{y}"
                );
            }
        }
    }

    #[test]
    fn yellow_moves_and_repeats() {
        assert_ne!(position("YELLOW", 0.0), position("YELLOW", 1.0));
        assert_eq!(position("YELLOW", 0.3), position("YELLOW", 12.3));
        let sample = shape("YELLOW", 2.0);
        assert_eq!(sample.color, "YELLOW");
        assert_eq!(sample.shapesize, SHAPE_SIZE);
    }
}
