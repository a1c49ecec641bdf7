//! What each fuzz target does with one input, shared by the fuzzer (fuzz/fuzz_targets/, through
//! the `tessera_fuzz` library) and by the corpus replay of the tests
//! (tests/suite/fuzz/corpus.rs, which includes this file as a module). Only `std`, `tessera`
//! and crates tessera depends on (`crc32fast`, `xxhash-rust`, `toml`, `libc`) are used here,
//! so both can compile it.
//!
//! Each check takes a stranger's bytes and returns `Err` only for a broken contract: a panic
//! or an abort is a finding by itself; a refusal of the input is the library's `Err`, which
//! is fine as long as it names the file it refuses. The fuzzer also caps every single
//! allocation at the target's ceiling (`CEILINGS`): an input must not make tessera allocate
//! what it merely claims.
//!
//! A file whose checksum the fuzzer breaks is refused before anything deeper is read, and a
//! fuzzer seldom mends a CRC or a hash by itself; so the PNG and part checks also read each
//! input with its checksums made right again (`with_png_crcs`, `with_part_checksum`).

#![allow(dead_code)]

use std::io::Cursor;
use std::path::Path;
use tessera::exr_header;
use tessera::image_file::png_header_of;
use tessera::partial::{Part, PartReader};
use tessera::recipe::Recipe;
use tessera::record::result::BenchResult;
use tessera::scene::{Overrides, Scene};

/// The targets, in the order ci.sh runs them, each with the directory of its corpus
/// (fuzz/corpus/NAME) and of its findings (fuzz/findings/NAME).
pub const TARGETS: &[&str] = &[
    "scene",
    "png_recipe",
    "exr_header",
    "part",
    "request",
    "result",
    "image",
];

/// The largest single allocation each target's input may cause, in bytes.
pub const CEILINGS: &[(&str, usize)] = &[
    // A scene's own spheres and its generated grid (at most `MAX_GRID` here) and their BVH;
    // the scene is parsed, not rendered.
    ("scene", 256 << 20),
    // A recipe is at most 1 MiB (its scene parsed, not rendered), an EXR header 4 MiB.
    ("png_recipe", 64 << 20),
    ("exr_header", 64 << 20),
    // The seeds are a few kilobytes: reading one never needs 16 MiB at once.
    ("part", 16 << 20),
    // Requests of at most a few kilobytes, answered with pages and a 16x9 frame.
    ("request", 16 << 20),
    // A result is at most 1 MiB of JSON (`record::result::MAX_FILE`), its value tree a few
    // times that.
    ("result", 64 << 20),
    // An image of at most `MAX_COMPARED_PIXELS` (2^24) pixels compared, its decoded bytes
    // (16 a pixel, RGBA floats) and floats (12) each one allocation; a texture of at most
    // `MAX_TEXTURE_PIXELS` (2^25), 16 bytes a pixel decoded. A few dozen kilobytes of
    // zeros may well deflate to that much.
    ("image", 1 << 30),
];

/// The largest input each target is run on (libFuzzer's `-max_len`, given by ci.sh), in
/// bytes.
pub const MAX_LEN: &[(&str, usize)] = &[
    ("scene", 64 << 10),
    ("png_recipe", 64 << 10),
    ("exr_header", 64 << 10),
    ("part", 64 << 10),
    // Past the server's 8 KiB limit on a request's head (answered 431).
    ("request", 12 << 10),
    ("result", 64 << 10),
    ("image", 64 << 10),
];

/// A target's check of one input: `Err` says what contract it broke.
pub type Check = fn(&[u8]) -> Result<(), String>;

/// The check of target `name`.
pub fn check_of(name: &str) -> Option<Check> {
    Some(match name {
        "scene" => scene,
        "png_recipe" => png_recipe,
        "exr_header" => exr_header,
        "part" => part,
        #[cfg(feature = "preview")]
        "request" => request::request,
        "result" => result,
        "image" => image,
        _ => return None,
    })
}

