//! The live preview as a user and a hostile client meet it: the viewer's HTTP answers over a
//! plain TCP socket, statuses that only grow, frames that decode, a final frame equal to the
//! batch render, the server's limits while a render runs, errors before a render starts,
//! and the preview file with shards, sample ranges and checkpoints. The image of a watched
//! render is byte-identical to an unwatched one.

use crate::common::*;
use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::Path;
use std::process::{Child, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// The longest a test waits for anything; a hang guard, not a measure of speed.
const PATIENCE: Duration = Duration::from_secs(120);

/// A `tessera render --preview` running in the background, its standard error collected.
struct Viewer {
    child: Child,
    addr: SocketAddr,
    /// The key every path begins with, from the address printed.
    key: String,
    stderr: Arc<Mutex<String>>,
}

impl Viewer {
    /// Starts tessera with `args` in `dir` and waits for it to print the viewer's address.
    fn start(args: &[&str], dir: &Path) -> Viewer {
        let mut command = tessera();
        command.args(args);
        Viewer::start_command(command, dir)
    }

    /// Starts `command` (tessera, or a shell that runs it) in `dir` and waits for it to print
    /// the viewer's address.
    fn start_command(mut command: std::process::Command, dir: &Path) -> Viewer {
        let mut child = command
            .current_dir(dir)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start tessera");
        let stderr = Arc::new(Mutex::new(String::new()));
        let (found, address) = std::sync::mpsc::channel();
        {
            let stderr = Arc::clone(&stderr);
            let pipe = child.stderr.take().unwrap();
            std::thread::spawn(move || {
                for line in BufReader::new(pipe).lines().map_while(Result::ok) {
                    if let Some(rest) = line.strip_prefix("tessera: preview at http://") {
                        let _ = found.send(rest.trim_end_matches('/').to_owned());
                    }
                    let mut all = stderr.lock().unwrap();
                    all.push_str(&line);
                    all.push('\n');
                }
            });
        }
        let (addr, key) = match address.recv_timeout(PATIENCE) {
            Ok(a) => {
                let (addr, key) = a.split_once('/').expect("an address and a key");
                (addr.parse().expect("an address"), key.to_owned())
            }
            Err(_) => {
                let _ = child.kill();
                panic!("no preview address: {}", stderr.lock().unwrap());
            }
        };
        assert_eq!(key.len(), 32, "a key of 128 bits in hex: {key}");
        Viewer {
            child,
            addr,
            key,
            stderr,
        }
    }

    /// The answer to a GET of `path` under the viewer's key.
    fn get(&self, path: &str) -> Answer {
        self.get_raw(&format!("/{}{path}", self.key))
    }

    /// The answer to a GET of `path` as it is.
    fn get_raw(&self, path: &str) -> Answer {
        request(
            self.addr,
            &format!("GET {path} HTTP/1.1\r\n{}", self.host()),
        )
    }

    fn host(&self) -> String {
        format!("Host: {}\r\nConnection: close\r\n\r\n", self.addr)
    }

    /// The status as JSON. A 503 ("too many viewers") is waited out, within `PATIENCE`: a
    /// test's own closed connections hold their places until the server sees them close.
    fn status(&self) -> serde_json::Value {
        let start = Instant::now();
        loop {
            let a = self.get("/status");
            if a.code == 503 && start.elapsed() < PATIENCE {
                std::thread::sleep(Duration::from_millis(30));
                continue;
            }
            assert_eq!(a.code, 200, "{}", a.text());
            return serde_json::from_slice(&a.body).expect("status is JSON");
        }
    }

    /// Polls the status until `done` says so.
    fn wait_for(&self, what: &str, done: impl Fn(&serde_json::Value) -> bool) -> serde_json::Value {
        let start = Instant::now();
        loop {
            let s = self.status();
            if done(&s) {
                return s;
            }
            assert!(
                start.elapsed() < PATIENCE,
                "waited too long for {what}: {s}"
            );
            std::thread::sleep(Duration::from_millis(30));
        }
    }

    /// Waits for a finished render's `--preview-hold` message, then sends SIGINT: the
    /// status says `finished` before the viewer starts holding, and a Ctrl-C sent in between
    /// would end tessera by the default action (or be lost where SIGINT is ignored, as in a
    /// shell's background job).
    fn interrupt_held(self) -> (i32, String) {
        let start = Instant::now();
        while !self.stderr.lock().unwrap().contains("until Ctrl-C") {
            assert!(
                start.elapsed() < PATIENCE,
                "no hold message: {}",
                self.stderr.lock().unwrap()
            );
            std::thread::sleep(Duration::from_millis(20));
        }
        self.interrupt()
    }

    /// Sends SIGINT (Ctrl-C) and waits for the exit status.
    fn interrupt(mut self) -> (i32, String) {
        let _ = std::process::Command::new("kill")
            .args(["-INT", &self.child.id().to_string()])
            .status();
        let code = self.wait();
        (code, self.stderr.lock().unwrap().clone())
    }

    fn wait(&mut self) -> i32 {
        let start = Instant::now();
        loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                // Let the reader thread take the last lines.
                std::thread::sleep(Duration::from_millis(50));
                return status.code().unwrap_or(-1);
            }
            if start.elapsed() > PATIENCE {
                let _ = self.child.kill();
                panic!("tessera did not end: {}", self.stderr.lock().unwrap());
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

impl Drop for Viewer {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// An HTTP answer: status code, headers (lower-case names) and body.
struct Answer {
    code: u16,
    headers: Vec<(String, String)>,
    body: Vec<u8>,
}

impl Answer {
    fn header(&self, name: &str) -> Option<&str> {
        (self.headers.iter())
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_str())
    }

    fn text(&self) -> String {
        String::from_utf8_lossy(&self.body).into_owned()
    }
}

/// Sends `raw` (a whole request, `Connection: close`) and reads the answer to the end.
fn request(addr: SocketAddr, raw: &str) -> Answer {
    let mut stream = TcpStream::connect_timeout(&addr, PATIENCE).expect("connect");
    stream.set_read_timeout(Some(PATIENCE)).unwrap();
    stream.write_all(raw.as_bytes()).expect("send");
    let mut bytes = Vec::new();
    let _ = stream.read_to_end(&mut bytes);
    parse_answer(&bytes)
}

fn parse_answer(bytes: &[u8]) -> Answer {
    let end = (bytes.windows(4))
        .position(|w| w == b"\r\n\r\n")
        .unwrap_or_else(|| panic!("no header end in {:?}", String::from_utf8_lossy(bytes)));
    let head = String::from_utf8_lossy(&bytes[..end]).into_owned();
    let mut lines = head.split("\r\n");
    let code = (lines.next().unwrap().split(' ').nth(1))
        .and_then(|c| c.parse().ok())
        .expect("a status code");
    let headers = lines
        .filter_map(|l| l.split_once(':'))
        .map(|(n, v)| (n.trim().to_ascii_lowercase(), v.trim().to_owned()))
        .collect();
    Answer {
        code,
        headers,
        body: bytes[end + 4..].to_vec(),
    }
}

fn decode_png(bytes: &[u8]) -> image::RgbImage {
    image::load_from_memory_with_format(bytes, image::ImageFormat::Png)
        .expect("a PNG")
        .to_rgb8()
}

/// The cover at `width`, as arguments.
fn cover_args(width: u32, spp: u32) -> Vec<String> {
    vec![
        "render".into(),
        cover(),
        "--width".into(),
        width.to_string(),
        "--spp".into(),
        spp.to_string(),
    ]
}

fn strs(args: &[String]) -> Vec<&str> {
    args.iter().map(String::as_str).collect()
}

/// Renders `args` unwatched to `plain.png` in `dir` and checks that `watched` has its bytes.
fn assert_unwatched_bytes(dir: &Path, mut args: Vec<String>, watched: &str) {
    args.extend(["-o", "plain.png"].map(String::from));
    ok(&strs(&args), dir);
    assert_eq!(
        std::fs::read(dir.join("plain.png")).unwrap(),
        std::fs::read(dir.join(watched)).unwrap(),
        "{watched} differs from a render nobody watched"
    );
}

#[test]
fn a_watched_render_shows_growing_frames_and_ends_with_the_batch_image() {
    let dir = temp_dir("preview-watch");
    let mut args = cover_args(240, 128);
    args.extend(
        [
            "--threads",
            "1",
            "-o",
            "watched.png",
            "--preview",
            "--preview-hold",
        ]
        .map(String::from),
    );
    let viewer = Viewer::start(&strs(&args), &dir);
    let (mut spp, mut frames, mut last_version) = (Vec::new(), 0, 0);
    let mut percent = Vec::new();
    let finished = loop {
        let s = viewer.status();
        spp.push(s["spp_done"].as_u64().unwrap());
        percent.push(s["percent"].as_f64().unwrap());
        let version = s["frame"]["version"].as_u64().unwrap();
        if version > last_version && frames < 4 {
            let a = viewer.get("/frame.png");
            assert_eq!(a.code, 200);
            assert_eq!(a.header("content-type"), Some("image/png"));
            let img = decode_png(&a.body);
            assert_eq!(img.dimensions(), (240, 160));
            frames += 1;
            last_version = version;
        }
        if s["state"] == "finished" {
            break s;
        }
        assert_eq!(s["state"], "rendering");
        std::thread::sleep(Duration::from_millis(40));
    };
    assert!(spp.is_sorted(), "samples per pixel went down: {spp:?}");
    assert!(percent.is_sorted(), "percent went down: {percent:?}");
    assert!(frames >= 2, "saw {frames} frames");
    assert_eq!(finished["spp_done"], 128);
    assert_eq!(finished["spp_total"], 128);
    assert_eq!(finished["percent"], 100.0);
    assert_eq!(finished["about"]["scene"], "cover");
    assert_eq!(finished["about"]["width"], 240);
    assert_eq!(finished["passes"], 5);
    // The final frame holds the image file's pixels, and the download is the very file,
    // recipe included, under its own name.
    let last = viewer.get("/frame.png");
    let watched = image::open(dir.join("watched.png")).unwrap().to_rgb8();
    assert!(decode_png(&last.body) == watched, "the final frame differs");
    let file = std::fs::read(dir.join("watched.png")).unwrap();
    assert_eq!(finished["about"]["held"], true);
    assert_eq!(finished["download"]["name"], "watched.png");
    assert_eq!(finished["download"]["bytes"], file.len());
    let download = viewer.get("/download");
    assert_eq!(download.code, 200);
    assert_eq!(download.header("content-type"), Some("image/png"));
    assert!((download.header("content-disposition").unwrap()).contains("filename=\"watched.png\""));
    assert!(
        download.body == file,
        "the download is not the file the render wrote"
    );
    let (code, stderr) = viewer.interrupt_held();
    assert_eq!(code, 0, "Ctrl-C ends a held viewer cleanly: {stderr}");
    assert!(stderr.contains("until Ctrl-C"), "{stderr}");
    let mut plain = cover_args(240, 128);
    plain.extend(["--threads", "1"].map(String::from));
    assert_unwatched_bytes(&dir, plain, "watched.png");
}

#[test]
fn the_page_its_assets_and_the_event_stream_are_served() {
    let dir = temp_dir("preview-page");
    let mut args = cover_args(64, 8);
    args.extend(["-o", "a.png", "--preview=127.0.0.1:0", "--preview-hold"].map(String::from));
    let viewer = Viewer::start(&strs(&args), &dir);
    viewer.wait_for("the end", |s| s["state"] == "finished");
    let page = viewer.get("/");
    assert_eq!(page.code, 200);
    assert!(
        page.header("content-type")
            .unwrap()
            .starts_with("text/html")
    );
    assert!(page.header("content-security-policy").is_some());
    let html = page.text();
    for asset in ["/viewer.css", "/viewer.js"] {
        // Relative to the key's folder, the page's own.
        assert!(
            html.contains(&format!("\"{}\"", &asset[1..])),
            "the page links {asset}"
        );
        let a = viewer.get(asset);
        assert_eq!(a.code, 200, "{asset}");
        assert!(a.body.len() > 500, "{asset} is there");
    }
    assert!(
        !html.contains("http://") && !html.contains("https://"),
        "nothing from outside"
    );
    // The run's token: in the page, with every answer and first in the event stream, and
    // not the key (which every request carries): a program that takes the port after the
    // server has gone cannot send it, and the page takes nothing without it.
    let slot = "<meta name=\"tessera-run\" content=\"";
    let run = html
        .split(slot)
        .nth(1)
        .expect("the page holds its run's token");
    let run = &run[..run.find('"').unwrap()];
    assert!(
        run.len() == 32 && run.bytes().all(|c| c.is_ascii_hexdigit()) && run != viewer.key,
        "{run}"
    );
    for path in ["/", "/status", "/frame.png", "/download"] {
        assert_eq!(
            viewer.get(path).header("x-tessera-run"),
            Some(run),
            "{path}"
        );
    }
    let head = request(
        viewer.addr,
        &format!(
            "HEAD /{}/frame.png HTTP/1.1\r\n{}",
            viewer.key,
            viewer.host()
        ),
    );
    assert_eq!(head.code, 200);
    assert!(head.body.is_empty(), "HEAD has no body");
    // The event stream sends the latest status at once.
    let mut stream = events_of(&viewer);
    let mut seen = Vec::new();
    let mut buf = [0u8; 4096];
    while !String::from_utf8_lossy(&seen).contains("\"state\":\"finished\"") {
        let n = stream.read(&mut buf).expect("events arrive");
        assert!(
            n > 0,
            "the stream closed: {}",
            String::from_utf8_lossy(&seen)
        );
        seen.extend_from_slice(&buf[..n]);
    }
    let text = String::from_utf8_lossy(&seen);
    assert!(text.contains("text/event-stream"), "{text}");
    assert!(text.contains("event: status\ndata: {"), "{text}");
    let first = text.find("event: ").unwrap();
    assert!(
        text[first..].starts_with(&format!("event: run\ndata: {run}\n\n")),
        "{text}"
    );
    drop(stream);
    assert_eq!(viewer.interrupt_held().0, 0);
}

/// tessera with `args` where no file can grow past 0 bytes (`ulimit -f 0`), as on a full
/// disk: every write of an output fails.
fn with_no_room_to_write(args: &[String]) -> std::process::Command {
    let mut command = std::process::Command::new("sh");
    command
        .args(["-c", "ulimit -f 0 && exec \"$0\" \"$@\""])
        .arg(env!("CARGO_BIN_EXE_tessera"))
        .args(args);
    command
}

/// A render whose output cannot be written (here past the file size limit, as on a full
/// disk) tells its viewer it failed before the viewer goes: the page was left showing a
/// render at 100% "rendering", its stream cut, waiting for an image that never came.
#[test]
fn a_render_whose_output_cannot_be_written_tells_its_viewer_it_failed() {
    for output in ["a.png", "a.part"] {
        let dir = temp_dir("preview-failed-output");
        let mut args = cover_args(160, 64);
        args.extend(["--threads", "1", "-o", output, "--preview"].map(String::from));
        if output.ends_with(".part") {
            args.extend(["--shard", "0/1"].map(String::from));
        }
        let mut viewer = Viewer::start_command(with_no_room_to_write(&args), &dir);
        let mut stream = events_of(&viewer);
        // The stream to its end: the server goes after the last status.
        let mut seen = Vec::new();
        let _ = stream.read_to_end(&mut seen);
        let (text, last) = last_status(&seen);
        assert_eq!(last["state"], "failed", "{output}: {text}");
        assert_eq!(last["percent"], 100.0, "{output}");
        assert!(last["download"].is_null(), "{output}: {last}");
        let code = viewer.wait();
        let stderr = viewer.stderr.lock().unwrap().clone();
        assert_eq!(code, 2, "{output}: {stderr}");
        assert!(stderr.contains("File too large"), "{output}: {stderr}");
        assert!(!dir.join(output).exists(), "{output}");
    }
}

/// A stream of `viewer`'s events, opened: what a page reads.
fn events_of(viewer: &Viewer) -> TcpStream {
    let mut stream = TcpStream::connect(viewer.addr).unwrap();
    stream.set_read_timeout(Some(PATIENCE)).unwrap();
    write!(
        stream,
        "GET /{}/events HTTP/1.1\r\nHost: {}\r\n\r\n",
        viewer.key, viewer.addr
    )
    .unwrap();
    stream
}

/// Sends the signal `signal` ("INT", "TERM") to `viewer`'s render while its event stream
/// is read to its end (the server goes after the last status): the render's exit status,
/// what it said, and the stream.
fn signalled(viewer: &mut Viewer, signal: &str) -> (i32, String, Vec<u8>) {
    let mut stream = events_of(viewer);
    let _ = std::process::Command::new("kill")
        .args([&format!("-{signal}"), &viewer.child.id().to_string()])
        .status();
    let mut seen = Vec::new();
    let _ = stream.read_to_end(&mut seen);
    let code = viewer.wait();
    let stderr = viewer.stderr.lock().unwrap().clone();
    (code, stderr, seen)
}

/// The text of an event stream read to its end, and the last status it gave.
fn last_status(seen: &[u8]) -> (String, serde_json::Value) {
    let text = String::from_utf8_lossy(seen).into_owned();
    let last = text
        .rsplit("event: status\ndata: ")
        .next()
        .and_then(|data| data.lines().next())
        .expect("a status");
    let last = serde_json::from_str(last).expect("a status is JSON");
    (text, last)
}

/// An interrupted render whose checkpoint cannot be written has lost its progress: its page
/// said "interrupted", as if the progress were saved, while the terminal said it was not
/// (exit 2). The page now says it failed, as the docs promise for a checkpoint not written.
#[test]
fn an_interrupted_render_whose_checkpoint_cannot_be_written_tells_its_viewer_it_failed() {
    let dir = temp_dir("preview-failed-checkpoint");
    let mut args = cover_args(400, 256);
    args.extend(
        [
            "--threads",
            "1",
            "-o",
            "out.png",
            "--checkpoint",
            "c.part",
            "--checkpoint-every",
            "3600",
            "--preview",
        ]
        .map(String::from),
    );
    let mut viewer = Viewer::start_command(with_no_room_to_write(&args), &dir);
    viewer.wait_for("the second pass", |s| s["spp_done"].as_u64() >= Some(4));
    let (code, stderr, seen) = signalled(&mut viewer, "INT");
    if code == 0 {
        return skip(
            "an_interrupted_render_whose_checkpoint_cannot_be_written",
            "the render ended before Ctrl-C",
        );
    }
    assert_eq!(code, 2, "{stderr}");
    assert!(stderr.contains("could not be saved"), "{stderr}");
    let (text, last) = last_status(&seen);
    assert_eq!(last["state"], "failed", "{text}");
    assert!(last["download"].is_null(), "{last}");
}

/// A watched render without `--checkpoint` had no signal handler: Ctrl-C or SIGTERM ended
/// it at once, and its page said "connection lost" where the docs promise "interrupted". It
/// now stops, tells its viewer it was interrupted, writes no image and exits 130.
#[test]
fn a_watched_render_without_a_checkpoint_tells_its_viewer_it_was_interrupted() {
    for signal in ["INT", "TERM"] {
        let dir = temp_dir(&format!("preview-interrupted-{signal}"));
        let mut args = cover_args(400, 256);
        args.extend(["--threads", "1", "-o", "out.png", "--preview"].map(String::from));
        let mut viewer = Viewer::start(&strs(&args), &dir);
        viewer.wait_for("the second pass", |s| s["spp_done"].as_u64() >= Some(4));
        let (code, stderr, seen) = signalled(&mut viewer, signal);
        if code == 0 {
            return skip(
                "a_watched_render_without_a_checkpoint_tells_its_viewer",
                "the render ended before the signal",
            );
        }
        assert_eq!(code, 130, "SIG{signal}: {stderr}");
        assert!(stderr.contains("interrupted at"), "{stderr}");
        assert!(stderr.contains("nothing is saved"), "{stderr}");
        assert!(!dir.join("out.png").exists(), "SIG{signal}");
        let (text, last) = last_status(&seen);
        assert_eq!(last["state"], "interrupted", "SIG{signal}: {text}");
        assert!(last["download"].is_null(), "{last}");
    }
}

/// A preview file that leads to standard output redirected to a file (a link `p.png` to
/// `/dev/stdout`, `> shown.png`) was written in place: each frame was added after the last,
/// and a 200x133 render left four PNGs one after another (203,460 bytes) in a file that
/// showed only the first. It is refused before the render, as `/dev/stdout` named itself
/// is, by its extension.
#[test]
fn a_preview_file_that_leads_to_redirected_standard_output_is_refused() {
    let dir = temp_dir("preview-file-stdout");
    std::os::unix::fs::symlink("/dev/stdout", dir.join("p.png")).unwrap();
    let shown = dir.join("shown.png");
    let o = tessera()
        .args([
            "render",
            &cover(),
            "--width",
            "32",
            "--spp",
            "4",
            "-o",
            "out.png",
            "--preview-file",
            "p.png",
        ])
        .current_dir(&dir)
        .stdout(std::fs::File::create(&shown).unwrap())
        .output()
        .unwrap();
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("--preview-file: p.png is not a file of its own"),
        "{err}"
    );
    assert_eq!(std::fs::metadata(&shown).unwrap().len(), 0);
    assert!(!dir.join("out.png").exists());
    let o = run(
        &[
            "render",
            &cover(),
            "--width",
            "32",
            "-o",
            "out.png",
            "--preview-file",
            "/dev/stdout",
        ],
        &dir,
    );
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("--preview-file must name a .png file, not /dev/stdout"),
        "{err}"
    );
}

/// A scene file's name and an output's are text a stranger may choose (a scene handed over
/// under its name): a right-to-left override (U+202E) in them reached the viewer's page raw
/// and reversed what it showed of the scene, the title, the output and the download's name
/// (`cov\u{202e}gnp` shows as "covpng"), and a terminal escape came along. The status now
/// carries every such character as a `\u{…}` escape, as the terminal shows it.
#[test]
fn the_viewer_shows_a_stranger_s_names_escaped() {
    let dir = temp_dir("preview-names");
    let scene = "cov\u{202e}gnp.toml";
    std::fs::write(dir.join(scene), GOOD).unwrap();
    let output = "o\u{202e}\u{1b}[31mx.png";
    let viewer = Viewer::start(
        &[
            "render",
            scene,
            "-o",
            output,
            "--preview=127.0.0.1:0",
            "--preview-hold",
        ],
        &dir,
    );
    let status = viewer.wait_for("the end", |s| {
        s["state"] == "finished" && !s["download"].is_null()
    });
    let shown = [
        &status["about"]["scene"],
        &status["about"]["scene_file"],
        &status["about"]["output"],
        &status["download"]["name"],
    ];
    for text in shown.map(|v| v.as_str().unwrap_or_default()) {
        assert!(
            !text.chars().any(|c| c == '\u{202e}' || c.is_control()),
            "raw in the page: {text:?}"
        );
        assert!(text.contains("\\u{202e}"), "{text:?}");
    }
    assert!(dir.join(output).is_file(), "the image keeps its own name");
    assert_eq!(viewer.interrupt_held().0, 0);
}

/// A page of another origin that names the viewer in an `<img>` gets the image (the
/// browser sends the viewer's own loopback Host): measured with Chromium, a page on
/// `http://localhost:PORT2` loaded `/download` and read its 300x200 size. Every answer says
/// `Cross-Origin-Resource-Policy: same-origin`, so browsers refuse such loads.
#[test]
fn every_answer_keeps_other_origins_pages_from_loading_it() {
    let dir = temp_dir("preview-corp");
    let mut args = cover_args(64, 8);
    args.extend(["-o", "a.png", "--preview=127.0.0.1:0", "--preview-hold"].map(String::from));
    let viewer = Viewer::start(&strs(&args), &dir);
    viewer.wait_for("the end", |s| s["state"] == "finished");
    let answers = [
        ("/", viewer.get("/")),
        ("/viewer.js", viewer.get("/viewer.js")),
        ("/status", viewer.get("/status")),
        ("/frame.png", viewer.get("/frame.png")),
        ("/download", viewer.get("/download")),
        ("/nothing", viewer.get("/nothing")),
        (
            "HEAD /events",
            request(
                viewer.addr,
                &format!("HEAD /{}/events HTTP/1.1\r\n{}", viewer.key, viewer.host()),
            ),
        ),
        (
            "a foreign Host",
            request(
                viewer.addr,
                &format!(
                    "GET /{}/download HTTP/1.1\r\nHost: evil.example\r\nConnection: close\r\n\r\n",
                    viewer.key
                ),
            ),
        ),
    ];
    for (what, answer) in &answers {
        assert_eq!(
            answer.header("cross-origin-resource-policy"),
            Some("same-origin"),
            "{what}: {} {:?}",
            answer.code,
            answer.headers
        );
    }
    assert_eq!(answers[4].1.code, 200, "the download is served");
    assert_eq!(viewer.interrupt_held().0, 0);
}

/// The Host check reads the request's one host: a second Host header after a loopback
/// one, or an absolute URL naming another host, was answered 200 with the status (measured
/// by hand: `Host: 127.0.0.1` then `Host: evil.com`, and `GET http://evil.example/status`).
#[test]
fn a_second_host_or_a_foreign_absolute_url_is_misdirected() {
    let dir = temp_dir("preview-hosts");
    let mut args = cover_args(64, 8);
    args.extend(["-o", "a.png", "--preview=127.0.0.1:0", "--preview-hold"].map(String::from));
    let viewer = Viewer::start(&strs(&args), &dir);
    viewer.wait_for("the end", |s| s["state"] == "finished");
    let addr = viewer.addr;
    let key = &viewer.key;
    let ask = |raw: String| request(addr, &raw).code;
    assert_eq!(
        ask(format!(
            "GET /{key}/status HTTP/1.1\r\nHost: {addr}\r\nHost: evil.example\r\nConnection: close\r\n\r\n"
        )),
        421,
        "two Host headers"
    );
    assert_eq!(
        ask(format!(
            "GET http://evil.example/{key}/status HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"
        )),
        421,
        "an absolute URL of another host"
    );
    let port = addr.port();
    for host in [
        format!("evil@localhost:{port}"),
        format!("evil.example@{addr}"),
    ] {
        assert_eq!(
            ask(format!(
                "GET /{key}/status HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n"
            )),
            421,
            "a Host with a user part: {host}"
        );
        assert_eq!(
            ask(format!(
                "GET http://{host}/{key}/status HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"
            )),
            421,
            "an absolute URL with a user part: {host}"
        );
    }
    assert_eq!(
        ask(format!(
            "GET http://{addr}/{key}/status HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"
        )),
        200,
        "an absolute URL of the viewer itself"
    );
    assert_eq!(
        ask(format!(
            "GET /{key}/status HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"
        )),
        200
    );
    assert_eq!(viewer.interrupt_held().0, 0);
}

#[test]
fn the_server_refuses_what_it_does_not_serve_while_the_render_goes_on() {
    let dir = temp_dir("preview-limits");
    let mut args = cover_args(300, 384);
    args.extend(["-o", "limited.png", "--preview", "--preview-hold"].map(String::from));
    let viewer = Viewer::start(&strs(&args), &dir);
    let addr = viewer.addr;
    let key = viewer.key.clone();
    let host = viewer.host();
    // Nothing to download before the render has finished.
    let early = viewer.get("/download");
    assert_eq!(early.code, 404, "{}", early.text());
    assert!(early.text().contains("when the render has finished"));
    // A client that asks for frame after frame and never reads an answer.
    let mut stuck = TcpStream::connect(addr).unwrap();
    let pipelined = format!("GET /{key}/frame.png HTTP/1.1\r\nHost: {addr}\r\n\r\n").repeat(200);
    stuck
        .set_write_timeout(Some(Duration::from_secs(5)))
        .unwrap();
    let _ = stuck.write_all(pipelined.as_bytes());
    // A client that floods status requests on one connection, for a while.
    let flood_key = key.clone();
    let flood = std::thread::spawn(move || {
        let start = Instant::now();
        let mut answered = 0;
        if let Ok(mut s) = TcpStream::connect(addr) {
            s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
            let one = format!("GET /{flood_key}/status HTTP/1.1\r\nHost: {addr}\r\n\r\n");
            let mut reader = BufReader::new(s.try_clone().unwrap());
            while start.elapsed() < Duration::from_secs(2) {
                if s.write_all(one.as_bytes()).is_err() {
                    break;
                }
                // Read one answer: headers, then the body by its length.
                let mut length = 0;
                let mut line = String::new();
                loop {
                    line.clear();
                    if reader.read_line(&mut line).unwrap_or(0) == 0 {
                        return answered;
                    }
                    if let Some(v) = line.to_ascii_lowercase().strip_prefix("content-length:") {
                        length = v.trim().parse().unwrap_or(0);
                    }
                    if line == "\r\n" {
                        break;
                    }
                }
                let mut body = vec![0u8; length];
                if reader.read_exact(&mut body).is_err() {
                    return answered;
                }
                answered += 1;
            }
        }
        answered
    });
    // Unknown paths, other methods, huge headers, other hosts.
    for path in [
        "/nope",
        "/../../etc/passwd",
        "/frame.png/x",
        "/statusx",
        "//",
    ] {
        let a = viewer.get(path);
        assert_eq!(a.code, 404, "{path}");
    }
    // Without the key, or with another, nothing is served: another user of the machine, or
    // a page guessing ports, would watch the render and take the image. The key's folder
    // without its slash is redirected to it, where the page's relative links work.
    let other_key = "0".repeat(32);
    for path in [
        "/".to_owned(),
        "/index.html".to_owned(),
        "/status".to_owned(),
        "/frame.png".to_owned(),
        "/events".to_owned(),
        format!("/{other_key}/status"),
        format!("/{}/status", &key[..31]),
        format!("/{key}x/status"),
        format!("/x{key}/"),
    ] {
        let a = viewer.get_raw(&path);
        assert_eq!(a.code, 404, "{path}");
        assert!(
            a.text().contains("the address tessera printed") && !a.text().contains(&key),
            "{path}: {}",
            a.text()
        );
    }
    let folder = viewer.get_raw(&format!("/{key}"));
    assert_eq!(folder.code, 308);
    assert_eq!(folder.header("location"), Some(format!("/{key}/").as_str()));
    for method in ["POST", "PUT", "DELETE", "OPTIONS", "PATCH"] {
        let a = request(addr, &format!("{method} /{key}/status HTTP/1.1\r\n{host}"));
        assert_eq!(a.code, 405, "{method}");
        assert_eq!(a.header("allow"), Some("GET, HEAD"));
    }
    let huge = format!(
        "GET /{key}/status HTTP/1.1\r\nX-Padding: {}\r\n{host}",
        "a".repeat(16 * 1024)
    );
    assert_eq!(request(addr, &huge).code, 431);
    let many = format!(
        "GET /{key}/status HTTP/1.1\r\n{}{host}",
        "X-A: b\r\n".repeat(100)
    );
    assert_eq!(request(addr, &many).code, 431);
    let elsewhere =
        "GET /status HTTP/1.1\r\nHost: attacker.example:80\r\nConnection: close\r\n\r\n";
    assert_eq!(request(addr, elsewhere).code, 421);
    // Too many clients: fill the places with event streams; the next one gets 503.
    let mut holders = Vec::new();
    let mut refused = None;
    for _ in 0..32 {
        let mut s = TcpStream::connect(addr).unwrap();
        s.set_read_timeout(Some(PATIENCE)).unwrap();
        write!(s, "GET /{key}/events HTTP/1.1\r\nHost: {addr}\r\n\r\n").unwrap();
        let mut first = [0u8; 12];
        s.read_exact(&mut first).unwrap();
        if &first == b"HTTP/1.1 503" {
            refused = Some(holders.len());
            break;
        }
        assert_eq!(&first, b"HTTP/1.1 200");
        holders.push(s);
    }
    let served = refused.expect("some client was refused");
    assert!(served <= 8, "{served} clients at once");
    drop(holders);
    drop(stuck);
    let flooded = flood.join().unwrap();
    assert!(flooded > 0, "the flooding client was served too");
    // The render finished, with the bytes of an unwatched one, and the viewer answers.
    let end = viewer.wait_for("the end", |s| s["state"] == "finished");
    assert_eq!(end["spp_done"], 384);
    let (code, stderr) = viewer.interrupt_held();
    assert_eq!(code, 0, "{stderr}");
    assert_unwatched_bytes(&dir, cover_args(300, 384), "limited.png");
}

#[test]
fn bad_preview_addresses_are_errors_before_the_render() {
    let dir = temp_dir("preview-errors");
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = taken.local_addr().unwrap().port();
    let in_use = format!("--preview=127.0.0.1:{port}");
    let foreign = "--preview=192.0.2.1:8080".to_owned(); // TEST-NET-1: no machine's own
    let cases: [(&str, &str); 5] = [
        (&in_use, "is in use"),
        ("--preview=nonsense", "is not an address"),
        ("--preview=127.0.0.1:99999", "is not an address"),
        (&foreign, "is not an address of this machine"),
        ("--preview=", "is not an address"),
    ];
    for (flag, message) in cases {
        let o = run(
            &["render", &cover(), "--width", "32", "-o", "x.png", flag],
            &dir,
        );
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{flag}: {err}");
        assert!(err.contains(message), "{flag}: {err}");
        assert!(!dir.join("x.png").exists(), "{flag} rendered anyway");
    }
    // `--preview ADDR` (no `=`) makes ADDR the scene, or an argument too many after one;
    // the error says what was meant either way.
    let scene = cover();
    for args in [
        &["render", "--preview", "127.0.0.1:8080"][..],
        &["render", "--preview", "8080"],
        &["render", &scene, "--preview", "8080", "--width", "32"],
        &[
            "render",
            &scene,
            "--width",
            "32",
            "--preview",
            "localhost:8080",
        ],
    ] {
        let o = run(args, &dir);
        assert_eq!(o.status.code(), Some(2), "{args:?}");
        let spec = args[args.iter().position(|a| *a == "--preview").unwrap() + 1];
        assert!(
            stderr(&o).contains(&format!("--preview={spec}")),
            "{args:?}: {}",
            stderr(&o)
        );
    }
    // A port below 1024 needs root.
    let root = std::process::Command::new("id")
        .arg("-u")
        .output()
        .is_ok_and(|o| o.stdout.starts_with(b"0"));
    if !root {
        let o = run(
            &["render", &cover(), "--width", "32", "--preview=127.0.0.1:1"],
            &dir,
        );
        assert_eq!(o.status.code(), Some(2));
        assert!(stderr(&o).contains("permission"), "{}", stderr(&o));
    }
    // Preview files are PNG, and their flags go together.
    for args in [
        &["--preview-file", "p.jpg"][..],
        &["--preview-file", "p.png", "--preview-every", "0"],
        &["--preview-file", "p.png", "--preview-every", "-1"],
        &["--preview-every", "5"],
        &["--preview-hold"],
    ] {
        let scene = cover();
        let mut all = vec!["render", &scene, "--width", "32", "-o", "x.png"];
        all.extend_from_slice(args);
        let o = run(&all, &dir);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(!stderr(&o).contains("no such scene file"), "{}", stderr(&o));
        assert!(!dir.join("x.png").exists());
    }
    // A preview file is not the output, however spelt: the image would hold part of the
    // render while it runs, and after Ctrl-C.
    std::fs::write(dir.join("x.png"), b"an earlier image").unwrap();
    let scene = cover();
    let o = run(
        &[
            "render",
            &scene,
            "--width",
            "32",
            "-o",
            "x.png",
            "--preview-file",
            "./x.png",
        ],
        &dir,
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("--preview-file ./x.png names the same file as -o"),
        "{}",
        stderr(&o)
    );
    assert_eq!(
        std::fs::read(dir.join("x.png")).unwrap(),
        b"an earlier image"
    );
}

#[test]
fn a_public_address_warns_that_anyone_can_see() {
    let dir = temp_dir("preview-public");
    let mut args = cover_args(32, 2);
    args.extend(["-o", "a.png", "--preview=0.0.0.0:0"].map(String::from));
    let viewer = Viewer::start(&strs(&args), &dir);
    let mut viewer = viewer;
    assert_eq!(viewer.wait(), 0);
    let err = viewer.stderr.lock().unwrap().clone();
    assert!(err.contains("warning") && err.contains("anyone"), "{err}");
}

/// A preview file that is a pipe (FIFO) was written in place, and opening a pipe for writing
/// waits for a reader: with none, the preview's writer waited for ever, and tessera, its
/// image written, never ended. It is refused before the render.
#[test]
fn a_preview_file_that_is_a_pipe_is_refused_before_the_render() {
    let dir = temp_dir("preview-file-pipe");
    let made = std::process::Command::new("mkfifo")
        .arg(dir.join("pipe.png"))
        .status();
    if !made.is_ok_and(|s| s.success()) {
        return skip("a_preview_file_that_is_a_pipe", "no mkfifo");
    }
    let mut child = tessera()
        .args([
            "render",
            &cover(),
            "--width",
            "32",
            "--spp",
            "4",
            "-o",
            "x.png",
            "--preview-file",
            "pipe.png",
        ])
        .current_dir(&dir)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start tessera");
    let start = Instant::now();
    let code = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status.code();
        }
        if start.elapsed() > PATIENCE {
            let _ = child.kill();
            let _ = child.wait();
            panic!("tessera did not end: it waits for a reader of the preview's pipe");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut err = String::new();
    let _ = child.stderr.take().unwrap().read_to_string(&mut err);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("is a pipe"), "{err}");
    assert!(!dir.join("x.png").exists(), "rendered anyway");
}

