//! The HTTP/1.1 server behind `rl status --serve`: GET (and HEAD) of a few fixed paths, one
//! request per connection, nothing else.
//!
//! Hand-written over `std::net` rather than a crate: the server only ever answers a handful
//! of read-only paths from an in-memory snapshot, so request parsing is a request line and a
//! header block, and a dependency (with its own threads, TLS and chunked-body code) would
//! weigh on the Pi binary for nothing. Every connection gets a thread, a read and write
//! timeout and a bounded request size; at most [`MAX_CONNECTIONS`] are served at once; bad
//! input gets a 4xx answer and never a panic.

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// The longest request head (request line and headers) read; longer ones get 431.
pub const MAX_REQUEST_BYTES: usize = 8 * 1024;

/// Connections served at once; more are answered 503 and closed.
pub const MAX_CONNECTIONS: usize = 32;

/// How long a client may take to send its request, or to take the answer.
const IO_TIMEOUT: Duration = Duration::from_secs(5);

/// An answer to send.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Response {
    pub status: u16,
    pub content_type: &'static str,
    pub body: Vec<u8>,
    /// Extra header lines, each without its CRLF.
    pub headers: Vec<String>,
}

impl Response {
    pub fn ok(content_type: &'static str, body: impl Into<Vec<u8>>) -> Response {
        Response {
            status: 200,
            content_type,
            body: body.into(),
            headers: Vec::new(),
        }
    }

    /// A plain-text error answer: the status line's reason as the body.
    pub fn error(status: u16) -> Response {
        Response {
            status,
            content_type: "text/plain; charset=utf-8",
            body: format!("{status} {}\n", reason(status)).into_bytes(),
            headers: Vec::new(),
        }
    }
}

/// The reason phrase of the statuses this server sends.
fn reason(status: u16) -> &'static str {
    match status {
        200 => "OK",
        400 => "Bad Request",
        404 => "Not Found",
        405 => "Method Not Allowed",
        408 => "Request Timeout",
        431 => "Request Header Fields Too Large",
        503 => "Service Unavailable",
        _ => "Error",
    }
}

/// A parsed request: what the handler needs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Request {
    /// `GET` or `HEAD` (others never reach the handler).
    pub head_only: bool,
    /// The path, without the query string.
    pub path: String,
}

/// Parses a request head (everything before the blank line). `Err` is the answer to send.
pub fn parse_request(head: &[u8]) -> Result<Request, Response> {
    let text = std::str::from_utf8(head).map_err(|_| Response::error(400))?;
    let request_line = text.split("\r\n").next().unwrap_or_default();
    let mut parts = request_line.split(' ');
    let (Some(method), Some(target), Some(version), None) =
        (parts.next(), parts.next(), parts.next(), parts.next())
    else {
        return Err(Response::error(400));
    };
    if !version.starts_with("HTTP/1.") || !target.starts_with('/') {
        return Err(Response::error(400));
    }
    if method.is_empty() || !method.bytes().all(|b| b.is_ascii_uppercase()) {
        return Err(Response::error(400));
    }
    let head_only = match method {
        "GET" => false,
        "HEAD" => true,
        _ => {
            let mut answer = Response::error(405);
            answer.headers.push("Allow: GET, HEAD".into());
            return Err(answer);
        }
    };
    let path = target.split(['?', '#']).next().unwrap_or("/").to_string();
    Ok(Request { head_only, path })
}

/// The bytes of an answer; a HEAD answer has the headers only.
pub fn encode(response: &Response, head_only: bool) -> Vec<u8> {
    let mut out = format!(
        "HTTP/1.1 {} {}\r\nContent-Type: {}\r\nContent-Length: {}\r\nCache-Control: no-store\r\n\
         X-Content-Type-Options: nosniff\r\nConnection: close\r\n",
        response.status,
        reason(response.status),
        response.content_type,
        response.body.len()
    )
    .into_bytes();
    for header in &response.headers {
        out.extend_from_slice(header.as_bytes());
        out.extend_from_slice(b"\r\n");
    }
    out.extend_from_slice(b"\r\n");
    if !head_only {
        out.extend_from_slice(&response.body);
    }
    out
}

/// Reads a request head: up to the blank line, at most [`MAX_REQUEST_BYTES`]. `Err` is the
/// answer to send (431 too large, 400 closed early, 408 too slow).
fn read_head(stream: &mut TcpStream) -> Result<Vec<u8>, Response> {
    let mut head = Vec::with_capacity(1024);
    let mut chunk = [0u8; 1024];
    loop {
        if let Some(end) = find_blank_line(&head) {
            head.truncate(end);
            return Ok(head);
        }
        if head.len() > MAX_REQUEST_BYTES {
            return Err(Response::error(431));
        }
        match stream.read(&mut chunk) {
            Ok(0) => return Err(Response::error(400)),
            Ok(n) => head.extend_from_slice(&chunk[..n]),
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) =>
            {
                return Err(Response::error(408))
            }
            Err(_) => return Err(Response::error(400)),
        }
    }
}