/// A refusal of `file`: its message must start with the file's name.
fn names(e: &tessera::Error, file: &str) -> Result<(), String> {
    let message = e.to_string();
    if message.starts_with(file) {
        Ok(())
    } else {
        Err(format!("a refusal that does not name {file}: {message}"))
    }
}

/// A refusal of a scene file `file`: its message must start `file:LINE:COLUMN:`.
fn located(e: &tessera::Error, file: &str) -> Result<(), String> {
    let message = e.to_string();
    let mut fields = message.splitn(4, ':');
    let placed = fields.next() == Some(file)
        && fields.next().is_some_and(|l| l.parse::<u32>().is_ok())
        && fields.next().is_some_and(|c| c.parse::<u32>().is_ok());
    if placed {
        Ok(())
    } else {
        Err(format!("a refusal without {file}:line:column: {message}"))
    }
}

/// The largest `random_spheres.grid` a scene is built with here: a grid of `g` makes
/// `(2g)^2` spheres, and the largest tessera allows (1000: four million spheres, 800 MB)
/// takes about 10 s to build in a release binary and 25 s in a fuzzing one, which is no
/// bug but would stall the fuzzer (or trip its timeout). 128 builds in well under a second.
pub const MAX_GRID: i64 = 128;

/// The most spheres a `[[random_sphere_clouds]]`, and boxes a `[[random_boxes]]`, is built
/// with here, for the same reason (tessera allows 2²⁰ and 100,000).
pub const MAX_GENERATED: i64 = 20_000;

/// Whether the TOML `text` asks, anywhere, for a generated grid above `MAX_GRID` or a
/// generator `count` above `MAX_GENERATED`.
pub fn too_slow(text: &str) -> bool {
    fn count(v: &toml::Value) -> i64 {
        match v {
            toml::Value::Integer(n) => *n,
            toml::Value::Array(a) => a
                .iter()
                .map(|v| v.as_integer().unwrap_or(0).max(0))
                .fold(1i64, |p, n| p.saturating_mul(n)),
            _ => 0,
        }
    }
    fn big(v: &toml::Value) -> bool {
        match v {
            toml::Value::Table(t) => t.iter().any(|(k, v)| {
                (k == "grid" && v.as_integer().is_some_and(|g| g > MAX_GRID))
                    || (k == "count" && count(v) > MAX_GENERATED)
                    || big(v)
            }),
            toml::Value::Array(a) => a.iter().any(big),
            _ => false,
        }
    }
    // Parsing costs as much again: only where a key could say `grid` or `count` (escapes
    // too).
    let could = text.contains("grid")
        || text.contains("count")
        || text.contains("\\u")
        || text.contains("\\U");
    could && toml::from_str::<toml::Table>(text).is_ok_and(|t| big(&toml::Value::Table(t)))
}

/// The image textures a fuzzed scene may name: the book's earth, compiled in, so no input
/// reads a file from disk.
const TEXTURES: &[(&str, &[u8])] = &[("earthmap.jpg", include_bytes!("../scenes/earthmap.jpg"))];

/// 1. A scene file: parsed and built (BVH and all) with no overrides. The bytes are read as
///    UTF-8, invalid sequences replaced, so that every input reaches the parser (refusing
///    invalid UTF-8 is `Scene::read_text`'s, tested in tests/suite/fuzz/scenes.rs).
pub fn scene(bytes: &[u8]) -> Result<(), String> {
    let text = String::from_utf8_lossy(bytes);
    if too_slow(&text) {
        return Ok(());
    }
    let textures = tessera::scene::TextureSource::Embedded(TEXTURES);
    match Scene::parse_with(
        &text,
        Path::new("fuzz.toml"),
        &Overrides::default(),
        &textures,
    ) {
        Ok(scene) => {
            let _ = scene.fingerprint();
            Ok(())
        }
        Err(e) => located(&e, "fuzz.toml"),
    }
}