#[test]
fn preview_files_show_the_jobs_own_pixels() {
    let dir = temp_dir("preview-file");
    let base = cover_args(120, 16);
    let with = |extra: &[&str]| {
        let mut a = strs(&base);
        a.extend_from_slice(extra);
        ok(&a, &dir);
    };
    with(&["-o", "whole.png", "--preview-file", "whole-preview.png"]);
    let whole = image::open(dir.join("whole.png")).unwrap().to_rgb8();
    let preview = image::open(dir.join("whole-preview.png"))
        .unwrap()
        .to_rgb8();
    assert!(whole == preview, "the last preview is the image");
    // A band of rows: the preview is that band.
    with(&[
        "--shard",
        "1/2",
        "--split",
        "rows",
        "-o",
        "rows.part",
        "--preview-file",
        "rows.png",
    ]);
    let band = image::open(dir.join("rows.png")).unwrap().to_rgb8();
    assert_eq!(band.dimensions(), (120, 40));
    assert!(band == image::imageops::crop_imm(&whole, 0, 40, 120, 40).to_image());
    // A sample range: every pixel, its own samples.
    with(&[
        "--samples",
        "0..4",
        "-o",
        "s.part",
        "--preview-file",
        "samples.png",
    ]);
    let samples = image::open(dir.join("samples.png")).unwrap().to_rgb8();
    assert_eq!(samples.dimensions(), (120, 80));
    assert!(samples != whole);
    // Parts still merge to the image.
    with(&[
        "--samples",
        "4..16",
        "-o",
        "t.part",
        "--preview-file",
        "samples.png",
    ]);
    ok(&["merge", "s.part", "t.part", "-o", "merged.png"], &dir);
    assert_eq!(
        std::fs::read(dir.join("merged.png")).unwrap(),
        std::fs::read(dir.join("whole.png")).unwrap()
    );
}

