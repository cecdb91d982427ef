//! The front of `model explore`: stateright's explorer UI with the initial states named.
//!
//! stateright's UI names the initial states `Init 0`, `Init 1`, ... (its JSON for them, the
//! answer to `GET /.states`, has no `action`), and stateright offers no hook to name them. So
//! its explorer runs on an internal loopback port, and this front, on the user's address,
//! forwards every request to it (method, path, body and Content-Type; then the status,
//! Content-Type and body of the answer). It changes one answer only: to each element of the
//! initial-state list it adds the state's name ([`render::initial_state_name`]) as `action`,
//! which the UI shows instead of `Init i`.

use crate::{render, RlModel};
use stateright::Model;
use std::fmt::Debug;
use std::hash::Hash;
use std::io::{Read, Write};
use std::net::{Ipv4Addr, SocketAddr, TcpListener, TcpStream};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};
use tiny_http::{Header, Method, Request, Response, Server, StatusCode};

/// Why the explorer could not start.
#[derive(Debug, thiserror::Error)]
pub enum ExploreError {
    /// The user's address is taken, malformed or not ours.
    #[error("explore: cannot listen on {addr}: {reason}")]
    Bind { addr: String, reason: String },
    /// stateright's explorer did not answer on a loopback port (each attempt's reason).
    #[error("explore: stateright's explorer did not start on a loopback port: {0}")]
    Explorer(String),
}

/// The front, listening on the user's address, with stateright's explorer running behind it.
pub struct Front {
    server: Server,
    explorer: SocketAddr,
    names: Arc<Vec<String>>,
}

impl Front {
    /// Listens on `addr`, then starts stateright's explorer of `model` on a free loopback port
    /// and waits until it answers.
    pub fn start(model: &RlModel, addr: &str) -> Result<Front, ExploreError> {
        Front::start_named(model, initial_state_names(model), addr)
    }

    /// The same for any model (the output model, `crate::outputs`), its initial states named
    /// by `names` in stateright's order.
    pub fn start_named<M>(model: &M, names: Vec<String>, addr: &str) -> Result<Front, ExploreError>
    where
        M: Model + Clone + Send + Sync + 'static,
        M::State: Debug + Hash + Send + Sync + Clone + PartialEq,
        M::Action: Debug + Send + Sync + Clone + PartialEq,
    {
        let server = Server::http(addr).map_err(|error| ExploreError::Bind {
            addr: addr.to_string(),
            reason: error.to_string(),
        })?;
        Ok(Front {
            server,
            explorer: start_explorer(model)?,
            names: Arc::new(names),
        })
    }

    /// The names of the initial states, in the explorer's order.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// Serves until the process ends, each request on a thread of its own.
    pub fn run(self) {
        for request in self.server.incoming_requests() {
            let names = Arc::clone(&self.names);
            let explorer = self.explorer;
            std::thread::spawn(move || answer(request, explorer, &names));
        }
    }
}

/// The names of `model`'s initial states, in stateright's order.
pub fn initial_state_names(model: &RlModel) -> Vec<String> {
    model
        .init_states()
        .iter()
        .map(render::initial_state_name)
        .collect()
}

/// Runs stateright's explorer on a free loopback port; three attempts, since another process
/// may take the port between our pick and stateright's bind.
fn start_explorer<M>(model: &M) -> Result<SocketAddr, ExploreError>
where
    M: Model + Clone + Send + Sync + 'static,
    M::State: Debug + Hash + Send + Sync + Clone + PartialEq,
    M::Action: Debug + Send + Sync + Clone + PartialEq,
{
    let mut failures = Vec::new();
    for _ in 0..3 {
        let addr = TcpListener::bind((Ipv4Addr::LOCALHOST, 0))
            .and_then(|listener| listener.local_addr())
            .map_err(|error| ExploreError::Explorer(format!("no free loopback port: {error}")))?;
        let model = model.clone();
        let serving = std::thread::spawn(move || {
            model.checker().serve(addr);
        });
        match wait_answering(addr, &serving) {
            Ok(()) => return Ok(addr),
            Err(reason) => failures.push(format!("{addr}: {reason}")),
        }
    }
    Err(ExploreError::Explorer(failures.join("; ")))
}

