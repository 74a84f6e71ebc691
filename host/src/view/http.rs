//! HTTP/1.1 as the view speaks it, on one connection, with a bound on everything a client could
//! hold: the request head must arrive whole within [`HEAD_TIME`], in at most [`MAX_HEAD`] bytes
//! and [`MAX_HEADERS`] headers; a body has a length given up front, a cap set by the caller, and
//! [`BODY_TIME`] to arrive; every answer has [`WRITE_TIME`] to leave; and the connection closes
//! after one answer, so no client keeps one idle. The head is parsed by `httparse` (hyper's
//! parser). A chunked body is refused: the page and every HTTP client send a length.

use std::io::{ErrorKind, Read, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};

use super::api::ApiError;

/// The longest request head: a browser's is under 2 KiB.
pub const MAX_HEAD: usize = 16 << 10;
/// The most header lines a request may have: a browser sends about 15.
pub const MAX_HEADERS: usize = 32;
/// How long the whole request head may take to arrive, from the connection's start.
pub const HEAD_TIME: Duration = Duration::from_secs(5);
/// How long a body may take to arrive, whatever its length (4 MiB takes milliseconds locally).
pub const BODY_TIME: Duration = Duration::from_secs(10);
/// How long an answer may take to leave (a client that does not read is dropped).
pub const WRITE_TIME: Duration = Duration::from_secs(5);

/// Headers whose every copy matters: a request with two of one is refused, since two parsers may
/// pick different ones.
const SINGLE: [&str; 7] =
    ["host", "origin", "authorization", "content-length", "content-type", "transfer-encoding", "sec-websocket-key"];

/// A request's head.
#[derive(Debug, Clone)]
pub struct Head {
    /// `GET`, `POST`, ...
    pub method: String,
    /// The path, without the query.
    pub path: String,
    /// What follows `?`, if anything.
    pub query: Option<String>,
    /// Name (lower case) and value of each header.
    headers: Vec<(String, String)>,
}

impl Head {
    /// The value of header `name` (lower case).
    pub fn header(&self, name: &str) -> Option<&str> {
        self.headers.iter().find(|(n, _)| n == name).map(|(_, v)| v.as_str())
    }
}

/// Why a connection ends without an answer worth sending: the client closed it, or nothing
/// arrived at all before the deadline.
pub const SILENT: u16 = 0;

fn timed_out(e: &std::io::Error) -> bool {
    matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut)
}

/// Reads a request head, within the limits above. Returns the head and the bytes of the body
/// that came with it. An error with status [`SILENT`] means: close without answering.
pub fn read_head(stream: &mut TcpStream) -> Result<(Head, Vec<u8>), ApiError> {
    let deadline = Instant::now() + HEAD_TIME;
    let mut buf = Vec::with_capacity(1024);
    let mut chunk = [0u8; 2048];
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Err(ApiError::new(
                408,
                format!("the request head did not arrive within {} s", HEAD_TIME.as_secs()),
            ));
        }
        stream.set_read_timeout(Some(left)).map_err(|_| ApiError::new(SILENT, ""))?;
        let want = chunk.len().min(MAX_HEAD + 1 - buf.len());
        let n = match stream.read(&mut chunk[..want]) {
            Ok(0) => return Err(ApiError::new(SILENT, "")),
            Ok(n) => n,
            Err(e) if e.kind() == ErrorKind::Interrupted => continue,
            Err(e) if timed_out(&e) => continue,
            Err(_) => return Err(ApiError::new(SILENT, "")),
        };
        // Only parse once the blank line that ends the head is in (a byte at a time is cheap).
        let from = buf.len().saturating_sub(3);
        buf.extend_from_slice(&chunk[..n]);
        if !buf[from..].windows(4).any(|w| w == b"\r\n\r\n") {
            if buf.len() > MAX_HEAD {
                return Err(ApiError::new(431, format!("the request head is longer than {MAX_HEAD} bytes")));
            }
            continue;
        }
        return parse_head(&buf);
    }
}

/// Parses a complete head (ending in a blank line).
fn parse_head(buf: &[u8]) -> Result<(Head, Vec<u8>), ApiError> {
    let mut headers = [httparse::EMPTY_HEADER; MAX_HEADERS];
    let mut request = httparse::Request::new(&mut headers);
    let end = match request.parse(buf) {
        Ok(httparse::Status::Complete(end)) => end,
        Ok(httparse::Status::Partial) => return Err(ApiError::bad("the request head is incomplete")),
        Err(httparse::Error::TooManyHeaders) => {
            return Err(ApiError::new(431, format!("more than {MAX_HEADERS} header lines")))
        }
        Err(e) => return Err(ApiError::bad(format!("not an HTTP request: {e}"))),
    };
    if end > MAX_HEAD {
        return Err(ApiError::new(431, format!("the request head is longer than {MAX_HEAD} bytes")));
    }
    let (Some(method), Some(target)) = (request.method, request.path) else {
        return Err(ApiError::bad("not an HTTP request"));
    };
    let mut list = Vec::with_capacity(request.headers.len());
    for h in request.headers.iter() {
        let name = h.name.to_ascii_lowercase();
        let Ok(value) = std::str::from_utf8(h.value) else {
            return Err(ApiError::bad(format!("header {name}: not text")));
        };
        if SINGLE.contains(&name.as_str()) && list.iter().any(|(n, _)| *n == name) {
            return Err(ApiError::bad(format!("header {name} given twice")));
        }
        list.push((name, value.trim().to_string()));
    }
    let (path, query) = match target.split_once('?') {
        Some((path, query)) => (path.to_string(), Some(query.to_string())),
        None => (target.to_string(), None),
    };
    Ok((Head { method: method.to_string(), path, query, headers: list }, buf[end..].to_vec()))
}