#[test]
fn ctrl_c_in_a_watched_render_saves_the_checkpoint_and_resumes_to_the_same_bytes() {
    let dir = temp_dir("preview-checkpoint");
    let mut args = cover_args(400, 256);
    args.extend(
        [
            "--threads",
            "1",
            "-o",
            "resumed.png",
            "--checkpoint",
            "c.part",
            "--preview",
            "--preview-file",
            "p.png",
        ]
        .map(String::from),
    );
    let viewer = Viewer::start(&strs(&args), &dir);
    let seen = viewer.wait_for("the second pass", |s| s["spp_done"].as_u64() >= Some(4));
    assert_eq!(seen["state"], "rendering");
    let (code, stderr) = viewer.interrupt();
    if code == 0 {
        // The machine rendered it all before the signal came: nothing to resume.
        return skip(
            "ctrl_c_in_a_watched_render",
            "the render ended before Ctrl-C",
        );
    }
    assert_eq!(code, 130, "{stderr}");
    assert!(stderr.contains("Run the same command again"), "{stderr}");
    assert!(dir.join("c.part").exists() && dir.join("p.png").exists());
    assert!(!dir.join("resumed.png").exists());
    let mut quiet = strs(&args);
    quiet.retain(|a| *a != "--preview");
    ok(&quiet, &dir);
    assert_unwatched_bytes(&dir, cover_args(400, 256), "resumed.png");
    let preview = image::open(dir.join("p.png")).unwrap().to_rgb8();
    let image = image::open(dir.join("resumed.png")).unwrap().to_rgb8();
    assert!(preview == image, "the last preview is the final image");
}

