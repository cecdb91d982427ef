//! `rl demo --architecture` and `--controllers`: which of the paper's architectures the demo
//! shows, with how many controllers, and the configuration that carries the choice to the
//! children.

use rl_layer::config::{ArchitectureName, Config};
use rl_layer::core::ControllerId;
use std::path::{Path, PathBuf};

/// `rl demo --architecture`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum DemoArchitecture {
    /// Three-way voting (RL's protocol).
    Voting,
    /// The simple duplex.
    Duplex,
    /// The lockstep pair in software.
    Pair,
}

impl DemoArchitecture {
    pub(super) fn config_name(self) -> ArchitectureName {
        match self {
            DemoArchitecture::Voting => ArchitectureName::Voting,
            DemoArchitecture::Duplex => ArchitectureName::Duplex,
            DemoArchitecture::Pair => ArchitectureName::Pair,
        }
    }
}

/// The controllers the demo runs: `--controllers` of voting's 1 to 3 (default 3), or the two
/// a duplex or a pair configures.
pub(super) fn controller_ids(
    config: &Config,
    controllers: Option<u8>,
) -> Result<Vec<ControllerId>, crate::Error> {
    let members = match config.architecture {
        ArchitectureName::Voting => return Ok((1..=controllers.unwrap_or(3)).collect()),
        ArchitectureName::Duplex => vec![config.duplex.primary, config.duplex.standby],
        ArchitectureName::Pair => config.pair.members.to_vec(),
    };
    match controllers {
        None | Some(2) => Ok(members),
        Some(n) => Err(crate::Error::Usage(format!(
            "--controllers {n}: a {} has exactly 2 controllers",
            architecture_name(config.architecture)
        ))),
    }
}

pub(super) fn architecture_name(name: ArchitectureName) -> &'static str {
    match name {
        ArchitectureName::Voting => "three-way voting",
        ArchitectureName::Duplex => "simple duplex",
        ArchitectureName::Pair => "lockstep pair",
    }
}

/// Writes the children's configuration (`demo.toml` in the recording directory, else in the
/// temp dir, named by the demo's pid) and returns its path.
pub(super) fn write_children_config(
    config: &Config,
    record: Option<&Path>,
) -> Result<PathBuf, crate::Error> {
    let path = match record {
        Some(dir) => dir.join("demo.toml"),
        None => std::env::temp_dir().join(format!("rl-demo-{}.toml", std::process::id())),
    };
    let text = config
        .to_toml_string()
        .map_err(|e| crate::Error::runtime(format!("writing the children's configuration: {e}")))?;
    std::fs::write(&path, text)
        .map_err(|e| crate::Error::io(format!("writing {}", path.display()), e))?;
    Ok(path)
}
