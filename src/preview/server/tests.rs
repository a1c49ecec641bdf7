//! The viewer server's own tests: its key, its places, its answers in memory.

use super::*;

#[test]
fn buckets_allow_a_burst_then_pace() {
    let mut b = Bucket::new();
    for _ in 0..BURST as usize {
        assert_eq!(b.take(), Duration::ZERO);
    }
    let wait = b.take();
    assert!(
        wait > Duration::ZERO && wait <= Duration::from_millis(60),
        "{wait:?}"
    );
}

/// A viewer of a small blank job.
fn blank_previewer() -> super::super::Previewer {
    super::super::Previewer::blank("blank")
}

/// The key of the paths served in memory here.
const KEY: &str = "k3y";

/// Every run's server has a key of its own, 128 bits the kernel drew: the address
/// printed is all that reaches the page.
#[test]
fn each_server_has_a_key_of_its_own() {
    let previewer = blank_previewer();
    let url_and_key = || {
        let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let server = Server::start(listener, previewer.hub()).unwrap();
        let found = (server.url(), server.key().to_owned());
        server.stop();
        found
    };
    let ((a, key_a), (_, key_b)) = (url_and_key(), url_and_key());
    assert!(a.starts_with("http://127.0.0.1:") && a.ends_with(&format!("/{key_a}/")));
    assert_eq!(key_a.len(), 32, "{a}");
    assert!(key_a.bytes().all(|c| c.is_ascii_hexdigit()), "{a}");
    assert_ne!(key_a, key_b);
    assert!(same_key(&key_a, &key_a) && !same_key(&key_a, &key_b));
    assert!(!same_key(&key_a[..31], &key_a) && !same_key("", &key_a));
}

/// Reads one answer from `stream` (its head, then its body by length), as text.
fn read_answer(stream: &mut std::net::TcpStream) -> String {
    use std::io::Read;
    let mut got = Vec::new();
    let mut byte = [0u8; 1];
    while !got.ends_with(b"\r\n\r\n") {
        match stream.read(&mut byte) {
            Ok(1) => got.push(byte[0]),
            _ => return String::from_utf8_lossy(&got).into_owned(),
        }
    }
    let head = String::from_utf8_lossy(&got).to_ascii_lowercase();
    let length = (head.lines())
        .find_map(|l| l.strip_prefix("content-length:"))
        .map_or(0, |v| v.trim().parse().unwrap());
    let mut body = vec![0u8; length];
    stream.read_exact(&mut body).unwrap();
    got.extend_from_slice(&body);
    String::from_utf8_lossy(&got).into_owned()
}

/// A connection to the server at `addr`; the read timeout is only a guard against hanging.
fn connect(addr: SocketAddr) -> std::net::TcpStream {
    let s = std::net::TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    s
}

/// The answer to a GET of `path` on `s`, a connection to the server at `addr`.
fn ask(s: &mut std::net::TcpStream, addr: SocketAddr, path: &str) -> String {
    use std::io::Write;
    write!(s, "GET {path} HTTP/1.1\r\nHost: {addr}\r\n\r\n").unwrap();
    read_answer(s)
}

/// Another local user, without the key, opens connection after connection and keeps
/// them (asking for keyless paths, or saying nothing): each takes the place of none that
/// showed the key, so the owner's page is still served; only connections that have shown
/// it fill the server.
#[test]
fn clients_without_the_key_cannot_keep_the_owner_out() {
    let previewer = blank_previewer();
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let server = Server::start(listener, previewer.hub()).unwrap();
    let (addr, key) = (server.addr(), server.key().to_owned());
    let connect = || connect(addr);
    let ask = |s: &mut std::net::TcpStream, path: &str| ask(s, addr, path);
    let mut strangers = Vec::new();
    for i in 0..MAX_WAITING + 2 * MAX_CLIENTS {
        let mut s = connect();
        if i % 2 == 0 {
            let answer = ask(&mut s, "/status");
            assert!(answer.starts_with("HTTP/1.1 404"), "{answer}");
        }
        strangers.push(s);
    }
    let mut owners = Vec::new();
    for _ in 0..MAX_CLIENTS {
        let mut s = connect();
        let answer = ask(&mut s, &format!("/{key}/status"));
        assert!(answer.starts_with("HTTP/1.1 200"), "{answer}");
        owners.push(s);
    }
    // Every place has shown the key now: one more is refused, whoever it is.
    let mut one_more = connect();
    let answer = ask(&mut one_more, &format!("/{key}/status"));
    assert!(answer.starts_with("HTTP/1.1 503"), "{answer}");
    assert!(server.stats().evicted.load(Ordering::Relaxed) >= MAX_CLIENTS as u64);
    drop((strangers, owners));
    server.stop();
}

