//! `rl chain act`: one actuator controller of the chain. It reads the navigation group's aims
//! through an owner feed of that group ([`Redundancy::owner_feed_of_group`]: only that group's
//! live controllers' writers, the strongest owning), applies each frame's aim once with the
//! tracker's PD law, and writes the servo commands on `dds.command_topic` at its own role's
//! strength. While another actuator controller commands, it takes the gimbal's position from
//! that one's commands (bumpless transfer, as `rl controller` does).

use super::{
    aim_topic, elapsed_ms, note_write, run_stage, stage_config, wait, Aim, ChainLine, StageArgs,
    AIM_TYPE, NAV_GROUP,
};
use crate::tracker::{control_law, ControlLaw};
use rl_layer::api::Redundancy;
use rl_layer::core::ControllerId;
use rl_layer::owner_feed::{Delivery, OwnerFeed};
use rl_layer::wire::ServoControl;
use rustdds::mio::{Events, Poll, PollOpt, Ready, Token};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;
use tracing::warn;

/// Arguments of `rl chain act`.
#[derive(clap::Args, Debug)]
pub struct ActArgs {
    #[command(flatten)]
    pub stage: StageArgs,
    /// The navigation group whose aims it applies (that group's `rl chain nav --group`). The
    /// actuator group is the configuration's `dds.group` and must differ from it.
    #[arg(long, default_value = NAV_GROUP, value_name = "NAME")]
    pub nav_group: String,
}

const AIMS: Token = Token(0);

/// Runs `rl chain act`.
pub fn run(args: ActArgs) -> Result<(), crate::Error> {
    let config = stage_config(&args.stage, None)?;
    if config.dds.group == args.nav_group {
        return Err(crate::Error::Usage(format!(
            "--nav-group {}: the actuator controllers' group (dds.group = {:?}) must be another \
             group than the navigation controllers'",
            args.nav_group, config.dds.group
        )));
    }
    let mut stage = ActStage {
        id: args.stage.id,
        json_events: args.stage.json_events,
        pan_tilt: control_law(config.tracker.law, config.tracker.servo_frequency_hz),
        last_frame: None,
        aim_owner: None,
        write_errors: 0,
    };
    run_stage(&args.stage, &config, |rl, stop| {
        stage.drive(rl, &config, &args.nav_group, stop)
    })
}

/// One actuator controller's application state.
struct ActStage {
    id: ControllerId,
    json_events: bool,
    pan_tilt: Box<dyn ControlLaw>,
    /// The frame of the last aim applied: each frame moves the gimbal once.
    last_frame: Option<u64>,
    /// The navigation controller whose aims it applies (`Some(None)`: a writer not matched to
    /// a controller yet).
    aim_owner: Option<Option<ControllerId>>,
    write_errors: u64,
}

impl ActStage {
    /// The navigation owner's aims in, servo commands out, until a signal or RL stops.
    fn drive(
        &mut self,
        rl: &Redundancy,
        config: &rl_layer::config::Config,
        nav_group: &str,
        stop: &AtomicBool,
    ) -> Result<(), crate::Error> {
        let dds = |e: rl_layer::dds::DdsError| crate::Error::dds(e);
        let session = rl.session();
        let mut aims = rl.owner_feed_of_group::<Aim>(nav_group, &aim_topic(nav_group), AIM_TYPE)?;
        let mut owner_commands = OwnerFeed::open(
            session,
            session.command_follower_reader().map_err(dds)?,
            config.timing.command_deadline_ms,
            config.timing.peer_deadline_ms,
        )
        .map_err(dds)?;
        let own_participant = session.participant_key();
        let mut commands = rl.command_writer()?;
        let poll = Poll::new().map_err(|e| crate::Error::io("creating the event poll", e))?;
        for reader in aims.readers() {
            poll.register(reader, AIMS, Ready::readable(), PollOpt::edge())
                .map_err(|e| crate::Error::io("registering the aim reader", e))?;
        }
        let mut events = Events::with_capacity(8);
        let started = Instant::now();
        // The gimbal starts centred, and that is held until the first aim.
        let mut fresh = Some(self.pan_tilt.command());
        while !stop.load(Ordering::SeqCst) && !rl.is_finished() {
            let now_ms = elapsed_ms(started);
            if let Some((command, writer)) = owner_commands.take(session, now_ms) {
                if rl_layer::dds::participant_key(writer) != own_participant {
                    self.pan_tilt.align(command.pan, command.tilt);
                }
            }
            for delivery in aims.deliveries(session, now_ms) {
                if let Delivery::Offered {
                    value,
                    writer,
                    decision,
                    ..
                } = delivery
                {
                    if decision.accepted {
                        self.follow(aims.controller_of(writer));
                        fresh = self.apply(value).or(fresh);
                    }
                }
            }
            let written = match fresh.take() {
                Some(command) => commands.write(ServoControl {
                    pan: command.pan,
                    tilt: command.tilt,
                    frequency: command.frequency,
                }),
                None => commands.keep_alive(),
            };
            note_write(written, &mut self.write_errors, "command");
            wait(&poll, &mut events, commands.keep_alive_due_in(), "aims")?;
        }
        Ok(())
    }

    /// One PD step for an aim of a frame not applied yet; `None` for a frame already applied
    /// (a re-published aim, or the same frame from the next owner).
    fn apply(&mut self, aim: Aim) -> Option<crate::tracker::ServoCommand> {
        if self.last_frame == Some(aim.frame) {
            return None;
        }
        self.last_frame = Some(aim.frame);
        Some(
            self.pan_tilt
                .update_errors(i64::from(aim.pan_error), i64::from(aim.tilt_error)),
        )
    }

    /// Says when the aims come from another navigation controller.
    fn follow(&mut self, controller: Option<ControllerId>) {
        if self.aim_owner == Some(controller) {
            return;
        }
        let line = ChainLine::AimOwner {
            id: self.id,
            from: self.aim_owner.flatten(),
            to: controller,
        };
        self.aim_owner = Some(controller);
        if self.json_events {
            match serde_json::to_string(&line) {
                Ok(text) => println!("{text}"),
                Err(error) => warn!("aim owner line: {error}"),
            }
        } else {
            let name = |id: Option<ControllerId>| id.map_or("-".to_string(), |id| format!("C{id}"));
            println!("C{}: aims from navigation {}", self.id, name(controller));
        }
    }
}