/// The body's length as the head gives it, refused beyond `cap` before any of it is read.
pub fn body_length(head: &Head, cap: usize) -> Result<usize, ApiError> {
    if head.header("transfer-encoding").is_some() {
        return Err(ApiError::new(411, "a body sent in chunks is not taken: send Content-Length"));
    }
    let Some(value) = head.header("content-length") else {
        return Err(ApiError::new(411, "a POST needs Content-Length"));
    };
    let len: usize = value.parse().map_err(|_| ApiError::bad(format!("Content-Length {value:?} is not a length")))?;
    if len > cap {
        return Err(ApiError::new(413, format!("the body is {len} bytes; this endpoint takes at most {cap}")));
    }
    Ok(len)
}

/// Reads the rest of a body of `len` bytes, of which `early` came with the head, within
/// [`BODY_TIME`].
pub fn read_body(stream: &mut TcpStream, mut early: Vec<u8>, len: usize) -> Result<Vec<u8>, ApiError> {
    if early.len() > len {
        return Err(ApiError::bad("more bytes than Content-Length (one request per connection)"));
    }
    let deadline = Instant::now() + BODY_TIME;
    early.reserve_exact(len - early.len());
    let mut chunk = vec![0u8; (len - early.len()).min(64 << 10)];
    while early.len() < len {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Err(ApiError::new(
                408,
                format!("the body did not arrive within {} s ({} of {len} bytes)", BODY_TIME.as_secs(), early.len()),
            ));
        }
        stream.set_read_timeout(Some(left)).map_err(|_| ApiError::new(SILENT, ""))?;
        let want = chunk.len().min(len - early.len());
        match stream.read(&mut chunk[..want]) {
            Ok(0) => return Err(ApiError::new(SILENT, "")),
            Ok(n) => early.extend_from_slice(&chunk[..n]),
            Err(e) if e.kind() == ErrorKind::Interrupted || timed_out(&e) => {}
            Err(_) => return Err(ApiError::new(SILENT, "")),
        }
    }
    Ok(early)
}

/// An answer.
pub struct Answer {
    /// The status code.
    pub status: u16,
    /// Its content type.
    pub content_type: &'static str,
    /// The body.
    pub body: Vec<u8>,
}

impl Answer {
    /// A JSON answer.
    pub fn json(status: u16, body: &serde_json::Value) -> Self {
        Self { status, content_type: "application/json", body: body.to_string().into_bytes() }
    }

    /// An error's answer: `{"error": "..."}`.
    pub fn error(e: &ApiError) -> Self {
        Self::json(e.status, &e.body())
    }
}

/// The reason phrase of a status code.
fn reason(status: u16) -> &'static str {
    match status {
        100 => "Continue",
        101 => "Switching Protocols",
        200 => "OK",
        400 => "Bad Request",
        403 => "Forbidden",
        404 => "Not Found",
        405 => "Method Not Allowed",
        408 => "Request Timeout",
        409 => "Conflict",
        411 => "Length Required",
        413 => "Content Too Large",
        415 => "Unsupported Media Type",
        422 => "Unprocessable Content",
        426 => "Upgrade Required",
        431 => "Request Header Fields Too Large",
        503 => "Service Unavailable",
        _ => "Status",
    }
}

/// Headers on every answer: nothing cached, nothing sniffed, never framed by another page, no
/// referrer (the page's address carries the token), and no CORS header ever.
const COMMON: &str = "Cache-Control: no-store\r\nX-Content-Type-Options: nosniff\r\n\
    Content-Security-Policy: frame-ancestors 'none'\r\nX-Frame-Options: DENY\r\nReferrer-Policy: no-referrer\r\n";

/// Writes `answer` and closes the sending side, within [`WRITE_TIME`]. A failure means the client
/// went away or does not read; there is no one to tell.
pub fn respond(stream: &mut TcpStream, answer: &Answer) {
    respond_within(stream, answer, WRITE_TIME);
}

/// [`respond`] within `limit`.
pub fn respond_within(stream: &mut TcpStream, answer: &Answer, limit: Duration) {
    let head = format!(
        "HTTP/1.1 {} {}\r\nContent-Type: {}\r\nContent-Length: {}\r\n{COMMON}Connection: close\r\n\r\n",
        answer.status,
        reason(answer.status),
        answer.content_type,
        answer.body.len()
    );
    let _ = stream.set_write_timeout(Some(limit));
    let _ = stream.write_all(head.as_bytes()).and_then(|_| stream.write_all(&answer.body)).and_then(|_| stream.flush());
    let _ = stream.shutdown(std::net::Shutdown::Write);
}

