//! The explorer serves the UI, and a reviewer sees actions, states and the initial states by
//! name: checked over plain HTTP and in headless Chromium. The Chromium test is ignored by
//! default (it needs the browser installed); `cargo test -- --include-ignored` runs it and
//! fails without Chromium.

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::{Mutex, MutexGuard};
use std::time::{Duration, Instant};

/// The explorer process, killed when the test ends.
struct Explorer(Child);

impl Drop for Explorer {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("a free loopback port")
}

/// The two tests run one after the other (each holds this while its explorer runs), so
/// neither can take the other's port or connect to the other's explorer.
static ONE_EXPLORER_AT_A_TIME: Mutex<()> = Mutex::new(());

fn one_explorer_at_a_time() -> MutexGuard<'static, ()> {
    ONE_EXPLORER_AT_A_TIME
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// Starts an explorer on a free port and waits until it listens; returns it and its port.
/// An explorer that exits at start (the port was taken between `free_port` and its bind) is
/// replaced by one on another port.
fn start() -> (Explorer, u16) {
    let mut exits = Vec::new();
    for _ in 0..3 {
        let port = free_port();
        let child = Command::new(env!("CARGO_BIN_EXE_model"))
            .args(["explore", "--addr", &format!("127.0.0.1:{port}")])
            .args(["--late-joiners", "0", "--crashes", "0", "--restarts", "0"])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("the model binary starts");
        let mut explorer = Explorer(child);
        match wait_listening(&mut explorer.0, port) {
            Ok(()) => return (explorer, port),
            Err(exit) => exits.push(format!("port {port}: {exit}")),
        }
    }
    panic!("the explorer did not stay up: {exits:?}");
}