/// Where the head ends (the index of `\r\n\r\n`), if it has.
fn find_blank_line(bytes: &[u8]) -> Option<usize> {
    bytes.windows(4).position(|w| w == b"\r\n\r\n")
}

/// Serves one connection: one request, one answer.
fn serve_connection(mut stream: TcpStream, handler: &(dyn Fn(&Request) -> Response + Sync)) {
    let _ = stream.set_read_timeout(Some(IO_TIMEOUT));
    let _ = stream.set_write_timeout(Some(IO_TIMEOUT));
    let (answer, head_only) = match read_head(&mut stream).and_then(|h| parse_request(&h)) {
        Ok(request) => (handler(&request), request.head_only),
        Err(answer) => (answer, false),
    };
    let _ = stream.write_all(&encode(&answer, head_only));
    let _ = stream.flush();
    let _ = stream.shutdown(std::net::Shutdown::Write);
    // Let the client read the answer before the close resets what it has not sent yet.
    let mut rest = [0u8; 512];
    let _ = stream.set_read_timeout(Some(Duration::from_millis(200)));
    while matches!(stream.read(&mut rest), Ok(n) if n > 0) {}
}

/// Accepts connections on `listener` until the process ends, each on its own thread.
pub fn serve(
    listener: TcpListener,
    handler: Arc<dyn Fn(&Request) -> Response + Send + Sync>,
) -> std::io::Result<std::thread::JoinHandle<()>> {
    let active = Arc::new(AtomicUsize::new(0));
    std::thread::Builder::new()
        .name("status-http".into())
        .spawn(move || {
            for stream in listener.incoming() {
                let Ok(mut stream) = stream else {
                    // Out of descriptors, say: wait for some to close rather than spin.
                    std::thread::sleep(Duration::from_millis(50));
                    continue;
                };
                if active.fetch_add(1, Ordering::SeqCst) >= MAX_CONNECTIONS {
                    active.fetch_sub(1, Ordering::SeqCst);
                    let _ = stream.set_write_timeout(Some(Duration::from_secs(1)));
                    let _ = stream.write_all(&encode(&Response::error(503), false));
                    continue;
                }
                let handler = Arc::clone(&handler);
                let active_here = Arc::clone(&active);
                let spawned = std::thread::Builder::new()
                    .name("status-conn".into())
                    .spawn(move || {
                        serve_connection(stream, handler.as_ref());
                        active_here.fetch_sub(1, Ordering::SeqCst);
                    });
                if spawned.is_err() {
                    active.fetch_sub(1, Ordering::SeqCst);
                }
            }
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_get_and_head_and_drops_the_query() {
        let get = parse_request(b"GET /metrics?x=1 HTTP/1.1\r\nHost: a").unwrap();
        assert_eq!(
            get,
            Request {
                head_only: false,
                path: "/metrics".into()
            }
        );
        assert!(parse_request(b"HEAD / HTTP/1.0").unwrap().head_only);
    }

    #[test]
    fn refuses_what_it_does_not_serve() {
        let status = |head: &[u8]| parse_request(head).unwrap_err().status;
        assert_eq!(status(b"POST / HTTP/1.1"), 405);
        assert_eq!(status(b"DELETE /x HTTP/1.1"), 405);
        assert_eq!(status(b"garbage"), 400);
        assert_eq!(status(b"GET / HTTP/1.1 extra"), 400);
        assert_eq!(status(b"GET / SPDY/3"), 400);
        assert_eq!(status(b"GET http://x/ HTTP/1.1"), 400);
        assert_eq!(status(b"get / HTTP/1.1"), 400);
        assert_eq!(status(b"\xff\xfe / HTTP/1.1"), 400);
        assert_eq!(status(b""), 400);
    }

    #[test]
    fn encodes_head_without_body() {
        let answer = Response::ok("text/plain", "hi");
        let full = String::from_utf8(encode(&answer, false)).unwrap();
        assert!(full.starts_with("HTTP/1.1 200 OK\r\n"), "{full}");
        assert!(full.contains("Content-Length: 2\r\n"), "{full}");
        assert!(full.ends_with("\r\n\r\nhi"), "{full}");
        let head = String::from_utf8(encode(&answer, true)).unwrap();
        assert!(head.ends_with("\r\n\r\n"), "{head}");
    }
}
