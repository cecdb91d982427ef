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
    /// A window due at a boundary that the trace leaves open into the round.
    #[error(
        "step {step}: C{controller}'s window, due at the boundary before, is left open into \
         the round (the implementation expires every due window at the boundary)"
    )]
    WindowLeftOpen { step: usize, controller: u8 },
    /// `DeliverVotes` belongs to the paper variant.
    #[error("durable-vote delivery exists only in the paper variant")]
    PaperVariantAction,
    /// A slowed process or a stall that ends unnoticed (F18): the lab runs them on processes
    /// (`lab run starve-primary`, `freeze-primary`), the trace set has none.
    #[error("a gray process fault (\"{action}\"): the fault lab's, not the trace replay's")]
    GrayFault { action: Action },
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
    /// Faults after a pulled cable is plugged back in need a quiescent boundary to
    /// re-align at.
    #[error(
        "round {round} has faults after a pulled cable was plugged back in, with no quiescent \
         boundary to re-align at"
    )]
    FaultsAfterReplug { round: usize },
    /// A controller heard a round or two after its cables are plugged back in would change
    /// the settled end.
    #[error(
        "its settled end changes if the controller plugged back in in round {round} is heard \
         {rounds} round(s) later"
    )]
    ReplugHeardLate { round: usize, rounds: usize },
    /// The model refused the run with a controller heard late after its heal.
    #[error("with {newcomers} heard late after a heal: {cause}")]
    ReplugHeardLateRun {
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
            PlanError::WindowLeftOpen { .. } => "a window due at a boundary left open",
            PlanError::PaperVariantAction => "durable-vote delivery (the paper variant)",
            PlanError::GrayFault { .. } => "a gray process fault (the fault lab's)",
            PlanError::CutBeyondTheLan { .. } => "a cut among more than three controllers",
            PlanError::NoSettle { .. } => "no settled end",
            PlanError::NoRoundEnds => "no round ends",
            PlanError::FaultsAfterReplug { .. } => {
                "faults after a pulled cable plugged back in, with no quiescent boundary"
            }
            PlanError::ReplugHeardLate { .. } => {
                "a controller heard late after a heal changes its settled end"
            }
            PlanError::ReplugHeardLateRun { cause, .. } => {
                return format!(
                    "with a controller heard late after a heal: {}",
                    cause.reason()
                )
            }
        };
        kind.to_string()
    }
}