/// The owner closes or reloads a tab of a render that has ended and is held (no status comes
/// any more), again and again: each page's event stream was its connection's last request,
/// and the server, which keeps serving a client that has closed its side (`half_close`),
/// sees it gone at its next write. Its place is given back within a few seconds, not at the
/// stream's end: a page opened then is served, not told that too many viewers are connected.
#[test]
fn closed_pages_event_streams_give_their_places_back_while_nothing_is_published() {
    let previewer = blank_previewer();
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let server = Server::start(listener, previewer.hub()).unwrap();
    let (addr, key) = (server.addr(), server.key().to_owned());
    use std::io::Read;
    for _ in 0..MAX_CLIENTS {
        let mut s = connect(addr);
        let answer = ask(&mut s, addr, &format!("/{key}/events"));
        assert!(answer.starts_with("HTTP/1.1 200"), "{answer}");
        // The page has read all that came (the run's token, its chunk), so closing sends a FIN.
        let mut event = Vec::new();
        while !event.ends_with(b"\n\n\r\n") {
            let mut byte = [0u8; 1];
            assert_eq!(s.read(&mut byte).unwrap(), 1);
            event.push(byte[0]);
        }
    }
    // Well within the stream's life, however slow the machine; 2 heartbeats are enough.
    let until = Instant::now() + STREAM_LIFETIME / 3;
    while server.stats().keyed.load(Ordering::Relaxed) > 0 && Instant::now() < until {
        std::thread::sleep(Duration::from_millis(20));
    }
    let keyed = server.stats().keyed.load(Ordering::Relaxed);
    assert_eq!(keyed, 0, "places still held by closed pages");
    let mut s = connect(addr);
    let answer = ask(&mut s, addr, &format!("/{key}/status"));
    assert!(answer.starts_with("HTTP/1.1 200"), "{answer}");
    drop(s);
    server.stop();
}

/// A browser opens a connection before it has a request for it (a preconnection), and
/// another local user floods the port meanwhile, holding connections or closing them at
/// once: the owner's connection is not closed to make room for the newer ones, and every
/// request of the owner's, each on a connection of its own, is answered.
#[test]
fn a_flood_of_strangers_closes_no_connection_of_the_owner_s() {
    use std::sync::atomic::AtomicBool;
    let previewer = blank_previewer();
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let server = Server::start(listener, previewer.hub()).unwrap();
    let (addr, key) = (server.addr(), server.key().to_owned());
    // Every answer is expected, however slow.
    let connect = || connect(addr);
    let ask = |s: &mut std::net::TcpStream, path: &str| ask(s, addr, path);
    let mut early = connect();
    // Each stranger's answer shows it was accepted after the owner's connection.
    let mut strangers = Vec::new();
    for _ in 0..2 * MAX_CLIENTS {
        let mut s = connect();
        let answer = ask(&mut s, "/status");
        assert!(answer.starts_with("HTTP/1.1 404"), "{answer}");
        strangers.push(s);
    }
    let answer = ask(&mut early, &format!("/{key}/status"));
    assert!(answer.starts_with("HTTP/1.1 200"), "{answer}");
    drop(early);
    // Three strangers flood the port while the owner asks, 12 times, afresh.
    let flooding = AtomicBool::new(true);
    let made = AtomicU64::new(0);
    std::thread::scope(|scope| {
        for holds in [false, true, false] {
            let (flooding, made) = (&flooding, &made);
            scope.spawn(move || {
                let mut held = std::collections::VecDeque::new();
                while flooding.load(Ordering::Relaxed) {
                    if let Ok(s) = std::net::TcpStream::connect(addr) {
                        made.fetch_add(1, Ordering::Relaxed);
                        if holds {
                            held.push_back(s);
                            if held.len() > MAX_WAITING + MAX_CLIENTS {
                                held.pop_front();
                            }
                        }
                    }
                }
            });
        }
        for _ in 0..12 {
            let mut s = connect();
            let answer = ask(&mut s, &format!("/{key}/status"));
            assert!(answer.starts_with("HTTP/1.1 200"), "{answer}");
            let stats = server.stats();
            assert!(stats.keyed.load(Ordering::Relaxed) <= MAX_CLIENTS);
            assert!(stats.waiting.load(Ordering::Relaxed) <= MAX_WAITING + 1);
        }
        // The flood goes on until it has made more connections than there are waiting
        // places, twice over, and some were closed to make room, however slowly the machine
        // lets it connect (a fixed flood once made 509 on a loaded machine); the deadline
        // is only a guard against hanging.
        let guard = Instant::now() + Duration::from_secs(120);
        while (made.load(Ordering::Relaxed) <= 2 * MAX_WAITING as u64
            || server.stats().evicted.load(Ordering::Relaxed) == 0)
            && Instant::now() < guard
        {
            std::thread::sleep(Duration::from_millis(10));
        }
        flooding.store(false, Ordering::Relaxed);
    });
    let stats = server.stats();
    let (made, evicted) = (made.into_inner(), stats.evicted.load(Ordering::Relaxed));
    assert!(made > 2 * MAX_WAITING as u64, "{made} connections made");
    assert!(evicted > 0, "{evicted} of {made} closed to make room");
    drop(strangers);
    server.stop();
}

