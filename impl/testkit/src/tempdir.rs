//! The tests' temporary directories: one per test, named after it, removed when dropped.

/// A fresh directory under the system's temporary directory, removed on drop.
pub struct Dir(pub std::path::PathBuf);

impl Dir {
    /// `rl-test-<tag>-<pid>-<nanoseconds>`: unique across tests and runs.
    pub fn new(tag: &str) -> Dir {
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |since| since.as_nanos());
        let path =
            std::env::temp_dir().join(format!("rl-test-{tag}-{}-{nanos}", std::process::id()));
        std::fs::create_dir_all(&path)
            .unwrap_or_else(|e| panic!("creating {}: {e}", path.display()));
        Dir(path)
    }
}

impl Drop for Dir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}
