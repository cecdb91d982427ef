//! The Raspberry Pi package's files (impl/debian/): the systemd unit passes
//! `systemd-analyze verify` with no output at all (it exits 0 even on bad values, so any
//! output is a failure) and stays hardened (`systemd-analyze security`); it has the settings
//! the deployment relies on; the packaged configuration is the example's defaults with GPIO
//! LEDs; and, when impl/scripts/pi-build made one (`RL_PI_DEB`), the .deb holds what a Pi
//! needs.
//!
//! The tests that need `systemd-analyze` (Debian package systemd) or the .deb are ignored by
//! default; `cargo test -- --include-ignored` runs them (.ci/run provides both), and then a
//! missing tool or package fails the test.

use std::path::{Path, PathBuf};
use std::process::Command;

mod missing;
use missing::Missing;

const UNIT_NAME: &str = "rl@.service";

fn debian_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("debian")
}

fn unit_text() -> String {
    std::fs::read_to_string(debian_dir().join(UNIT_NAME)).unwrap()
}

fn systemd_analyze() -> Result<(), Missing> {
    match Command::new("systemd-analyze").arg("--version").output() {
        Ok(output) if output.status.success() => Ok(()),
        _ => Err(Missing(
            "systemd-analyze not found (apt-get install systemd)".into(),
        )),
    }
}

/// A root directory holding this machine's systemd units (the unit's dependencies), the
/// unit under test and an `rl` at `/usr/bin/rl`, for `systemd-analyze --root`.
struct UnitRoot(PathBuf);