#[test]
fn a_connection_in_memory_is_answered_as_a_socket_s_is() {
    let previewer = blank_previewer();
    let addr = SocketAddr::from(([127, 0, 0, 1], 8000));
    let ask = |request: &[u8]| {
        let started = Instant::now();
        let answer =
            answer_in_memory(previewer.hub(), addr, KEY, request, Duration::from_secs(5)).unwrap();
        (
            String::from_utf8_lossy(&answer).into_owned(),
            started.elapsed(),
        )
    };
    // Answered, and at once: the connection closes when the client's side has.
    let (status, took) = ask(b"GET /k3y/status HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n");
    assert!(status.starts_with("HTTP/1.1 200"), "{status}");
    assert!(took < Duration::from_secs(2), "{took:?}");
    let (keyless, _) = ask(b"GET /status HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n");
    assert!(keyless.starts_with("HTTP/1.1 404"), "{keyless}");
    let (folder, _) = ask(b"GET /k3y HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n");
    assert!(
        folder.starts_with("HTTP/1.1 308") && folder.contains("location: /k3y/\r\n"),
        "{folder}"
    );
    let (two, _) = ask(
        b"GET /k3y/viewer.css HTTP/1.1\r\nHost: localhost:8000\r\n\r\n\
          GET /k3y/nothing HTTP/1.1\r\nHost: localhost\r\n\r\n",
    );
    assert!(
        two.starts_with("HTTP/1.1 200") && two.contains("HTTP/1.1 404"),
        "{two}"
    );
    let (foreign, _) = ask(b"GET / HTTP/1.1\r\nHost: example.com\r\n\r\n");
    assert!(foreign.starts_with("HTTP/1.1 421"), "{foreign}");
    let (other_port, _) = ask(b"GET / HTTP/1.1\r\nHost: 127.0.0.1:8001\r\n\r\n");
    assert!(other_port.starts_with("HTTP/1.1 421"), "{other_port}");
    let (post, _) = ask(b"POST / HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n");
    assert!(post.starts_with("HTTP/1.1 405"), "{post}");
    let (garbage, _) = ask(b"\x16\x03\x01 not http\r\n\r\n");
    assert!(
        garbage.is_empty() || garbage.starts_with("HTTP/1.1 400"),
        "{garbage}"
    );
    // An event stream is cut off after its head, well before `at_most`.
    let (events, took) = ask(b"GET /k3y/events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n");
    assert!(events.contains("text/event-stream"), "{events}");
    assert!(took < Duration::from_secs(2), "{took:?}");
}

