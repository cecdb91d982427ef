//! The GPIO LED bank's line values, through a fake GPIO chip (the only mock: a build machine
//! has no GPIO lines, and the kernel here has no gpio-sim). Three real voting cores exchange
//! heartbeats in memory; each core's LED commands go to its own `GpioLeds` over a fake chip
//! that records every write, and the tests read the pins of the original wiring: LED1 Primary
//! 20/21, LED2 Secondary 7/8, LED3 Tertiary 24/23, LED4 own status 15/14 (green pin first).
//! One process test runs a real controller configured for GPIO on a machine without the chip
//! (DDS domain 184).

use rl_layer::config::Config;
use rl_layer::core::{Command, ControllerId, Core, CoreConfig, Input, Phase, Role, Rounds};
use rl_layer::leds::gpio::{GpioChip, GpioFault, GpioLeds, OutputLines};
use rl_layer::leds::{LedBank, LedPattern};
use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// Every write a fake chip saw, each the full state of its lines after the write.
#[derive(Debug, Default)]
struct ChipRecord {
    requested: Vec<u32>,
    levels: BTreeMap<u32, bool>,
    writes: Vec<BTreeMap<u32, bool>>,
    released: bool,
}

/// A GPIO chip that hands out lines recording into a shared [`ChipRecord`], or refuses with
/// a chosen fault.
#[derive(Clone, Default)]
struct FakeChip {
    record: Arc<Mutex<ChipRecord>>,
    refuse: Option<GpioFault>,
}

struct FakeLines {
    record: Arc<Mutex<ChipRecord>>,
}

impl GpioChip for FakeChip {
    type Lines = FakeLines;
    fn request_outputs(&self, offsets: &[u32]) -> Result<FakeLines, GpioFault> {
        if let Some(fault) = &self.refuse {
            return Err(fault.clone());
        }
        let mut record = self.record.lock().unwrap();
        record.requested = offsets.to_vec();
        record.levels = offsets.iter().map(|&line| (line, false)).collect();
        Ok(FakeLines {
            record: Arc::clone(&self.record),
        })
    }
}

impl OutputLines for FakeLines {
    fn set_values(&mut self, values: &[(u32, bool)]) -> Result<(), GpioFault> {
        let mut record = self.record.lock().unwrap();
        for &(line, high) in values {
            assert!(
                record.requested.contains(&line),
                "line {line} was not requested"
            );
            record.levels.insert(line, high);
        }
        let levels = record.levels.clone();
        record.writes.push(levels);
        Ok(())
    }
}

impl Drop for FakeLines {
    fn drop(&mut self) {
        self.record.lock().unwrap().released = true;
    }
}

const PINS: [[u32; 2]; 4] = [[20, 21], [7, 8], [24, 23], [15, 14]];

/// Pin levels for the four LEDs: `"G"` green, `"R"` red, `"-"` off, LED1..LED4.
fn levels(leds: &str) -> BTreeMap<u32, bool> {
    let colours: Vec<char> = leds.chars().collect();
    assert_eq!(colours.len(), 4);
    let mut out = BTreeMap::new();
    for (colour, [green, red]) in colours.iter().zip(PINS) {
        let (g, r) = match colour {
            'G' => (true, false),
            'R' => (false, true),
            '-' => (false, false),
            other => panic!("colour {other}"),
        };
        out.insert(green, g);
        out.insert(red, r);
    }
    out
}

/// The LEDs the pins show, in the notation of [`levels`] (`?` for both high).
fn read_leds(pins: &BTreeMap<u32, bool>) -> String {
    PINS.iter()
        .map(|[green, red]| match (pins[green], pins[red]) {
            (true, false) => 'G',
            (false, true) => 'R',
            (false, false) => '-',
            (true, true) => '?',
        })
        .collect()
}

/// One controller: a real voting core whose LED commands drive a GPIO bank on a fake chip.
struct Unit {
    core: Core,
    leds: GpioLeds<FakeLines>,
    chip: FakeChip,
    alive: bool,
}

impl Unit {
    fn shown(&self) -> String {
        read_leds(&self.chip.record.lock().unwrap().levels)
    }

