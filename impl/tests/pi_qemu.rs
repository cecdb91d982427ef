//! The Raspberry Pi binary (impl/scripts/pi-build: static aarch64 musl, profile `pi`) checked
//! on this machine: its format and size, and, run under qemu-user, a role in a three-controller
//! formation with two native controllers over real DDS (domain 180), the native servo
//! following it, and a failover away from it when it is killed. With the `security` feature
//! (the native `rl` then has it too) the same formation secured (domain 185): the Pi binary
//! authenticates and signs under emulation.
//!
//! The binary comes from `RL_AARCH64_BIN`, the emulator from `RL_QEMU_AARCH64` or
//! `qemu-aarch64-static` on PATH (qemu-user 10 from bookworm-backports: Debian 12's own 7.2
//! lacks `IP_MULTICAST_IF` and RustDDS panics). The tests are ignored by default;
//! `cargo test -- --include-ignored` runs them (.ci/run builds and installs both first), and
//! then a missing binary or emulator fails the test.

use rl::procs::{parse_servo_event, Fleet, Line, ServoEvent};
use rl_layer::core::{Phase, Role, Status};
use rl_layer::event::{Event, EventLine};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::mpsc::Receiver;
use std::time::{Duration, Instant};

mod missing;
mod support;
use missing::Missing;

const DOMAIN: u16 = 180;
#[cfg(feature = "security")]
const SECURED_DOMAIN: u16 = 185;
const SIZE_LIMIT_BYTES: u64 = 8_000_000;

/// The aarch64 binary, or why the test cannot run.
fn binary() -> Result<PathBuf, Missing> {
    let binary = std::env::var_os("RL_AARCH64_BIN")
        .map(PathBuf::from)
        .ok_or_else(|| {
            Missing("RL_AARCH64_BIN is not set (impl/scripts/pi-build prints the path)".into())
        })?;
    if !binary.is_file() {
        return Err(Missing(format!(
            "RL_AARCH64_BIN={} does not exist",
            binary.display()
        )));
    }
    Ok(binary)
}

/// The emulator, or why the test cannot run.
fn qemu() -> Result<PathBuf, Missing> {
    match std::env::var_os("RL_QEMU_AARCH64") {
        Some(path) if Path::new(&path).is_file() => Ok(PathBuf::from(path)),
        Some(path) => Err(Missing(format!(
            "RL_QEMU_AARCH64={} does not exist",
            Path::new(&path).display()
        ))),
        None => find_on_path("qemu-aarch64-static").ok_or_else(|| {
            Missing(
                "qemu-aarch64-static not found (impl/scripts/pi-qemu-install installs it from \
                 bookworm-backports)"
                    .into(),
            )
        }),
    }
}

fn find_on_path(name: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|dir| dir.join(name))
        .find(|candidate| candidate.is_file())
}

#[test]
#[ignore = "needs the Pi binary: RL_AARCH64_BIN, printed by impl/scripts/pi-build"]
fn the_pi_binary_is_static_aarch64_and_under_8_mb() -> Result<(), Missing> {
    let binary = binary()?;
    let bytes = std::fs::read(&binary).unwrap();
    assert_eq!(&bytes[..4], b"\x7fELF", "not an ELF file");
    assert_eq!(bytes[4], 2, "not 64-bit");
    let u16_at = |offset: usize| u16::from_le_bytes([bytes[offset], bytes[offset + 1]]);
    let u32_at = |offset: usize| u32::from_le_bytes(bytes[offset..offset + 4].try_into().unwrap());
    let u64_at = |offset: usize| u64::from_le_bytes(bytes[offset..offset + 8].try_into().unwrap());
    const EM_AARCH64: u16 = 183;
    assert_eq!(u16_at(0x12), EM_AARCH64, "not aarch64");
    // No program interpreter: static, so Bullseye's glibc 2.31 does not matter.
    const PT_INTERP: u32 = 3;
    let (table, entry_size, entries) = (u64_at(0x20) as usize, u16_at(0x36), u16_at(0x38));
    for index in 0..usize::from(entries) {
        let header = table + index * usize::from(entry_size);
        assert_ne!(u32_at(header), PT_INTERP, "dynamically linked");
    }
    let size = bytes.len() as u64;
    assert!(
        size < SIZE_LIMIT_BYTES,
        "{} is {size} bytes",
        binary.display()
    );
    println!("{}: {size} bytes, static aarch64", binary.display());
    Ok(())
}

