//! Headless Chromium for the status page tests: finding it, a page's DOM after its script ran,
//! the LEDs and card facts in a dumped DOM (of any group, or of one group's section), a
//! Chromium kept open on a page (read through the DevTools protocol) and screenshots for the
//! documentation.

// Shared by two test files (status_page.rs, status_groups.rs), each using part of it.
#![allow(dead_code)]

use super::http::{free_port, get};
use crate::support;
use serde_json::Value;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

/// Chromium on PATH (Debian's `chromium`, or `chromium-browser` elsewhere).
pub fn chromium() -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .flat_map(|dir| [dir.join("chromium"), dir.join("chromium-browser")])
        .find(|candidate| candidate.is_file())
}

pub const HEADLESS: &[&str] = &[
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
];

/// Chromium at a lower CPU priority (`nice -n 10`, the same pid): it is the test's observer,
/// and on a two-core machine its start-up would otherwise starve the controllers it watches
/// past their stall detection (a starved controller rightly starts a new life).
pub fn browser_command(browser: &PathBuf) -> Command {
    let mut command = Command::new("nice");
    command.args(["-n", "10"]).arg(browser);
    command
}

/// A fresh profile directory for one Chromium run.
pub fn profile(tag: &str) -> support::tempdir::Dir {
    support::tempdir::Dir::new(&format!("chromium-{tag}"))
}

/// The page's DOM after its script ran for a while (in Chromium's virtual time).
pub fn dump_dom(browser: &PathBuf, url: &str) -> String {
    let dir = profile("dom");
    let output = browser_command(browser)
        .args(HEADLESS)
        .args(["--virtual-time-budget=2000", "--dump-dom"])
        .arg(format!("--user-data-dir={}", dir.0.display()))
        .arg(url)
        .stderr(Stdio::null())
        .output()
        .expect("chromium runs");
    String::from_utf8_lossy(&output.stdout).into_owned()
}

/// The colour an LED shows in a dumped DOM (`None`: no such LED).
pub fn led(dom: &str, controller: u8, led: u8) -> Option<String> {
    let tag_start = format!("data-controller=\"{controller}\" data-led=\"{led}\" data-colour=\"");
    let at = dom.find(&tag_start)? + tag_start.len();
    dom[at..].split('"').next().map(str::to_string)
}

/// The colour an LED of group `group`'s controller shows in a dumped DOM (`None`: no such LED).
pub fn group_led(dom: &str, group: &str, controller: u8, led: u8) -> Option<String> {
    let tag_start = format!(
        "data-group=\"{group}\" data-controller=\"{controller}\" data-led=\"{led}\" data-colour=\""
    );
    let at = dom.find(&tag_start)? + tag_start.len();
    dom[at..].split('"').next().map(str::to_string)
}

/// A fact the page shows on a controller's card in a dumped DOM (`None`: no such card or fact).
pub fn card_field(dom: &str, controller: u8, field: &str) -> Option<String> {
    let card = format!("data-controller=\"{controller}\" data-alive=");
    let card_at = dom.find(&card)?;
    let tag = format!("data-field=\"{field}\">");
    let at = card_at + dom[card_at..].find(&tag)? + tag.len();
    dom[at..].split('<').next().map(str::to_string)
}

/// A Chromium kept open on a page; its tabs' titles read through the DevTools HTTP endpoint.
pub struct OpenPage {
    browser: Child,
    debug_port: u16,
    _profile: support::tempdir::Dir,
}

impl OpenPage {
    pub fn open(browser: &PathBuf, url: &str) -> OpenPage {
        let dir = profile("live");
        let debug_port = free_port();
        let child = browser_command(browser)
            .args(HEADLESS)
            .arg(format!("--remote-debugging-port={debug_port}"))
            .arg("--remote-allow-origins=*")
            .arg(format!("--user-data-dir={}", dir.0.display()))
            .arg(url)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("chromium runs");
        OpenPage {
            browser: child,
            debug_port,
            _profile: dir,
        }
    }