    /// Every distinct LED state the unit showed, in order.
    fn history(&self) -> Vec<String> {
        let mut out: Vec<String> = Vec::new();
        for write in &self.chip.record.lock().unwrap().writes {
            let leds = read_leds(write);
            if out.last() != Some(&leds) {
                out.push(leds);
            }
        }
        out
    }
}

/// Three (or more) controllers on an in-memory network that delivers every heartbeat at once.
struct Bench {
    units: BTreeMap<ControllerId, Unit>,
    now_ms: u64,
    rounds: Rounds,
    period_ms: u64,
    next_incarnation: u64,
}

impl Bench {
    fn new() -> Bench {
        let mut timing = Config::default().timing;
        timing.init_window_ms = 1000;
        Bench {
            units: BTreeMap::new(),
            now_ms: 1_000_000,
            rounds: timing.rounds(),
            period_ms: timing.heartbeat_period_ms,
            next_incarnation: 1,
        }
    }

    fn start(&mut self, id: ControllerId) {
        let chip = FakeChip::default();
        let leds = GpioLeds::open(&chip, "/dev/gpiochip0", PINS)
            .unwrap()
            .with_lamp_test_step(Duration::ZERO);
        let config = CoreConfig::new(id, self.next_incarnation, self.period_ms, self.rounds);
        self.next_incarnation += 1;
        let mut unit = Unit {
            core: Core::new(config, self.now_ms),
            leds,
            chip,
            alive: true,
        };
        unit.leds.lamp_test().unwrap();
        self.units.insert(id, unit);
    }

    /// The Pi loses power: its core stops and its heartbeats with it.
    fn kill(&mut self, id: ControllerId) {
        self.units.get_mut(&id).unwrap().alive = false;
    }

    /// Runs every due timer of every live core until `ms` has passed.
    fn run_for(&mut self, ms: u64) {
        let until = self.now_ms + ms;
        loop {
            let next = self
                .units
                .iter()
                .filter(|(_, u)| u.alive)
                .map(|(&id, u)| (u.core.next_deadline(), id))
                .map(|(deadline, id)| (deadline.at_ms, deadline.timer, id))
                .min();
            let Some((due, timer, id)) = next.filter(|(due, _, _)| *due <= until) else {
                break;
            };
            self.now_ms = due.max(self.now_ms);
            self.input(id, Input::Timer(timer));
        }
        self.now_ms = until;
    }

    fn input(&mut self, id: ControllerId, input: Input) {
        let now = self.now_ms;
        let unit = self.units.get_mut(&id).unwrap();
        let commands = unit.core.step(input, now);
        // The adapter's rule: the LEDs follow the status.
        let pattern = rl_layer::leds::pattern_of(&unit.core.status());
        if unit.leds.shown() != Some(pattern) {
            unit.leds.show(pattern).unwrap();
        }
        let heartbeats: Vec<_> = commands
            .into_iter()
            .filter_map(|command| match command {
                Command::PublishHeartbeat(heartbeat) => Some(heartbeat),
                _ => None,
            })
            .collect();
        for heartbeat in heartbeats {
            let peers: Vec<ControllerId> = self
                .units
                .iter()
                .filter(|(&peer, u)| peer != id && u.alive)
                .map(|(&peer, _)| peer)
                .collect();
            for peer in peers {
                self.input(peer, Input::Heartbeat(heartbeat));
            }
        }
    }

    fn role(&self, id: ControllerId) -> Option<Role> {
        self.units[&id].core.state().role
    }

    fn phase(&self, id: ControllerId) -> Phase {
        self.units[&id].core.state().phase
    }

    fn shown(&self, id: ControllerId) -> String {
        self.units[&id].shown()
    }
}

/// `expected` appears in `history` in this order (other states may come between).
fn shows_in_order(history: &[String], expected: &[&str]) -> bool {
    let mut rest = history.iter();
    expected
        .iter()
        .all(|want| rest.by_ref().any(|seen| seen == want))
}

