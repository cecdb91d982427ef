//! Writing the trace set to its directory, and comparing a directory with it
//! (`traces --check`).

use super::TraceSet;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The trace directory or one of its files could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum TraceFileError {
    /// Reading, writing, listing or removing `path` failed.
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
}

fn io_error(path: &Path) -> impl FnOnce(std::io::Error) -> TraceFileError + '_ {
    move |source| TraceFileError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Writes the set, replacing the trace files already in `dir`.
pub fn write(set: &TraceSet, dir: &Path) -> Result<(), TraceFileError> {
    std::fs::create_dir_all(dir).map_err(io_error(dir))?;
    for old in existing(dir)? {
        let path = dir.join(&old);
        std::fs::remove_file(&path).map_err(io_error(&path))?;
    }
    for (name, text) in &set.files {
        let path = dir.join(name);
        std::fs::write(&path, text).map_err(io_error(&path))?;
    }
    Ok(())
}

/// The files that differ between the set and `dir` (missing, extra or changed).
pub fn compare(set: &TraceSet, dir: &Path) -> Result<Vec<String>, TraceFileError> {
    let on_disk: BTreeSet<String> = existing(dir)?.into_iter().collect();
    let generated: BTreeMap<&str, &str> = set
        .files
        .iter()
        .map(|(n, t)| (n.as_str(), t.as_str()))
        .collect();
    let mut differences = Vec::new();
    for (name, text) in &generated {
        match std::fs::read_to_string(dir.join(name)) {
            Ok(committed) if committed == *text => {}
            Ok(_) => differences.push(format!("{name} (content changed)")),
            Err(_) => differences.push(format!("{name} (missing)")),
        }
    }
    for name in on_disk {
        if !generated.contains_key(name.as_str()) {
            differences.push(format!("{name} (no longer generated)"));
        }
    }
    Ok(differences)
}

fn existing(dir: &Path) -> Result<Vec<String>, TraceFileError> {
    let entries = match std::fs::read_dir(dir) {
        Ok(entries) => entries,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => return Err(io_error(dir)(e)),
    };
    let mut names = Vec::new();
    for entry in entries {
        let entry = entry.map_err(io_error(dir))?;
        let name = entry.file_name().to_string_lossy().into_owned();
        if name.ends_with(".jsonl") || name == "index.json" || name == super::REACHABLE_FILE {
            names.push(name);
        }
    }
    names.sort();
    Ok(names)
}
