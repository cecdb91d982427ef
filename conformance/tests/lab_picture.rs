//! The fault lab's picture of a run (`lab::plot`) renders in a browser: a run with a fault,
//! role changes and an owner change at both actuators is drawn to SVG, and headless Chromium
//! loads it as an image of the drawn size. A deliberately broken SVG is refused by the same
//! page, so the check can fail.
//!
//! Needs Debian's `chromium` (`.ci/run` installs it), so it is ignored by default.

use conformance::lab::judge::{FaultRecord, Metrics};
use conformance::lab::observe::{ControllerEvent, Observations, OwnerSpan};
use conformance::lab::procs::Life;
use conformance::lab::run::Outcome;
use rl_layer::core::{Assignment, Holder, Phase, Role, SelfReport, Status};
use rl_layer::event::{Event, EventLine};
use std::path::{Path, PathBuf};
use std::process::Command;

fn chromium() -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .flat_map(|dir| [dir.join("chromium"), dir.join("chromium-browser")])
        .find(|candidate| candidate.is_file())
}

fn status_event(id: u8, at_ms: f64, role: Role) -> ControllerEvent {
    let mut status = Status::initial(id, 7);
    status.report = SelfReport {
        phase: Phase::Steady,
        role: Some(role),
        strength: Some(role.strength()),
        agreed: Some(Assignment::from_ranked([Holder {
            id: 1,
            incarnation: 7,
        }])),
        ..status.report
    };
    ControllerEvent {
        life: format!("C{id}"),
        at_ms,
        line: EventLine {
            t_ms: at_ms as u64,
            id,
            incarnation: 7,
            event: Event::Status {
                status: Box::new(status),
            },
        },
    }
}

fn span(from_ms: f64, to_ms: f64, owner: &str) -> OwnerSpan {
    OwnerSpan {
        from_ms,
        to_ms,
        owner: owner.into(),
    }
}

/// A run: C1 killed at 3 s, C2 promoted, the actuators following C2 after a 200 ms gap.
fn sample_run(picture: &Path) -> (Outcome, Observations, Vec<Life>) {
    let mut observed = Observations::default();
    observed.controller = vec![
        status_event(1, 1000.0, Role::Primary),
        status_event(2, 1000.0, Role::Secondary),
        status_event(2, 3750.0, Role::Primary),
    ];
    let life = |id: u8, ended_ms: Option<f64>| Life {
        id,
        number: 1,
        pid: 0,
        clock_offset_s: 0.0,
        clock_rate: 1.0,
        started_ms: 500.0,
        started_wall_ms: 500.0,
        ended_ms,
        paused: Vec::new(),
        exit: None,
    };
    let owners = vec![span(1000.0, 3000.0, "C1"), span(3200.0, 8000.0, "C2")];
    let outcome = Outcome {
        scenario: "kill-primary".into(),
        about: "a drawn example".into(),
        seed: 1,
        architecture: "voting",
        mutation: None,
        faults: vec![FaultRecord {
            label: "kill -9 C1, restart".into(),
            applied_ms: 3000.0,
            healed_ms: Some(6000.0),
            target: Some(1),
            alarm_within_ms: None,
        }],
        metrics: Metrics {
            judged_from_ms: 1000.0,
            servo_owners: owners.clone(),
            connext_owners: Some(owners),
            servo_gap: Some((200.0, 3200.0)),
            ..Metrics::default()
        },
        validation: Ok(conformance::validate::Accepted::default()),
        network: None,
        network_alarm_changes: Vec::new(),
        output: None,
        failures: Vec::new(),
        dir: PathBuf::new(),
        picture: picture.to_path_buf(),
        replay: String::new(),
    };
    (
        outcome,
        observed,
        vec![life(1, Some(3000.0)), life(2, None)],
    )
}

/// What the page's title says after Chromium loaded `svg` as an image.
fn load_in_chromium(browser: &Path, dir: &Path, svg: &str) -> String {
    let page = dir.join(format!("{svg}.html"));
    let html = format!(
        "<html><head><title>pending</title></head><body><img src=\"{svg}\" \
         onload=\"document.title='loaded '+this.naturalWidth+'x'+this.naturalHeight\" \
         onerror=\"document.title='refused'\"></body></html>"
    );
    std::fs::write(&page, html).unwrap();
    // At a lower CPU priority: the tests that run beside it judge timing.
    let output = Command::new("nice")
        .args(["-n", "10"])
        .arg(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--no-first-run",
            "--allow-file-access-from-files",
            "--virtual-time-budget=5000",
            "--dump-dom",
        ])
        .arg(format!("--user-data-dir={}", dir.join("profile").display()))
        .arg(format!("file://{}", page.display()))
        .output()
        .expect("chromium runs");
    let dom = String::from_utf8_lossy(&output.stdout).into_owned();
    dom.split("<title>")
        .nth(1)
        .and_then(|rest| rest.split("</title>").next())
        .unwrap_or("")
        .to_string()
}

#[test]
#[ignore = "needs chromium (apt install chromium)"]
fn chromium_renders_a_run_picture() {
    let browser =
        chromium().unwrap_or_else(|| panic!("no chromium on PATH (apt install chromium)"));
    let temporary = rl_testkit::tempdir::Dir::new("lab-picture");
    let dir = &temporary.0;
    let picture = dir.join("run.svg");
    let (outcome, observed, lives) = sample_run(&picture);
    conformance::lab::plot::draw(&picture, &outcome, &observed, &lives, 8000.0).unwrap();
    let svg = std::fs::read_to_string(&picture).unwrap();
    assert!(
        svg.contains("kill -9 C1, restart"),
        "the fault is not labelled"
    );
    assert!(svg.contains("largest gap 200 ms"), "the gap is not marked");
    std::fs::write(dir.join("broken.svg"), &svg[..svg.len() / 2]).unwrap();

    let drawn = load_in_chromium(&browser, dir, "run.svg");
    let broken = load_in_chromium(&browser, dir, "broken.svg");
    assert_eq!(drawn, "loaded 1400x460", "the picture did not render");
    assert_eq!(broken, "refused", "a broken picture was not refused");
}