/// A recipe's text found in `image`: parsed, and its scene parsed and checked against it.
fn recipe(text: &str, image: &str) -> Result<(), String> {
    if text.len() > tessera::recipe::MAX_BYTES {
        return Err(format!("accepted a recipe of {} bytes", text.len()));
    }
    let path = Path::new(image);
    let recipe = match Recipe::parse(text, path) {
        Ok(recipe) => recipe,
        Err(e) => return names(&e, image),
    };
    let _ = (recipe.window(), recipe.to_json());
    if too_slow(&recipe.scene.text) {
        return Ok(());
    }
    match recipe.scene(path, &[]) {
        Ok(_) => Ok(()),
        Err(e) => names(&e, image),
    }
}

/// `bytes` with the CRC of every iTXt chunk (the recipe's kind, the only one tessera checks)
/// made right, as far as the chunks' lengths can be followed.
pub fn with_png_crcs(bytes: &[u8]) -> Vec<u8> {
    let mut b = bytes.to_vec();
    let mut at = 8;
    while at + 8 <= b.len() {
        let length = u32::from_be_bytes(b[at..at + 4].try_into().expect("4 bytes")) as usize;
        let Some(end) = (at + 8).checked_add(length).filter(|&e| e + 4 <= b.len()) else {
            break;
        };
        if &b[at + 4..at + 8] == b"iTXt" {
            let crc = crc32fast::hash(&b[at + 4..end]);
            b[end..end + 4].copy_from_slice(&crc.to_be_bytes());
        }
        at = end + 4;
    }
    b
}

/// 2. A PNG image: its header and recipe chunk read, then its recipe parsed; then the same
///    with its recipe chunk's CRC made right.
pub fn png_recipe(bytes: &[u8]) -> Result<(), String> {
    png_recipe_as_is(bytes)?;
    let fixed = with_png_crcs(bytes);
    if fixed != bytes {
        png_recipe_as_is(&fixed)?;
    }
    Ok(())
}

fn png_recipe_as_is(bytes: &[u8]) -> Result<(), String> {
    let Ok(header) = png_header_of(bytes) else {
        return Ok(());
    };
    match header.recipe {
        Some(text) => recipe(&text, "fuzz.png"),
        None => Ok(()),
    }
}

/// 3. An OpenEXR image: its header read by tessera's own parser, then its recipe parsed.
pub fn exr_header(bytes: &[u8]) -> Result<(), String> {
    let Ok(header) = exr_header::read(Cursor::new(bytes), bytes.len() as u64) else {
        return Ok(());
    };
    match header.recipe {
        Some(text) => recipe(&text, "fuzz.exr"),
        None => Ok(()),
    }
}

/// The scene the part seeds of fuzz/corpus/part were rendered from (`tessera render
/// part.toml --shard I/N ...`), so that resuming them gets past the scene check.
pub const PART_SCENE: &str = r#"[image]
width = 16
height = 9
samples_per_pixel = 4
max_depth = 5

[materials.red]
type = "lambertian"
albedo = [0.9, 0.1, 0.1]

[[spheres]]
center = [0.0, 0.0, -1.0]
radius = 0.5
material = "red"
"#;

/// 4. A part file (a shard or a checkpoint): its header read alone, as a merge first does,
///    then the whole of it; what is accepted is consistent, and merging it, resuming it and
///    parsing the recipe source it carries never panic.
///    The same again with the file's checksum made right.
pub fn part(bytes: &[u8]) -> Result<(), String> {
    part_as_is(bytes)?;
    let fixed = with_part_checksum(bytes);
    if fixed != bytes {
        part_as_is(&fixed)?;
    }
    Ok(())
}

/// `bytes` with its last 8 bytes the checksum of a part file: XXH3-64 of all before them,
/// little endian.
pub fn with_part_checksum(bytes: &[u8]) -> Vec<u8> {
    let mut b = bytes.to_vec();
    if let Some(body) = b.len().checked_sub(8).filter(|&n| n >= 24) {
        let sum = xxhash_rust::xxh3::xxh3_64(&b[..body]);
        b[body..].copy_from_slice(&sum.to_le_bytes());
    }
    b
}