#[test]
fn download_names_are_plain() {
    assert_eq!(safe_name("cover.png"), "cover.png");
    assert_eq!(
        safe_name("img-1.16-glass-hollow.png"),
        "img-1.16-glass-hollow.png"
    );
    assert_eq!(safe_name("../../etc/passwd\"\r\n"), "etcpasswd.png");
    assert_eq!(safe_name(".hidden"), "hidden.png");
    assert_eq!(safe_name("é"), "render.png");
}

/// A connection over an in-memory pipe that counts the bytes the server has read from it.
struct Counted {
    pipe: tokio::io::DuplexStream,
    read: Arc<AtomicUsize>,
}

impl tokio::io::AsyncRead for Counted {
    fn poll_read(
        mut self: std::pin::Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
        buf: &mut tokio::io::ReadBuf<'_>,
    ) -> std::task::Poll<std::io::Result<()>> {
        let before = buf.filled().len();
        let polled = std::pin::Pin::new(&mut self.pipe).poll_read(cx, buf);
        let n = buf.filled().len() - before;
        self.read.fetch_add(n, Ordering::Relaxed);
        polled
    }
}

impl tokio::io::AsyncWrite for Counted {
    fn poll_write(
        mut self: std::pin::Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
        buf: &[u8],
    ) -> std::task::Poll<std::io::Result<usize>> {
        std::pin::Pin::new(&mut self.pipe).poll_write(cx, buf)
    }

    fn poll_flush(
        mut self: std::pin::Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
    ) -> std::task::Poll<std::io::Result<()>> {
        std::pin::Pin::new(&mut self.pipe).poll_flush(cx)
    }

    fn poll_shutdown(
        mut self: std::pin::Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
    ) -> std::task::Poll<std::io::Result<()>> {
        std::pin::Pin::new(&mut self.pipe).poll_shutdown(cx)
    }
}

/// Another local user's request, its line sent before the server stops and the rest after:
/// at the stop the connection is closed, unanswered, whether the server had read the line
/// (hyper then counts the request as begun and would finish it) or its task had not run
/// since it was accepted. Each step is taken on one thread, in order, over in-memory pipes:
/// on sockets, which the server reads first, the line or the stop, is the scheduler's to say.
#[test]
fn a_stranger_s_request_finished_after_the_stop_is_not_answered() {
    const LINE: &[u8] = b"GET /x HTTP/1.1\r\n";
    const REST: &[u8] = b"Host: 127.0.0.1:8000\r\n\r\n";
    let previewer = blank_previewer();
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_time()
        .build()
        .unwrap();
    let (stop, stopping) = tokio::sync::watch::channel(false);
    let addr = SocketAddr::from(([127, 0, 0, 1], 8000));
    let shared = Shared::in_memory(previewer.hub(), addr, KEY, stopping);
    // The stranger's connection, served as the accept loop serves one.
    let connect = || {
        let (client, pipe) = tokio::io::duplex(64 << 10);
        let read = Arc::new(AtomicUsize::new(0));
        let server_side = Counted {
            pipe,
            read: Arc::clone(&read),
        };
        let place = Place::enter(&shared.stats);
        (client, server_side, read, place)
    };
    let answer_to_rest = |mut client: tokio::io::DuplexStream| async move {
        let _ = client.write_all(REST).await;
        let mut answer = Vec::new();
        let _ = client.read_to_end(&mut answer).await;
        String::from_utf8_lossy(&answer).into_owned()
    };
    runtime.block_on(async {
        // Its line read before the stop, the rest sent after, before its task runs again.
        let (mut client, server_side, read, place) = connect();
        let served = tokio::spawn(serve(server_side, Arc::clone(&shared), place));
        client.write_all(LINE).await.unwrap();
        for _ in 0..1000 {
            if read.load(Ordering::Relaxed) == LINE.len() {
                break;
            }
            tokio::task::yield_now().await;
        }
        assert_eq!(read.load(Ordering::Relaxed), LINE.len());
        stop.send(true).unwrap();
        let answer = answer_to_rest(client).await;
        assert!(answer.is_empty(), "{answer}");
        served.await.unwrap();

        // Accepted just before the stop, its task first run after it.
        let (mut client, server_side, _, place) = connect();
        client.write_all(LINE).await.unwrap();
        let served = tokio::spawn(serve(server_side, Arc::clone(&shared), place));
        let answer = answer_to_rest(client).await;
        assert!(answer.is_empty(), "{answer}");
        served.await.unwrap();
    });
    assert_eq!(shared.stats.clients.load(Ordering::Relaxed), 0);
}

