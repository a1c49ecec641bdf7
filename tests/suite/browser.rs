//! The viewer as a person sees it: a real headless Chromium (Debian's `chromium`) opens the
//! page during a render, driven over the DevTools protocol. Its screenshots must show the
//! image (not blank, in the current frame's colours), the progress text, the tiles being
//! rendered and, at the end, the final image with its download link. The screenshots are
//! kept in the target directory for a person to look at.
//!
//! Without Chromium the test is skipped, saying so; under `CI=true` it fails instead.

use crate::common::*;
use base64::Engine;
use serde_json::{Value, json};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::Receiver;
use std::time::{Duration, Instant};

/// How long a page may take: generous, as these tests share two cores with others.
const PATIENCE: Duration = Duration::from_secs(60);

/// The Chromium to drive: `TESSERA_CHROMIUM`, or Debian's, or one on the PATH.
fn chromium() -> Option<PathBuf> {
    if let Ok(path) = std::env::var("TESSERA_CHROMIUM") {
        return Some(PathBuf::from(path));
    }
    let path = std::env::var_os("PATH").unwrap_or_default();
    let dirs: Vec<PathBuf> = std::env::split_paths(&path).collect();
    ["chromium", "chromium-browser", "google-chrome"]
        .iter()
        .flat_map(|name| dirs.iter().map(move |d| d.join(name)))
        .find(|p| p.is_file())
}

/// A headless Chromium showing one page, and a DevTools connection to that page.
struct Browser {
    child: Child,
    profile: PathBuf,
    socket: tungstenite::WebSocket<tungstenite::stream::MaybeTlsStream<TcpStream>>,
    next_id: u64,
}

impl Browser {
    fn open(binary: &Path, url: &str, profile: PathBuf) -> Browser {
        let mut child = Command::new(binary)
            .args([
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--disable-dev-shm-usage",
                "--no-first-run",
                "--disable-background-networking",
                "--disable-component-update",
                "--disable-sync",
                "--disable-quic",
                "--force-color-profile=srgb",
                "--hide-scrollbars",
                "--window-size=1000,760",
                "--remote-debugging-port=0",
                "--remote-allow-origins=*",
            ])
            .arg(format!("--user-data-dir={}", profile.display()))
            .arg(url)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start chromium");
        // Chromium says where its DevTools listen on standard error.
        let mut lines = BufReader::new(child.stderr.take().unwrap()).lines();
        let endpoint = loop {
            match lines.next() {
                Some(Ok(line)) => {
                    if let Some(rest) = line.strip_prefix("DevTools listening on ws://") {
                        break rest.split('/').next().unwrap().to_owned();
                    }
                }
                _ => {
                    let _ = child.kill();
                    panic!("chromium ended without opening its DevTools");
                }
            }
        };
        // Keep draining its messages so that it never blocks on a full pipe.
        std::thread::spawn(move || lines.for_each(drop));
        let socket = page_socket(&endpoint);
        let (socket, _) = tungstenite::connect(socket.as_str()).expect("DevTools socket");
        let mut browser = Browser {
            child,
            profile,
            socket,
            next_id: 0,
        };
        browser.call("Page.enable", json!({}));
        browser.call("Runtime.enable", json!({}));
        browser
    }

    /// Calls a DevTools method and returns its result, skipping the events in between.
    fn call(&mut self, method: &str, params: Value) -> Value {
        self.next_id += 1;
        let id = self.next_id;
        let message = json!({"id": id, "method": method, "params": params}).to_string();
        self.socket
            .send(tungstenite::Message::text(message))
            .expect("send to DevTools");
        loop {
            let reply = self.socket.read().expect("DevTools answers");
            let Ok(text) = reply.to_text() else {
                continue;
            };
            let value: Value = serde_json::from_str(text).expect("DevTools JSON");
            if value["id"] == id {
                assert!(value.get("error").is_none(), "{method}: {value}");
                return value["result"].clone();
            }
        }
    }

    /// The value of a JavaScript expression in the page.
    fn eval(&mut self, expression: &str) -> Value {
        let r = self.call(
            "Runtime.evaluate",
            json!({"expression": expression, "returnByValue": true}),
        );
        r["result"]["value"].clone()
    }