    /// The LED colours the open page shows now, read from its live DOM through the DevTools
    /// protocol (`Runtime.evaluate` over the tab's WebSocket): (controller, LED) -> colour.
    /// One group's page only: with several, see [`OpenPage::group_leds`].
    pub fn leds(&self) -> Option<std::collections::BTreeMap<(u8, u8), String>> {
        let leds = self.group_leds()?;
        Some(
            leds.into_iter()
                .map(|((_, controller, led), colour)| ((controller, led), colour))
                .collect(),
        )
    }

    /// The LED colours the open page shows now, by group: (group, controller, LED) -> colour.
    pub fn group_leds(&self) -> Option<std::collections::BTreeMap<(String, u8, u8), String>> {
        let expression = "JSON.stringify([...document.querySelectorAll('[data-led]')].map(\
            e => [e.dataset.group, e.dataset.controller, e.dataset.led, e.dataset.colour]))";
        let value = self.evaluate(expression)?;
        let list: Vec<(String, String, String, String)> =
            serde_json::from_str(value.as_str()?).ok()?;
        Some(
            list.into_iter()
                .filter_map(|(group, c, n, colour)| {
                    Some(((group, c.parse().ok()?, n.parse().ok()?), colour))
                })
                .collect(),
        )
    }

    /// The value of a JavaScript `expression` in the open page (`Runtime.evaluate` over the
    /// tab's DevTools WebSocket).
    fn evaluate(&self, expression: &str) -> Option<Value> {
        let (_, body) = get(self.debug_port, "/json/list")?;
        let tabs: Value = serde_json::from_str(&body).ok()?;
        let socket_url = tabs.as_array()?.iter().find(|t| t["type"] == "page")?
            ["webSocketDebuggerUrl"]
            .as_str()?
            .to_string();
        // Chromium names the host the request named; the port is the debugging port.
        let path = &socket_url[socket_url.find("/devtools/")?..];
        let socket_url = format!("ws://127.0.0.1:{}{path}", self.debug_port);
        let (mut socket, _) = match tungstenite::connect(socket_url.as_str()) {
            Ok(connected) => connected,
            Err(error) => {
                eprintln!("DevTools WebSocket {socket_url}: {error}");
                return None;
            }
        };
        let request = serde_json::json!({
            "id": 1,
            "method": "Runtime.evaluate",
            "params": {"expression": expression, "returnByValue": true}
        });
        socket
            .send(tungstenite::Message::text(request.to_string()))
            .ok()?;
        loop {
            let reply = socket.read().ok()?;
            let Ok(text) = reply.to_text() else { continue };
            let reply: Value = serde_json::from_str(text).ok()?;
            if reply["id"] != 1 {
                continue;
            }
            let _ = socket.close(None);
            return Some(reply["result"]["result"]["value"].clone());
        }
    }

    /// The title of the page's tab now, if the browser answers.
    pub fn title(&self) -> Option<String> {
        let (_, body) = get(self.debug_port, "/json/list")?;
        let tabs: Value = serde_json::from_str(&body).ok()?;
        tabs.as_array()?
            .iter()
            .filter(|t| t["type"] == "page")
            .find_map(|t| {
                t["title"]
                    .as_str()
                    .filter(|t| t.starts_with("RL:"))
                    .map(str::to_string)
            })
    }
}

impl Drop for OpenPage {
    fn drop(&mut self) {
        let _ = self.browser.kill();
        let _ = self.browser.wait();
        // Chromium's helper processes outlive the browser briefly and write to the profile.
        std::thread::sleep(Duration::from_millis(300));
    }
}

/// A screenshot of the page (for the documentation: `RL_STATUS_SCREENSHOT_DIR=docs/img`).
pub fn screenshot(browser: &PathBuf, url: &str, path: &str) {
    let dir = profile("shot");
    let status = browser_command(browser)
        .args(HEADLESS)
        .args([
            "--virtual-time-budget=2000",
            "--hide-scrollbars",
            "--window-size=1200,800",
        ])
        .arg(format!("--screenshot={path}"))
        .arg(format!("--user-data-dir={}", dir.0.display()))
        .arg(url)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .expect("chromium runs");
    assert!(status.success(), "chromium --screenshot failed");
}
