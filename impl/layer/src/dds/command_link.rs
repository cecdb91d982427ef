//! How this process's commands go out (a `fault-injection` build only): on time, late or held
//! back, as a starved link makes them, set by the controller's stdin control
//! (`delay-commands <ms>`, `hold-commands`, crate::runtime's fault injection) and applied by
//! [`super::StrengthWriter::write`]. The DDS-level replay gives the model's `Starve`, `Lag`
//! and `CatchUp` with it in the trace's round; heartbeats and votes are not touched, as the
//! model's starved link carries them on time. Kept in the DDS adapter, which applies it, so
//! the runtime sets it without the writer reaching back into the runtime.

use std::sync::Mutex;

static COMMAND_LINK: Mutex<CommandLink> = Mutex::new(CommandLink::OnTime);

/// How the commands are to go out.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CommandLink {
    /// Written at once (`delay-commands 0`).
    #[default]
    OnTime,
    /// Each command written this long after it was stamped (`delay-commands <ms>`): late to
    /// every reader, within the command deadline.
    Delayed(u64),
    /// None written (`hold-commands`): the readers miss the command deadline.
    Held,
}

/// How the commands are to go out now.
pub fn get() -> CommandLink {
    *COMMAND_LINK.lock().unwrap_or_else(|e| e.into_inner())
}

/// From now on, the commands go out as `link` says.
pub fn set(link: CommandLink) {
    *COMMAND_LINK.lock().unwrap_or_else(|e| e.into_inner()) = link;
    tracing::warn!("fault injection: commands {link:?}");
}
