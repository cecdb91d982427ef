//! `rl chain nav`: one navigation controller of the chain. It reads the camera's circles of
//! the configured colour and writes, for each frame, the [`Aim`] that frame asks for on
//! `<group>/aim` through a role writer: its ownership strength follows its role in its own
//! group, so the actuator controllers apply the navigation Primary's aims, and the
//! Secondary's within the command deadline when the Primary dies.

use super::{
    aim_topic, note_write, run_stage, stage_config, wait, Aim, StageArgs, AIM_TYPE, NAV_GROUP,
};
use crate::tracker::errors_of;
use rl_layer::api::{AperiodicPolicy, Redundancy, RoleWriter};
use rl_layer::dds::Received;
use rl_layer::wire::ShapeTypeExtended;
use rustdds::mio::{Events, Poll, PollOpt, Ready, Token};
use std::sync::atomic::{AtomicBool, Ordering};

/// Arguments of `rl chain nav`.
#[derive(clap::Args, Debug)]
pub struct NavArgs {
    #[command(flatten)]
    pub stage: StageArgs,
    /// The navigation group's name: its `dds.group`, and the actuator controllers'
    /// `--nav-group`.
    #[arg(long, default_value = NAV_GROUP, value_name = "NAME")]
    pub group: String,
}

const CAMERA: Token = Token(0);

/// Runs `rl chain nav`.
pub fn run(args: NavArgs) -> Result<(), crate::Error> {
    let config = stage_config(&args.stage, Some(&args.group))?;
    run_stage(&args.stage, &config, |rl, stop| {
        steer(rl, &config.tracker.color, &args.group, stop)
    })
}

/// The aim a camera sample asks for; `fallback_frame` when the camera did not stamp it.
pub fn aim_of(shape: &Received<ShapeTypeExtended>, fallback_frame: u64) -> Aim {
    let (pan_error, tilt_error) = errors_of(shape.value.x, shape.value.y);
    let within =
        |error: i64| i32::try_from(error).unwrap_or(if error < 0 { i32::MIN } else { i32::MAX });
    Aim {
        pan_error: within(pan_error),
        tilt_error: within(tilt_error),
        frame: shape
            .source_timestamp
            .map_or(fallback_frame, |stamp| stamp.to_ticks()),
    }
}

/// Camera in, aims out, until a signal or RL stops.
fn steer(rl: &Redundancy, color: &str, group: &str, stop: &AtomicBool) -> Result<(), crate::Error> {
    let dds = |e: rl_layer::dds::DdsError| crate::Error::dds(e);
    let mut camera = rl.session().camera_reader().map_err(dds)?;
    // Republish: the last aim goes out again before the deadline while the camera is quiet,
    // so the actuator controllers never fall to a weaker navigation controller meanwhile.
    let mut aims: RoleWriter<Aim> =
        rl.role_writer(&aim_topic(group), AIM_TYPE, AperiodicPolicy::Republish)?;
    let poll = Poll::new().map_err(|e| crate::Error::io("creating the event poll", e))?;
    poll.register(&camera, CAMERA, Ready::readable(), PollOpt::edge())
        .map_err(|e| crate::Error::io("registering the camera reader", e))?;
    let mut events = Events::with_capacity(8);
    let mut unstamped_frames = 0u64;
    let mut write_errors = 0u64;
    while !stop.load(Ordering::SeqCst) && !rl.is_finished() {
        for shape in camera.take() {
            if shape.value.color != color {
                continue;
            }
            // An unstamped frame gets a number of this controller's own (high bit set, so it
            // never equals a stamp); only the owner's aims reach the actuator group anyway.
            unstamped_frames += 1;
            let aim = aim_of(&shape, (1 << 63) | unstamped_frames);
            note_write(aims.write(aim), &mut write_errors, "aim");
        }
        note_write(aims.keep_alive(), &mut write_errors, "aim");
        wait(
            &poll,
            &mut events,
            aims.keep_alive_due_in(),
            "camera samples",
        )?;
    }
    Ok(())
}