/// Why a request could not be forwarded to stateright's explorer, or its answer not used.
#[derive(Debug, thiserror::Error)]
enum ForwardError {
    #[error("reading the request's body: {0}")]
    RequestBody(std::io::Error),
    #[error("{0}")]
    Io(#[from] std::io::Error),
    #[error("an answer without the end of its header")]
    NoHeaderEnd,
    #[error("a malformed status line {0:?}")]
    StatusLine(String),
    #[error("a malformed Content-Length {0:?}")]
    ContentLength(String),
    #[error("{got} of {length} bytes")]
    Truncated { got: usize, length: usize },
    #[error("the initial states are not JSON: {0}")]
    NotJson(#[from] serde_json::Error),
    #[error("the initial states are not a JSON array of objects")]
    NotAList,
    #[error("{got} initial states, the model has {model}")]
    Count { got: usize, model: usize },
    #[error("it stopped (its port was probably taken)")]
    Stopped,
    #[error("no answer within 30 s")]
    NoAnswer,
}

/// Waits until the explorer at `addr` answers `GET /.status` while `serving` still runs.
fn wait_answering(addr: SocketAddr, serving: &JoinHandle<()>) -> Result<(), ForwardError> {
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        if serving.is_finished() {
            return Err(ForwardError::Stopped);
        }
        let timeout = Some(Duration::from_secs(2));
        let answer = exchange(addr, "GET", "/.status", None, &[], timeout);
        if answer.is_ok_and(|reply| reply.status == 200) && !serving.is_finished() {
            return Ok(());
        }
        if Instant::now() >= deadline {
            return Err(ForwardError::NoAnswer);
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// An answer of the explorer.
#[derive(Debug)]
struct Reply {
    status: u16,
    content_type: Option<String>,
    body: Vec<u8>,
}

/// Forwards `request` to the explorer and answers it; 502 with the reason if that fails.
fn answer(mut request: Request, explorer: SocketAddr, names: &[String]) {
    let initial_states =
        *request.method() == Method::Get && matches!(request.url(), "/.states" | "/.states/");
    let reply = forward(&mut request, explorer).and_then(|mut reply| {
        if initial_states && reply.status == 200 {
            reply.body = name_initial_states(&reply.body, names)?;
        }
        Ok(reply)
    });
    let response = match reply {
        Ok(reply) => {
            let mut response = Response::from_data(reply.body).with_status_code(reply.status);
            if let Some(header) = reply
                .content_type
                .and_then(|value| Header::from_bytes("Content-Type", value).ok())
            {
                response = response.with_header(header);
            }
            response
        }
        Err(reason) => Response::from_string(format!(
            "explore: {} {}: stateright's explorer at {explorer}: {reason}\n",
            request.method(),
            request.url()
        ))
        .with_status_code(StatusCode(502)),
    };
    // A client that has gone away needs no answer.
    let _ = request.respond(response);
}

fn forward(request: &mut Request, explorer: SocketAddr) -> Result<Reply, ForwardError> {
    let mut body = Vec::new();
    request
        .as_reader()
        .read_to_end(&mut body)
        .map_err(ForwardError::RequestBody)?;
    let content_type = request
        .headers()
        .iter()
        .find(|header| header.field.equiv("Content-Type"))
        .map(|header| header.value.to_string());
    let method = request.method().to_string();
    exchange(
        explorer,
        &method,
        request.url(),
        content_type.as_deref(),
        &body,
        None,
    )
}

/// One HTTP/1.0 request to `addr` (the answer ends with the connection).
fn exchange(
    addr: SocketAddr,
    method: &str,
    url: &str,
    content_type: Option<&str>,
    body: &[u8],
    timeout: Option<Duration>,
) -> Result<Reply, ForwardError> {
    let mut stream = TcpStream::connect(addr)?;
    stream.set_read_timeout(timeout)?;
    let mut head = format!("{method} {url} HTTP/1.0\r\nHost: {addr}\r\n");
    if let Some(content_type) = content_type {
        head.push_str(&format!("Content-Type: {content_type}\r\n"));
    }
    head.push_str(&format!("Content-Length: {}\r\n\r\n", body.len()));
    stream.write_all(head.as_bytes())?;
    stream.write_all(body)?;
    let mut raw = Vec::new();
    stream.read_to_end(&mut raw)?;
    parse_reply(&raw)
}

/// Status, Content-Type and body of an HTTP/1.x answer.
fn parse_reply(raw: &[u8]) -> Result<Reply, ForwardError> {
    let end = raw
        .windows(4)
        .position(|window| window == b"\r\n\r\n")
        .ok_or(ForwardError::NoHeaderEnd)?;
    let head = String::from_utf8_lossy(&raw[..end]);
    let mut lines = head.split("\r\n");
    let status_line = lines.next().unwrap_or_default();
    let status = match status_line.split(' ').collect::<Vec<_>>()[..] {
        [version, code, ..] if version.starts_with("HTTP/1.") => code.parse().ok(),
        _ => None,
    }
    .ok_or_else(|| ForwardError::StatusLine(status_line.to_string()))?;
    let mut reply = Reply {
        status,
        content_type: None,
        body: raw[end + 4..].to_vec(),
    };
    for (name, value) in lines.filter_map(|line| line.split_once(':')) {
        let value = value.trim();
        if name.eq_ignore_ascii_case("Content-Type") {
            reply.content_type = Some(value.to_string());
        } else if name.eq_ignore_ascii_case("Content-Length") {
            let length: usize = value
                .parse()
                .map_err(|_| ForwardError::ContentLength(value.to_string()))?;
            if reply.body.len() < length {
                return Err(ForwardError::Truncated {
                    got: reply.body.len(),
                    length,
                });
            }
            reply.body.truncate(length);
        }
    }
    Ok(reply)
}

/// Adds `"action": names[i]` to element i of the initial-state list.
fn name_initial_states(body: &[u8], names: &[String]) -> Result<Vec<u8>, ForwardError> {
    let mut states: serde_json::Value = serde_json::from_slice(body)?;
    let list = states.as_array_mut().ok_or(ForwardError::NotAList)?;
    if list.len() != names.len() {
        return Err(ForwardError::Count {
            got: list.len(),
            model: names.len(),
        });
    }
    for (state, name) in list.iter_mut().zip(names) {
        let fields = state.as_object_mut().ok_or(ForwardError::NotAList)?;
        fields.insert("action".to_string(), name.clone().into());
    }
    Ok(serde_json::to_vec(&states)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_initial_states_are_named_by_who_starts() {
        let model = RlModel::new(crate::Config::default());
        assert_eq!(
            initial_state_names(&model),
            [
                "C1 starts; C2, C3, C4 may join later",
                "C1, C2 start; C3, C4 may join later",
                "C1, C2, C3 start; C4 may join later",
            ]
        );
    }

    #[test]
    fn initial_states_get_their_names_and_keep_their_fields() {
        let body = br#"[{"state":"a","actionIndex":0},{"state":"b","actionIndex":1}]"#;
        let names = ["C1 starts".to_string(), "C1, C2 start".to_string()];
        let named = name_initial_states(body, &names).expect("named");
        let named: serde_json::Value = serde_json::from_slice(&named).expect("JSON");
        assert_eq!(named[0]["action"], "C1 starts");
        assert_eq!(named[1]["action"], "C1, C2 start");
        assert_eq!(named[1]["state"], "b");
        assert_eq!(named[1]["actionIndex"], 1);
        assert!(name_initial_states(b"{}", &names).is_err());
        assert!(name_initial_states(br#"[{"state":"a"}]"#, &names).is_err());
    }

    #[test]
    fn an_answer_is_read_up_to_its_length() {
        let raw =
            b"HTTP/1.0 404 Not Found\r\ncontent-type: text/plain\r\nContent-Length: 2\r\n\r\nnoX";
        let reply = parse_reply(raw).expect("parsed");
        assert_eq!(reply.status, 404);
        assert_eq!(reply.content_type.as_deref(), Some("text/plain"));
        assert_eq!(reply.body, b"no");
        assert!(parse_reply(b"HTTP/1.0 200 OK\r\nContent-Length: 9\r\n\r\nshort").is_err());
        assert!(parse_reply(b"GET / HTTP/1.0\r\n\r\n").is_err());
    }
}