/// `100 Continue`, for a client that waits for it before sending its body (curl does, past 1 KiB).
pub fn send_continue(stream: &mut TcpStream) {
    let _ = stream.set_write_timeout(Some(WRITE_TIME));
    let _ = stream.write_all(b"HTTP/1.1 100 Continue\r\n\r\n");
}

/// The websocket handshake's answer (RFC 6455), written within [`WRITE_TIME`].
pub fn switch_to_websocket(stream: &mut TcpStream, key: &str) -> std::io::Result<()> {
    let accept = tungstenite::handshake::derive_accept_key(key.as_bytes());
    stream.set_write_timeout(Some(WRITE_TIME))?;
    write!(
        stream,
        "HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Accept: {accept}\r\n\r\n"
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_a_head_and_keeps_the_early_body() {
        let (head, rest) = parse_head(
            b"POST /api/stop?x=1 HTTP/1.1\r\nHost: 127.0.0.1:8765\r\nContent-Type: application/json\r\nContent-Length: 2\r\n\r\n{}",
        )
        .unwrap();
        assert_eq!(
            (head.method.as_str(), head.path.as_str(), head.query.as_deref()),
            ("POST", "/api/stop", Some("x=1"))
        );
        assert_eq!(head.header("host"), Some("127.0.0.1:8765"));
        assert_eq!(head.header("content-type"), Some("application/json"));
        assert_eq!(rest, b"{}");
        assert_eq!(body_length(&head, 10), Ok(2));
        assert_eq!(body_length(&head, 1).unwrap_err().status, 413);
    }

    #[test]
    fn refuses_what_could_confuse_or_hold_it() {
        let twice = parse_head(b"GET / HTTP/1.1\r\nHost: a:1\r\nHost: b:2\r\n\r\n").unwrap_err();
        assert_eq!((twice.status, twice.message.as_str()), (400, "header host given twice"));
        let many: String = (0..=MAX_HEADERS).map(|i| format!("X-{i}: 1\r\n")).collect::<String>() + "\r\n";
        let err = parse_head(format!("GET / HTTP/1.1\r\n{many}").as_bytes()).unwrap_err();
        assert_eq!(err.status, 431);
        assert_eq!(parse_head(b"\x16\x03\x01garbage\r\n\r\n").unwrap_err().status, 400);
        let (chunked, _) = parse_head(b"POST /api/play HTTP/1.1\r\nTransfer-Encoding: chunked\r\n\r\n").unwrap();
        assert_eq!(body_length(&chunked, 10).unwrap_err().status, 411);
        let (none, _) = parse_head(b"POST /api/play HTTP/1.1\r\n\r\n").unwrap();
        assert_eq!(body_length(&none, 10).unwrap_err().status, 411);
        let (bad, _) = parse_head(b"POST /api/play HTTP/1.1\r\nContent-Length: -1\r\n\r\n").unwrap();
        assert_eq!(body_length(&bad, 10).unwrap_err().status, 400);
    }

    mod random {
        use super::*;
        use proptest::prelude::*;

        proptest! {
            /// Any bytes: an error or a head within the limits, never a panic.
            #[test]
            fn any_bytes_are_a_head_within_the_limits_or_refused(bytes in proptest::collection::vec(any::<u8>(), 0..600)) {
                let mut input = bytes;
                input.extend_from_slice(b"\r\n\r\n");
                if let Ok((head, _)) = parse_head(&input) {
                    prop_assert!(head.headers.len() <= MAX_HEADERS);
                    for name in SINGLE {
                        prop_assert!(head.headers.iter().filter(|(n, _)| n == name).count() <= 1);
                    }
                    let _ = body_length(&head, 4096);
                }
            }

            /// A head as a client writes it reads back as written, the body's first bytes kept.
            #[test]
            fn a_written_head_reads_back(
                method in prop::sample::select(vec!["GET", "POST", "OPTIONS", "PUT"]),
                path in "/[a-z/]{0,20}",
                query in proptest::option::of("[a-z0-9=&]{1,20}"),
                headers in proptest::collection::vec(("X-[A-Za-z]{1,8}", "[ -~&&[^ ]]{0,30}"), 0..MAX_HEADERS),
                body in "[a-z]{0,10}",
            ) {
                let target = match &query { Some(q) => format!("{path}?{q}"), None => path.clone() };
                let lines: String = headers.iter().map(|(n, v)| format!("{n}: {v}\r\n")).collect();
                let text = format!("{method} {target} HTTP/1.1\r\n{lines}\r\n{body}");
                let (head, rest) = parse_head(text.as_bytes()).unwrap();
                prop_assert_eq!(&head.method, method);
                prop_assert_eq!(&head.path, &path);
                prop_assert_eq!(&head.query, &query);
                let expected: Vec<(String, String)> =
                    headers.iter().map(|(n, v)| (n.to_ascii_lowercase(), v.trim().to_string())).collect();
                prop_assert_eq!(&head.headers, &expected);
                prop_assert_eq!(rest, body.as_bytes());
            }
        }
    }
}
