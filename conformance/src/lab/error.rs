//! What can go wrong in the fault lab: the host (not root, a tool missing), a system command
//! (`ip`, `nft`, `tc`), the processes under test, the run's output files. A run that completes
//! but fails a judge is not an error: it is a verdict (`super::judge`).

use std::path::PathBuf;

/// Why a lab run could not be carried out.
#[derive(Debug, thiserror::Error)]
pub enum LabError {
    /// The lab creates network namespaces, links, qdiscs and firewall rules.
    #[error("the lab needs root: it creates network namespaces, links and nftables rules (run it as root)")]
    NotRoot,
    /// A program the lab runs is not installed.
    #[error("`{tool}` is missing (Debian: apt-get install {package}); the lab needs it {why}")]
    MissingTool {
        tool: String,
        package: &'static str,
        why: &'static str,
    },
    /// A judge cannot run, and `--lenient` was not given to go on without it.
    #[error("{judge} cannot run: {fix}; a run with a judge missing is refused (--lenient skips it with a warning)")]
    MissingJudge { judge: String, fix: String },
    /// A system command exited non-zero or could not start.
    #[error("`{command}` failed: {message}")]
    Command { command: String, message: String },
    /// A process under test could not be started.
    #[error("starting {what}: {source}")]
    Spawn {
        what: String,
        source: std::io::Error,
    },
    /// The `rl` binary the processes run is not where it was looked for.
    #[error("no rl binary at {} (build it: cargo build --release -p rl; or pass --rl PATH)", path.display())]
    NoRlBinary { path: PathBuf },
    /// A file or directory of the run's output.
    #[error("{}: {source}", path.display())]
    Output {
        path: PathBuf,
        source: std::io::Error,
    },
    /// The picture of a run could not be drawn.
    #[error("drawing {}: {message}", path.display())]
    Plot { path: PathBuf, message: String },
    /// `lab run NAME` with a name `lab list` does not show.
    #[error("no scenario named {name:?} (`lab list` shows them)")]
    UnknownScenario { name: String },
    /// A scenario without expectations of its own (`super::expect::for_scenario`).
    #[error(transparent)]
    NoExpectations(#[from] super::expect::UnknownScenario),
    /// The system did not form before faults were due (P, S, T steady, the actuator following).
    #[error("{scenario} is not run under the {architecture}: {reason}")]
    NotUnderArchitecture {
        scenario: String,
        architecture: &'static str,
        reason: &'static str,
    },

    #[error("no formation within {waited_s} s: {detail}")]
    NoFormation { waited_s: u64, detail: String },
    /// `--mutation NAME`, and a controller's `rl` exited saying it knows no such mutation.
    #[error("the rl at {} rejected the mutation {name:?}: {message}", rl.display())]
    MutationRejected {
        name: String,
        rl: PathBuf,
        message: String,
    },
    /// `--vote-mutation` for a scenario without a voting reader.
    #[error("--vote-mutation breaks the voting reader, which only the wrong-output scenarios run ({scenario} does not: `lab list`)")]
    NoVotingReader { scenario: String },
    /// A controller asked for wrong commands never said it took the fault: its `rl` was built
    /// without the `fault-injection` feature, which leaves stdin unread.
    #[error("the rl at {} did not take the wrong-output fault ({lives} never acknowledged it): the wrong-output scenarios need an rl built with the `fault-injection` feature (the workspace's test build, --all-features)", rl.display())]
    InjectionIgnored { rl: PathBuf, lives: String },
    /// `--mutation NAME`, and controllers formed without saying they run it: their `rl` was
    /// built without the `mutation` feature, which ignores `RL_MUTATION`.
    #[error("the rl at {} does not run the mutation {name:?} ({silent} never announced it): --mutation needs an rl built with the `mutation` feature (cargo build --release -p rl --features mutation, or the workspace's test build with --all-features)", rl.display())]
    MutationIgnored {
        name: String,
        rl: PathBuf,
        silent: String,
    },
}

impl LabError {
    /// A system command's failure, with the command line as it was run.
    pub fn command(program: &str, args: &[&str], message: impl Into<String>) -> LabError {
        LabError::Command {
            command: std::iter::once(program)
                .chain(args.iter().copied())
                .collect::<Vec<_>>()
                .join(" "),
            message: message.into(),
        }
    }

    /// An output file's I/O error, naming the file.
    pub fn output(path: &std::path::Path, source: std::io::Error) -> LabError {
        LabError::Output {
            path: path.to_path_buf(),
            source,
        }
    }
}