/// A client that asks for frames and never reads them holds the viewer's close for seconds;
/// an interrupted render's progress is saved before that, not after (a container has a few
/// seconds between SIGTERM and SIGKILL): the checkpoint is there while tessera still waits.
#[test]
fn an_interrupted_render_saves_its_checkpoint_before_a_stuck_viewer_lets_go() {
    use std::io::Write;
    let dir = temp_dir("preview-stuck-checkpoint");
    let mut args = cover_args(400, 256);
    // No save before the interruption: the checkpoint's appearing is the one at the end.
    args.extend(
        [
            "--threads",
            "1",
            "-o",
            "out.png",
            "--checkpoint",
            "c.part",
            "--checkpoint-every",
            "3600",
            "--preview",
        ]
        .map(String::from),
    );
    let mut viewer = Viewer::start(&strs(&args), &dir);
    viewer.wait_for("the second pass", |s| s["spp_done"].as_u64() >= Some(4));
    // Frames asked for two hundred times over one connection, none read: tens of MB the
    // server cannot send.
    let mut stuck = std::net::TcpStream::connect(viewer.addr).unwrap();
    let ask = format!(
        "GET /{}/frame.png HTTP/1.1\r\nHost: {}\r\n\r\n",
        viewer.key, viewer.addr
    );
    stuck.write_all(ask.repeat(200).as_bytes()).unwrap();
    std::thread::sleep(Duration::from_millis(300));
    let _ = std::process::Command::new("kill")
        .args(["-INT", &viewer.child.id().to_string()])
        .status();
    let start = Instant::now();
    while !dir.join("c.part").exists() {
        if viewer.child.try_wait().unwrap().is_some() {
            break;
        }
        assert!(start.elapsed() < PATIENCE, "no checkpoint");
        std::thread::sleep(Duration::from_millis(5));
    }
    if viewer.child.try_wait().unwrap().is_some() && !dir.join("c.part").exists() {
        // The render ended before the signal came: nothing to save.
        return skip(
            "an_interrupted_render_saves_its_checkpoint",
            "the render ended first",
        );
    }
    assert!(
        viewer.child.try_wait().unwrap().is_none(),
        "the checkpoint came only as tessera ended, after the viewer let go"
    );
    drop(stuck);
    let code = viewer.wait();
    assert_eq!(code, 130, "{}", viewer.stderr.lock().unwrap());
}