fn part_as_is(bytes: &[u8]) -> Result<(), String> {
    thread_local! {
        static SCENE: Scene = Scene::parse(PART_SCENE, Path::new("part.toml"), &Overrides::default())
            .expect("the part scene parses");
    }
    let path = Path::new("fuzz.part");
    let len = bytes.len() as u64;
    let header = match PartReader::new(Cursor::new(bytes), len, path) {
        Ok(reader) => reader.into_header(),
        Err(e) => return names(&e, "fuzz.part: "),
    };
    let part = match Part::from_bytes(bytes, path) {
        Ok(part) => part,
        Err(e) => return names(&e, "fuzz.part: "),
    };
    let state = &part.state;
    if state.sums.len() as u64 != state.job.region.area() {
        return Err(format!(
            "accepted {} sums for region {:?}",
            state.sums.len(),
            state.job.region
        ));
    }
    if header.render != part.render || header.state.job != state.job {
        return Err("the header read alone differs from the part read whole".to_owned());
    }
    // A merge writes this recipe into its image when it describes the parts, and leaves it
    // out with a warning when it does not: any refusal will do.
    if let Some(source) = &part.render.recipe {
        let _ = source.parse(path, &[]);
    }
    let named = vec![(path.to_owned(), part.clone())];
    if let Ok((film, _)) = tessera::partial::merge(&named)
        && film.sums.len() as u64 != u64::from(film.width) * u64::from(film.height)
    {
        return Err("merged into a film of the wrong size".to_owned());
    }
    SCENE.with(|scene| {
        let mut job = state.job;
        job.samples.end = job.samples.end.saturating_add(1);
        // The seeds name the build that rendered them, which no later build is: resumed as
        // this build's, they reach the checks past the build's.
        let mut part = part.clone();
        part.render.tessera = tessera::recipe::Maker::this_build();
        if let Ok(resumed) = part.resume(scene, job, path) {
            let _ = (resumed.percent_done(), resumed.unfinished_tiles());
        }
    });
    Ok(())
}

/// 5. Requests to the live viewer. Its server (src/preview/server.rs) has no entry point
///    without a socket (`respond` is private and takes hyper's `Request<Incoming>`), so each
///    input is sent as it is over a loopback connection to one server started for the whole
///    run, in this process; the answer is read until the server closes the connection or
///    falls silent. Seeds name the host without a port (`Host: 127.0.0.1`), which the server
///    accepts whatever port it listens on.
#[cfg(feature = "preview")]
pub mod request {
    use std::io::{Read, Write};
    use std::net::{Shutdown, SocketAddr, TcpStream};
    use std::sync::Arc;
    use std::sync::OnceLock;
    use std::time::{Duration, Instant};
    use tessera::preview::server::{Server, answer_in_memory};
    use tessera::preview::{Hub, Previewer};

    /// How long the server may be silent before an answer counts as complete, and the most
    /// one input may take in all. The server closes the connection once it has answered
    /// (the client has closed its side), so only a request it delays (beyond its burst of
    /// requests a connection) or an answer that does not end waits this long: briefly while
    /// fuzzing, generously in a test, where a loaded machine may be slow to answer at all.
    /// (`fuzzing` is the cfg the fuzz build sets, unknown to the tests' build.)
    #[allow(unexpected_cfgs)]
    const QUIET: Duration = Duration::from_millis(if cfg!(fuzzing) { 100 } else { 3000 });
    #[allow(unexpected_cfgs)]
    const AT_MOST: Duration = Duration::from_millis(if cfg!(fuzzing) { 500 } else { 10_000 });

    /// The hub of a small blank job's viewer, made once and kept for the process's life.
    fn hub() -> Arc<Hub> {
        static HUB: OnceLock<Arc<Hub>> = OnceLock::new();
        Arc::clone(HUB.get_or_init(|| {
            let previewer = Previewer::blank("fuzz");
            let hub = previewer.hub();
            // It lives as long as the process.
            std::mem::forget(previewer);
            hub
        }))
    }

    /// The key of the in-memory server's paths (`request`): the seeds' requests name it.
    pub const KEY: &str = "0123456789abcdef0123456789abcdef";