    fn screenshot(&mut self) -> image::RgbImage {
        let r = self.call("Page.captureScreenshot", json!({"format": "png"}));
        let bytes = base64::engine::general_purpose::STANDARD
            .decode(r["data"].as_str().expect("screenshot data"))
            .expect("base64");
        image::load_from_memory(&bytes).expect("a PNG").to_rgb8()
    }

    /// Polls `expression` until `done` says so.
    fn wait_for(&mut self, what: &str, expression: &str, done: impl Fn(&Value) -> bool) -> Value {
        let start = Instant::now();
        let mut seen = Vec::new();
        loop {
            let v = self.eval(expression);
            if done(&v) {
                return v;
            }
            if seen.last() != Some(&v) {
                seen.push(v);
            }
            assert!(
                start.elapsed() < PATIENCE,
                "waited too long for {what}; saw {}",
                seen.iter()
                    .map(Value::to_string)
                    .collect::<Vec<_>>()
                    .join("\n")
            );
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

impl Drop for Browser {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = std::fs::remove_dir_all(&self.profile);
    }
}

/// The DevTools WebSocket address of the browser's page, from its `/json/list`.
fn page_socket(endpoint: &str) -> String {
    let start = Instant::now();
    loop {
        let body = http_get(endpoint, "/json/list");
        let targets: Value = serde_json::from_slice(&body).unwrap_or(Value::Null);
        let page = (targets.as_array().into_iter().flatten())
            .find(|t| t["type"] == "page")
            .and_then(|t| t["webSocketDebuggerUrl"].as_str());
        if let Some(url) = page {
            return url.to_owned();
        }
        assert!(start.elapsed() < PATIENCE, "no page in {targets}");
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// The body of `GET path` from `host:port`, read to its length (Chromium's DevTools keep the
/// connection open).
fn http_get(host: &str, path: &str) -> Vec<u8> {
    let mut s = TcpStream::connect(host).expect("connect");
    s.set_read_timeout(Some(PATIENCE)).unwrap();
    write!(
        s,
        "GET {path} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    let mut reader = BufReader::new(s);
    let mut length = None;
    let mut line = String::new();
    loop {
        line.clear();
        reader.read_line(&mut line).expect("an HTTP answer");
        if let Some(v) = line.to_ascii_lowercase().strip_prefix("content-length:") {
            length = v.trim().parse::<usize>().ok();
        }
        if line == "\r\n" || line.is_empty() {
            break;
        }
    }
    let mut body = Vec::new();
    match length {
        Some(n) => {
            body.resize(n, 0);
            reader.read_exact(&mut body).expect("the whole body");
        }
        None => {
            let _ = reader.read_to_end(&mut body);
        }
    }
    body
}

/// The part of `shot` where the page draws the image, from its canvas's place on the page.
fn image_on_screen(browser: &mut Browser, shot: &image::RgbImage) -> image::RgbImage {
    // The canvas fills the stage and draws the image inside it at its own shape.
    let rect = browser.eval(
        "(() => { const c = document.getElementById('image'); \
          const r = c.getBoundingClientRect(); \
          const z = Math.min(r.width / c.width, r.height / c.height); \
          const w = c.width * z, h = c.height * z; \
          const d = window.devicePixelRatio; \
          return [r.left + (r.width - w) / 2, r.top + (r.height - h) / 2, w, h] \
            .map((v) => Math.round(v * d)); })()",
    );
    let r: Vec<u32> = (rect.as_array().expect("a rectangle").iter())
        .map(|v| v.as_u64().unwrap() as u32)
        .collect();
    assert!(
        r[2] > 50 && r[3] > 30,
        "the image is drawn at a visible size: {r:?}"
    );
    assert!(
        r[0] + r[2] <= shot.width() && r[1] + r[3] <= shot.height(),
        "{r:?}"
    );
    image::imageops::crop_imm(shot, r[0], r[1], r[2], r[3]).to_image()
}

/// The mean colour of each cell of a `cells × cells` grid over `img`.
fn cell_means(img: &image::RgbImage, cells: u32) -> Vec<[f64; 3]> {
    let small = image::imageops::resize(img, cells, cells, image::imageops::FilterType::Triangle);
    small.pixels().map(|p| p.0.map(f64::from)).collect()
}

/// Checks that the screen's image shows `frame`: the same colours cell by cell, roughly (the
/// browser scales it, and the page may be a frame behind), and not a blank.
fn assert_shows(screen: &image::RgbImage, frame: &image::RgbImage, what: &str) {
    let (a, b) = (cell_means(screen, 8), cell_means(frame, 8));
    let worst = (a.iter().zip(&b))
        .flat_map(|(x, y)| (0..3).map(move |c| (x[c] - y[c]).abs()))
        .fold(0.0, f64::max);
    assert!(
        worst < 24.0,
        "{what}: the screen's colours differ by {worst:.1} of 255"
    );
    let mean = a.iter().map(|c| c[0] + c[1] + c[2]).sum::<f64>() / (3.0 * a.len() as f64);
    let spread = a
        .iter()
        .map(|c| ((c[0] + c[1] + c[2]) / 3.0 - mean).abs())
        .fold(0.0, f64::max);
    assert!(
        spread > 20.0,
        "{what}: the image on screen is flat (a blank?)"
    );
}

fn save_for_people(name: &str, img: &image::RgbImage) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("preview-screenshots");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    img.save(&path).unwrap();
    path
}

#[test]
fn a_browser_shows_the_render_converging_and_the_final_image() {
    let Some(binary) = browser_for("a_browser_shows_the_render") else {
        return;
    };
    let dir = temp_dir("browser");
    let (mut viewer, url, held) = watched_render(
        &dir,
        &[
            "--width",
            "400",
            "--spp",
            "256",
            "--threads",
            "1",
            "-o",
            "watched.png",
            "--preview-hold",
        ],
    );
    // `http://ADDR:PORT/KEY/`: every path is under the key.
    let (host, key) = url
        .trim_start_matches("http://")
        .trim_end_matches('/')
        .split_once('/')
        .map(|(host, key)| (host.to_owned(), key.to_owned()))
        .expect("an address and a key");
    let mut browser = Browser::open(&binary, &url, dir.join("profile"));

    // During the render: a frame drawn, the progress text, tiles outlined.
    let texts = "(() => { const t = (id) => document.getElementById(id).textContent; \
                 return { state: t('state'), spp: t('spp'), percent: t('percent'), \
                 pass: t('pass'), elapsed: t('elapsed'), eta: t('eta'), sps: t('sps'), \
                 mrays: t('mrays'), settings: t('settings'), scene: t('scene'), shown, \
                 tiles: last ? last.tiles.length : 0 }; })()";
    let during = browser.wait_for("a frame drawn during the render", texts, |v| {
        v["state"] == "rendering" && v["shown"].as_u64() > Some(0) && v["tiles"].as_u64() > Some(0)
    });
    let shot = browser.screenshot();
    let frame = decode(&http_get(&host, &format!("/{key}/frame.png")));
    let screen = image_on_screen(&mut browser, &shot);
    let during_path = save_for_people("during.png", &shot);
    assert_shows(&screen, &frame, "during the render");
    assert_eq!(during["scene"], "cover");
    let spp = during["spp"].as_str().unwrap();
    assert!(
        spp.ends_with(" / 256"),
        "samples per pixel done and to do: {spp}"
    );
    assert!(during["percent"].as_str().unwrap().ends_with('%'));
    assert!(
        during["pass"].as_str().unwrap().ends_with("of 5"),
        "{during}"
    );
    for field in ["elapsed", "eta", "sps", "mrays"] {
        let text = during[field].as_str().unwrap();
        assert!(
            text.chars().any(|c| c.is_ascii_digit()),
            "{field}: `{text}`"
        );
    }
    let settings = during["settings"].as_str().unwrap();
    assert!(
        settings.contains("400×266") && settings.contains("256 spp"),
        "{settings}"
    );
    let download_hidden = "document.getElementById('download').hidden";
    assert_eq!(browser.eval(download_hidden), true);

    // At the end: the final image, with its download link.
    browser.wait_for("the final frame", texts, |v| {
        v["state"] == "finished"
            && v["shown"].as_u64() == http_status(&host, &key)["frame"]["version"].as_u64()
    });
    let shot = browser.screenshot();
    let screen = image_on_screen(&mut browser, &shot);
    let end_path = save_for_people("finished.png", &shot);
    let image = image::open(dir.join("watched.png")).unwrap().to_rgb8();
    assert_shows(&screen, &image, "at the end");
    assert_eq!(browser.eval(download_hidden), false);
    // The page's own copy, taken with the run's token, even while the server stays.
    let href = browser.eval("document.getElementById('download').href");
    assert!(href.as_str().unwrap().starts_with("blob:"), "{href}");
    assert_eq!(
        browser.eval("document.getElementById('download').download"),
        "watched.png"
    );
    let _ = writeln!(
        std::io::stderr(),
        "browser screenshots: {} {}",
        during_path.display(),
        end_path.display()
    );
    drop(browser);
    held.recv_timeout(PATIENCE)
        .expect("tessera holds the final image");
    let _ = Command::new("kill")
        .args(["-INT", &viewer.0.id().to_string()])
        .status();
    let status = viewer.0.wait().unwrap();
    assert!(status.success(), "{status}");
}

/// Without `--preview-hold` the server goes when the render ends: the page keeps the image
/// file itself and its link still gives the very file afterwards. A small image is shown
/// enlarged by a whole factor with sharp pixels, not smoothed.
#[test]
fn a_page_keeps_the_final_image_after_the_viewer_has_gone() {
    let Some(binary) = browser_for("a_page_keeps_the_final_image") else {
        return;
    };
    let dir = temp_dir("browser-gone");
    let (mut viewer, url, _) = watched_render(
        &dir,
        &[
            "--width",
            "64",
            "--spp",
            "16384",
            "--threads",
            "1",
            "-o",
            "small.png",
        ],
    );
    let mut browser = Browser::open(&binary, &url, dir.join("profile"));
    let sizing = "(() => { const c = document.getElementById('image'); \
                  const r = c.getBoundingClientRect(); \
                  return { w: c.width, h: c.height, shown_w: r.width, shown_h: r.height, \
                  whole: c.classList.contains('whole'), \
                  rendering: getComputedStyle(c).imageRendering }; })()";
    let size = browser.wait_for("the first frame", sizing, |v| v["w"] == 64);
    let (w, shown) = (
        size["w"].as_f64().unwrap(),
        size["shown_w"].as_f64().unwrap(),
    );
    let k = shown / w;
    assert!(
        k >= 2.0 && k == k.round(),
        "64 pixels shown {shown} wide: not a whole factor ({size})"
    );
    assert_eq!(
        size["shown_h"].as_f64().unwrap(),
        size["h"].as_f64().unwrap() * k
    );
    assert_eq!(size["whole"], true);
    assert_eq!(size["rendering"], "pixelated", "{size}");
    let shot = browser.screenshot();
    save_for_people("small-enlarged.png", &shot);

    // The render ends and the server goes; the link is the page's own copy of the file.
    let status = viewer.0.wait().unwrap();
    assert!(status.success(), "{status}");
    let link = browser.wait_for(
        "the kept download",
        "(() => { const a = document.getElementById('download'); \
         return { hidden: a.hidden, href: a.href, name: a.download, \
         state: document.getElementById('state').textContent }; })()",
        |v| v["hidden"] == false && v["state"].as_str().is_some_and(|s| s.contains("closed")),
    );
    assert!(
        link["href"].as_str().unwrap().starts_with("blob:"),
        "{link}"
    );
    assert_eq!(link["name"], "small.png");
    // A click on the link saves the page's copy, as a person would.
    let downloads = dir.join("downloads");
    std::fs::create_dir_all(&downloads).unwrap();
    browser.call(
        "Page.setDownloadBehavior",
        json!({"behavior": "allow", "downloadPath": downloads.to_str().unwrap()}),
    );
    browser.eval("document.getElementById('download').click()");
    let saved = downloads.join("small.png");
    let start = Instant::now();
    while !saved.exists() {
        assert!(start.elapsed() < PATIENCE, "the click saved nothing");
        std::thread::sleep(Duration::from_millis(100));
    }
    // Chromium writes a download under another name and renames it when it is whole.
    let kept = std::fs::read(&saved).unwrap();
    let file = std::fs::read(dir.join("small.png")).unwrap();
    assert!(
        kept == file,
        "the page keeps another file than the render wrote"
    );
}

/// The page shows the output's path, a stranger's text of any length. A path of 40
/// directories of 40 letters (1,650 characters, no space) ran off the right edge of the
/// header, cut mid-word with no way to read the rest. It now breaks anywhere, stops at a few
/// lines (the whole in its tooltip), and the header keeps the window's width.
#[test]
fn a_long_output_path_keeps_the_page_s_header_in_the_window() {
    let Some(binary) = browser_for("a_long_output_path_keeps_the_page_s_header") else {
        return;
    };
    let dir = temp_dir("browser-long-path");
    let deep = vec!["d".repeat(40); 40].join("/");
    std::fs::create_dir_all(dir.join(&deep)).unwrap();
    let output = format!("{deep}/out.png");
    let flags = [
        "--width",
        "64",
        "--spp",
        "16384",
        "--threads",
        "1",
        "-o",
        &output,
    ];
    let (_viewer, url, _) = watched_render(&dir, &flags);
    let mut browser = Browser::open(&binary, &url, dir.join("profile"));
    let layout = "(() => { const box = (id) => document.getElementById(id).getBoundingClientRect(); \
                  const s = document.getElementById('settings'); \
                  return { width: window.innerWidth, height: window.innerHeight, \
                  settings: box('settings').right, scene: box('scene').right, \
                  state: box('state').right, stage: box('stage').height, \
                  tip: s.title, text: s.textContent.length }; })()";
    let v = browser.wait_for("the settings", layout, |v| v["text"].as_u64() > Some(1600));
    let width = v["width"].as_f64().unwrap();
    for part in ["settings", "scene", "state"] {
        assert!(
            v[part].as_f64().unwrap() <= width,
            "{part} runs off the window: {v}"
        );
    }
    let height = v["height"].as_f64().unwrap();
    assert!(
        v["stage"].as_f64().unwrap() > height / 2.0,
        "the image lost its room: {v}"
    );
    assert!(v["tip"].as_str().unwrap().ends_with(&output), "{v}");
}

/// A render whose process dies (killed, out of memory) leaves its page asking the port, key
/// and all, and another local user's program can take the port at once. Its answers, a
/// forged "finished" with a frame and a download of its own, were taken: the page showed
/// them and asked it for the frame. The page now takes only answers that carry its run's
/// token, which no request carries, and at the first that does not it stops asking.
#[test]
fn a_page_takes_nothing_from_whoever_has_the_port_after_its_server() {
    let Some(binary) = browser_for("a_page_takes_nothing_from_whoever_has_the_port") else {
        return;
    };
    let dir = temp_dir("browser-port-taken");
    let (mut viewer, url, _) = watched_render(
        &dir,
        &[
            "--width",
            "64",
            "--spp",
            "65536",
            "--threads",
            "1",
            "-o",
            "small.png",
        ],
    );
    let addr = url["http://".len()..].split('/').next().unwrap().to_owned();
    let mut browser = Browser::open(&binary, &url, dir.join("profile"));
    let state = "document.getElementById('state').textContent";
    browser.wait_for(
        "the first frame",
        "document.getElementById('image').width",
        |v| v == 64,
    );
    browser.wait_for("the render's status", state, |v| v == "rendering");

    // The render dies; another program takes the port and answers whatever it is asked.
    viewer.0.kill().unwrap();
    viewer.0.wait().unwrap();
    let start = Instant::now();
    let taken = loop {
        match std::net::TcpListener::bind(&addr) {
            Ok(l) => break l,
            Err(e) => assert!(start.elapsed() < PATIENCE, "{addr}: {e}"),
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    let forged = json!({
        "state": "finished", "spp_done": 9, "spp_max": 9, "spp_total": 9, "percent": 100.0,
        "pass": 1, "passes": 1, "pass_spp": 9, "elapsed_s": 1.0, "eta_s": 0.0,
        "samples_per_sec": 1.0, "mrays_per_sec": 1.0, "tiles": [],
        "frame": {"version": 999, "width": 64, "height": 43, "scale": 1},
        "download": {"name": "small.png", "bytes": 100},
        "about": {"scene": "forged", "scene_file": "forged.toml", "width": 64, "height": 43,
            "spp": 9, "max_depth": 5, "seed": 0, "shading": "path", "threads": 1, "tile": 16,
            "simd": "x", "region": [0, 0, 64, 43], "samples": [0, 9], "job": "whole image",
            "output": "small.png", "held": true}
    })
    .to_string();
    let asked = std::sync::Arc::new(std::sync::Mutex::new(Vec::<String>::new()));
    {
        let asked = std::sync::Arc::clone(&asked);
        std::thread::spawn(move || {
            for stream in taken.incoming() {
                let Ok(mut stream) = stream else { continue };
                let mut head = Vec::new();
                let mut byte = [0u8; 1];
                while !head.ends_with(b"\r\n\r\n") && stream.read(&mut byte).unwrap_or(0) == 1 {
                    head.push(byte[0]);
                }
                let line = String::from_utf8_lossy(&head);
                let path = line.split(' ').nth(1).unwrap_or("").to_owned();
                asked.lock().unwrap().push(path.clone());
                let answer = if path.ends_with("/events") {
                    format!(
                        "HTTP/1.1 200 OK\r\ncontent-type: text/event-stream\r\n\r\n\
                         event: status\ndata: {forged}\n\n"
                    )
                } else {
                    format!(
                        "HTTP/1.1 200 OK\r\ncontent-type: application/json\r\n\
                         content-length: {}\r\n\r\n{forged}",
                        forged.len()
                    )
                };
                let _ = stream.write_all(answer.as_bytes());
                std::thread::spawn(move || {
                    std::thread::sleep(Duration::from_secs(5));
                    drop(stream);
                });
            }
        });
    }
    browser.wait_for("the page to be asked of another", state, |v| {
        v != "rendering" && v != "connecting"
    });
    std::thread::sleep(Duration::from_secs(4));
    let shown = browser.eval(
        "(() => ({ state: document.getElementById('state').textContent, \
         scene: document.getElementById('scene').textContent, \
         link: !document.getElementById('download').hidden }))()",
    );
    let asked = asked.lock().unwrap().clone();
    assert_eq!(
        shown["state"], "connection lost",
        "{shown}; asked {asked:?}"
    );
    assert_ne!(shown["scene"], "forged", "{shown}");
    assert_eq!(shown["link"], false, "{shown}");
    assert!(
        !asked.is_empty() && asked.iter().all(|p| !p.contains("frame.png")),
        "{asked:?}"
    );
    assert!(asked.len() <= 2, "the page went on asking: {asked:?}");
}

/// With `--preview-hold` the finished page linked to the server's `download`: a link the
/// browser follows without the page seeing the answer. Once the held server had stopped
/// (Ctrl-C), a program that took its port and answered the event stream's reconnection
/// with a 404 closed the stream after one error, so the page never said "connection lost"
/// and kept the link, and a click saved that program's file under its name. The page now
/// keeps its own copy of the file, taken with the run's token, held or not, and a stream
/// that cannot reconnect is lost at once.
#[test]
fn a_held_page_s_download_is_never_another_program_s_file() {
    let Some(binary) = browser_for("a_held_page_s_download_is_never_another_program_s_file") else {
        return;
    };
    let dir = temp_dir("browser-held-port-taken");
    let (mut viewer, url, held) = watched_render(
        &dir,
        &[
            "--width",
            "64",
            "--spp",
            "16",
            "--threads",
            "1",
            "-o",
            "small.png",
            "--preview-hold",
        ],
    );
    let addr = url["http://".len()..].split('/').next().unwrap().to_owned();
    let mut browser = Browser::open(&binary, &url, dir.join("profile"));
    let link = "(() => { const a = document.getElementById('download'); \
                return { hidden: a.hidden, href: a.href, name: a.download, \
                state: document.getElementById('state').textContent }; })()";
    browser.wait_for("the download offered", link, |v| {
        v["hidden"] == false && v["state"] == "finished"
    });
    held.recv_timeout(PATIENCE)
        .expect("tessera holds the final image");

    // The held viewer is stopped; another program takes the port at once and refuses the
    // event stream, but has a file of its own to download.
    let _ = Command::new("kill")
        .args(["-INT", &viewer.0.id().to_string()])
        .status();
    viewer.0.wait().unwrap();
    let start = Instant::now();
    let taken = loop {
        match std::net::TcpListener::bind(&addr) {
            Ok(l) => break l,
            Err(e) => assert!(start.elapsed() < PATIENCE, "{addr}: {e}"),
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    let forged = b"not the render".to_vec();
    std::thread::spawn(move || {
        for stream in taken.incoming() {
            let Ok(mut stream) = stream else { continue };
            let mut head = Vec::new();
            let mut byte = [0u8; 1];
            while !head.ends_with(b"\r\n\r\n") && stream.read(&mut byte).unwrap_or(0) == 1 {
                head.push(byte[0]);
            }
            let line = String::from_utf8_lossy(&head);
            let path = line.split(' ').nth(1).unwrap_or("").to_owned();
            let answer = if path.ends_with("/download") {
                let mut a = format!(
                    "HTTP/1.1 200 OK\r\ncontent-type: image/png\r\n\
                     content-disposition: attachment; filename=\"small.png\"\r\n\
                     content-length: {}\r\nconnection: close\r\n\r\n",
                    forged.len()
                )
                .into_bytes();
                a.extend_from_slice(&forged);
                a
            } else {
                b"HTTP/1.1 404 Not Found\r\ncontent-length: 0\r\nconnection: close\r\n\r\n".to_vec()
            };
            let _ = stream.write_all(&answer);
        }
    });
    std::thread::sleep(Duration::from_secs(6));
    let shown = browser.eval(link);
    // A click on the link, if there is one, saves the page's copy of the render's file.
    let downloads = dir.join("downloads");
    std::fs::create_dir_all(&downloads).unwrap();
    browser.call(
        "Page.setDownloadBehavior",
        json!({"behavior": "allow", "downloadPath": downloads.to_str().unwrap()}),
    );
    browser.eval("document.getElementById('download').click()");
    std::thread::sleep(Duration::from_secs(3));
    let saved = std::fs::read(downloads.join("small.png")).ok();
    if shown["hidden"] == false {
        assert!(
            shown["href"].as_str().unwrap().starts_with("blob:"),
            "{shown}; the click saved {saved:?}"
        );
        let file = std::fs::read(dir.join("small.png")).unwrap();
        assert!(saved == Some(file), "{shown}: the click saved another file");
    } else {
        assert_eq!(saved, None, "{shown}");
    }
    assert_ne!(
        shown["state"], "finished",
        "{shown}: the page did not see its server go"
    );
}

/// The browser to run the test `test` with: None (the test returns) where heavy tests are
/// off, or where there is no Chromium, said as a skip.
fn browser_for(test: &str) -> Option<PathBuf> {
    if !heavy("a browser test") {
        return None;
    }
    let binary = chromium();
    if binary.is_none() {
        skip(
            test,
            "no chromium (Debian's `chromium` package; or set TESSERA_CHROMIUM)",
        );
    }
    binary
}

/// Starts `tessera render` of the cover in `dir` with `flags` and `--preview`, and gives it,
/// the address it prints, and a channel told when it says it holds the final image (with
/// `--preview-hold`; the rest of its messages are read and dropped).
fn watched_render(dir: &Path, flags: &[&str]) -> (KillOnDrop, String, Receiver<()>) {
    let mut viewer = KillOnDrop(
        tessera()
            .args(["render", &cover()])
            .args(flags)
            .arg("--preview")
            .current_dir(dir)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start tessera"),
    );
    let mut err = BufReader::new(viewer.0.stderr.take().unwrap()).lines();
    let url = loop {
        let line = err.next().expect("tessera prints the address").unwrap();
        if let Some(rest) = line.strip_prefix("tessera: preview at ") {
            break rest.to_owned();
        }
    };
    let (held_tx, held) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in err.map_while(Result::ok) {
            if line.contains("until Ctrl-C") {
                let _ = held_tx.send(());
            }
        }
    });
    (viewer, url, held)
}

fn http_status(host: &str, key: &str) -> Value {
    serde_json::from_slice(&http_get(host, &format!("/{key}/status"))).expect("status JSON")
}

fn decode(bytes: &[u8]) -> image::RgbImage {
    image::load_from_memory(bytes).expect("a PNG").to_rgb8()
}

/// A child process killed when the test ends, however it ends.
struct KillOnDrop(Child);

impl Drop for KillOnDrop {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// The results report (`tessera results report`) as a person opens it: every line ranked,
/// its charts drawn, a CPU model full of markup shown as text and run as nothing, and on a
/// phone's width no sideways scrolling of the page.
#[test]
fn the_results_report_reads_in_a_browser_on_a_desktop_and_a_phone() {
    let Some(binary) = browser_for("the_results_report_reads_in_a_browser") else {
        return;
    };
    let dir = temp_dir("browser-report");
    let db = dir.join("r.db");
    let bench = |simd: &str, out: &str| {
        let o = tessera()
            .args([
                "bench",
                &cover(),
                "--width",
                "64",
                "--spp",
                "2",
                "--repeat",
                "2",
            ])
            .args(["--warmup", "0", "--simd", simd, "--out", out])
            .env("TESSERA_DB", &db)
            .current_dir(&dir)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", stderr(&o));
    };
    bench("portable", "portable.json");
    bench("auto", "auto.json");
    let mut evil: Value =
        serde_json::from_slice(&std::fs::read(dir.join("auto.json")).unwrap()).unwrap();
    let markup =
        "<script>document.title='pwned'</script><img src=x onerror=\"document.title='pwned'\">";
    evil["host"]["cpu_model"] = Value::from(markup);
    evil["host"]["machine_id"] = Value::from("m-0123456789abcdef");
    evil["method"]["started_unix_s"] = Value::from(1_700_000_000u64);
    std::fs::write(dir.join("evil.json"), evil.to_string()).unwrap();
    let ok_in = |args: &[&str]| {
        let o = tessera()
            .args(args)
            .env("TESSERA_DB", &db)
            .current_dir(&dir)
            .output()
            .unwrap();
        assert!(o.status.success(), "{args:?}: {}", stderr(&o));
    };
    ok_in(&["results", "import", "evil.json"]);
    ok_in(&["results", "report", "-o", "report.html", "--all"]);
    let page = std::fs::read_to_string(dir.join("report.html")).unwrap();
    assert!(
        !page.contains("<script") && !page.contains("<img"),
        "markup got through"
    );
    assert!(
        !page.contains("http://") && !page.contains("https://"),
        "it refers elsewhere"
    );

    let url = format!("file://{}", dir.join("report.html").display());
    let mut browser = Browser::open(&binary, &url, dir.join("profile"));
    // The report itself loaded, not the blank page Chromium may show before it (complete
    // too: CI once counted its zero rows).
    let loaded = "location.protocol === 'file:' && document.readyState === 'complete'";
    browser.wait_for("the page", loaded, |v| v == true);
    assert_eq!(
        browser.eval("document.querySelectorAll('table.rank tbody tr').length"),
        3
    );
    assert!(
        browser
            .eval("document.querySelectorAll('svg polyline').length")
            .as_u64()
            >= Some(3)
    );
    assert_eq!(
        browser.eval("document.querySelectorAll('script, img').length"),
        0
    );
    let title = browser.eval("document.title");
    assert!(!title.as_str().unwrap().contains("pwned"), "{title}");
    let text = browser.eval("document.body.innerText");
    assert!(
        text.as_str().unwrap().contains("<script>"),
        "the CPU model is not shown as text"
    );
    let desktop = browser.screenshot();
    println!(
        "{}",
        save_for_people("results-report.png", &desktop).display()
    );

    browser.call(
        "Emulation.setDeviceMetricsOverride",
        json!({"width": 390, "height": 844, "deviceScaleFactor": 1, "mobile": true}),
    );
    browser.call("Page.reload", json!({}));
    browser.wait_for("the page again", loaded, |v| v == true);
    let overflow = browser.eval("document.documentElement.scrollWidth - window.innerWidth");
    assert!(
        overflow.as_i64() <= Some(0),
        "the page scrolls sideways by {overflow} px on a phone"
    );
    // Each line is a card with its score on screen, not off to the right.
    let score = browser.eval(
        "(() => { const s = document.querySelector('table.rank td.score').getBoundingClientRect(); \
          return [s.left, s.right, s.width, window.innerWidth]; })()",
    );
    let s: Vec<f64> = (score.as_array().unwrap().iter())
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert!(
        s[0] >= 0.0 && s[1] <= s[3] && s[2] > 0.0,
        "the score is off the screen: {score}"
    );
    let phone = browser.screenshot();
    assert_eq!(phone.width(), 390);
    println!(
        "{}",
        save_for_people("results-report-phone.png", &phone).display()
    );
}
