//! Why a trace cannot be replayed on real processes ([`PlanError`], the plan's refusal), and
//! the kind of each refusal without its particulars ([`PlanError::reason`]), by which
//! `dds-replay-all` counts them. Kept apart from [`mod@super::plan`], which decides them.

use model::Action;

/// Why a trace cannot be replayed on real processes.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum PlanError {
    /// The paper variant and model mutations are not RL's rules.
    #[error("not a default-variant trace")]
    NotDefaultVariant,
    /// The trace names an initial state the model does not have.
    #[error("its initial state index {index} is not one of the model's")]
    UnknownInitialState { index: usize },
    /// The run's round lengths change the initial state.
    #[error("its initial state differs under the run's round lengths")]
    InitialStateDiffers,
    /// A step the model does not offer in the state it is taken in.
    #[error("the model does not allow \"{action}\" here")]
    NotAllowed { action: Action },
    /// A step reaches another state under the run's round lengths.
    #[error(
        "step {step} ({action}) reaches another state with a {run_window_rounds}-round window \
         (the trace was generated with {trace_window_rounds} rounds)"
    )]
    StateDiffers {
        step: usize,
        action: Action,
        run_window_rounds: u8,
        trace_window_rounds: u8,
    },
    /// Windows expire at the boundary, before anything else of the round.
    #[error("step {step}: a window expires after another action of its round")]
    WindowAfterOtherAction { step: usize },
    /// `DeliverVotes` belongs to the paper variant.
    #[error("durable-vote delivery exists only in the paper variant")]
    PaperVariantAction,
    /// A starved link delays some datagrams and drops others as the queue decides: the round
    /// in which the actuator misses a deadline or a peer sees a late command (`Lag`,
    /// `CatchUp`, F17's takeover) is the kernel's, not a round the replay can choose (the
    /// fault lab's `tbf-*` scenarios judge it by outcome).
    #[error("step {step}: \"{action}\" (a starved link) is not replayed on processes")]
    StarvedLink { step: usize, action: Action },
    /// A resume sooner than a peer deadline after its pause: the runtime restarts only after
    /// a stall of at least a peer deadline (impl/layer/src/stall.rs), which the model's
    /// `Resume` stands for.
    #[error(
        "step {step}: C{controller} resumes {rounds} round(s) after its pause, sooner than \
         the stall the runtime restarts after ({stall_rounds} rounds)"
    )]
    ShortPause {
        step: usize,
        controller: u8,
        rounds: usize,
        stall_rounds: u8,
    },
    /// A cut needs each controller in a network namespace of its own, and the virtual LAN
    /// has three.
    #[error("a cut among {controllers} controllers (the virtual LAN has three)")]
    CutBeyondTheLan { controllers: usize },
    /// The model keeps changing after the trace's last step.
    #[error("does not settle within {rounds} rounds")]
    NoSettle { rounds: usize },
    /// Nothing to compare: the trace ends before its first round does.
    #[error("no round ends")]
    NoRoundEnds,
    /// The replay aligns on the first report; without one it cannot.
    #[error(
        "no controller reports anything at the first round's end, so the replay cannot tell \
         which real round it is"
    )]
    NoFirstReport,
    /// Faults after a late start need a quiescent boundary to re-align at.
    #[error(
        "round {round} has faults after a process started late, with no quiescent boundary to \
         re-align at"
    )]
    FaultsAfterLateStart { round: usize },
    /// DDS discovery at start would change the trace's states.
    #[error("its states change if {late} is heard one round later at start (DDS discovery)")]
    DiscoveryAtStart { late: String },
    /// DDS discovery of a late process would change the settled end.
    #[error(
        "its settled end changes if the process started in round {round} is heard {rounds} \
         round(s) later (DDS discovery)"
    )]
    DiscoveryAfterLateStart { round: usize, rounds: usize },
    /// The model refused the run with a late-discovered newcomer.
    #[error("with {newcomers} discovered late: {cause}")]
    LateDiscoveryRun {
        newcomers: String,
        cause: Box<PlanError>,
    },
}

impl PlanError {
    /// The kind of refusal, without its step, round or controllers: what `dds-replay-all`
    /// counts refusals by, each kind argued in docs/conformance.md ("What real processes
    /// cannot take").
    pub fn reason(&self) -> String {
        let kind = match self {
            PlanError::NotDefaultVariant => "not a default-variant trace",
            PlanError::UnknownInitialState { .. } => "an initial state the model does not have",
            PlanError::InitialStateDiffers => {
                "its initial state differs under the run's round lengths"
            }
            PlanError::NotAllowed { .. } => "a step the model does not allow",
            PlanError::StateDiffers { .. } => {
                "a step reaches another state under the run's round lengths"
            }
            PlanError::WindowAfterOtherAction { .. } => {
                "a window expires after another action of its round"
            }
            PlanError::PaperVariantAction => "durable-vote delivery (the paper variant)",
            PlanError::StarvedLink { .. } => "a starved link",
            PlanError::ShortPause { .. } => "a pause shorter than a stall",
            PlanError::CutBeyondTheLan { .. } => "a cut among more than three controllers",
            PlanError::NoSettle { .. } => "no settled end",
            PlanError::NoRoundEnds => "no round ends",
            PlanError::NoFirstReport => "no report at the first round's end",
            PlanError::FaultsAfterLateStart { .. } => {
                "faults after a late start with no quiescent boundary"
            }
            PlanError::DiscoveryAtStart { .. } => "DDS discovery at start changes its states",
            PlanError::DiscoveryAfterLateStart { .. } => {
                "DDS discovery of a late process changes its settled end"
            }
            PlanError::LateDiscoveryRun { cause, .. } => {
                return format!("with a late-discovered newcomer: {}", cause.reason())
            }
        };
        kind.to_string()
    }
}