    /// The server of that hub on a loopback port, started once and kept for the process's
    /// life: its address, and the key its paths begin with.
    pub fn server() -> (SocketAddr, &'static str) {
        static SERVER: OnceLock<(SocketAddr, String)> = OnceLock::new();
        let (addr, key) = SERVER.get_or_init(|| {
            let listener = std::net::TcpListener::bind("127.0.0.1:0").expect("a loopback port");
            let server = Server::start(listener, hub()).expect("the server starts");
            let found = (server.addr(), server.key().to_owned());
            // It lives as long as the process.
            std::mem::forget(server);
            found
        });
        (*addr, key)
    }

    /// Makes closing `stream` reset it rather than leave it in TIME_WAIT for a minute: tens of
    /// thousands of connections a minute in TIME_WAIT slow every `connect` (the kernel searches
    /// its ports past them), and the fuzzer with it.
    fn no_time_wait(stream: &TcpStream) {
        use std::os::fd::AsRawFd;
        let linger = libc::linger {
            l_onoff: 1,
            l_linger: 0,
        };
        // SAFETY: `linger` is a valid `struct linger` of the size given, and the descriptor
        // is the open socket `stream` owns.
        unsafe {
            libc::setsockopt(
                stream.as_raw_fd(),
                libc::SOL_SOCKET,
                libc::SO_LINGER,
                (&raw const linger).cast(),
                std::mem::size_of::<libc::linger>() as libc::socklen_t,
            );
        }
    }

    /// Sends `bytes` on a new connection and reads the answer.
    pub fn exchange(bytes: &[u8]) -> Result<Vec<u8>, String> {
        let (addr, _) = server();
        let mut stream =
            TcpStream::connect(addr).map_err(|e| format!("cannot connect to the server: {e}"))?;
        let _ = stream.set_nodelay(true);
        no_time_wait(&stream);
        stream
            .set_read_timeout(Some(QUIET))
            .map_err(|e| e.to_string())?;
        // A server that closes early (a refusal) makes writing fail: that is an answer too.
        if stream.write_all(bytes).is_ok() {
            let _ = stream.shutdown(Shutdown::Write);
        }
        let start = Instant::now();
        let mut answer = Vec::new();
        let mut buf = [0u8; 16 << 10];
        while start.elapsed() < AT_MOST && answer.len() < 4 << 20 && !streaming(&answer) {
            match stream.read(&mut buf) {
                Ok(0) | Err(_) => break,
                Ok(n) => answer.extend_from_slice(&buf[..n]),
            }
        }
        Ok(answer)
    }

    /// Whether `answer` has come to the head of an event stream, which never ends by itself.
    fn streaming(answer: &[u8]) -> bool {
        let find = |hay: &[u8], needle: &[u8]| hay.windows(needle.len()).position(|w| w == needle);
        find(answer, b"content-type: text/event-stream")
            .is_some_and(|at| find(&answer[at..], b"\r\n\r\n").is_some())
    }

    /// 5. One input sent as it is, on a connection of its own without a socket (an
    ///    in-memory pipe, served as a socket's connection is): answered (if at all) with an
    ///    HTTP/1 status line, and serving it never panics.
    pub fn request(bytes: &[u8]) -> Result<(), String> {
        let addr = SocketAddr::from(([127, 0, 0, 1], 8000));
        let answer =
            answer_in_memory(hub(), addr, KEY, bytes, AT_MOST).map_err(|e| e.to_string())?;
        if !answer.is_empty() && !answer.starts_with(b"HTTP/1.") {
            let head = String::from_utf8_lossy(&answer[..answer.len().min(80)]).into_owned();
            return Err(format!("an answer that is not HTTP/1: {head:?}"));
        }
        Ok(())
    }

    /// The server still answers a well-formed request for its status.
    pub fn alive() -> Result<(), String> {
        let (_, key) = server();
        let ask = format!("GET /{key}/status HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n");
        let answer = exchange(ask.as_bytes())?;
        if answer.starts_with(b"HTTP/1.1 200") {
            Ok(())
        } else {
            let head = String::from_utf8_lossy(&answer[..answer.len().min(80)]).into_owned();
            Err(format!("the server no longer answers /status: {head:?}"))
        }
    }
}