impl UnitRoot {
    fn new(tag: &str, unit_text: &str) -> UnitRoot {
        let root = std::env::temp_dir().join(format!("rl-test-unit-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        let units = root.join("usr/lib/systemd/system");
        std::fs::create_dir_all(&units).unwrap();
        std::fs::create_dir_all(root.join("usr/bin")).unwrap();
        std::os::unix::fs::symlink("usr/lib", root.join("lib")).unwrap();
        let host_units = std::fs::canonicalize("/lib/systemd/system").unwrap();
        for entry in std::fs::read_dir(&host_units).unwrap() {
            let entry = entry.unwrap();
            let target = units.join(entry.file_name());
            let kind = entry.file_type().unwrap();
            if kind.is_symlink() {
                let link = std::fs::read_link(entry.path()).unwrap();
                std::os::unix::fs::symlink(link, target).unwrap();
            } else if kind.is_file() {
                std::fs::copy(entry.path(), target).unwrap();
            }
        }
        std::fs::write(units.join(UNIT_NAME), unit_text).unwrap();
        std::fs::copy(env!("CARGO_BIN_EXE_rl"), root.join("usr/bin/rl")).unwrap();
        UnitRoot(root)
    }

    /// `systemd-analyze <args> --root=<root> rl@1.service`: exit success, and everything it
    /// printed.
    fn analyze(&self, args: &[&str]) -> (bool, String) {
        let output = Command::new("systemd-analyze")
            .args(args)
            .arg(format!("--root={}", self.0.display()))
            .arg("rl@1.service")
            .output()
            .unwrap();
        let mut text = String::from_utf8_lossy(&output.stdout).into_owned();
        text.push_str(&String::from_utf8_lossy(&output.stderr));
        (output.status.success(), text)
    }
}

impl Drop for UnitRoot {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[test]
#[ignore = "needs systemd-analyze (apt install systemd)"]
fn systemd_analyze_verify_prints_nothing_for_the_unit() -> Result<(), Missing> {
    systemd_analyze()?;
    let root = UnitRoot::new("verify", &unit_text());
    let (ok, output) = root.analyze(&["verify"]);
    assert!(ok && output.is_empty(), "systemd-analyze verify:\n{output}");

    // The same check on a unit with a bad value and an unknown key does print: the empty
    // output above means something.
    let broken = unit_text().replace("WatchdogSec=5s", "WatchdogSec=soon\nWatchdogSecs=5s");
    let root = UnitRoot::new("verify-broken", &broken);
    let (_, output) = root.analyze(&["verify"]);
    assert!(output.contains("WatchdogSecs"), "{output}");
    assert!(output.contains("soon"), "{output}");
    Ok(())
}

#[test]
#[ignore = "needs systemd-analyze (apt install systemd)"]
fn the_unit_stays_hardened() -> Result<(), Missing> {
    systemd_analyze()?;
    let root = UnitRoot::new("security", &unit_text());
    // Exposure 0.0 (locked down) .. 10.0 (unprotected); the unit scores 1.9 ("OK").
    let (ok, output) = root.analyze(&["security", "--offline=true", "--threshold=25"]);
    let overall = output
        .lines()
        .find(|line| line.contains("Overall exposure level"))
        .unwrap_or("(no overall level)");
    assert!(ok, "exposure above 2.5: {overall}\n{output}");
    println!("{overall}");
    Ok(())
}

/// The value of `key=` in the unit (the last one wins, as in systemd).
fn setting(unit: &str, key: &str) -> Option<String> {
    unit.lines()
        .filter_map(|line| line.strip_prefix(&format!("{key}=")))
        .next_back()
        .map(str::to_string)
}

#[test]
fn the_unit_is_a_notify_service_with_a_watchdog_restarted_on_failure() {
    let unit = unit_text();
    for (key, value) in [
        ("Type", "notify"),
        ("NotifyAccess", "main"),
        (
            "ExecStart",
            "/usr/bin/rl controller --id %i --config /etc/rl/rl.toml",
        ),
        ("Restart", "on-failure"),
        ("RestartPreventExitStatus", "2"),
        ("WatchdogSec", "5s"),
        ("DynamicUser", "yes"),
        ("User", "rl"),
        ("SupplementaryGroups", "gpio"),
        ("DevicePolicy", "closed"),
        ("DeviceAllow", "char-gpiochip rw"),
        ("NoNewPrivileges", "yes"),
        ("ProtectSystem", "strict"),
        ("CapabilityBoundingSet", ""),
        ("WantedBy", "multi-user.target"),
    ] {
        assert_eq!(setting(&unit, key).as_deref(), Some(value), "{key}=");
    }
}

#[test]
fn the_packaged_configuration_is_the_defaults_with_gpio_leds() {
    let packaged = std::fs::read_to_string(debian_dir().join("rl.toml")).unwrap();
    let config = rl_layer::config::Config::from_toml_str(&packaged, "debian/rl.toml").unwrap();
    let mut expected = rl_layer::config::Config::default();
    expected.leds.backend = rl_layer::config::LedBackend::Gpio;
    assert_eq!(config, expected);
    // The defaults it shows (commented out) are the example's, which the package ships as
    // /usr/share/doc/rl/rl.toml.example.
    let example =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("rl.toml.example"))
            .unwrap();
    let shown: Vec<&str> = packaged
        .lines()
        .filter(|line| line.starts_with("# ") && line.contains(" = "))
        .collect();
    assert!(!shown.is_empty());
    for line in shown {
        assert!(
            example.lines().any(|l| l == line),
            "{line:?} is not in rl.toml.example"
        );
    }
}

#[test]
fn the_maintainer_scripts_are_valid_shell() {
    for script in ["postinst", "prerm", "postrm"] {
        let path = debian_dir().join(script);
        let status = Command::new("sh").arg("-n").arg(&path).status().unwrap();
        assert!(status.success(), "{script}: sh -n failed");
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(&path).unwrap().permissions().mode();
        assert!(mode & 0o111 != 0, "{script} is not executable");
    }
}

/// `dpkg-deb <args> <deb>`, stdout.
fn dpkg_deb(args: &[&str], deb: &Path) -> String {
    let output = Command::new("dpkg-deb")
        .args(args)
        .arg(deb)
        .output()
        .unwrap();
    assert!(output.status.success(), "dpkg-deb {args:?}");
    String::from_utf8_lossy(&output.stdout).into_owned()
}

/// The package `RL_PI_DEB` names, or why the test cannot run.
fn pi_deb() -> Result<PathBuf, Missing> {
    let deb = std::env::var_os("RL_PI_DEB")
        .map(PathBuf::from)
        .ok_or_else(|| {
            Missing("RL_PI_DEB is not set (impl/scripts/pi-build prints the .deb's path)".into())
        })?;
    if !deb.is_file() {
        return Err(Missing(format!(
            "RL_PI_DEB={} does not exist",
            deb.display()
        )));
    }
    Ok(deb)
}

#[test]
#[ignore = "needs the Pi package: RL_PI_DEB, printed by impl/scripts/pi-build"]
fn the_deb_holds_the_binary_unit_conffile_and_udev_rule_for_arm64() -> Result<(), Missing> {
    let deb = pi_deb()?;
    let field = |name: &str| {
        dpkg_deb(&["--field"], &deb)
            .lines()
            .find_map(|line| line.strip_prefix(&format!("{name}: ")).map(str::to_string))
    };
    assert_eq!(field("Package").as_deref(), Some("rl"));
    assert_eq!(field("Architecture").as_deref(), Some("arm64"));
    // Static binary: no libc6; adduser for the postinst's addgroup. Nothing Bullseye lacks.
    assert_eq!(field("Depends").as_deref(), Some("adduser"));
    let contents = dpkg_deb(&["--contents"], &deb);
    for path in [
        "./usr/bin/rl",
        "./etc/rl/rl.toml",
        "./lib/systemd/system/rl@.service",
        "./lib/udev/rules.d/60-rl-gpio.rules",
        "./usr/lib/sysctl.d/60-rl.conf",
        "./usr/share/doc/rl/deploy-pi.md",
        "./usr/share/doc/rl/rl.toml.example",
    ] {
        assert!(
            contents.lines().any(|line| line.ends_with(path)),
            "{path} missing:\n{contents}"
        );
    }
    let control = std::env::temp_dir().join(format!("rl-test-deb-control-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&control);
    let status = Command::new("dpkg-deb")
        .arg("--control")
        .arg(&deb)
        .arg(&control)
        .status()
        .unwrap();
    assert!(status.success());
    let conffiles = std::fs::read_to_string(control.join("conffiles")).unwrap();
    assert_eq!(conffiles.trim(), "/etc/rl/rl.toml");
    for script in ["postinst", "prerm", "postrm"] {
        let packaged = std::fs::read(control.join(script)).unwrap();
        assert_eq!(
            packaged,
            std::fs::read(debian_dir().join(script)).unwrap(),
            "{script}"
        );
    }
    let _ = std::fs::remove_dir_all(&control);
    let size = std::fs::metadata(&deb).unwrap().len();
    println!("{}: {size} bytes", deb.display());
    Ok(())
}
