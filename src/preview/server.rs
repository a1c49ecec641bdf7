//! The web viewer's server: hyper on a single-threaded tokio runtime of its own thread,
//! serving the page and its assets (compiled in), the status, the current frame and an event
//! stream of statuses, and nothing else, each under a path of a key of its own. Everything
//! a client sends is hostile input: the limits below bound what any client can make it hold
//! or do, and no client can reach the render, which only ever replaces the hub's snapshot.

use super::{Hub, Snapshot};
use bytes::Bytes;
use http_body_util::{BodyExt, Full, channel::Channel};
use hyper::body::Incoming;
use hyper::header::{self, HeaderValue};
use hyper::{Method, Request, Response, StatusCode};
use hyper_util::rt::{TokioIo, TokioTimer};
use std::convert::Infallible;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicU8, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, Weak};
use std::time::{Duration, Instant};
use tokio::io::{AsyncReadExt, AsyncWriteExt};

/// Connections that have shown the key, served at once; a browser tab uses one to three.
/// A connection takes one of these places with its first request under the key; when all
/// are taken, that request is answered 503 and the connection closed.
pub const MAX_CLIENTS: usize = 8;
/// Connections that have not shown the key (yet), held at once: every connection waits
/// among these from when it is accepted until a request of its shows the key. When a
/// newcomer finds them all taken, the oldest is closed. Accepting never pauses, so the
/// kernel's queue does not fill, and a client without the key (another local user's) can
/// close only connections that have not shown it, the newest last: a flood of them cannot
/// keep the owner's page out; it delays it only by the share of the machine it takes.
/// Well below the 1,024 file descriptors a process is given by default.
pub const MAX_WAITING: usize = 256;
/// Connections accepted in a row before the connections being served have a turn: a
/// flood cannot keep a newcomer from reading its first request before it is the oldest.
const ACCEPT_BATCH: usize = 16;
/// The kernel's queue of connections not yet accepted.
const BACKLOG: i32 = 4096;
/// The most a request's line and headers may take; more is answered 431 (hyper's smallest
/// read buffer).
pub const MAX_HEADER_BYTES: usize = 8192;
/// Headers in one request; more is answered 431.
const MAX_HEADERS: usize = 32;
/// A request's headers must arrive within this, and an idle connection closes after it.
const HEADER_TIMEOUT: Duration = Duration::from_secs(5);
/// A connection is asked to close after this, and closed at most `GRACE` later: a client
/// that stops reading holds a place for no longer. Browsers reconnect by themselves.
const CONNECTION_LIFETIME: Duration = Duration::from_secs(60);
const GRACE: Duration = Duration::from_secs(5);
/// When the server stops, a response being sent (the finished image to a page that keeps
/// it) may finish for this long; event streams end at once.
const STOP_GRACE: Duration = Duration::from_secs(3);
/// An event stream ends after this (before the connection's lifetime); the page's
/// EventSource reconnects after `retry`.
const STREAM_LIFETIME: Duration = Duration::from_secs(45);
/// An event stream with no status to send for this long sends a comment (`:`, which the page's
/// EventSource ignores). The server keeps serving a client that has closed its side
/// (`half_close`), so it reads nothing more from a stream's connection and learns that its
/// page has gone (closed, reloaded) only when a write fails, the second after the close:
/// without anything to write, as when a held render has ended, a closed page's connection
/// would keep its place among `MAX_CLIENTS` for the whole `STREAM_LIFETIME`, and a few
/// reloads would leave the owner's next page refused.
const STREAM_HEARTBEAT: Duration = Duration::from_secs(1);
/// Requests a connection may make per second, with a burst of `BURST`; faster ones are
/// delayed, so a flood costs the machine a bounded amount of work.
const REQUESTS_PER_SEC: f64 = 20.0;
const BURST: f64 = 40.0;
const INDEX_HTML: &str = include_str!("assets/index.html");
/// Where the page holds its run's token (`Shared::run`), filled in when the server starts.
const RUN_SLOT: &str = r#"<meta name="tessera-run" content="">"#;
/// The header of every answer under the key that carries the run's token.
const RUN_HEADER: &str = "x-tessera-run";
const VIEWER_CSS: &str = include_str!("assets/viewer.css");
const VIEWER_JS: &str = include_str!("assets/viewer.js");