#[test]
fn lamp_test_then_own_status_before_roles_exist() {
    let mut bench = Bench::new();
    bench.start(1);
    let record = bench.units[&1]
        .chip
        .record
        .lock()
        .unwrap()
        .requested
        .clone();
    let mut sorted = record.clone();
    sorted.sort_unstable();
    assert_eq!(
        sorted,
        vec![7, 8, 14, 15, 20, 21, 23, 24],
        "eight lines requested"
    );
    // Open: all off; lamp test: all green, all red, all off.
    assert_eq!(bench.units[&1].history(), ["----", "GGGG", "RRRR", "----"]);
    bench.run_for(10);
    // Initializing: only LED4, green (pin 15 high, 14 low).
    assert_eq!(bench.phase(1), Phase::Initializing);
    assert_eq!(bench.shown(1), "---G");
    let pins = bench.units[&1].chip.record.lock().unwrap().levels.clone();
    assert!(pins[&15] && !pins[&14]);
    assert!([20, 21, 7, 8, 24, 23].iter().all(|pin| !pins[pin]));
}

#[test]
fn roles_failure_promotion_and_return_on_the_lines() {
    let mut bench = Bench::new();
    for id in 1..=3 {
        bench.start(id);
    }
    bench.run_for(3_000);
    assert_eq!(
        [bench.role(1), bench.role(2), bench.role(3)],
        [
            Some(Role::Primary),
            Some(Role::Secondary),
            Some(Role::Tertiary)
        ]
    );
    // A working tracker: green on its own role, backups operational = off.
    assert_eq!(bench.shown(1), "G--G");
    assert_eq!(bench.shown(2), "-G-G");
    assert_eq!(bench.shown(3), "--GG");
    let pins = bench.units[&1].chip.record.lock().unwrap().levels.clone();
    assert_eq!(pins, levels("G--G"));
    assert!(pins[&20] && !pins[&21] && pins[&15] && !pins[&14]);

    // The Primary dies. The survivors first show the failed unit's role red, then, after the
    // re-vote promoted them, the vacated Tertiary red.
    bench.kill(1);
    bench.run_for(5_000);
    assert_eq!(bench.role(2), Some(Role::Primary));
    assert_eq!(bench.role(3), Some(Role::Secondary));
    assert_eq!(bench.shown(2), "G-RG");
    assert_eq!(bench.shown(3), "-GRG");
    assert!(
        shows_in_order(&bench.units[&2].history(), &["-G-G", "RG-G", "G-RG"]),
        "C2 showed {:?}",
        bench.units[&2].history()
    );
    assert!(
        shows_in_order(&bench.units[&3].history(), &["--GG", "R-GG", "-GRG"]),
        "C3 showed {:?}",
        bench.units[&3].history()
    );
    let pins = bench.units[&2].chip.record.lock().unwrap().levels.clone();
    assert!(!pins[&24] && pins[&23], "LED3 red: pin 23 high, 24 low");

    // The replaced unit comes back (a new incarnation) and takes the lowest free role; the
    // alarm clears and the red goes out.
    bench.start(1);
    bench.run_for(5_000);
    assert_eq!(bench.role(1), Some(Role::Tertiary));
    assert_eq!(bench.shown(1), "--GG");
    assert_eq!(bench.shown(2), "G--G");
    assert_eq!(bench.shown(3), "-G-G");
}

#[test]
fn a_unit_that_fails_itself_shows_led4_red_and_the_others_its_role_red() {
    let mut bench = Bench::new();
    for id in 1..=3 {
        bench.start(id);
    }
    bench.run_for(3_000);
    assert_eq!(bench.shown(3), "--GG");
    bench.input(3, Input::LocalFault);
    bench.run_for(100);
    assert_eq!(bench.phase(3), Phase::Failed);
    // LED4 red (14 high, 15 low); the failed unit gave up its role, so no role LED is its.
    assert_eq!(bench.shown(3), "---R");
    let pins = bench.units[&3].chip.record.lock().unwrap().levels.clone();
    assert!(pins[&14] && !pins[&15]);
    assert!([20, 21, 7, 8, 24, 23].iter().all(|pin| !pins[pin]));
    // The others mark the failed unit's role.
    bench.run_for(5_000);
    assert_eq!(bench.shown(1), "G-RG");
    assert_eq!(bench.shown(2), "-GRG");
}

#[test]
fn no_write_ever_drives_both_leads_of_an_led_high() {
    let mut bench = Bench::new();
    for id in 1..=3 {
        bench.start(id);
    }
    bench.run_for(3_000);
    bench.kill(2);
    bench.run_for(5_000);
    bench.input(1, Input::LocalFault);
    bench.run_for(3_000);
    for (id, unit) in &bench.units {
        let record = unit.chip.record.lock().unwrap();
        assert!(
            record.writes.len() > 4,
            "C{id} wrote {}",
            record.writes.len()
        );
        for write in &record.writes {
            assert_eq!(write.len(), 8, "every write sets all eight lines");
            assert!(!read_leds(write).contains('?'), "C{id}: {write:?}");
        }
    }
}

