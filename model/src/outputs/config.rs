//! The size and the rules of an output-voting check: how many controllers may go wrong over a
//! run, whether two wrong ones may agree, the cross-check rule and its limit N (from which the
//! bound K follows), and the deliberately broken rules the mutation tests use.
//!
//! Everything else about the scope is fixed: three controllers, each with a role, and the
//! six ways an answer can go wrong (`super::state::Fault`: four of the output, one of the
//! input, one of the law).

use serde::{Deserialize, Serialize};

/// How a controller counts the inputs at which it was the odd one out of three.
#[derive(
    Clone,
    Copy,
    Debug,
    PartialEq,
    Eq,
    PartialOrd,
    Ord,
    Hash,
    Serialize,
    Deserialize,
    clap::ValueEnum,
)]
#[serde(rename_all = "snake_case")]
pub enum CrossCheck {
    /// N odd-one-out inputs in one life, in a row or not: the rule the properties hold for.
    Cumulative,
    /// N odd-one-out inputs in a row (the rule as first worded): an input at which it is not
    /// the odd one out starts the count again. A controller wrong at every other input is
    /// never caught (finding O2 in docs/findings.md).
    Consecutive,
}

impl CrossCheck {
    pub fn name(self) -> &'static str {
        match self {
            CrossCheck::Cumulative => "cumulative",
            CrossCheck::Consecutive => "consecutive",
        }
    }
}

/// A deliberately broken rule of the output model, to show the checker notices.
#[derive(
    Clone,
    Copy,
    Debug,
    PartialEq,
    Eq,
    PartialOrd,
    Ord,
    Hash,
    Serialize,
    Deserialize,
    clap::ValueEnum,
)]
#[serde(rename_all = "snake_case")]
pub enum OutputMutation {
    /// The voting receiver accepts the first command that arrives for an input, without a
    /// second source agreeing.
    AcceptSingleSource,
    /// A controller closes its comparison of an input only after it has answered the next
    /// one (the cross-check lags one input behind the commands).
    CompareAfterNextCommand,
    /// The cross-check compares outputs only, not inputs: a controller whose input is wrong
    /// and whose output is right is never the odd one out.
    NoInputCongruence,
    /// The cross-check does not compare raw answers: a controller whose law is wrong and whose
    /// aligned output is right is never the odd one out.
    NoRawCompare,
}

/// The output model's configuration.
#[derive(Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct OutputConfig {
    /// Faults that may begin over a run (each makes one controller's output wrong): 0, 1 or 2.
    pub max_wrong: u8,
    /// Two wrong controllers never publish the same wrong value for one input (the scope of
    /// the fail-safe hold); otherwise they may agree (finding O1).
    pub wrong_values_differ: bool,
    /// How odd-one-out inputs are counted.
    pub cross_check: CrossCheck,
    /// N: the odd-one-out inputs after which a controller reports a local fault and leaves.
    pub odd_limit: u8,
    /// A deliberately broken rule (mutation tests only).
    pub mutation: Option<OutputMutation>,
}

/// An output configuration outside the model's bounds; each names the flag.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum OutputConfigError {
    /// More wrong controllers than the model takes: with three wrong there is nobody to
    /// compare with, and three pairwise different wrong values do not exist.
    #[error("wrong: {0} exceeds the output model's maximum of 2 wrong controllers")]
    TooManyWrong(u8),
    /// A limit of 0 would remove every controller before it answered anything.
    #[error("odd-limit: must be at least 1")]
    ZeroOddLimit,
    /// A limit beyond 3 gains nothing the model could show and grows the state space.
    #[error("odd-limit: {0} exceeds the output model's maximum of 3")]
    OddLimitTooLarge(u8),
}

impl Default for OutputConfig {
    /// The scope `check --outputs` runs: one wrong controller, the cumulative rule, N = 2.
    fn default() -> Self {
        OutputConfig {
            max_wrong: 1,
            wrong_values_differ: false,
            cross_check: CrossCheck::Cumulative,
            odd_limit: 2,
            mutation: None,
        }
    }
}

impl OutputConfig {
    /// Two wrong controllers that may agree: the scope of finding O1 (`--wrong 2`).
    pub fn two_wrong() -> OutputConfig {
        OutputConfig {
            max_wrong: 2,
            ..OutputConfig::default()
        }
    }

    /// Two wrong controllers that never agree on a wrong value: the fail-safe hold
    /// (`--wrong 2 --disagreeing`).
    pub fn two_wrong_disagreeing() -> OutputConfig {
        OutputConfig {
            wrong_values_differ: true,
            ..OutputConfig::two_wrong()
        }
    }

    pub fn validate(&self) -> Result<(), OutputConfigError> {
        if self.max_wrong > 2 {
            return Err(OutputConfigError::TooManyWrong(self.max_wrong));
        }
        match self.odd_limit {
            0 => Err(OutputConfigError::ZeroOddLimit),
            1..=3 => Ok(()),
            n => Err(OutputConfigError::OddLimitTooLarge(n)),
        }
    }

    /// K, the most wrong or missing commands an exclusive-ownership receiver takes from one
    /// wrong controller's life. K = N: while at most one controller is wrong, the two others
    /// are correct and agree, so each of the wrong controller's wrong or missing commands makes
    /// it the odd one out of that input; it closes an input's comparison before it answers
    /// the next one, so its N-th such command is its last (docs/protocol.md, "Output voting").
    pub fn exclusive_bound(&self) -> u8 {
        self.odd_limit
    }

    /// One line for the report.
    pub fn summary(&self) -> String {
        let mut line = format!(
            "output voting: 3 controllers, {} wrong at most{}, cross-check {} N={} (K={})",
            self.max_wrong,
            match (self.max_wrong, self.wrong_values_differ) {
                (2, true) => " (never agreeing on a wrong value)",
                (2, false) => " (free to agree)",
                _ => "",
            },
            self.cross_check.name(),
            self.odd_limit,
            self.exclusive_bound()
        );
        if let Some(mutation) = self.mutation {
            line.push_str(&format!(", MUTATION {mutation:?}"));
        }
        line
    }

    /// The flags that give this configuration, for the `explore` command printed with a
    /// counterexample.
    pub fn flags(&self) -> String {
        let mut flags = format!(
            "--outputs --wrong {} --cross-check {} --odd-limit {}",
            self.max_wrong,
            self.cross_check.name(),
            self.odd_limit
        );
        if self.wrong_values_differ {
            flags.push_str(" --disagreeing");
        }
        if let Some(mutation) = self.mutation {
            let name = match mutation {
                OutputMutation::AcceptSingleSource => "accept-single-source",
                OutputMutation::CompareAfterNextCommand => "compare-after-next-command",
                OutputMutation::NoInputCongruence => "no-input-congruence",
                OutputMutation::NoRawCompare => "no-raw-compare",
            };
            flags.push_str(&format!(" --output-mutation {name}"));
        }
        flags
    }
}
