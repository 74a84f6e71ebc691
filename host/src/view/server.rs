//! The HTTP side: the page's files, the JSON API and the telemetry websocket.
//!
//! One thread accepts; each connection gets a thread of its own ([`super::workers`]), bounded in number
//! ([`MAX_CONNECTIONS`], and [`MAX_WEBSOCKETS`] once upgraded) and in time ([`super::http`]'s
//! limits), so no client, slow or many, holds the others: a stop is read and queued on its own
//! thread whatever else is connected, and goes ahead of every queued job ([`super::jobs`]).
//! Every request is checked ([`super::access`]) before its body is read. Reading the status or
//! drawing data never waits on the link.
//!
//! [`ViewServer::shutdown`] closes the listener and every open connection at once, so closing
//! never waits on a client.
//!
//! A rig's view (`armctl view --rig`) serves every arm of the rig the same way, each request naming
//! its arm by path: `/api/arm/NAME/status`, `POST /api/arm/NAME/joints`, ... (see [`rig_route`]);
//! `POST /api/stop` stops every arm, `GET /api/rig` says what the rig is, and the websocket carries
//! every arm's telemetry, each message naming its arm.

use std::collections::HashMap;
use std::net::{IpAddr, Ipv4Addr, Ipv6Addr, SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use anyhow::{anyhow, Result};
use serde_json::Value;
use tungstenite::protocol::Role;
use tungstenite::{Message, WebSocket};

use super::access::{self, Access, Token};
use super::api::{self, ApiError, Request, MAX_BODY};
use super::assets;
use super::http::{self, Answer, Head, SILENT};
use super::jobs::JobQueue;
use super::telemetry::Latest;
use super::workers::Workers;

/// Connections being read or answered at once; one more is answered 503 and closed. Each holds
/// a thread for at most the head and body times of [`super::http`].
pub const MAX_CONNECTIONS: usize = 128;
/// Websockets open at once (a person has a tab or two; each gets every status).
pub const MAX_WEBSOCKETS: usize = 16;
/// The largest body of every endpoint but `play`'s: a joint move of many joints is under 1 KiB.
pub const SMALL_BODY: usize = 4 << 10;
/// How long one websocket message may take to leave before the client is dropped.
const WS_WRITE_TIME: Duration = Duration::from_secs(2);
/// Stack of a connection's thread: a request is parsed there (serde_json's depth is bounded).
const CONNECTION_STACK: usize = 256 << 10;

/// What the server serves besides the page.
pub struct Served {
    /// The arms, in the rig's order: one in the one-arm view.
    pub arms: Vec<ServedArm>,
    /// `GET /api/rig`: the rig's name and its arms with their bases; `None` in the one-arm view,
    /// whose API has no arm names.
    pub rig: Option<Rig>,
    /// `GET /api/mesh/K`: the files of the meshes.
    pub meshes: Vec<std::path::PathBuf>,
    /// The newest telemetry, one slot per arm.
    pub latest: Arc<Latest>,
}

/// One arm of the view.
pub struct ServedArm {
    /// Its name in the rig (the one-arm view's is not used).
    pub name: String,
    /// `GET /api/arm` (`/api/arm/NAME` in a rig's view).
    pub arm: Value,
    /// Its arm loop's queue.
    pub jobs: Arc<JobQueue>,
}

/// The rig of a rig's view.
pub struct Rig {
    /// Its name.
    pub name: String,
    /// `GET /api/rig`.
    pub json: Value,
}

/// What every connection's thread shares.
struct Shared {
    served: Served,
    token: Token,
    access: Access,
    /// Open connections (websockets included), to close them all at shutdown.
    open: Mutex<HashMap<u64, TcpStream>>,
    connections: AtomicUsize,
    websockets: AtomicUsize,
    closing: AtomicBool,
}

/// A running server.
pub struct ViewServer {
    shared: Arc<Shared>,
    bound: SocketAddr,
    url: String,
    acceptor: Option<JoinHandle<()>>,
}

impl ViewServer {
    /// Listens on `addr` (port 0 for a free one); answers nothing until [`Self::start`].
    pub fn bind(addr: SocketAddr) -> Result<TcpListener> {
        TcpListener::bind(addr).map_err(|e| anyhow!("--listen {addr}: cannot listen there: {e}"))
    }

    /// Starts answering on `listener`; requests to the API must carry `token`.
    pub fn start(listener: TcpListener, served: Served, token: Token) -> Result<Self> {
        if served.arms.is_empty() || (served.rig.is_none() && served.arms.len() > 1) {
            return Err(anyhow!("a view serves one arm, or a rig's arms"));
        }
        let bound = listener.local_addr()?;
        // The address a person types: the loopback one for a server on every address.
        let shown = match bound.ip() {
            IpAddr::V4(ip) if ip.is_unspecified() => SocketAddr::new(Ipv4Addr::LOCALHOST.into(), bound.port()),
            IpAddr::V6(ip) if ip.is_unspecified() => SocketAddr::new(Ipv6Addr::LOCALHOST.into(), bound.port()),
            _ => bound,
        };
        let url = format!("http://{shown}/?token={}", token.as_str());
        let shared = Arc::new(Shared {
            served,
            token,
            access: Access::new(bound),
            open: Mutex::new(HashMap::new()),
            connections: AtomicUsize::new(0),
            websockets: AtomicUsize::new(0),
            closing: AtomicBool::new(false),
        });
        let acceptor = {
            let shared = shared.clone();
            std::thread::Builder::new().name("view-accept".into()).spawn(move || accept(&listener, &shared))?
        };
        Ok(Self { shared, bound: shown, url, acceptor: Some(acceptor) })
    }

    /// The page's address, with the token.
    pub fn url(&self) -> &str {
        &self.url
    }

    /// Stops accepting and closes every open connection (websockets too) now; the threads of the
    /// connections end as their sockets do. Bounded: it waits on no client.
    pub fn shutdown(&mut self) {
        self.shared.closing.store(true, Ordering::SeqCst);
        // Wake the acceptor with a connection of our own; it sees `closing` and ends.
        let _ = TcpStream::connect_timeout(&self.bound, Duration::from_millis(200));
        if let Some(acceptor) = self.acceptor.take() {
            let _ = acceptor.join();
        }
        let open = std::mem::take(&mut *self.shared.open.lock().unwrap_or_else(|e| e.into_inner()));
        for stream in open.values() {
            let _ = stream.shutdown(std::net::Shutdown::Both);
        }
    }
}

impl Drop for ViewServer {
    fn drop(&mut self) {
        self.shutdown();
    }
}

/// Takes connections until shutdown; each gets its thread, or a 503 past [`MAX_CONNECTIONS`].
fn accept(listener: &TcpListener, shared: &Arc<Shared>) {
    let ids = AtomicU64::new(0);
    // Every connection counted, and every websocket, holds a worker.
    let workers = Workers::new(MAX_CONNECTIONS + MAX_WEBSOCKETS, CONNECTION_STACK);
    for stream in listener.incoming() {
        if shared.closing.load(Ordering::SeqCst) {
            return;
        }
        let Ok(mut stream) = stream else {
            // Out of descriptors, or a connection reset before it was taken: go on.
            std::thread::sleep(Duration::from_millis(5));
            continue;
        };
        if shared.connections.load(Ordering::SeqCst) >= MAX_CONNECTIONS {
            let busy = ApiError::new(503, format!("{MAX_CONNECTIONS} connections are open already: try again"));
            // On the acceptor's own thread: briefly, whatever the client does.
            http::respond_within(&mut stream, &Answer::error(&busy), Duration::from_millis(100));
            continue;
        }
        let id = ids.fetch_add(1, Ordering::SeqCst);
        let Ok(clone) = stream.try_clone() else { continue };
        shared.open.lock().unwrap_or_else(|e| e.into_inner()).insert(id, clone);
        shared.connections.fetch_add(1, Ordering::SeqCst);
        let guard = Counted { shared: shared.clone(), id, counted: true };
        // Within the caps a worker is always free; a thread that cannot be had drops the
        // connection (and the guard lets go of it).
        drop(workers.run(Box::new(move || connection(stream, guard))));
    }
}

/// A connection listed open (for shutdown) and counted against [`MAX_CONNECTIONS`]; dropping it
/// lets go of both.
struct Counted {
    shared: Arc<Shared>,
    id: u64,
    counted: bool,
}

impl Counted {
    /// No longer counted against [`MAX_CONNECTIONS`] (a websocket has its own cap), still listed.
    fn uncount(&mut self) {
        if std::mem::take(&mut self.counted) {
            self.shared.connections.fetch_sub(1, Ordering::SeqCst);
        }
    }
}

impl Drop for Counted {
    fn drop(&mut self) {
        self.uncount();
        self.shared.open.lock().unwrap_or_else(|e| e.into_inner()).remove(&self.id);
    }
}

/// One connection: one request, one answer (or a websocket).
fn connection(mut stream: TcpStream, guard: Counted) {
    let shared = guard.shared.clone();
    let _ = stream.set_nodelay(true);
    let local = stream.local_addr().map_or(IpAddr::V4(Ipv4Addr::LOCALHOST), |a| a.ip());
    let (head, early) = match http::read_head(&mut stream) {
        Ok(read) => read,
        Err(e) if e.status == SILENT => return,
        Err(e) => return http::respond(&mut stream, &Answer::error(&e)),
    };
    match route(&shared, &head, local) {
        Route::Answer(answer) => http::respond(&mut stream, &answer),
        Route::Post(arm, endpoint) => {
            let answer = post(&shared, &mut stream, &head, early, arm, &endpoint).unwrap_or_else(|e| Answer::error(&e));
            http::respond(&mut stream, &answer);
        }
        Route::Job(arm, request) => {
            let answer = shared.served.arms[arm].jobs.submit(request);
            http::respond(
                &mut stream,
                &answer.map(|body| Answer::json(200, &body)).unwrap_or_else(|e| Answer::error(&e)),
            );
        }
        Route::Websocket(key) => websocket(stream, &shared, &key, guard),
    }
}

/// What to do with a request whose head is in.
enum Route {
    Answer(Answer),
    /// A POST to one arm (its index), or to every arm (`None`: a rig's stop).
    Post(Option<usize>, String),
    /// A GET the arm loop answers (what only it knows: the collision geometry now).
    Job(usize, Request),
    Websocket(String),
}

fn refused(status: u16, message: impl Into<String>) -> Route {
    Route::Answer(Answer::error(&ApiError::new(status, message)))
}

/// Checks the head (see [`super::access`]) and picks what answers it.
fn route(shared: &Shared, head: &Head, local: IpAddr) -> Route {
    let access = &shared.access;
    match head.header("host") {
        Some(host) if access.host_ok(host, local) => {}
        host => {
            return refused(
                403,
                format!(
                    "Host {:?} does not name this server: open it by its address (the URL armctl printed)",
                    host.unwrap_or("")
                ),
            )
        }
    }
    let (method, path) = (head.method.as_str(), head.path.as_str());
    let Some(endpoint) = path.strip_prefix("/api/") else {
        // The page's files: no secret in them, so no token (the page brings it to the API).
        return match (method, path) {
            ("GET", "/") => static_file("index.html"),
            ("GET", p) if p.starts_with("/assets/") => static_file(&p["/assets/".len()..]),
            _ => refused(404, format!("{method} {path}: not found")),
        };
    };
    if let Some(origin) = head.header("origin").filter(|o| !access.origin_ok(o, local)) {
        return refused(403, format!("Origin {origin:?} is not this server: another site's page cannot drive the arm"));
    }
    let offered = access::offered_token(head.header("authorization"), head.query.as_deref());
    if !offered.is_some_and(|t| shared.token.matches(t)) {
        return refused(
            403,
            format!(
                "{} token: the API needs the one in the URL armctl printed (Authorization: Bearer TOKEN)",
                if offered.is_some() { "wrong" } else { "no" }
            ),
        );
    }
    let served = &shared.served;
    if let ("GET", "ws") = (method, endpoint) {
        return match head.header("sec-websocket-key") {
            Some(key) if head.header("upgrade").is_some_and(|u| u.eq_ignore_ascii_case("websocket")) => {
                Route::Websocket(key.to_string())
            }
            _ => refused(426, "/api/ws is a websocket: connect with one"),
        };
    }
    if let Some(rig) = &served.rig {
        return rig_route(served, rig, method, endpoint);
    }
    match (method, endpoint) {
        ("GET", "arm") => Route::Answer(Answer::json(200, &served.arms[0].arm)),
        // The page asks first: `null` says one arm, and the API names none.
        ("GET", "rig") => Route::Answer(Answer::json(200, &Value::Null)),
        ("GET", "status") => status(served, 0),
        ("GET", "collision") => Route::Job(0, Request::Collision),
        ("GET", p) if p.starts_with("mesh/") => Route::Answer(mesh(&p["mesh/".len()..], served)),
        ("POST", endpoint) => Route::Post(Some(0), endpoint.to_string()),
        _ => refused(405, format!("{method} {path}: not an endpoint (see docs/view.md, the API)")),
    }
}

/// The newest telemetry of arm `arm`, as it was published.
fn status(served: &Served, arm: usize) -> Route {
    let (seq, text) = served.latest.get_arm(arm);
    match seq {
        0 => refused(503, "no status from the firmware yet"),
        _ => Route::Answer(Answer { status: 200, content_type: "application/json", body: text.as_bytes().to_vec() }),
    }
}

/// A rig's routes (after the checks of [`route`]): each arm's API under `/api/arm/NAME/`, as the
/// one-arm view's is under `/api/`; `GET /api/rig`; `GET /api/status`, every arm's telemetry by
/// name; `POST /api/stop`, every arm stopped. A request the one-arm view takes without a name is
/// refused with the names to use.
fn rig_route(served: &Served, rig: &Rig, method: &str, endpoint: &str) -> Route {
    let names = || served.arms.iter().map(|a| a.name.as_str()).collect::<Vec<_>>().join(", ");
    if let Some(rest) = endpoint.strip_prefix("arm/") {
        let (name, what) = rest.split_once('/').unwrap_or((rest, ""));
        let Some(index) = served.arms.iter().position(|a| a.name == name) else {
            // The name as given, within bounds: it is echoed on one line.
            let shown: String = name.chars().take(64).collect();
            return refused(400, format!("no arm {shown:?} in the rig {} (its arms: {})", rig.name, names()));
        };
        return match (method, what) {
            ("GET", "") => Route::Answer(Answer::json(200, &served.arms[index].arm)),
            ("GET", "status") => status(served, index),
            ("GET", "collision") => Route::Job(index, Request::Collision),
            ("POST", what) if !what.is_empty() => Route::Post(Some(index), what.to_string()),
            _ => refused(405, format!("{method} /api/arm/{name}/{what}: not an endpoint (see docs/view.md, the API)")),
        };
    }
    match (method, endpoint) {
        ("GET", "rig") => Route::Answer(Answer::json(200, &rig.json)),
        ("GET", "status") => {
            let mut body = format!("{{\"rig\":{},\"arms\":{{", Value::from(rig.name.as_str()));
            for (i, arm) in served.arms.iter().enumerate() {
                let (seq, text) = served.latest.get_arm(i);
                if seq == 0 {
                    return refused(503, format!("no status from the firmware of arm {} yet", arm.name));
                }
                let comma = if i > 0 { "," } else { "" };
                body += &format!("{comma}{}:{text}", Value::from(arm.name.as_str()));
            }
            body += "}}";
            Route::Answer(Answer { status: 200, content_type: "application/json", body: body.into_bytes() })
        }
        ("POST", "stop") => Route::Post(None, "stop".to_string()),
        ("GET", "arm") => refused(
            400,
            format!(
                "this view drives the rig {}: GET /api/rig for every arm, or /api/arm/NAME (its arms: {})",
                rig.name,
                names()
            ),
        ),
        ("POST", endpoint) if api::ENDPOINTS.contains(&endpoint) => refused(
            400,
            format!(
                "this view drives the rig {}: name the arm, POST /api/arm/NAME/{endpoint} (its arms: {})",
                rig.name,
                names()
            ),
        ),
        ("GET", p) if p.starts_with("mesh/") => Route::Answer(mesh(&p["mesh/".len()..], served)),
        ("POST", other) => refused(404, format!("no endpoint POST /api/{other}")),
        _ => refused(405, format!("{method} /api/{endpoint}: not an endpoint (see docs/view.md, the API)")),
    }
}

/// A POST: its type and length are checked before the body is read; then it is parsed and
/// queued for the arm loop.
fn post(
    shared: &Shared,
    stream: &mut TcpStream,
    head: &Head,
    early: Vec<u8>,
    arm: Option<usize>,
    endpoint: &str,
) -> Result<Answer, ApiError> {
    if !access::json_content_type(head.header("content-type")) {
        return Err(ApiError::new(
            415,
            format!("the body must be application/json, not {:?}", head.header("content-type").unwrap_or("nothing")),
        ));
    }
    let cap = if endpoint == "play" { MAX_BODY } else { SMALL_BODY };
    let len = http::body_length(head, cap)?;
    if head.header("expect").is_some_and(|e| e.eq_ignore_ascii_case("100-continue")) && early.len() < len {
        http::send_continue(stream);
    }
    let body = http::read_body(stream, early, len)?;
    let request = api::parse(endpoint, &body)?;
    let arms = &shared.served.arms;
    match arm {
        Some(arm) => arms[arm].jobs.submit(request).map(|body| Answer::json(200, &body)),
        None => stop_every_arm(arms, request),
    }
}

/// A rig's stop: queued on every arm first (ahead of each arm's other jobs), then each answer
/// awaited, so no arm's stop waits on another's. 200 when every arm took it; else the first
/// refusal's status, naming the arm, with every arm's answer.
fn stop_every_arm(arms: &[ServedArm], request: Request) -> Result<Answer, ApiError> {
    let pending: Vec<_> = arms.iter().map(|arm| arm.jobs.enqueue(request.clone())).collect();
    let mut each = serde_json::Map::new();
    let mut first: Option<ApiError> = None;
    for (arm, pending) in arms.iter().zip(pending) {
        let answer = pending.and_then(|p| p.wait());
        let body = match answer {
            Ok(body) => body,
            Err(e) => {
                let body = e.body();
                first.get_or_insert(ApiError::new(e.status, format!("arm {}: {}", arm.name, e.message)));
                body
            }
        };
        each.insert(arm.name.clone(), body);
    }
    match first {
        None => Ok(Answer::json(200, &serde_json::json!({"ok": true, "arms": each}))),
        Some(e) => Err(ApiError { detail: Some(serde_json::json!({"arms": each})), ..e }),
    }
}

fn static_file(path: &str) -> Route {
    match assets::get(path) {
        Some((bytes, kind)) => Route::Answer(Answer { status: 200, content_type: kind, body: bytes.to_vec() }),
        None => refused(404, format!("/assets/{path}: not found")),
    }
}

fn mesh(index: &str, served: &Served) -> Answer {
    let Some(file) = index.parse::<usize>().ok().and_then(|i| served.meshes.get(i)) else {
        return Answer::error(&ApiError::new(404, format!("no mesh {index}")));
    };
    match std::fs::read(file) {
        Ok(bytes) => Answer { status: 200, content_type: "model/stl", body: bytes },
        Err(e) => Answer::error(&ApiError::new(404, format!("mesh {}: {e}", file.display()))),
    }
}

/// A websocket counted open.
struct WebsocketSlot<'a>(&'a Shared);