/// Waits until something listens on `port` (not a connection of the socket to itself, which
/// a connect to a free local port can make) while `explorer` still runs.
fn wait_listening(explorer: &mut Child, port: u16) -> Result<(), String> {
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        if let Some(status) = explorer.try_wait().expect("the explorer's status") {
            return Err(format!("exited {status}"));
        }
        if let Ok(stream) = TcpStream::connect(("127.0.0.1", port)) {
            if stream.local_addr().ok() != stream.peer_addr().ok() {
                // A bind failure ends the process at once: still running now, it listens.
                std::thread::sleep(Duration::from_millis(200));
                return match explorer.try_wait().expect("the explorer's status") {
                    Some(status) => Err(format!("exited {status}")),
                    None => Ok(()),
                };
            }
        }
        if Instant::now() >= deadline {
            return Err("did not listen within 20 s".to_string());
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// One HTTP/1.0 GET (an answer of known length, never chunked). stateright's explorer server
/// sometimes resets a connection while its checker thread is busy on a loaded machine (the
/// front then answers 502): retry a few times before failing.
fn get(port: u16, path: &str) -> String {
    let mut last_error = None;
    for _ in 0..5 {
        match try_get(port, path) {
            Ok(response) if !response.starts_with("HTTP/1.0 502 ") => return response,
            Ok(response) => last_error = Some(response),
            Err(error) => last_error = Some(error.to_string()),
        }
        std::thread::sleep(Duration::from_millis(300));
    }
    panic!("GET {path}: {last_error:?}");
}

fn try_get(port: u16, path: &str) -> std::io::Result<String> {
    let mut stream = TcpStream::connect(("127.0.0.1", port))?;
    stream.set_read_timeout(Some(Duration::from_secs(20)))?;
    write!(stream, "GET {path} HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n")?;
    let mut response = String::new();
    stream.read_to_string(&mut response)?;
    Ok(response)
}

#[test]
fn explorer_json_names_actions_and_states() {
    let _serial = one_explorer_at_a_time();
    let (_explorer, port) = start();
    let status = get(port, "/.status");
    assert!(status.contains("200 OK"), "{status}");
    assert!(status.contains("actuator has a single owner"), "{status}");
    // The successors of the first initial state (C1 alone).
    let states = get(port, "/.states/0");
    assert!(states.contains("round ends"), "{states}");
    assert!(states.contains("C1 up#0 initializing"), "{states}");
    assert!(!states.contains("Controller {"), "raw Debug dump: {states}");
    // The initial states, named by who starts and who may join later (stateright's own
    // answer has no name, and its UI says "Init 0", ...).
    for path in ["/.states", "/.states/"] {
        let response = get(port, path);
        assert!(response.starts_with("HTTP/1.0 200 "), "{response}");
        assert_eq!(initial_state_names(&response), INITIAL_STATES, "{path}");
        assert!(!response.contains("Init"), "{response}");
    }
    let missing = get(port, "/.states/9");
    assert!(missing.starts_with("HTTP/1.0 404 "), "{missing}");
}

/// The initial states of the tests' configuration, as the explorer names them.
const INITIAL_STATES: [&str; 3] = [
    "C1 starts; C2, C3 may join later",
    "C1, C2 start; C3 may join later",
    "C1, C2, C3 start",
];

/// The `action` of each element of a `/.states` answer, in order.
fn initial_state_names(response: &str) -> Vec<String> {
    let (_, body) = response
        .split_once("\r\n\r\n")
        .unwrap_or_else(|| panic!("no body in {response}"));
    let states: Vec<serde_json::Value> =
        serde_json::from_str(body).unwrap_or_else(|error| panic!("{error}: {body}"));
    states
        .iter()
        .map(|state| match state["action"].as_str() {
            Some(name) => name.to_string(),
            None => panic!("an initial state without a name: {state}"),
        })
        .collect()
}

/// Chromium on PATH (Debian's `chromium`, or `chromium-browser` elsewhere).
fn chromium() -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .flat_map(|dir| [dir.join("chromium"), dir.join("chromium-browser")])
        .find(|candidate| candidate.is_file())
}

#[test]
#[ignore = "needs chromium (apt install chromium)"]
fn chromium_renders_an_action_and_a_state_by_name() {
    // Ignored unless asked for (`--include-ignored`, as .ci/run does): then Chromium must exist.
    let browser = chromium().unwrap_or_else(|| {
        panic!("no chromium or chromium-browser on PATH (apt install chromium)")
    });
    let _serial = one_explorer_at_a_time();
    let (_explorer, port) = start();
    // Deep link: the first initial state, then its first action (a round ends).
    let url = format!("http://127.0.0.1:{port}/#/steps/0/0");
    let dom = dump_dom(&browser, port, &url);
    assert!(dom.contains("round ends"), "no action by name in:\n{dom}");
    assert!(
        dom.contains("C1 up#0"),
        "no controller state by name in:\n{dom}"
    );
    assert!(
        dom.contains(INITIAL_STATES[0]),
        "the path does not start with the initial state's name:\n{dom}"
    );
    // The first screen: the initial states to choose from, each by name.
    let dom = dump_dom(&browser, port, &format!("http://127.0.0.1:{port}/#/steps"));
    for name in INITIAL_STATES {
        assert!(dom.contains(name), "no initial state {name:?} in:\n{dom}");
    }
    assert!(!dom.contains("Init 0"), "stateright's own name in:\n{dom}");
}

/// The page's DOM after its scripts ran, from headless Chromium. A Chromium that exits
/// without printing a page (it sometimes crashes on its first start after installation, or
/// under load) is started again with a fresh profile, twice at most; its exit status and
/// error output are in the failure message.
fn dump_dom(browser: &std::path::Path, port: u16, url: &str) -> String {
    let mut attempts = Vec::new();
    for attempt in 1..=3 {
        let profile = std::env::temp_dir().join(format!("rl-explorer-chromium-{port}-{attempt}"));
        let output = Command::new(browser)
            .args([
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--disable-dev-shm-usage",
                "--disable-quic",
                "--no-first-run",
                "--disable-background-networking",
                "--disable-component-update",
                "--disable-sync",
                "--virtual-time-budget=10000",
                "--dump-dom",
            ])
            .arg(format!("--user-data-dir={}", profile.display()))
            .arg(url)
            .output()
            .expect("chromium runs");
        let _ = std::fs::remove_dir_all(&profile);
        let dom = String::from_utf8_lossy(&output.stdout).into_owned();
        if output.status.success() && dom.contains("<body") {
            return dom;
        }
        let stderr = String::from_utf8_lossy(&output.stderr);
        let tail: String = stderr.lines().rev().take(8).collect::<Vec<_>>().join("\n");
        attempts.push(format!(
            "attempt {attempt}: {} with {} bytes of DOM; stderr ends:\n{tail}",
            output.status,
            dom.len()
        ));
        std::thread::sleep(Duration::from_secs(1));
    }
    panic!("chromium printed no page:\n{}", attempts.join("\n"));
}
