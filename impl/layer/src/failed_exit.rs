//! Leaving after failing itself: the exit status a controller that failed itself exits with,
//! on which the systemd unit restarts it, and the line the operator reads. When it fails and
//! when it leaves are the core's decisions (rl-core's `failure` module, `Command::Failed` and
//! `Command::Exit`).

pub use crate::core::failure::{Failure, FailureCause};

/// The exit status of a controller that failed itself: `EX_TEMPFAIL` of sysexits.h ("try
/// again later"), distinct from 1 (a runtime error) and 2 (bad configuration or arguments).
pub const EXIT_STATUS: u8 = 75;

/// What the operator reads when it fails: why, and when it exits with which status
/// (`exit_in_ms`: `None` when the configuration keeps it up).
pub fn notice(failure: &Failure, exit_in_ms: Option<u64>) -> String {
    match exit_in_ms {
        Some(ms) => {
            format!("{failure}; exits in {ms} ms with status {EXIT_STATUS} to be restarted")
        }
        None => format!("{failure}; stays up FAILED"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_notice_says_why_and_when_it_exits() {
        let failure = Failure {
            id: 3,
            cause: FailureCause::LocalFault,
            disagreed_with: Vec::new(),
            own_vote: None,
            their_vote: None,
        };
        assert_eq!(
            notice(&failure, Some(300)),
            "C3 FAILED: its application reported a fault; exits in 300 ms with status 75 to \
             be restarted"
        );
    }
}