/// The address a listener is bound to is reachable from other machines: any but a loopback
/// one, whichever way it is written (`[::ffff:127.0.0.1]`, an IPv4 loopback address mapped
/// into IPv6, is loopback; `0.0.0.0`, `[::]` and `[::ffff:0.0.0.0]` are every address).
pub fn is_public(addr: &SocketAddr) -> bool {
    !is_loopback(addr.ip())
}

/// Whether `ip` is a loopback address, an IPv4 one mapped into IPv6 included (which
/// `IpAddr::is_loopback` alone does not count).
fn is_loopback(ip: std::net::IpAddr) -> bool {
    ip.to_canonical().is_loopback()
}

/// The URL of the page of a server listening on `addr` under `key`, as a browser takes it.
/// On every address (`0.0.0.0`, `[::]`) it names loopback, this machine's own way in:
/// browsers refuse to open the unspecified address, and the warning names the address
/// others reach. An IPv6 zone is written `%25`, the percent sign escaped, as a URL's host
/// spells it (RFC 6874); `SocketAddr` writes a bare `%`, which makes no URL.
fn page_url(addr: SocketAddr, key: &str) -> String {
    let port = addr.port();
    let host = match addr {
        SocketAddr::V4(v4) if v4.ip().is_unspecified() => "127.0.0.1".to_owned(),
        SocketAddr::V4(v4) => v4.ip().to_string(),
        // Every IPv4 address, taken on an IPv6 socket: reached through IPv4's loopback.
        SocketAddr::V6(v6)
            if v6
                .ip()
                .to_ipv4_mapped()
                .is_some_and(|v4| v4.is_unspecified()) =>
        {
            "127.0.0.1".to_owned()
        }
        SocketAddr::V6(v6) if v6.ip().is_unspecified() => "[::1]".to_owned(),
        SocketAddr::V6(v6) if v6.scope_id() != 0 => format!("[{}%25{}]", v6.ip(), v6.scope_id()),
        SocketAddr::V6(v6) => format!("[{}]", v6.ip()),
    };
    format!("http://{host}:{port}/{key}/")
}

/// What the server has done, for its owner and tests.
#[derive(Default)]
pub struct ServerStats {
    /// Connections being served now, whether they have shown the key or not.
    pub clients: AtomicUsize,
    /// Of those, the ones that have shown the key (at most `MAX_CLIENTS`).
    pub keyed: AtomicUsize,
    /// Of those, the ones that have not (at most `MAX_WAITING`).
    pub waiting: AtomicUsize,
    /// The newest frame version sent to any client (0: none).
    pub frame_served: AtomicU64,
    /// How many times the finished image was asked for (its sending finishes, within a
    /// grace, before the server stops).
    pub downloads: AtomicU64,
    /// Connections accepted.
    pub accepted: AtomicU64,
    /// Requests under the key refused (503) because `MAX_CLIENTS` connections had shown it.
    pub refused: AtomicU64,
    /// Connections closed to make room for a newcomer, as none of their requests had the key.
    pub evicted: AtomicU64,
}

