//! Generated and mangled HTTP requests against the live viewer's server: each is answered
//! with a status line the server means (or the connection closed), a well-formed request
//! gets exactly the answer its method, host and path call for, and the server keeps
//! answering throughout (checked every tenth case, and at the end).

use super::harness::*;
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::sync::Arc;
use std::time::Duration;
use tessera::preview::Previewer;
use tessera::preview::server::Server;

/// A server for a small blank job, on a free loopback port.
fn server() -> (Server, Previewer) {
    let previewer = Previewer::blank("fuzz");
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    (Server::start(listener, previewer.hub()).unwrap(), previewer)
}

const METHODS: &[&str] = &[
    "GET",
    "GET",
    "GET",
    "HEAD",
    "POST",
    "PUT",
    "DELETE",
    "OPTIONS",
    "TRACE",
    "CONNECT",
    "PATCH",
    "get",
    "G\0T",
    "",
    "GETGETGETGETGETGETGETGETGETGET",
];
/// The paths the server serves under its key's folder (with any query), and others.
const SERVED: &[&str] = &[
    "",
    "index.html",
    "viewer.js",
    "viewer.css",
    "status",
    "frame.png",
];
const PATHS: &[&str] = &[
    "/frame.png?download",
    "/frame.png?v=12&download",
    "/status?",
    "/../../etc/passwd",
    "//status",
    "/%00",
    "/status/",
    "/STATUS",
    "*",
    "http://127.0.0.1/status",
    "/\u{00e9}",
    "",
    "/favicon.ico",
];
const VERSIONS: &[&str] = &[
    "HTTP/1.1", "HTTP/1.1", "HTTP/1.0", "HTTP/2.0", "HTTP/9.9", "", "FOO",
];
const ENDINGS: &[&str] = &["\r\n", "\r\n", "\r\n", "\n", "\r", ""];

/// What a generated request is, and whether it is well formed (then its answer is known).
struct Case {
    bytes: Vec<u8>,
    expect: Option<u16>,
}

fn host_header(g: &mut Gen, addr: SocketAddr) -> (Option<String>, bool) {
    let port = addr.port();
    match g.below(9) {
        0..=3 => (Some(format!("127.0.0.1:{port}")), true),
        4 => (Some(format!("localhost:{port}")), true),
        5 => (Some("attacker.example".into()), false),
        6 => (Some(format!("127.0.0.1:{}", port.wrapping_add(1))), false),
        7 => (Some(String::new()), false),
        _ => (None, false),
    }
}

fn generate(g: &mut Gen, addr: SocketAddr, key: &str) -> Case {
    let method = g.pick(METHODS);
    // A served path under the key, one under no key or another, or something else.
    let path = if g.chance(5) {
        "/".repeat(1 + g.below(20_000))
    } else if g.chance(40) {
        format!("/{key}/{}", g.pick(SERVED))
    } else if g.chance(10) {
        let other = if g.chance(50) {
            "0".repeat(32)
        } else {
            key[1..].to_owned()
        };
        format!("/{other}/{}", g.pick(SERVED))
    } else if g.chance(10) {
        format!("/{}", g.pick(SERVED))
    } else {
        g.pick(PATHS).to_owned()
    };
    let version = g.pick(VERSIONS);
    let end = if g.chance(85) {
        "\r\n"
    } else {
        g.pick(ENDINGS)
    };
    let (host, host_ok) = host_header(g, addr);
    let mut text = format!("{method} {path} {version}{end}");
    if let Some(h) = &host {
        text.push_str(&format!("Host: {h}{end}"));
    }
    // Origin-form ASCII targets only: their path is what the server routes on.
    let mut plain = end == "\r\n"
        && version == "HTTP/1.1"
        && path.starts_with('/')
        && path.is_ascii()
        && path.len() < 1024;
    for _ in 0..g.below(4) {
        plain = false;
        let header = match g.below(8) {
            0 => format!("X-Long: {}", "v".repeat(g.below(20_000))),
            1 => "Content-Length: 99999999999999999999".to_owned(),
            2 => "Content-Length: -1".to_owned(),
            3 => "Transfer-Encoding: chunked".to_owned(),
            4 => "no colon here".to_owned(),
            5 => " folded continuation".to_owned(),
            6 => format!("Host: {}", host.clone().unwrap_or_default()),
            _ => "X-Many: 1".repeat(1 + g.below(50)),
        };
        text.push_str(&header);
        text.push_str(end);
    }
    text.push_str("Connection: close");
    text.push_str(end);
    text.push_str(end);
    let mut bytes = text.into_bytes();
    if g.chance(15) {
        plain = false;
        let more = bytes.clone();
        bytes.extend_from_slice(&more);
    }
    if g.chance(15) {
        plain = false;
        for _ in 0..1 + g.below(8) {
            let at = g.below(bytes.len());
            bytes[at] = g.below(256) as u8;
        }
    }
    if g.chance(10) {
        plain = false;
        let keep = g.below(bytes.len());
        bytes.truncate(keep);
    }
    if g.chance(3) {
        plain = false;
        bytes = (0..g.below(4096)).map(|_| g.below(256) as u8).collect();
    }
    let bare = path.split('?').next().unwrap_or("");
    let served = bare
        .strip_prefix(&format!("/{key}/"))
        .is_some_and(|name| SERVED.contains(&name));
    let expect = plain.then(|| {
        if method != "GET" && method != "HEAD" {
            405
        } else if !host_ok {
            421
        } else if served {
            200
        } else {
            404
        }
    });
    // Methods hyper cannot read as a token (a NUL, an empty one) are its own 400.
    let expect =
        expect.filter(|_| method.bytes().all(|b| b.is_ascii_alphabetic()) && !method.is_empty());
    Case { bytes, expect }
}

