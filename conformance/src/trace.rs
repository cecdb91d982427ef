//! Reading the model's trace set (`traces/NNNN-what-it-shows.jsonl` and `traces/index.json`).
//!
//! The format is the model's (`model/src/traces/`, docs/model.md "Traces"): a header line
//! with the configuration, purpose, description and initial abstract state, then one line per
//! step with the action and the abstract state after it. Lines are read into the model's own
//! types ([`HeaderLine`], [`StepLine`], [`IndexEntry`]), which reject unknown fields so that a
//! format change is noticed rather than half read. File input is never trusted: every problem
//! is a [`TraceError`] naming the file and line.

use model::traces::{AbstractState, HeaderLine, StepLine, FORMAT};
use model::{Action, Config, Variant};
use std::collections::{BTreeMap, BTreeSet};
use std::fmt;
use std::path::{Path, PathBuf};

pub use model::traces::IndexEntry;

/// One trace file, parsed.
#[derive(Clone, Debug)]
pub struct Trace {
    /// The file name, e.g. `0005-late-joiner-becomes-tertiary.jsonl`.
    pub file: String,
    /// The number the file name starts with (5 for `0005-...`): how tools refer to a trace.
    pub number: usize,
    pub model_hash: String,
    pub config: Config,
    pub purpose: String,
    /// One line saying what the trace shows.
    pub description: String,
    /// Which of the model's initial states the trace starts from.
    pub initial_state_index: usize,
    pub initial: AbstractState,
    pub steps: Vec<TraceStep>,
}

/// One step: the action and the abstract state the model reached with it.
#[derive(Clone, Debug)]
pub struct TraceStep {
    /// 1-based, as in the file.
    pub number: usize,
    pub action: Action,
    pub state: AbstractState,
}

impl Trace {
    /// The variant of the rules the trace was generated with.
    pub fn variant(&self) -> Variant {
        self.config.variant
    }

    /// The state before step `index` (0-based): the initial state or the previous step's.
    pub fn state_before(&self, index: usize) -> &AbstractState {
        match index.checked_sub(1) {
            Some(previous) => &self.steps[previous].state,
            None => &self.initial,
        }
    }
}

/// A file (a trace, or a recording of a run) that cannot be read: where, and why.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FileError {
    pub path: PathBuf,
    /// 1-based line, when the problem is on one line.
    pub line: Option<usize>,
    pub message: String,
}

/// A trace file that cannot be read.
pub type TraceError = FileError;

impl fmt::Display for FileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            Some(line) => write!(f, "{}:{line}: {}", self.path.display(), self.message),
            None => write!(f, "{}: {}", self.path.display(), self.message),
        }
    }
}

impl std::error::Error for FileError {}

/// Reads one trace file.
pub fn read_trace(path: &Path) -> Result<Trace, TraceError> {
    let error = |line: Option<usize>, message: String| TraceError {
        path: path.to_path_buf(),
        line,
        message,
    };
    let text = std::fs::read_to_string(path).map_err(|e| error(None, e.to_string()))?;
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let (_, header_text) = lines
        .next()
        .ok_or_else(|| error(None, "empty file: no header line".into()))?;
    let header: HeaderLine =
        serde_json::from_str(header_text).map_err(|e| error(Some(1), format!("header: {e}")))?;
    if header.format != FORMAT {
        return Err(error(
            Some(1),
            format!("format {:?}, this suite reads {FORMAT:?}", header.format),
        ));
    }
    let mut steps = Vec::new();
    for (index, line) in lines {
        let parsed: StepLine =
            serde_json::from_str(line).map_err(|e| error(Some(index + 1), format!("step: {e}")))?;
        if parsed.step != steps.len() + 1 {
            return Err(error(
                Some(index + 1),
                format!(
                    "step {} where step {} was expected",
                    parsed.step,
                    steps.len() + 1
                ),
            ));
        }
        steps.push(TraceStep {
            number: parsed.step,
            action: parsed.action,
            state: parsed.state,
        });
    }
    let file = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let number = model::traces::number_of(&file).ok_or_else(|| {
        error(
            None,
            "the file name does not start with a trace number".into(),
        )
    })?;
    Ok(Trace {
        file,
        number,
        model_hash: header.model_hash,
        config: header.config,
        purpose: header.purpose,
        description: header.description,
        initial_state_index: header.initial_state_index,
        initial: header.initial,
        steps,
    })
}

/// Reads every `*.jsonl` trace of a directory, in file-name order.
pub fn read_dir(dir: &Path) -> Result<Vec<Trace>, TraceError> {
    let error = |message: String| TraceError {
        path: dir.to_path_buf(),
        line: None,
        message,
    };
    let mut paths = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(|e| error(e.to_string()))? {
        let path = entry.map_err(|e| error(e.to_string()))?.path();
        if path.extension().is_some_and(|ext| ext == "jsonl") {
            paths.push(path);
        }
    }
    paths.sort();
    paths.iter().map(|path| read_trace(path)).collect()
}

/// Every entry of `index.json`, in file order.
pub fn read_index_entries(path: &Path) -> Result<Vec<IndexEntry>, TraceError> {
    let error = |message: String| TraceError {
        path: path.to_path_buf(),
        line: None,
        message,
    };
    let text = std::fs::read_to_string(path).map_err(|e| error(e.to_string()))?;
    serde_json::from_str(&text).map_err(|e| error(e.to_string()))
}

/// `index.json`: for each trace file, the coverage classes the model says it covers
/// (`tick@steady`, `join@notstarted`, ...).
pub fn read_index(path: &Path) -> Result<BTreeMap<String, BTreeSet<String>>, TraceError> {
    Ok(read_index_entries(path)?
        .into_iter()
        .map(|entry| (entry.file, entry.covers.into_iter().collect()))
        .collect())
}

/// The path of trace number `number` in `dir` (`5` finds `0005-late-joiner-becomes-tertiary.jsonl`).
pub fn path_of(dir: &Path, number: usize) -> Result<PathBuf, TraceError> {
    let error = |message: String| TraceError {
        path: dir.to_path_buf(),
        line: None,
        message,
    };
    let mut found = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(|e| error(e.to_string()))? {
        let path = entry.map_err(|e| error(e.to_string()))?.path();
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        if name.ends_with(".jsonl") && model::traces::number_of(&name) == Some(number) {
            found.push(path);
        }
    }
    match found.len() {
        1 => Ok(found.remove(0)),
        0 => Err(error(format!("no trace number {number:04}"))),
        n => Err(error(format!("{n} traces numbered {number:04}"))),
    }
}

/// The repository's trace directory (`traces/` beside this crate).
pub fn default_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("traces")
}
