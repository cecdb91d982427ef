//! The gray process faults, made with cgroups v1 as a host makes them without any signal: a
//! freeze (the freezer group: a paused virtual machine, an I/O stall, a blocked journal
//! write) and a CPU starvation (a CFS quota: a runaway neighbour, a throttled Pi). A
//! controller's whole process (every thread) goes into a group of its own, named after the
//! lab's process and the fault, and back to the root group when the fault heals; the group is
//! removed then. Writes to cgroup files need root, as the rest of the lab does.

use super::error::LabError;
use std::path::{Path, PathBuf};

const FREEZER: &str = "/sys/fs/cgroup/freezer";
const CPU: &str = "/sys/fs/cgroup/cpu";
/// The CFS period the quota is a share of: the kernel's default, 100 ms.
const CPU_PERIOD_US: u32 = 100_000;

/// A controller's process in a group of its own.
#[derive(Debug)]
pub struct Group {
    /// The hierarchy's root (`/sys/fs/cgroup/freezer` or `.../cpu`).
    root: &'static str,
    /// The group's directory.
    dir: PathBuf,
    pid: u32,
}

/// Whether this host has the cgroup v1 hierarchies the gray faults need, and if not which.
pub fn missing_hierarchy() -> Option<&'static str> {
    [FREEZER, CPU]
        .into_iter()
        .find(|root| !Path::new(root).join("cgroup.procs").exists())
}

/// Freezes process `pid` (every thread, no signal): it stays frozen until [`thaw`].
pub fn freeze(pid: u32, name: &str) -> Result<Group, LabError> {
    let group = Group::enter(FREEZER, name, pid)?;
    write(&group.dir.join("freezer.state"), "FROZEN")?;
    Ok(group)
}

/// Thaws a frozen process and takes it out of its group.
pub fn thaw(group: Group) -> Result<(), LabError> {
    write(&group.dir.join("freezer.state"), "THAWED")?;
    group.leave()
}

/// Gives process `pid` `percent` % of one core (a CFS quota of that share of 100 ms) until
/// [`feed`].
pub fn starve(pid: u32, name: &str, percent: u8) -> Result<Group, LabError> {
    let group = Group::enter(CPU, name, pid)?;
    let quota_us = CPU_PERIOD_US / 100 * u32::from(percent.clamp(1, 100));
    write(
        &group.dir.join("cpu.cfs_period_us"),
        &CPU_PERIOD_US.to_string(),
    )?;
    write(&group.dir.join("cpu.cfs_quota_us"), &quota_us.to_string())?;
    Ok(group)
}

/// Ends a starvation: the process back in the root group, its quota gone with the group.
pub fn feed(group: Group) -> Result<(), LabError> {
    group.leave()
}

impl Group {
    /// A new group `name` under `root`, with `pid` in it (the whole thread group moves).
    fn enter(root: &'static str, name: &str, pid: u32) -> Result<Group, LabError> {
        let dir = Path::new(root).join(format!("rl-lab-{}-{name}", std::process::id()));
        match std::fs::create_dir(&dir) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
            Err(e) => return Err(io_error("mkdir", &dir, &e)),
        }
        write(&dir.join("cgroup.procs"), &pid.to_string())?;
        Ok(Group { root, dir, pid })
    }

    /// The process back in the root group, and the group removed. A process that has exited
    /// meanwhile leaves the group by itself.
    fn leave(self) -> Result<(), LabError> {
        let back = write(
            &Path::new(self.root).join("cgroup.procs"),
            &self.pid.to_string(),
        );
        if let Err(e) = std::fs::remove_dir(&self.dir) {
            return Err(io_error("rmdir", &self.dir, &e));
        }
        // A pid that is gone cannot be moved (ESRCH): the group empty is what matters.
        back.or(Ok(()))
    }
}

fn write(file: &Path, value: &str) -> Result<(), LabError> {
    std::fs::write(file, value).map_err(|e| io_error(&format!("echo {value} >"), file, &e))
}

fn io_error(what: &str, path: &Path, error: &std::io::Error) -> LabError {
    LabError::command(what, &[&path.display().to_string()], error.to_string())
}
