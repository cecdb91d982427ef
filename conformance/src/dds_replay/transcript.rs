//! What the processes printed: every line kept for the recording (one log per process), and
//! a readable transcript (wall ms, round, rounds since boundary 1) for failure reports.

use super::error::ReplayError;
use crate::record::describe_event;
use rl_layer::event::{Event, EventLine};
use std::collections::BTreeMap;
use std::path::Path;

/// Lines of the transcript shown with a failure.
pub const TAIL_LINES: usize = 50;
/// Lines of one process's own output shown when it exited.
pub const PROCESS_TAIL_LINES: usize = 20;

/// Everything the processes printed in one attempt.
#[derive(Clone, Debug, Default)]
pub struct Output {
    /// `(source, line)` in arrival order; stderr sources end in `!`.
    lines: Vec<(String, String)>,
    /// Readable lines for failure reports.
    transcript: Vec<String>,
}

impl Output {
    /// Keeps a line as printed.
    pub fn keep(&mut self, source: &str, text: &str) {
        self.lines.push((source.to_string(), text.to_string()));
    }

    /// Adds a readable line to the transcript.
    pub fn show(&mut self, line: String) {
        self.transcript.push(line);
    }

    /// The last [`TAIL_LINES`] transcript lines.
    pub fn transcript_tail(&self) -> &[String] {
        let skip = self.transcript.len().saturating_sub(TAIL_LINES);
        &self.transcript[skip..]
    }

    /// The last lines a process printed (stdout and stderr): controller events as short
    /// lines (`leds` left out), log text without colours.
    pub fn process_tail(&self, source: &str) -> Vec<String> {
        let stderr = format!("{source}!");
        let mine: Vec<String> = self
            .lines
            .iter()
            .filter(|(s, _)| s == source || *s == stderr)
            .filter_map(|(s, text)| match EventLine::parse(text) {
                Some(event) if matches!(event.event, Event::Leds { .. }) => None,
                Some(event) => Some(format!("{s}: {}", describe_event(&event, None))),
                None => Some(format!("{s}: {}", without_terminal_colours(text))),
            })
            .collect();
        let skip = mine.len().saturating_sub(PROCESS_TAIL_LINES);
        mine[skip..].to_vec()
    }

    /// One log per process (`C1.log`, `C3#1.log`, `servo.log`, `C1.stderr.log`) in `dir`.
    pub fn write_record(&self, dir: &Path) -> Result<(), ReplayError> {
        let mut files: BTreeMap<String, String> = BTreeMap::new();
        for (source, text) in &self.lines {
            let name = format!("{}.log", source.replace('!', ".stderr"));
            let file = files.entry(name).or_default();
            file.push_str(text);
            file.push('\n');
        }
        for (name, text) in files {
            let path = dir.join(&name);
            std::fs::write(&path, text).map_err(|source| ReplayError::RecordDir {
                what: "writing",
                path,
                source,
            })?;
        }
        Ok(())
    }
}

/// A log line without its ANSI colour sequences (`ESC [ ... m`).
pub fn without_terminal_colours(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut chars = text.chars();
    while let Some(c) = chars.next() {
        if c == '\u{1b}' {
            for end in chars.by_ref() {
                if end.is_ascii_alphabetic() {
                    break;
                }
            }
        } else {
            out.push(c);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_process_tail_has_its_own_lines_only() {
        let mut output = Output::default();
        output.keep("C1", "one");
        output.keep("C2", "other");
        output.keep("C1!", "\u{1b}[33mWARN\u{1b}[0m rl: unknown mutation");
        output.keep(
            "C1",
            r#"{"t_ms":5,"id":1,"incarnation":9,"event":"leds","leds":"[P:off]"}"#,
        );
        output.keep(
            "C1",
            r#"{"t_ms":5,"id":1,"incarnation":9,"event":"heartbeat_dropped","from":2}"#,
        );
        assert_eq!(
            output.process_tail("C1"),
            vec![
                "C1: one",
                "C1!: WARN rl: unknown mutation",
                "C1: C1 heartbeat_dropped from C2"
            ]
        );
    }
}
