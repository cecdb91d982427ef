//! `rl status --serve` with real processes: three controllers and the status server on one
//! DDS domain. `/status.json` is the `rl status --json` object, bad requests get 4xx and the
//! server serves on, `/metrics` parses with the Prometheus client library, and headless
//! Chromium shows the LEDs and sees the page follow a `kill -9` of the Primary.
//!
//! The Chromium and Prometheus tests need outside tools (Debian's `chromium`, Python's
//! `prometheus_client`; `.ci/run` installs both), so they are ignored by default. Chromium's
//! side (finding it, reading a page, screenshots) is in `status_page/chromium.rs` (beside this file),
//! the HTTP client in `status_page/http.rs`; `status_groups.rs` uses both for several groups.

mod support;

mod status_page {
    pub mod chromium;
    pub mod http;
}

use rl_layer::core::Role;
use serde_json::Value;
use status_page::chromium::{card_field, chromium, dump_dom, led, screenshot, OpenPage};
use status_page::http::{exchange, free_port, get};
use std::io::Write;
use std::net::TcpStream;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};
use support::Cluster;

/// Three controllers in their roles and `rl status --serve` on a free port.
fn formation(tag: &str, domain: u16) -> (Cluster, u16) {
    let mut cluster = Cluster::new(tag, domain, "");
    for id in 1..=3 {
        cluster.start(id);
    }
    cluster.wait_for(
        "three controllers in three roles",
        Duration::from_secs(30),
        |c| {
            [Role::Primary, Role::Secondary, Role::Tertiary]
                .iter()
                .all(|role| (1..=3).any(|id| c.steady_with(id, Some(*role))))
        },
    );
    let port = free_port();
    let addr = format!("127.0.0.1:{port}");
    cluster
        .fleet
        .start_other("status", &["status", "--serve", &addr])
        .expect("start rl status --serve");
    let deadline = Instant::now() + Duration::from_secs(15);
    loop {
        if let Some((200, body)) = get(port, "/status.json") {
            let view: Value = serde_json::from_str(&body).unwrap_or(Value::Null);
            let alive = view["controllers"]
                .as_array()
                .map_or(0, |c| c.iter().filter(|c| c["alive"] == true).count());
            if alive == 3 {
                break;
            }
        }
        assert!(
            Instant::now() < deadline,
            "rl status --serve never showed three controllers"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    (cluster, port)
}

/// The shape of a JSON value: object keys (recursively), array element shapes, value kinds.
fn shape(value: &Value) -> Value {
    match value {
        Value::Object(map) => {
            Value::Object(map.iter().map(|(k, v)| (k.clone(), shape(v))).collect())
        }
        Value::Array(items) => Value::Array(items.iter().map(shape).collect()),
        Value::Number(_) => Value::String("number".into()),
        Value::String(_) => Value::String("string".into()),
        Value::Bool(_) => Value::String("bool".into()),
        Value::Null => Value::String("null".into()),
    }
}

#[test]
fn status_json_is_the_status_object_and_bad_requests_are_refused() {
    let (cluster, port) = formation("status-page-json", 170);

    // The same object `rl status --json --once` prints, field for field.
    let once = Command::new(support::rl())
        .args(["status", "--json", "--once", "--domain", "170"])
        .output()
        .expect("rl status --json --once");
    let printed: Value = serde_json::from_slice(&once.stdout).expect("rl status --json");
    let (status, body) = get(port, "/status.json").expect("an answer");
    assert_eq!(status, 200);
    let served: Value = serde_json::from_str(&body).expect("/status.json is JSON");
    assert_eq!(
        shape(&served),
        shape(&printed),
        "served {served}\nprinted {printed}"
    );
    for id in 1..=3u8 {
        let pick = |view: &Value| {
            view["controllers"]
                .as_array()
                .and_then(|c| c.iter().find(|c| c["id"] == id))
                .map(|c| {
                    (
                        c["role"].clone(),
                        c["strength"].clone(),
                        c["incarnation"].clone(),
                    )
                })
        };
        assert_eq!(pick(&served), pick(&printed), "C{id}");
        let role = cluster.role_of(id).map(|r| r.name());
        assert_eq!(pick(&served).map(|p| p.0), Some(Value::from(role)), "C{id}");
    }

    // Bad requests: answered 4xx, and the server serves on.
    let refused: &[(&str, Vec<u8>, u16)] = &[
        ("garbage", b"\x00\xffnot http at all\r\n\r\n".to_vec(), 400),
        (
            "a huge header",
            {
                let mut huge = b"GET / HTTP/1.1\r\nX-Filler: ".to_vec();
                huge.extend(std::iter::repeat_n(b'a', 64 * 1024));
                huge.extend_from_slice(b"\r\n\r\n");
                huge
            },
            431,
        ),
        (
            "an unknown path",
            b"GET /etc/passwd HTTP/1.1\r\n\r\n".to_vec(),
            404,
        ),
        (
            "a POST",
            b"POST /status.json HTTP/1.1\r\nContent-Length: 0\r\n\r\n".to_vec(),
            405,
        ),
        (
            "HTTP/2 preface",
            b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n".to_vec(),
            400,
        ),
    ];
    for (what, request, expected) in refused {
        let answer = exchange(port, request);
        assert_eq!(answer.map(|a| a.0), Some(*expected), "{what}");
        assert_eq!(
            get(port, "/status.json").map(|a| a.0),
            Some(200),
            "after {what}"
        );
    }
    // A client that connects and says nothing holds one connection, not the server.
    let _silent = TcpStream::connect(("127.0.0.1", port)).expect("connect");
    let (status, page) = get(port, "/").expect("the page");
    assert_eq!(status, 200);
    assert!(page.contains("data-led"), "{page}");
    assert!(
        !page.contains("http://") && !page.contains("https://"),
        "the page loads nothing from elsewhere"
    );
}

/// Runs Python's Prometheus parser over `text`: one `name{labels} value` JSON per sample.
fn prometheus_samples(text: &str) -> Vec<Value> {
    let script = "import sys, json\n\
        from prometheus_client.parser import text_string_to_metric_families\n\
        for family in text_string_to_metric_families(sys.stdin.read()):\n\
        \x20   for s in family.samples:\n\
        \x20       print(json.dumps({'family': family.name, 'type': family.type, 'name': s.name, 'labels': s.labels, 'value': s.value}))\n";
    let mut python = Command::new("python3")
        .args(["-c", script])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("python3 runs");
    python
        .stdin
        .take()
        .expect("stdin")
        .write_all(text.as_bytes())
        .expect("feed the parser");
    let output = python.wait_with_output().expect("python3 ends");
    assert!(
        output.status.success(),
        "prometheus_client refused the exposition ({}):\n{text}",
        String::from_utf8_lossy(&output.stderr)
    );
    String::from_utf8_lossy(&output.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).expect("a sample line"))
        .collect()
}

fn value_of(samples: &[Value], name: &str, labels: &[(&str, &str)]) -> Option<f64> {
    samples
        .iter()
        .find(|s| s["name"] == name && labels.iter().all(|(k, v)| s["labels"][*k] == *v))
        .and_then(|s| s["value"].as_f64())
}

#[test]
#[ignore = "needs Python's prometheus_client (pip install prometheus_client)"]
fn metrics_parse_with_the_prometheus_client() {
    let (mut cluster, port) = formation("status-page-metrics", 171);
    let (status, text) = get(port, "/metrics").expect("an answer");
    assert_eq!(status, 200);
    let samples = prometheus_samples(&text);
    for id in 1..=3u8 {
        let role = cluster.role_of(id).expect("a role");
        let c = id.to_string();
        let strength = value_of(&samples, "rl_strength", &[("controller", &c)]);
        assert_eq!(
            strength,
            Some(f64::from(role.strength().value())),
            "C{id}\n{text}"
        );
        let held = value_of(
            &samples,
            "rl_role",
            &[("controller", &c), ("role", role.name())],
        );
        assert_eq!(held, Some(1.0), "C{id}\n{text}");
        assert_eq!(
            value_of(&samples, "rl_alive", &[("controller", &c)]),
            Some(1.0)
        );
        let seen = value_of(&samples, "rl_heartbeats_seen_total", &[("controller", &c)]);
        assert!(seen.is_some_and(|n| n >= 1.0), "C{id}\n{text}");
    }
    let primary = (1..=3u8)
        .find(|id| cluster.role_of(*id) == Some(Role::Primary))
        .expect("a Primary");
    assert_eq!(
        value_of(&samples, "rl_commander", &[]),
        Some(f64::from(primary))
    );
    assert_eq!(
        value_of(&samples, "rl_commander_changes_total", &[]),
        Some(0.0)
    );
    assert!(
        samples.iter().all(|s| s["family"] != "rl_controller_alarm"),
        "{text}"
    );

    // Kill the Primary: the alarm, the new commander and the change appear. (Changes count
    // from the end of the status process's first listening window, 1.75 s after its start.)
    std::thread::sleep(Duration::from_secs(2));
    cluster.fleet.kill(primary).expect("kill -9");
    let about = primary.to_string();
    let deadline = Instant::now() + Duration::from_secs(10);
    let (samples, text) = loop {
        let (_, text) = get(port, "/metrics").expect("an answer");
        let samples = prometheus_samples(&text);
        let alarmed = value_of(
            &samples,
            "rl_controller_alarm",
            &[("about", &about), ("reason", "lost")],
        );
        let commander = value_of(&samples, "rl_commander", &[]);
        if alarmed == Some(1.0) && commander.is_some_and(|c| c != f64::from(primary)) {
            break (samples, text);
        }
        assert!(
            Instant::now() < deadline,
            "no alarm or new commander after the kill:\n{text}"
        );
        std::thread::sleep(Duration::from_millis(200));
    };
    assert_eq!(
        value_of(&samples, "rl_alive", &[("controller", &about)]),
        Some(0.0)
    );
    // The dead Primary's last announcement is not shown beside the live Primary's.
    for family in ["rl_role", "rl_strength"] {
        assert!(
            samples
                .iter()
                .all(|s| !(s["name"] == family && s["labels"]["controller"] == about.as_str())),
            "the killed C{primary} still exports {family}"
        );
    }
    assert!(
        value_of(&samples, "rl_commander_changes_total", &[]).is_some_and(|n| n >= 1.0),
        "{text}"
    );
    assert!(
        value_of(&samples, "rl_commander_last_gap_ms", &[]).is_some(),
        "{text}"
    );
    cluster.pump(Duration::from_millis(10));
}

#[test]
#[ignore = "needs chromium (apt install chromium)"]
fn chromium_shows_the_leds_and_follows_a_kill_of_the_primary() {
    let browser =
        chromium().unwrap_or_else(|| panic!("no chromium on PATH (apt install chromium)"));
    let (mut cluster, port) = formation("status-page-chromium", 172);
    let url = format!("http://127.0.0.1:{port}/");
    let primary = (1..=3u8)
        .find(|id| cluster.role_of(*id) == Some(Role::Primary))
        .expect("a Primary");

    let dom = dump_dom(&browser, &url);
    assert_page_shows_the_formation(&dom, &cluster, port);
    if let Ok(dir) = std::env::var("RL_STATUS_SCREENSHOT_DIR") {
        screenshot(&browser, &url, &format!("{dir}/status-page.png"));
    }

    // An open page follows the kill without a reload.
    let page = OpenPage::open(&browser, &url);
    let deadline = Instant::now() + Duration::from_secs(15);
    let formed = |t: &String| {
        ["primary", "secondary", "tertiary"]
            .iter()
            .all(|r| t.contains(r))
    };
    while !page.title().is_some_and(|t| formed(&t)) {
        assert!(
            Instant::now() < deadline,
            "the page never showed the formation: {:?}",
            page.title()
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    let killed = open_page_follows_a_kill(&page, &mut cluster, primary);

    // The LEDs: the killed controller's are unknown, a survivor shows the failed unit red.
    let deadline = Instant::now() + Duration::from_secs(5);
    loop {
        let dom = dump_dom(&browser, &url);
        let unknown = (1..=4).all(|n| led(&dom, primary, n).as_deref() == Some("unknown"));
        let red = (1..=3u8)
            .filter(|id| *id != primary)
            .any(|id| (1..=3).any(|n| led(&dom, id, n).as_deref() == Some("red")));
        if unknown && red {
            // Includes starting a fresh Chromium for the dump.
            eprintln!(
                "a page loaded after the kill showed the LEDs {} ms after it",
                killed.elapsed().as_millis()
            );
            break;
        }
        assert!(
            Instant::now() < deadline,
            "no red LED for the failed unit:\n{dom}"
        );
    }
    if let Ok(dir) = std::env::var("RL_STATUS_SCREENSHOT_DIR") {
        screenshot(&browser, &url, &format!("{dir}/status-page-after-kill.png"));
    }
    cluster.pump(Duration::from_millis(10));
}

/// Every controller's LEDs in `dom`: green on its own role and on LED4, off elsewhere; each
/// card's incarnation the controller's, to the last digit (they are 64 bits).
fn assert_page_shows_the_formation(dom: &str, cluster: &Cluster, port: u16) {
    for id in 1..=3u8 {
        let rank = cluster.role_of(id).expect("a role").rank() as u8 + 1;
        for n in 1..=4u8 {
            let expected = if n == rank || n == 4 { "green" } else { "off" };
            assert_eq!(
                led(dom, id, n).as_deref(),
                Some(expected),
                "C{id} LED{n}\n{dom}"
            );
        }
    }
    let (_, body) = get(port, "/status.json").expect("status.json answers");
    let status: Value = serde_json::from_str(&body).expect("status.json is JSON");
    for controller in status["controllers"].as_array().expect("controllers") {
        let id = controller["id"].as_u64().expect("an id") as u8;
        let incarnation = controller["incarnation"].as_u64().expect("an incarnation");
        assert_eq!(
            card_field(dom, id, "incarnation"),
            Some(incarnation.to_string()),
            "C{id}'s incarnation on the page"
        );
    }
}

/// Kills `primary` and waits for the open `page` to follow: its title names it lost and its
/// LEDs, read from the live DOM, show the killed controller's unknown and a survivor's red
/// for the failed unit, each within 2 s. Returns when the kill was sent.
fn open_page_follows_a_kill(page: &OpenPage, cluster: &mut Cluster, primary: u8) -> Instant {
    let lost = format!("C{primary} LOST");
    cluster.fleet.kill(primary).expect("kill -9");
    let killed = Instant::now();
    let mut title = page.title();
    while !title.as_ref().is_some_and(|t| t.contains(&lost)) {
        assert!(
            killed.elapsed() < Duration::from_secs(2),
            "the page did not show C{primary} lost within 2 s of the kill: {title:?}"
        );
        std::thread::sleep(Duration::from_millis(20));
        title = page.title();
    }
    let latency = killed.elapsed();
    eprintln!(
        "the open page showed the kill after {} ms: {title:?}",
        latency.as_millis()
    );
    let leds_follow = |leds: &std::collections::BTreeMap<(u8, u8), String>| {
        let unknown = (1..=4).all(|n| leds.get(&(primary, n)).is_some_and(|c| c == "unknown"));
        let red = (1..=3u8)
            .filter(|id| *id != primary)
            .any(|id| (1..=3).any(|n| leds.get(&(id, n)).is_some_and(|c| c == "red")));
        unknown && red
    };
    let mut leds = page.leds();
    while !leds.as_ref().is_some_and(leds_follow) {
        assert!(
            killed.elapsed() < Duration::from_secs(2),
            "the open page's LEDs did not follow the kill of C{primary} within 2 s: {leds:?}"
        );
        std::thread::sleep(Duration::from_millis(20));
        leds = page.leds();
    }
    eprintln!(
        "the open page's LEDs showed the kill after {} ms",
        killed.elapsed().as_millis()
    );
    killed
}