/// Sends `bytes`, closes the sending side and reads what comes back (at most 1 MiB, for at
/// most two seconds).
fn exchange(addr: SocketAddr, bytes: &[u8]) -> Result<Vec<u8>, String> {
    let mut s = TcpStream::connect_timeout(&addr, Duration::from_secs(10))
        .map_err(|e| format!("connect: {e}"))?;
    s.set_read_timeout(Some(Duration::from_secs(2))).unwrap();
    s.set_write_timeout(Some(Duration::from_secs(2))).unwrap();
    // The server may answer and close before reading everything (a 431): not an error.
    let _ = s.write_all(bytes);
    let _ = s.shutdown(std::net::Shutdown::Write);
    let mut answer = Vec::new();
    let mut buf = [0u8; 16 * 1024];
    while answer.len() < 1 << 20 {
        match s.read(&mut buf) {
            Ok(0) | Err(_) => break,
            Ok(n) => answer.extend_from_slice(&buf[..n]),
        }
    }
    Ok(answer)
}

/// The status code of an answer, if it starts with an HTTP/1.1 (or, to an HTTP/1.0
/// request, 1.0) status line.
fn status_code(answer: &[u8]) -> Option<u16> {
    let line = (answer.strip_prefix(b"HTTP/1.1 ")).or_else(|| answer.strip_prefix(b"HTTP/1.0 "))?;
    std::str::from_utf8(line.get(..3)?).ok()?.parse().ok()
}

#[test]
fn generated_requests_get_a_meant_answer_and_the_server_keeps_answering() {
    let (server, _previewer) = server();
    let addr = server.addr();
    let key = server.key().to_owned();
    let known = [200, 308, 400, 404, 405, 408, 421, 431, 501, 503, 505];
    let status = format!("GET /{key}/status HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n");
    let alive = Arc::new(move || {
        for _ in 0..20 {
            if let Ok(a) = exchange(addr, status.as_bytes())
                && status_code(&a) == Some(200)
            {
                return true;
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        false
    });
    let check_alive = Arc::clone(&alive);
    let checked = std::cell::Cell::new(0u32);
    run_family(
        "request",
        1_500,
        4 << 20,
        |g| {
            let case = generate(g, addr, &key);
            let shown = String::from_utf8_lossy(&case.bytes[..case.bytes.len().min(600)])
                .escape_debug()
                .to_string();
            (case, shown)
        },
        move |case| {
            let answer = exchange(addr, &case.bytes)?;
            match (status_code(&answer), case.expect) {
                (None, _) if answer.is_empty() => {}
                (None, _) => {
                    return Err(format!(
                        "an answer without a status line: {:?}",
                        String::from_utf8_lossy(&answer[..answer.len().min(200)])
                    ));
                }
                (Some(code), _) if !known.contains(&code) => {
                    return Err(format!("an unexpected status {code}"));
                }
                (Some(code), Some(want)) if code != want && code != 503 => {
                    return Err(format!("status {code}, expected {want}"));
                }
                _ => {}
            }
            checked.set(checked.get() + 1);
            if checked.get().is_multiple_of(10) && !check_alive() {
                return Err("the server stopped answering".into());
            }
            Ok(if status_code(&answer) == Some(200) {
                Outcome::Accepted
            } else {
                Outcome::Refused
            })
        },
    );
    assert!(alive(), "the server answers after the fuzzing");
    server.stop();
}