#[test]
fn dropping_the_bank_switches_every_led_off_and_releases_the_lines() {
    let chip = FakeChip::default();
    let mut leds = GpioLeds::open(&chip, "/dev/gpiochip0", PINS).unwrap();
    leds.show(LedPattern::ALL_GREEN).unwrap();
    let writes = chip.record.lock().unwrap().writes.len();
    // The same pattern again is not written again.
    leds.show(LedPattern::ALL_GREEN).unwrap();
    assert_eq!(chip.record.lock().unwrap().writes.len(), writes);
    drop(leds);
    let record = chip.record.lock().unwrap();
    assert_eq!(read_leds(&record.levels), "----");
    assert!(record.released);
}

#[test]
fn a_busy_line_is_named_with_the_chip_and_its_user() {
    let chip = FakeChip {
        refuse: Some(GpioFault::LineBusy {
            line: 14,
            consumer: "serial0".into(),
        }),
        ..FakeChip::default()
    };
    let error = GpioLeds::open(&chip, "/dev/gpiochip0", PINS)
        .err()
        .expect("busy");
    assert_eq!(
        error.to_string(),
        "GPIO /dev/gpiochip0: cannot request lines 20,21 7,8 24,23 15,14: line 14 is busy \
         (used by \"serial0\")"
    );
}

#[test]
fn configured_pins_are_the_lines_driven() {
    let chip = FakeChip::default();
    let pins = [[2, 3], [4, 17], [27, 22], [10, 9]];
    let mut leds = GpioLeds::open(&chip, "/dev/gpiochip0", pins).unwrap();
    leds.show(LedPattern([
        rl_layer::leds::LedColor::Green,
        rl_layer::leds::LedColor::Red,
        rl_layer::leds::LedColor::Off,
        rl_layer::leds::LedColor::Green,
    ]))
    .unwrap();
    let levels = chip.record.lock().unwrap().levels.clone();
    let high: Vec<u32> = levels.iter().filter(|(_, &h)| h).map(|(&p, _)| p).collect();
    assert_eq!(high, vec![2, 10, 17]);
    assert_eq!(levels.len(), 8);
}

/// A real controller configured for GPIO LEDs on a machine without that chip: one warning
/// naming the chip, the lines and the cause, then console LEDs, and it still takes a role.
#[test]
fn a_controller_without_the_gpio_chip_warns_once_and_shows_the_leds_on_the_console() {
    let dir = std::env::temp_dir().join(format!("rl-test-gpio-fallback-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let config = dir.join("rl.toml");
    std::fs::write(
        &config,
        "[timing]\ninit_window_ms = 1000\n[leds]\nbackend = \"gpio\"\nchip = \"/nonexistent/gpiochip9\"\n",
    )
    .unwrap();
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_rl"))
        .args([
            "controller",
            "--id",
            "1",
            "--domain",
            "184",
            "--duration-ms",
            "4000",
        ])
        .arg("--config")
        .arg(&config)
        .env("NO_COLOR", "1")
        .output()
        .unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    let stderr = String::from_utf8_lossy(&output.stderr);
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(output.status.success(), "{stderr}");
    let warnings: Vec<&str> = stderr
        .lines()
        .filter(|line| line.contains("WARN") && line.contains("status LEDs"))
        .collect();
    assert_eq!(warnings.len(), 1, "{stderr}");
    for words in [
        "/nonexistent/gpiochip9",
        "lines 20,21 7,8 24,23 15,14",
        "no such device",
        "showing them on the console instead",
    ] {
        assert!(
            warnings[0].contains(words),
            "{} lacks {words:?}",
            warnings[0]
        );
    }
    assert!(
        stderr.contains("LEDs [P:off S:off T:off | own:green]"),
        "{stderr}"
    );
    assert!(
        stderr.contains("LEDs [P:green S:off T:off | own:green]"),
        "alone, it becomes Primary: {stderr}\n{stdout}"
    );
}
