//! The malformed datagrams a participant ignored, counted and reported at most once per
//! [`REPORT_PERIOD`].
//!
//! The message receiver runs in the participant's event loop, which also sends every sample.
//! Anyone who can reach a DDS port can send it garbage at line rate, and one log line per
//! datagram (two, with the parse error) put the logger's I/O, and a console or journal that
//! cannot keep up, in the path of every send: a flood delayed the participant's own samples.
//! So the first malformed datagram is reported at once and the later ones are counted and
//! reported with the next datagram received after the period.

use std::time::{Duration, Instant};

/// The least time between two reports of malformed datagrams.
pub(crate) const REPORT_PERIOD: Duration = Duration::from_secs(10);

/// Why a datagram was ignored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Malformed {
  /// Shorter than an RTPS header.
  Short,
  /// Not starting with `RTPS` (nor `RTPX`).
  NotRtps,
  /// An RTPS header, then bytes that do not parse as submessages.
  Undecodable,
}

impl Malformed {
  fn describe(self) -> &'static str {
    match self {
      Malformed::Short => "shorter than an RTPS header",
      Malformed::NotRtps => "without the RTPS magic",
      Malformed::Undecodable => "an RTPS header, then submessages that do not decode",
    }
  }
}

/// What a report says.
#[derive(Debug, PartialEq, Eq)]
pub(crate) enum Report {
  /// The first malformed datagram of a period, with what was wrong with it.
  First(Malformed),
  /// `count` more were ignored in the `over` since the last report; the latest was `latest`.
  More {
    count: u64,
    over: Duration,
    latest: Malformed,
  },
}

/// The count since the last report.
#[derive(Debug, Default)]
pub(crate) struct MalformedDatagrams {
  last_report: Option<Instant>,
  /// Ignored since `last_report` and not reported yet.
  unreported: u64,
  latest: Option<Malformed>,
}

impl MalformedDatagrams {
  /// A malformed datagram was ignored at `now`: the report to log, if one is due.
  pub(crate) fn ignored(&mut self, why: Malformed, now: Instant) -> Option<Report> {
    let quiet_period = match self.last_report {
      None => true,
      Some(at) => self.unreported == 0 && now.saturating_duration_since(at) >= REPORT_PERIOD,
    };
    if quiet_period {
      self.last_report = Some(now);
      return Some(Report::First(why));
    }
    // Counted; reported with this one if a period has passed since the last report.
    self.unreported += 1;
    self.latest = Some(why);
    self.due(now)
  }

  /// Whether datagrams are counted and not reported yet (then [`Self::due`] may report).
  pub(crate) fn counting(&self) -> bool {
    self.unreported > 0
  }

  /// A datagram (of any kind) arrived at `now`: the report of the datagrams counted, if a
  /// period has passed since the last one.
  pub(crate) fn due(&mut self, now: Instant) -> Option<Report> {
    if self.unreported == 0 {
      return None;
    }
    let at = self.last_report?;
    let over = now.saturating_duration_since(at);
    if over < REPORT_PERIOD {
      return None;
    }
    let report = Report::More {
      count: self.unreported,
      over,
      latest: self.latest.unwrap_or(Malformed::Undecodable),
    };
    self.last_report = Some(now);
    self.unreported = 0;
    Some(report)
  }
}

impl std::fmt::Display for Report {
  fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
    match self {
      Report::First(why) => write!(
        f,
        "Ignored a malformed datagram ({}); more are counted and reported at most every {} s",
        why.describe(),
        REPORT_PERIOD.as_secs()
      ),
      Report::More {
        count,
        over,
        latest,
      } => write!(
        f,
        "Ignored {count} more malformed datagrams in the last {:.0} s (the latest {})",
        over.as_secs_f64(),
        latest.describe()
      ),
    }
  }
}

#[cfg(test)]
mod tests {
  use super::*;

  #[test]
  fn a_flood_of_malformed_datagrams_is_reported_once_per_period() {
    let mut count = MalformedDatagrams::default();
    let start = Instant::now();
    let mut reports = Vec::new();
    // 10 000 datagrams in one second, then quiet until a valid one 10 s after the first.
    for i in 0..10_000u32 {
      let at = start + Duration::from_micros(u64::from(i) * 100);
      reports.extend(count.ignored(Malformed::NotRtps, at));
    }
    assert_eq!(reports, [Report::First(Malformed::NotRtps)]);
    assert_eq!(count.due(start + Duration::from_secs(9)), None);
    assert_eq!(
      count.due(start + REPORT_PERIOD),
      Some(Report::More {
        count: 9_999,
        over: REPORT_PERIOD,
        latest: Malformed::NotRtps
      })
    );
    assert_eq!(
      count.due(start + 3 * REPORT_PERIOD),
      None,
      "nothing counted since"
    );
  }

  #[test]
  fn a_malformed_datagram_after_a_quiet_period_is_reported_at_once() {
    let mut count = MalformedDatagrams::default();
    let start = Instant::now();
    assert!(count.ignored(Malformed::Short, start).is_some());
    let later = start + 2 * REPORT_PERIOD;
    assert_eq!(
      count.ignored(Malformed::Undecodable, later),
      Some(Report::First(Malformed::Undecodable))
    );
    // One counted within the period, the next after it: both in one report, not lost.
    assert_eq!(
      count.ignored(Malformed::Short, later + Duration::from_secs(1)),
      None
    );
    assert_eq!(
      count.ignored(Malformed::NotRtps, later + REPORT_PERIOD),
      Some(Report::More {
        count: 2,
        over: REPORT_PERIOD,
        latest: Malformed::NotRtps
      })
    );
  }
}
