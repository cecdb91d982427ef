//! What a tool-needing test lacks on this machine, and how to get it: the error such a test
//! returns when it runs (`--include-ignored`) without its tool, so it fails with the reason.

/// What a test needs and this machine lacks, and how to get it.
pub struct Missing(pub String);

impl std::fmt::Debug for Missing {
    // The test harness prints a failed test's error with `Debug`: the message alone.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::fmt::Display for Missing {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Missing {}