/// A running viewer server; `stop` ends it.
pub struct Server {
    addr: SocketAddr,
    key: String,
    stats: Arc<ServerStats>,
    shutdown: tokio::sync::watch::Sender<bool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Server {
    /// Serves `hub`'s snapshots on `listener` (already bound, so that a bad address is an
    /// error before a render starts) from a thread of its own.
    pub fn start(listener: std::net::TcpListener, hub: Arc<Hub>) -> std::io::Result<Server> {
        let addr = listener.local_addr()?;
        let key = new_key()?;
        let run = new_key()?;
        listener.set_nonblocking(true)?;
        // Listened on again with a longer queue (the standard library's is 128; the kernel
        // caps it at net.core.somaxconn): a burst of connections waits there rather than
        // having the SYNs of those past it dropped, which their clients retry only after
        // a second.
        let _ = rustix::net::listen(&listener, BACKLOG);
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_io()
            .enable_time()
            .build()?;
        let listener = {
            let _context = runtime.enter();
            tokio::net::TcpListener::from_std(listener)?
        };
        let stats = Arc::new(ServerStats::default());
        let (shutdown, stopping) = tokio::sync::watch::channel(false);
        let shared = Arc::new(Shared {
            hub,
            addr,
            key: key.clone(),
            page: page_of(&run),
            run,
            stats: Arc::clone(&stats),
            png: Mutex::new(None),
            patch: Mutex::new(None),
            stopping,
        });
        let thread = std::thread::Builder::new()
            .name("preview-server".into())
            .spawn(move || {
                let stats = Arc::clone(&shared.stats);
                runtime.block_on(async move {
                    accept_loop(listener, shared).await;
                    // Connections that have shown the key finish what they are sending, within
                    // STOP_GRACE; dropping the runtime then closes whatever is still open. One
                    // that has not (another user's, its request half sent) is not waited for.
                    let until = tokio::time::Instant::now() + STOP_GRACE;
                    while stats.keyed.load(Ordering::Relaxed) > 0
                        && tokio::time::Instant::now() < until
                    {
                        tokio::time::sleep(Duration::from_millis(10)).await;
                    }
                });
            })?;
        Ok(Server {
            addr,
            key,
            stats,
            shutdown,
            thread: Some(thread),
        })
    }

    /// The address it listens on (the port chosen, when 0 was asked for).
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// The viewer's page: its address and key, the one URL under which it answers.
    pub fn url(&self) -> String {
        page_url(self.addr, &self.key)
    }

    /// The key every path it serves begins with.
    pub fn key(&self) -> &str {
        &self.key
    }

    pub fn stats(&self) -> &ServerStats {
        &self.stats
    }

    /// Stops accepting, lets responses being sent finish (at most `STOP_GRACE`), closes
    /// every connection and waits for the server's thread.
    pub fn stop(mut self) {
        self.halt();
    }

    fn halt(&mut self) {
        let _ = self.shutdown.send(true);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        self.halt();
    }
}

/// What every connection's tasks share.
struct Shared {
    hub: Arc<Hub>,
    addr: SocketAddr,
    /// The first segment of every path served (`new_key`).
    key: String,
    /// The run's token (drawn as the key is): written into the page, sent with every answer
    /// under the key and first in every event stream, and never part of a request. A program
    /// that takes the port once the server has gone (another user's) learns the key from
    /// the paths a page still asks for, but not this, so the page knows its answers are not
    /// its render's and stops asking.
    run: String,
    /// The page, with the run's token in it.
    page: Bytes,
    stats: Arc<ServerStats>,
    /// The newest frame's PNGs, made once for every client that asks: the whole frame and
    /// the patch from the frame before, each with its frame version.
    png: Mutex<Option<(u64, Bytes)>>,
    patch: Mutex<Option<(u64, Bytes)>>,
    stopping: tokio::sync::watch::Receiver<bool>,
}

impl Shared {
    /// What an in-memory connection's tasks share (`answer_in_memory`, the tests): the run's
    /// token is `RUN_IN_MEMORY`.
    fn in_memory(
        hub: Arc<Hub>,
        addr: SocketAddr,
        key: &str,
        stopping: tokio::sync::watch::Receiver<bool>,
    ) -> Arc<Self> {
        Arc::new(Self {
            hub,
            addr,
            key: key.to_owned(),
            page: page_of(RUN_IN_MEMORY),
            run: RUN_IN_MEMORY.to_owned(),
            stats: Arc::new(ServerStats::default()),
            png: Mutex::new(None),
            patch: Mutex::new(None),
            stopping,
        })
    }
}

async fn accept_loop(listener: tokio::net::TcpListener, shared: Arc<Shared>) {
    let mut stopping = shared.stopping.clone();
    // The places of connections that have not shown the key, oldest first; those that have
    // shown it since, or ended, are skipped (and dropped from the front as they come).
    let mut waiting: std::collections::VecDeque<Weak<Place>> = Default::default();
    let mut in_a_row = 0;
    loop {
        let accepted = tokio::select! {
            accepted = listener.accept() => accepted,
            _ = stopping.changed() => return,
        };
        let Ok((stream, _)) = accepted else {
            // Out of file descriptors, say: wait rather than spin.
            tokio::time::sleep(Duration::from_millis(50)).await;
            continue;
        };
        let _ = stream.set_nodelay(true);
        let stats = &shared.stats;
        stats.accepted.fetch_add(1, Ordering::Relaxed);
        let place = Place::enter(stats);
        waiting.push_back(Arc::downgrade(&place));
        while stats.waiting.load(Ordering::Relaxed) > MAX_WAITING {
            let Some(oldest) = waiting.pop_front() else {
                break;
            };
            if oldest.upgrade().is_some_and(|p| p.evict()) {
                stats.evicted.fetch_add(1, Ordering::Relaxed);
            }
        }
        while waiting
            .front()
            .is_some_and(|p| !p.upgrade().is_some_and(|p| p.waits()))
        {
            waiting.pop_front();
        }
        if waiting.len() > 2 * MAX_WAITING {
            waiting.retain(|p| p.upgrade().is_some_and(|p| p.waits()));
        }
        tokio::spawn(serve(stream, Arc::clone(&shared), place));
        in_a_row += 1;
        if in_a_row == ACCEPT_BATCH {
            in_a_row = 0;
            tokio::task::yield_now().await;
        }
    }
}

/// Where a connection stands: waiting to show the key, holding one of the `MAX_CLIENTS`
/// places of those that have, or gone.
const WAITING: u8 = 0;
const KEYED: u8 = 1;
const GONE: u8 = 2;

/// A connection's place, counted in `ServerStats` while it is served: among those waiting to
/// show the key, or among the `MAX_CLIENTS` that have shown it; and the call to end it when
/// it is waiting and its place is needed.
struct Place {
    state: AtomicU8,
    leave: tokio::sync::Notify,
    stats: Arc<ServerStats>,
}

impl Place {
    fn enter(stats: &Arc<ServerStats>) -> Arc<Self> {
        stats.clients.fetch_add(1, Ordering::Relaxed);
        stats.waiting.fetch_add(1, Ordering::Relaxed);
        Arc::new(Self {
            state: WAITING.into(),
            leave: tokio::sync::Notify::new(),
            stats: Arc::clone(stats),
        })
    }