/// 6. A benchmark result, as `results import` reads one (JSON): parsed and checked
///    (`BenchResult::parse`). One it accepts is added to a new results database (with the
///    `results` feature), where it must land once, as one run, and be given back as the same
///    JSON, which is accepted again.
pub fn result(bytes: &[u8]) -> Result<(), String> {
    match BenchResult::parse(bytes, "fuzz.json") {
        Ok(accepted) => imported(&accepted),
        Err(e) => {
            let message = format!("{e:#}");
            if message.starts_with("fuzz.json: ") {
                Ok(())
            } else {
                Err(format!("a refusal that does not name fuzz.json: {message}"))
            }
        }
    }
}

#[cfg(feature = "results")]
fn imported(accepted: &BenchResult) -> Result<(), String> {
    use tessera::record::db::{Filter, ResultsDb, Tally};
    let dir = tempfile::tempdir().map_err(|e| format!("no temporary directory: {e}"))?;
    let mut db = ResultsDb::open(&dir.path().join("results.db"))
        .map_err(|e| format!("a new database does not open: {e:#}"))?;
    let added = (db.add_all(std::slice::from_ref(accepted), "fuzz"))
        .map_err(|e| format!("an accepted result is not added: {e:#}"))?;
    if added != (Tally { new: 1, present: 0 }) {
        return Err(format!("one result added to a new database gave {added:?}"));
    }
    let runs = (db.runs(&Filter::default())).map_err(|e| format!("runs unread: {e:#}"))?;
    if runs.len() != 1 {
        return Err(format!("one result added, {} runs listed", runs.len()));
    }
    let kept: Vec<String> = (db.result_ids())
        .and_then(|ids| ids.iter().map(|&id| db.result_json(id)).collect())
        .map_err(|e| format!("results unread: {e:#}"))?;
    let written = serde_json::to_string(accepted).map_err(|e| e.to_string())?;
    if kept != [written] {
        return Err(format!("the database gives back {kept:?}"));
    }
    match BenchResult::parse(kept[0].as_bytes(), "kept.json") {
        Ok(_) => Ok(()),
        Err(e) => Err(format!("what the database keeps is refused: {e:#}")),
    }
}

#[cfg(not(feature = "results"))]
fn imported(_: &BenchResult) -> Result<(), String> {
    Ok(())
}

/// 7. An image file a stranger made, whatever its kind (PNG, JPEG, EXR, PNM, … found by its
///    content), as `compare` reads it and as a scene's image texture: decoded, or refused
///    naming the file, each within its bounds (`MAX_COMPARED_PIXELS`, `MAX_TEXTURE_PIXELS`),
///    which the target's ceiling holds it to; and its bytes walked as a sequential JPEG's
///    scans (`jpeg_end::sequential_fault`), which must end without a panic whatever they are.
pub fn image(bytes: &[u8]) -> Result<(), String> {
    let _ = tessera::jpeg_end::sequential_fault(bytes);
    let dir = tempfile::tempdir().map_err(|e| format!("no temporary directory: {e}"))?;
    // Without an extension, so that the kind is found from the bytes, as for a file whose
    // extension says nothing.
    let file = dir.path().join("fuzz-image");
    std::fs::write(&file, bytes).map_err(|e| format!("the input is not written: {e}"))?;
    if let Err(e) = tessera::image_diff::RgbImage::load(&file) {
        names(&e, &file.display().to_string())?;
    }
    // As the texture of a scene beside it.
    let scene = r#"[textures.stranger]
type = "image"
file = "fuzz-image"

[materials.m]
type = "lambertian"
albedo = "stranger"

[[spheres]]
center = [0.0, 0.0, -1.0]
radius = 0.5
material = "m"
"#;
    let textures = tessera::scene::TextureSource::Dirs(vec![dir.path().to_owned()]);
    match Scene::parse_with(
        scene,
        Path::new("fuzz.toml"),
        &Overrides::default(),
        &textures,
    ) {
        Ok(_) => Ok(()),
        Err(e) => located(&e, "fuzz.toml"),
    }
}