/// An IPv4 loopback address mapped into IPv6 (`--preview=[::ffff:127.0.0.1]:PORT`) is
/// loopback: not warned about as public, and its Host check stays on; a Host naming a
/// loopback address so spelled (as a browser writes `[::ffff:127.0.0.1]`) is answered.
/// Every address of the machine (`0.0.0.0`, `[::]`, `[::ffff:0.0.0.0]`) is public.
#[test]
fn a_mapped_loopback_address_is_loopback() {
    let addr = |s: &str| s.parse::<SocketAddr>().unwrap();
    for loopback in ["127.0.0.1:8000", "127.0.0.2:8000", "[::1]:8000"] {
        assert!(!is_public(&addr(loopback)), "{loopback}");
    }
    assert!(!is_public(&addr("[::ffff:127.0.0.1]:8000")));
    for public in [
        "0.0.0.0:8000",
        "[::]:8000",
        "[::ffff:0.0.0.0]:8000",
        "[::ffff:10.1.2.3]:8000",
        "10.1.2.3:8000",
        "[fe80::1%2]:8000",
        "[::127.0.0.1]:8000",
    ] {
        assert!(is_public(&addr(public)), "{public}");
    }
    let previewer = blank_previewer();
    let ask = |on: &str, host: &str| {
        let request = format!("GET /k3y/status HTTP/1.1\r\nHost: {host}\r\n\r\n");
        let answer = answer_in_memory(
            previewer.hub(),
            addr(on),
            KEY,
            request.as_bytes(),
            Duration::from_secs(5),
        )
        .unwrap();
        String::from_utf8_lossy(&answer).into_owned()
    };
    let mapped = "[::ffff:127.0.0.1]:8000";
    let foreign = ask(mapped, "rebound.example:8000");
    assert!(foreign.starts_with("HTTP/1.1 421"), "{foreign}");
    for host in [
        "[::ffff:127.0.0.1]:8000",
        "[::ffff:7f00:1]:8000",
        "localhost:8000",
    ] {
        let own = ask(mapped, host);
        assert!(own.starts_with("HTTP/1.1 200"), "{host}: {own}");
        let on_v4 = ask("127.0.0.1:8000", host);
        assert!(on_v4.starts_with("HTTP/1.1 200"), "{host}: {on_v4}");
    }
    for host in [
        "0.0.0.0:8000",
        "[::]:8000",
        "[::ffff:10.1.2.3]:8000",
        "[::1%25lo]:8000",
    ] {
        let other = ask(mapped, host);
        assert!(other.starts_with("HTTP/1.1 421"), "{host}: {other}");
    }
}

/// The printed URL is one a browser opens: on every address it names loopback (browsers
/// refuse `0.0.0.0`), and an IPv6 zone is escaped as `%25` (a bare `%4` is no URL).
#[test]
fn the_page_s_url_is_one_a_browser_opens() {
    let url = |s: &str| page_url(s.parse().unwrap(), KEY);
    assert_eq!(url("127.0.0.1:8000"), "http://127.0.0.1:8000/k3y/");
    assert_eq!(url("10.1.2.3:8000"), "http://10.1.2.3:8000/k3y/");
    assert_eq!(url("0.0.0.0:8000"), "http://127.0.0.1:8000/k3y/");
    assert_eq!(url("[::]:8000"), "http://[::1]:8000/k3y/");
    assert_eq!(url("[::ffff:0.0.0.0]:8000"), "http://127.0.0.1:8000/k3y/");
    assert_eq!(url("[::1]:8000"), "http://[::1]:8000/k3y/");
    assert_eq!(
        url("[::ffff:127.0.0.1]:8000"),
        "http://[::ffff:127.0.0.1]:8000/k3y/"
    );
    assert_eq!(url("[fe80::1%4]:8000"), "http://[fe80::1%254]:8000/k3y/");
    for written in ["0.0.0.0:8000", "[fe80::1%4]:8000", "[::]:8000"] {
        let url = url(written);
        assert!(
            url.parse::<hyper::http::Uri>().is_ok(),
            "{written}: {url} is not a URL"
        );
    }
}