    fn waits(&self) -> bool {
        self.state.load(Ordering::Relaxed) == WAITING
    }

    /// Its connection has shown the key: whether it holds (or now takes) one of the
    /// `MAX_CLIENTS` places of those that have.
    fn show_key(&self) -> bool {
        if self.state.load(Ordering::Relaxed) != WAITING {
            return self.state.load(Ordering::Relaxed) == KEYED;
        }
        let keyed = &self.stats.keyed;
        // The place is taken first, so that two connections at once cannot both have the last.
        let taken = keyed.fetch_update(Ordering::Relaxed, Ordering::Relaxed, |n| {
            (n < MAX_CLIENTS).then_some(n + 1)
        });
        if taken.is_err() {
            return false;
        }
        if self.leave_state(WAITING, KEYED) {
            true
        } else {
            keyed.fetch_sub(1, Ordering::Relaxed);
            false
        }
    }

    /// Ends its connection, if it is waiting: whether it was.
    fn evict(&self) -> bool {
        let evicted = self.leave_state(WAITING, GONE);
        if evicted {
            self.leave.notify_one();
        }
        evicted
    }

    /// Moves from `from` to `to`, if it is at `from`, no longer counted among `from`'s.
    fn leave_state(&self, from: u8, to: u8) -> bool {
        let left = (self.state)
            .compare_exchange(from, to, Ordering::Relaxed, Ordering::Relaxed)
            .is_ok();
        if left {
            let count = if from == WAITING {
                &self.stats.waiting
            } else {
                &self.stats.keyed
            };
            count.fetch_sub(1, Ordering::Relaxed);
        }
        left
    }
}

impl Drop for Place {
    fn drop(&mut self) {
        self.stats.clients.fetch_sub(1, Ordering::Relaxed);
        if !self.leave_state(WAITING, GONE) {
            self.leave_state(KEYED, GONE);
        }
    }
}

async fn serve<S>(stream: S, shared: Arc<Shared>, place: Arc<Place>)
where
    S: tokio::io::AsyncRead + tokio::io::AsyncWrite + Unpin + Send + 'static,
{
    let bucket = Arc::new(Mutex::new(Bucket::new()));
    let service = {
        let shared = Arc::clone(&shared);
        let place = Arc::clone(&place);
        hyper::service::service_fn(move |request| {
            let (shared, bucket) = (Arc::clone(&shared), Arc::clone(&bucket));
            let place = Arc::clone(&place);
            async move {
                let wait = bucket.lock().map_or(Duration::ZERO, |mut b| b.take());
                if !wait.is_zero() {
                    tokio::time::sleep(wait).await;
                }
                Ok::<_, Infallible>(respond(&shared, &place, &request))
            }
        })
    };
    let connection = hyper::server::conn::http1::Builder::new()
        .timer(TokioTimer::new())
        .header_read_timeout(HEADER_TIMEOUT)
        .max_buf_size(MAX_HEADER_BYTES)
        .max_headers(MAX_HEADERS)
        .keep_alive(true)
        // A client that closes its side once it has sent its request (`shutdown(SHUT_WR)`)
        // still gets its answer; without this, hyper drops the connection when it reads the
        // end before it has answered.
        .half_close(true)
        .serve_connection(TokioIo::new(stream), service);
    tokio::pin!(connection);
    let mut stopping = shared.stopping.clone();
    tokio::select! {
        // The server's stop is seen before anything more the connection sends, and also
        // when it came before this task first ran.
        biased;
        _ = async { drop(stopping.wait_for(|stop| *stop).await) } => {
            // A connection that never showed the key is closed at once: nothing of the
            // render is sent on it.
            if place.waits() {
                return;
            }
            // A response being sent finishes (the event stream ends by itself); an idle
            // keep-alive connection closes at once.
            connection.as_mut().graceful_shutdown();
            let _ = tokio::time::timeout(STOP_GRACE, connection.as_mut()).await;
        }
        _ = connection.as_mut() => {}
        _ = tokio::time::sleep(CONNECTION_LIFETIME) => {
            connection.as_mut().graceful_shutdown();
            let _ = tokio::time::timeout(GRACE, connection.as_mut()).await;
        }
        // Its place is needed, and it never showed the key: nothing of the render is lost.
        _ = place.leave.notified() => {}
    }
}

/// What the server answers `request`, the bytes one client sends before it closes its side
/// of the connection: the connection is served as a socket's is (hyper's parser, the limits,
/// the routes, the pacing), over an in-memory pipe on a runtime of the caller's thread, for
/// the fuzzers, which need no socket this way. `addr` is the address the server takes
/// itself to listen on (the Host header must name it), `key` the first segment of the
/// paths it serves (`Server::url`). The answer ends when the server
/// closes the connection, at the head of an event stream (which never ends by itself), or
/// after `at_most`. A panic while serving is an error.
pub fn answer_in_memory(
    hub: Arc<Hub>,
    addr: SocketAddr,
    key: &str,
    request: &[u8],
    at_most: Duration,
) -> std::io::Result<Vec<u8>> {
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_time()
        .build()?;
    let (_shutdown, stopping) = tokio::sync::watch::channel(false);
    let shared = Shared::in_memory(hub, addr, key, stopping);
    runtime.block_on(async move {
        let until = tokio::time::Instant::now() + at_most;
        let (client_side, server_side) = tokio::io::duplex(64 << 10);
        let place = Place::enter(&shared.stats);
        let served = tokio::spawn(serve(server_side, Arc::clone(&shared), place));
        let (mut reader, mut writer) = tokio::io::split(client_side);
        let mut answer = Vec::new();
        {
            // A server that answers before it has read everything (a refusal) stops reading:
            // sending and receiving go on together.
            let send = async {
                if writer.write_all(request).await.is_ok() {
                    let _ = writer.shutdown().await;
                }
            };
            let receive = async {
                let mut buf = [0u8; 16 << 10];
                while !answer_streams(&answer) {
                    match reader.read(&mut buf).await {
                        Ok(0) | Err(_) => break,
                        Ok(n) => answer.extend_from_slice(&buf[..n]),
                    }
                }
            };
            let _ = tokio::time::timeout_at(until, async { tokio::join!(send, receive) }).await;
        }
        drop((reader, writer));
        // The client is gone: what serving still does (an event stream waiting for its next
        // status, which would notice only when it sends) is stopped after a moment.
        let mut served = served;
        let outcome = match tokio::time::timeout(Duration::from_millis(20), &mut served).await {
            Ok(outcome) => outcome,
            Err(_) => {
                served.abort();
                served.await
            }
        };
        match outcome {
            Err(e) if e.is_panic() => Err(std::io::Error::other(format!(
                "serving the connection panicked: {e}"
            ))),
            _ => Ok(answer),
        }
    })
}

/// The run's token of a server in memory (`answer_in_memory`).
pub const RUN_IN_MEMORY: &str = "0123456789abcdef0123456789abcdef";

/// The page, its run's token filled in.
fn page_of(run: &str) -> Bytes {
    let slot = format!(r#"<meta name="tessera-run" content="{run}">"#);
    Bytes::from(INDEX_HTML.replacen(RUN_SLOT, &slot, 1))
}

/// Whether `answer` has come to the end of an event stream's head.
fn answer_streams(answer: &[u8]) -> bool {
    let find = |hay: &[u8], needle: &[u8]| hay.windows(needle.len()).position(|w| w == needle);
    find(answer, b"content-type: text/event-stream")
        .is_some_and(|at| find(&answer[at..], b"\r\n\r\n").is_some())
}

/// A token bucket of requests: `take` says how long to wait before serving the next one.
struct Bucket {
    tokens: f64,
    at: Instant,
}

impl Bucket {
    fn new() -> Self {
        Self {
            tokens: BURST,
            at: Instant::now(),
        }
    }

    fn take(&mut self) -> Duration {
        let now = Instant::now();
        let refill = now.duration_since(self.at).as_secs_f64() * REQUESTS_PER_SEC;
        self.tokens = (self.tokens + refill).min(BURST) - 1.0;
        self.at = now;
        if self.tokens >= 0.0 {
            Duration::ZERO
        } else {
            Duration::from_secs_f64(-self.tokens / REQUESTS_PER_SEC)
        }
    }
}

type Body = http_body_util::combinators::BoxBody<Bytes, Infallible>;

fn respond(shared: &Arc<Shared>, place: &Place, request: &Request<Incoming>) -> Response<Body> {
    if request.method() != Method::GET && request.method() != Method::HEAD {
        let mut r = text(StatusCode::METHOD_NOT_ALLOWED, "only GET and HEAD\n");
        r.headers_mut()
            .insert(header::ALLOW, HeaderValue::from_static("GET, HEAD"));
        return r;
    }
    if !host_allowed(shared.addr, request) {
        return text(
            StatusCode::MISDIRECTED_REQUEST,
            "this viewer answers only to its own address\n",
        );
    }
    let uri = request.uri();
    // Every path begins with the key: another local user, or a page that guesses the port,
    // finds nothing without it. The key alone is sent to its page.
    let path = uri.path().strip_prefix('/').unwrap_or_default();
    let (key, path) = path.split_once('/').unwrap_or((path, ""));
    if !same_key(key, &shared.key) {
        return text(
            StatusCode::NOT_FOUND,
            "not found: the viewer answers at the address tessera printed, key and all\n",
        );
    }
    if !place.show_key() {
        shared.stats.refused.fetch_add(1, Ordering::Relaxed);
        let mut r = text(
            StatusCode::SERVICE_UNAVAILABLE,
            "too many viewers are connected; try again shortly\n",
        );
        let h = r.headers_mut();
        h.insert(header::RETRY_AFTER, HeaderValue::from_static("2"));
        h.insert(header::CONNECTION, HeaderValue::from_static("close"));
        return r;
    }
    if !uri.path().ends_with('/') && path.is_empty() {
        // The page's links are relative to the key's folder.
        let mut r = text(
            StatusCode::PERMANENT_REDIRECT,
            "the viewer is one folder down\n",
        );
        if let Ok(to) = HeaderValue::from_str(&format!("/{key}/")) {
            r.headers_mut().insert(header::LOCATION, to);
        }
        return r;
    }
    let mut r = match path {
        "" | "index.html" => asset(shared.page.clone(), "text/html; charset=utf-8"),
        "viewer.css" => asset(
            Bytes::from_static(VIEWER_CSS.as_bytes()),
            "text/css; charset=utf-8",
        ),
        "viewer.js" => asset(
            Bytes::from_static(VIEWER_JS.as_bytes()),
            "text/javascript; charset=utf-8",
        ),
        "status" => {
            let latest = shared.hub.latest();
            dynamic(
                Full::new(latest.status_json.clone()).boxed(),
                "application/json",
            )
        }
        "frame.png" => frame(shared, uri.query()),
        "download" => download(shared),
        "events" => events(shared),
        _ => text(StatusCode::NOT_FOUND, "not found\n"),
    };
    if let Ok(run) = HeaderValue::from_str(&shared.run) {
        r.headers_mut().insert(RUN_HEADER, run);
    }
    r
}

/// A new key of the viewer's: 128 bits from the kernel's random source, as 32 hex digits.
/// On a loopback address any local user (and a page in any browser tab, guessing ports)
/// may connect; only who was shown the key can see the render.
fn new_key() -> std::io::Result<String> {
    let mut bytes = [0u8; 16];
    let mut filled = 0;
    while filled < bytes.len() {
        filled +=
            rustix::rand::getrandom(&mut bytes[filled..], rustix::rand::GetRandomFlags::empty())?;
    }
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

/// Whether `given` is `key`, compared in a time that does not depend on where they differ.
fn same_key(given: &str, key: &str) -> bool {
    given.len() == key.len()
        && given
            .bytes()
            .zip(key.bytes())
            .fold(0u8, |differ, (a, b)| differ | (a ^ b))
            == 0
}

/// With the server on a loopback address, only requests naming a loopback host are
/// answered: a web page elsewhere that points its own name at 127.0.0.1 (DNS rebinding)
/// cannot read the render. On another address, the user chose to be reachable.
fn host_allowed(addr: SocketAddr, request: &Request<Incoming>) -> bool {
    if is_public(&addr) {
        return true;
    }
    // One Host only: with two, the check would read the first and a proxy in front might
    // route by the other.
    let mut hosts = request.headers().get_all(header::HOST).iter();
    let (Some(host), None) = (hosts.next(), hosts.next()) else {
        return false;
    };
    let Ok(host) = host.to_str() else {
        return false;
    };
    // A request for an absolute URL (`GET http://name/ HTTP/1.1`) names its host in the URL,
    // which then counts rather than the Host header (RFC 9112, 3.2.2).
    let authority = match request.uri().authority() {
        Some(authority) => authority.clone(),
        None => match host.parse::<hyper::http::uri::Authority>() {
            Ok(authority) => authority,
            Err(_) => return false,
        },
    };
    // A Host has no user part (RFC 9110, 7.2), and a URL's is never sent: either is
    // another spelling of a name to be read, not answered.
    if authority.as_str().contains('@') || authority.port_u16().is_some_and(|p| p != addr.port()) {
        return false;
    }
    let name = authority
        .host()
        .trim_start_matches('[')
        .trim_end_matches(']');
    name.eq_ignore_ascii_case("localhost")
        || name.parse::<std::net::IpAddr>().is_ok_and(is_loopback)
}

/// The most row ranges a patch may have; a frame changed in more places is sent whole.
const MAX_PATCH_RANGES: usize = 32;

/// The latest frame as a PNG: the whole of it, or with `since=V` from a viewer that holds
/// frame V just before it, only the rows that changed, stacked. `x-frame-rows: a-b,c-d`
/// says which rows the PNG holds, in order; `x-frame-size` gives the frame's size.
fn frame(shared: &Arc<Shared>, query: Option<&str>) -> Response<Body> {
    let latest = shared.hub.latest();
    let frame = &latest.frame;
    let version = frame.version;
    let param = |name: &str| {
        (query.into_iter().flat_map(|q| q.split('&'))).find_map(|kv| match kv.split_once('=') {
            Some((k, v)) if k == name => Some(v),
            None if kv == name => Some(""),
            _ => None,
        })
    };
    let since = param("since").and_then(|v| v.parse::<u64>().ok());
    let patch = (frame.changed.as_ref())
        .filter(|_| since.is_some_and(|s| s.checked_add(1) == Some(version)))
        .filter(|rows| !rows.is_empty() && rows.len() <= MAX_PATCH_RANGES);
    let whole = [[0, frame.height]];
    let (rows, cache) = match patch {
        Some(rows) => (rows.as_slice(), &shared.patch),
        None => (&whole[..], &shared.png),
    };
    let png = {
        let mut cache = cache.lock().unwrap_or_else(|e| e.into_inner());
        match &*cache {
            Some((v, png)) if *v == version => png.clone(),
            _ => {
                let png = Bytes::from(frame.png_of_rows(rows));
                *cache = Some((version, png.clone()));
                png
            }
        }
    };
    shared
        .stats
        .frame_served
        .fetch_max(version, Ordering::Relaxed);
    let mut r = dynamic(Full::new(png).boxed(), "image/png");
    let headers = r.headers_mut();
    headers.insert("x-frame-version", HeaderValue::from(version));
    let ranges: Vec<String> = rows.iter().map(|[a, b]| format!("{a}-{b}")).collect();
    let digits = |text: String| HeaderValue::from_str(&text).expect("digits, '-' and ','");
    headers.insert("x-frame-rows", digits(ranges.join(",")));
    headers.insert(
        "x-frame-size",
        digits(format!("{},{}", frame.width, frame.height)),
    );
    r
}

/// The finished image as the render wrote it (recipe included), to save under its own
/// name; 404 until the render has finished.
fn download(shared: &Arc<Shared>) -> Response<Body> {
    let latest = shared.hub.latest();
    let Some(file) = &latest.download else {
        return text(
            StatusCode::NOT_FOUND,
            "nothing to download yet: the image is offered when the render has finished\n",
        );
    };
    shared.stats.downloads.fetch_add(1, Ordering::Relaxed);
    let mut r = dynamic(Full::new(file.png.clone()).boxed(), "image/png");
    let name = safe_name(&file.name);
    if let Ok(v) = HeaderValue::from_str(&format!("attachment; filename=\"{name}\"")) {
        r.headers_mut().insert(header::CONTENT_DISPOSITION, v);
    }
    r
}

/// A file name for a header: letters, digits, '-', '_' and '.' only (no leading dot), at
/// most 96 of them, ending in `.png`.
fn safe_name(name: &str) -> String {
    let stem = name.strip_suffix(".png").unwrap_or(name);
    let stem: String = (stem.chars())
        .filter(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'))
        .take(92)
        .collect();
    let stem = stem.trim_start_matches('.');
    if stem.is_empty() {
        "render.png".to_owned()
    } else {
        format!("{stem}.png")
    }
}

/// The event stream: every new snapshot's status as an `status` event, from the latest one
/// on, and a comment after each `STREAM_HEARTBEAT` without one. The stream holds only the
/// latest snapshot, so a client that reads slowly gets fewer events, never a backlog.
fn events(shared: &Arc<Shared>) -> Response<Body> {
    let (mut sender, body) = Channel::<Bytes, Infallible>::new(1);
    let mut snapshots = shared.hub.subscribe();
    snapshots.mark_changed();
    let mut stopping = shared.stopping.clone();
    // The run's token comes first: the page takes a stream's statuses only after it.
    let first = Bytes::from(format!("retry: 1000\nevent: run\ndata: {}\n\n", shared.run));
    tokio::spawn(async move {
        let deadline = tokio::time::sleep(STREAM_LIFETIME);
        tokio::pin!(deadline);
        let mut message = Some(first);
        loop {
            if let Some(m) = message.take() {
                tokio::select! {
                    sent = sender.send_data(m) => if sent.is_err() { return },
                    _ = &mut deadline => return,
                    _ = stopping.changed() => return,
                }
            }
            tokio::select! {
                changed = snapshots.changed() => if changed.is_err() { return },
                _ = tokio::time::sleep(STREAM_HEARTBEAT) => {
                    message = Some(Bytes::from_static(b":\n\n"));
                    continue;
                }
                _ = &mut deadline => return,
                _ = stopping.changed() => return,
            }
            let snapshot: Arc<Snapshot> = Arc::clone(&snapshots.borrow_and_update());
            let mut event = Vec::with_capacity(snapshot.status_json.len() + 32);
            event.extend_from_slice(b"event: status\ndata: ");
            event.extend_from_slice(&snapshot.status_json);
            event.extend_from_slice(b"\n\n");
            message = Some(Bytes::from(event));
        }
    });
    dynamic(body.boxed(), "text/event-stream")
}

fn asset(body: Bytes, content_type: &'static str) -> Response<Body> {
    let mut r = Response::new(Full::new(body).boxed());
    let h = r.headers_mut();
    h.insert(header::CONTENT_TYPE, HeaderValue::from_static(content_type));
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-cache"));
    secure(h);
    r
}

fn dynamic(body: Body, content_type: &'static str) -> Response<Body> {
    let mut r = Response::new(body);
    let h = r.headers_mut();
    h.insert(header::CONTENT_TYPE, HeaderValue::from_static(content_type));
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    secure(h);
    r
}

fn text(status: StatusCode, message: &'static str) -> Response<Body> {
    let mut r = dynamic(
        Full::new(Bytes::from_static(message.as_bytes())).boxed(),
        "text/plain; charset=utf-8",
    );
    *r.status_mut() = status;
    r
}

/// Headers that keep the page to its own resources, out of other sites' frames, and every
/// answer out of other origins' pages: without `Cross-Origin-Resource-Policy`, a page of any
/// site can load the frame or the finished image as an `<img>` (the browser sends a loopback
/// Host, so the Host check lets it through), learn its size and hold its pixels in its own
/// process.
fn secure(h: &mut hyper::HeaderMap) {
    h.insert(
        header::HeaderName::from_static("cross-origin-resource-policy"),
        HeaderValue::from_static("same-origin"),
    );
    h.insert(
        header::CONTENT_SECURITY_POLICY,
        HeaderValue::from_static(
            "default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self' blob:; \
             connect-src 'self'; frame-ancestors 'none'; base-uri 'none'; form-action 'none'",
        ),
    );
    h.insert(
        header::X_CONTENT_TYPE_OPTIONS,
        HeaderValue::from_static("nosniff"),
    );
    h.insert(
        header::REFERRER_POLICY,
        HeaderValue::from_static("no-referrer"),
    );
}

#[cfg(test)]
mod tests;