impl Drop for WebsocketSlot<'_> {
    fn drop(&mut self) {
        self.0.websockets.fetch_sub(1, Ordering::SeqCst);
    }
}

/// Upgrades to a websocket (within [`MAX_WEBSOCKETS`]) and sends the newest telemetry as it
/// comes, skipping what a slow client could not take, until the client goes away, stops reading
/// for [`WS_WRITE_TIME`], or the server shuts down.
fn websocket(mut stream: TcpStream, shared: &Shared, key: &str, mut guard: Counted) {
    if shared.websockets.fetch_add(1, Ordering::SeqCst) >= MAX_WEBSOCKETS {
        shared.websockets.fetch_sub(1, Ordering::SeqCst);
        let full = ApiError::new(503, format!("{MAX_WEBSOCKETS} websockets are open already: close a page"));
        return http::respond(&mut stream, &Answer::error(&full));
    }
    let _slot = WebsocketSlot(shared);
    guard.uncount();
    if http::switch_to_websocket(&mut stream, key).is_err() || stream.set_write_timeout(Some(WS_WRITE_TIME)).is_err() {
        return;
    }
    let mut socket = WebSocket::from_raw_socket(stream, Role::Server, None);
    // One number per arm: each arm's newest telemetry goes out as it comes.
    let mut seen = vec![0; shared.served.arms.len()];
    while !shared.closing.load(Ordering::SeqCst) {
        let newer = shared.served.latest.wait_any_newer(&mut seen, Duration::from_secs(1));
        let messages: Vec<Message> = match newer.is_empty() {
            false => newer.iter().map(|text| Message::text(text.as_str())).collect(),
            // No telemetry (the firmware is silent): a ping finds out whether the client is
            // still there.
            true => vec![Message::Ping(Vec::new().into())],
        };
        for message in messages {
            if socket.send(message).is_err() {
                return;
            }
        }
    }
}