#[test]
fn watched_renders_of_the_cover_and_every_figure_are_byte_identical() {
    let dir = temp_dir("preview-bytes");
    let mut scenes: Vec<String> = std::fs::read_dir(root().join("scenes"))
        .unwrap()
        .map(|e| e.unwrap().path().to_string_lossy().into_owned())
        .filter(|p| p.ends_with(".toml"))
        .collect();
    scenes.sort();
    assert!(scenes.len() >= 22);
    for scene in &scenes {
        // The Next Week's scenes ask for hundreds of samples (the final scene 10,000):
        // 64 of them, four passes, show the same.
        let spp: &[&str] = if scene.contains("img-2.") {
            &["--spp", "64"]
        } else {
            &[]
        };
        let args = |threads: &'static str, out: &'static str| {
            let mut a = vec![
                "render",
                scene,
                "--width",
                "96",
                "--threads",
                threads,
                "-o",
                out,
            ];
            a.extend(spp);
            a
        };
        // The plain render once: its bytes are the same at any thread count (the determinism
        // tests), so each watched render is held to the one-thread render.
        ok(&args("1", "plain.png"), &dir);
        let plain = std::fs::read(dir.join("plain.png")).unwrap();
        for threads in ["1", "2"] {
            let mut watched = args(threads, "watched.png");
            watched.extend(["--preview-file", "p.png"]);
            ok(&watched, &dir);
            assert!(
                plain == std::fs::read(dir.join("watched.png")).unwrap(),
                "{scene}, {threads} threads"
            );
        }
    }
}