/// Children's lines, the latest status per controller and the servo's events.
struct Formation {
    fleet: Fleet,
    lines: Receiver<Line>,
    status: BTreeMap<u8, Status>,
    servo: Vec<ServoEvent>,
    transcript: Vec<String>,
    started: Instant,
    _dir: TempDir,
}

struct TempDir(PathBuf);

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

impl Formation {
    /// A fleet whose executable runs the native `rl`, or, given `aarch64` as first argument,
    /// the Pi binary under qemu.
    fn new(binary: &Path, qemu: &Path, domain: u16) -> Formation {
        let dir =
            std::env::temp_dir().join(format!("rl-test-pi-qemu-{}-{domain}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let config = dir.join("rl.toml");
        std::fs::write(&config, "[timing]\ninit_window_ms = 1000\n").unwrap();
        let launcher = dir.join("rl-mixed");
        std::fs::write(
            &launcher,
            format!(
                "#!/bin/sh\nif [ \"$1\" = aarch64 ]; then shift; exec '{}' '{}' \"$@\"; fi\n\
                 exec '{}' \"$@\"\n",
                qemu.display(),
                binary.display(),
                env!("CARGO_BIN_EXE_rl")
            ),
        )
        .unwrap();
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&launcher, std::fs::Permissions::from_mode(0o755)).unwrap();
        let (fleet, lines) = Fleet::new(&launcher, Some(&config), domain);
        Formation {
            fleet,
            lines,
            status: BTreeMap::new(),
            servo: Vec::new(),
            transcript: Vec::new(),
            started: Instant::now(),
            _dir: TempDir(dir),
        }
    }

    fn pump(&mut self, wait: Duration) {
        let deadline = Instant::now() + wait;
        while let Some(left) = deadline.checked_duration_since(Instant::now()) {
            let Ok(line) = self.lines.recv_timeout(left) else {
                break;
            };
            let t = line.at.duration_since(self.started).as_millis();
            self.transcript
                .push(format!("{t:>6} ms {:>7}: {}", line.source, line.text));
            if line.source == "servo" {
                self.servo.extend(parse_servo_event(&line.text));
            } else if let Some(EventLine {
                id,
                event: Event::Status { status },
                ..
            }) = EventLine::parse(&line.text)
            {
                self.status.insert(id, *status);
            }
        }
    }

    fn wait_for(&mut self, what: &str, timeout: Duration, done: impl Fn(&Formation) -> bool) {
        let deadline = Instant::now() + timeout;
        while !done(self) {
            if Instant::now() >= deadline {
                let tail: Vec<&String> = self.transcript.iter().rev().take(60).rev().collect();
                panic!(
                    "timed out after {timeout:?} waiting for: {what}\n--- transcript ---\n{}",
                    tail.iter()
                        .map(|line| line.as_str())
                        .collect::<Vec<_>>()
                        .join("\n")
                );
            }
            self.pump(Duration::from_millis(50));
        }
    }

    fn steady_with(&self, id: u8, role: Role) -> bool {
        self.status.get(&id).is_some_and(|s| {
            s.report.phase == Phase::Steady
                && s.report.role == Some(role)
                && s.report.strength == Some(role.strength())
        })
    }

    fn servo_commander(&self) -> Option<u8> {
        self.servo.iter().rev().find_map(|event| match event {
            ServoEvent::Command { controller_id, .. } => Some(*controller_id),
            _ => None,
        })?
    }
}

impl Drop for Formation {
    fn drop(&mut self) {
        self.fleet.stop_all();
    }
}

#[test]
#[ignore = "needs the Pi binary (RL_AARCH64_BIN, impl/scripts/pi-build) and qemu-aarch64-static \
            (impl/scripts/pi-qemu-install)"]
fn the_emulated_pi_binary_takes_the_primary_role_among_two_native_controllers(
) -> Result<(), Missing> {
    let (binary, qemu) = (binary()?, qemu()?);
    let mut formation = Formation::new(&binary, &qemu, DOMAIN);
    formation
        .fleet
        .start_other("servo", &["servo", "--json"])
        .unwrap();
    // C1, the lowest id and so the Primary, is the Pi binary under qemu.
    let emulated = formation
        .fleet
        .start_other(
            "C1(arm)",
            &["aarch64", "controller", "--id", "1", "--json-events"],
        )
        .unwrap();
    for id in [2, 3] {
        formation
            .fleet
            .start_controller_with(id, &["--json-events"])
            .unwrap();
    }
    formation.wait_for("P=1 (aarch64) S=2 T=3", Duration::from_secs(30), |f| {
        f.steady_with(1, Role::Primary)
            && f.steady_with(2, Role::Secondary)
            && f.steady_with(3, Role::Tertiary)
    });
    println!(
        "formed P=1 (aarch64 under {}) S=2 T=3 in {} ms",
        qemu.display(),
        formation.started.elapsed().as_millis()
    );
    assert!(
        formation
            .transcript
            .iter()
            .any(|line| line.contains("C1(arm)") && line.contains("\"event\":\"status\"")),
        "the Primary's events came from the emulated process"
    );
    let agreed = formation.status[&3].report.agreed.map(|a| a.to_string());
    assert_eq!(agreed.as_deref(), Some("P=1 S=2 T=3"));
    // The native servo takes the emulated Primary's commands.
    formation.wait_for("servo follows C1", Duration::from_secs(10), |f| {
        f.servo_commander() == Some(1)
    });

    // Killed, the emulated Primary hands over to the native Secondary.
    rl::procs::signal(emulated, libc::SIGKILL).unwrap();
    formation.wait_for("C2 Primary, C3 Secondary", Duration::from_secs(15), |f| {
        f.steady_with(2, Role::Primary) && f.steady_with(3, Role::Secondary)
    });
    formation.wait_for("servo follows C2", Duration::from_secs(5), |f| {
        f.servo_commander() == Some(2)
    });
    println!(
        "after killing the emulated Primary: P=2 S=3, servo follows C2 at {} ms",
        formation.started.elapsed().as_millis()
    );
    Ok(())
}

#[cfg(feature = "security")]
#[test]
#[ignore = "needs the Pi binary (RL_AARCH64_BIN, impl/scripts/pi-build) and qemu-aarch64-static \
            (impl/scripts/pi-qemu-install)"]
fn the_emulated_pi_binary_takes_the_primary_role_secured() -> Result<(), Missing> {
    let (binary, qemu) = (binary()?, qemu()?);
    let mut formation = Formation::new(&binary, &qemu, SECURED_DOMAIN);
    let dir = formation._dir.0.clone();
    let keys_dir = support::keys::keystores(&dir);
    // Secured discovery takes about 2 s natively and longer emulated: a 10 s window lets the
    // three form at once.
    let config = |name: &str| {
        let path = dir.join(format!("{name}.toml"));
        std::fs::write(
            &path,
            format!(
                "[timing]\ninit_window_ms = 10000\n[security]\nkeystore = {:?}\n",
                keys_dir.join(name).display().to_string()
            ),
        )
        .unwrap();
        path
    };
    formation
        .fleet
        .start_other_configured("servo", &config("servo"), &["servo", "--json"])
        .unwrap();
    let emulated = formation
        .fleet
        .start_other_configured(
            "C1(arm)",
            &config("c1"),
            &["aarch64", "controller", "--id", "1", "--json-events"],
        )
        .unwrap();
    for id in [2, 3] {
        formation
            .fleet
            .start_controller_configured(id, &config(&format!("c{id}")), &["--json-events"])
            .unwrap();
    }
    formation.wait_for(
        "P=1 (aarch64) S=2 T=3, secured",
        Duration::from_secs(60),
        |f| {
            f.steady_with(1, Role::Primary)
                && f.steady_with(2, Role::Secondary)
                && f.steady_with(3, Role::Tertiary)
        },
    );
    formation.wait_for(
        "the secured servo follows C1",
        Duration::from_secs(20),
        |f| f.servo_commander() == Some(1),
    );
    println!(
        "secured: formed P=1 (aarch64) S=2 T=3 and the servo follows C1 at {} ms",
        formation.started.elapsed().as_millis()
    );
    rl::procs::signal(emulated, libc::SIGKILL).unwrap();
    formation.wait_for(
        "the secured servo follows C2",
        Duration::from_secs(15),
        |f| f.servo_commander() == Some(2),
    );
    Ok(())
}
