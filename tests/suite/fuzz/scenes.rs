//! Mutated scene files: a refusal says file:line:column; an accepted scene renders.

use super::harness::*;
use crate::common::*;
use std::path::{Path, PathBuf};
use tessera::render::{self, RenderOptions};
use tessera::scene::{Overrides, Scene};

/// Numbers chosen to sit on every edge: zero, signs, f32 and integer limits, NaN.
pub(crate) const NUMBERS: &[&str] = &[
    "0",
    "-0.0",
    "1",
    "-1",
    "2",
    "0.5",
    "1e-45",
    "1e-39",
    "1e-30",
    "1e-18",
    "1e18",
    "1e19",
    "1e20",
    "3e38",
    "4e38",
    "1.7e308",
    "-1.7e308",
    "nan",
    "inf",
    "-inf",
    "1e-300",
    "255",
    "4294967295",
    "4294967296",
    "2147483648",
    "268435457",
    "16384",
    "9223372036854775807",
    "-9223372036854775808",
    "18446744073709551616",
    "1000",
    "1001",
    "179.99999",
    "180",
];

/// Values of other types and shapes, to put where a number or string belongs.
const VALUES: &[&str] = &[
    "\"junk\"",
    "\"metal\"",
    "\"dielectric\"",
    "\"lambertian\"",
    "\"uniform\"",
    "\"gradient\"",
    "\"always\"",
    "\"inverted\"",
    "\"normals\"",
    "\"uv\"",
    "true",
    "[]",
    "[1, 2]",
    "[0, 0, 0]",
    "[1, 2, 3, 4]",
    "[0, 0, -1, \"junk\", [1, 2]]",
    "[1e20, 0, 0]",
    "[0, 1e-18, 0]",
    "[nan, 0, 0]",
    "[1, 0, 9223372036854775807, 4]",
    "[0, 0, 4294967295, 4294967295]",
    "{ a = 1 }",
    "1979-05-27",
    "'''\nmulti\n'''",
];

/// Whole lines to insert: keys of every table, some in the wrong place.
const LINES: &[&str] = &[
    "crop = [1, 1, 4, 4]",
    "crop = [0, 0, 9223372036854775807, 1]",
    "seed = 18446744073709551615",
    "vup = [0, 1e20, 0]",
    "aperture = 1e18",
    "focus_dist = 1e-30",
    "[camera]\nlookfrom = [3e38, 0, 0]\nlookat = [-3e38, 0, 0]\nvfov_deg = 90",
    "[camera]\nlookfrom = [0, 0, 0]\nlookat = [0, 0, 0]\nvfov_deg = 90",
    "[[spheres]]\ncenter = [0, 0, 0]\nradius = 1e18\nmaterial = \"ground\"",
    "[[spheres]]\ncenter = [0, 0, 0]\nradius = -1e-18\nmaterial = \"x\"",
    "[materials.x]\ntype = \"dielectric\"\nir = 1e-30\nrefraction = \"inverted\"",
    "[materials.y]\ntype = \"metal\"\nalbedo = [3e38, 3e38, 3e38]\nfuzz = 1",
    "[background]\ntype = \"uniform\"\ncolor = [3e38, 0, 1]",
    "[random_spheres]\ngrid = 3\nradius = 1e18",
    "[render]\nshading = \"normals\"\ngamma = 1e-30\nt_min = 1e30",
    "t_min = \"auto\"",
    "t_min = \"Auto\"",
    "t_min = 1e-45",
    "[image]\nwidth = 1\nheight = 268435456\nsamples_per_pixel = 1\nmax_depth = 1",
    "width = 0",
    "height = -5",
    "max_depth = 4294967296",
    "unknown = 1",
    "[[spheres]]",
    "[materials]",
    "\u{feff}",
    "\u{0}",
];

/// A scene with a table of every kind, as a seed for mutation besides the scene files.
const EVERYTHING: &str = r#"[image]
width = 24
height = 16
samples_per_pixel = 2
max_depth = 6
seed = 3
crop = [2, 2, 20, 12]

[render]
shading = "path"
diffuse = "unit_sphere"
gamma = 2.2
t_min = 0.001
jitter = true

[camera]
lookfrom = [3.0, 2.0, 3.0]
lookat = [0.0, 0.0, -1.0]
vup = [0.0, 1.0, 0.0]
vfov_deg = 40.0
aperture = 0.2
focus_dist = 4.0

[background]
type = "gradient"
bottom = [1.0, 1.0, 1.0]
top = [0.5, 0.7, 1.0]

[materials.ground]
type = "lambertian"
albedo = [0.8, 0.8, 0.0]

[materials.glass]
type = "dielectric"
ir = 1.5
refraction = "snell"

[materials.gold]
type = "metal"
albedo = [0.8, 0.6, 0.2]
fuzz = 0.3

[[spheres]]
center = [0.0, -100.5, -1.0]
radius = 100.0
material = "ground"

[[spheres]]
center = [-1.0, 0.0, -1.0]
radius = -0.45
material = "glass"

[[spheres]]
center = [1.0, 0.0, -1.0]
radius = 0.5
material = "gold"

[random_spheres]
grid = 2
radius = 0.2
keep_clear = [[4.0, 0.2, 0.0]]
clearance = 0.9
p_diffuse = 0.8
p_metal = 0.15
glass_ir = 1.5
seed = 7
"#;

/// The scene files to mutate: every scene file in `scenes/` and `EVERYTHING`.
fn scene_corpus() -> Vec<String> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(root().join("scenes"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    files.sort();
    let mut corpus: Vec<String> = files
        .iter()
        .map(|p| std::fs::read_to_string(p).unwrap())
        .collect();
    corpus.push(EVERYTHING.to_owned());
    corpus
}

/// Byte offsets of the numbers in `text` (runs of digits, signs, points and exponents).
pub(crate) fn number_spans(bytes: &[u8]) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i].is_ascii_digit() {
            let start = if i > 0 && bytes[i - 1] == b'-' {
                i - 1
            } else {
                i
            };
            while i < bytes.len()
                && (bytes[i].is_ascii_alphanumeric() || b".+-_".contains(&bytes[i]))
            {
                i += 1;
            }
            spans.push((start, i));
        } else {
            i += 1;
        }
    }
    spans
}

/// One random change to a scene file's bytes; `keep_syntax` keeps to changes that mostly
/// leave valid TOML, so the checks behind the parser are reached.
fn mutate_scene(g: &mut Gen, text: &mut Vec<u8>, keep_syntax: bool) {
    let lines =
        |t: &[u8]| -> Vec<Vec<u8>> { t.split(|&b| b == b'\n').map(<[u8]>::to_vec).collect() };
    match if keep_syntax { g.below(4) } else { g.below(9) } {
        // A number becomes an edge value.
        0 | 1 => {
            let spans = number_spans(text);
            if let Some(&(a, b)) = spans.get(g.below(spans.len())) {
                text.splice(a..b, g.pick(NUMBERS).bytes());
            }
        }
        // A value (after `=`) becomes something of another type or shape.
        2 => {
            let mut ls = lines(text);
            let i = g.below(ls.len());
            if let Some(eq) = ls[i].iter().position(|&b| b == b'=') {
                ls[i].truncate(eq + 1);
                ls[i].extend_from_slice(b" ");
                ls[i].extend_from_slice(g.pick(VALUES).as_bytes());
            }
            *text = ls.join(&b'\n');
        }
        // A line is inserted, deleted, duplicated or moved.
        3 => {
            let mut ls = lines(text);
            let at = g.below(ls.len() + 1);
            ls.insert(at, g.pick(LINES).as_bytes().to_vec());
            *text = ls.join(&b'\n');
        }
        4 => {
            let mut ls = lines(text);
            let (i, j) = (g.below(ls.len()), g.below(ls.len()));
            match g.below(3) {
                0 => drop(ls.remove(i)),
                1 => ls.insert(j, ls[i].clone()),
                _ => ls.swap(i, j),
            }
            *text = ls.join(&b'\n');
        }
        // Bytes: flipped, set to an odd value, inserted or cut.
        5 => {
            if !text.is_empty() {
                let i = g.below(text.len());
                text[i] ^= 1 << g.below(8);
            }
        }
        6 => {
            let i = g.below(text.len() + 1);
            let byte = g.pick(&[0u8, 0xff, 0xc3, b'[', b']', b'"', b'=', b'\n', b'#']);
            text.insert(i, byte);
        }
        7 => {
            let i = g.below(text.len() + 1);
            text.truncate(i);
        }
        // Everything doubled: duplicate tables and keys.
        _ => {
            let copy = text.clone();
            text.push(b'\n');
            text.extend_from_slice(&copy);
        }
    }
}

/// Checks that refusal `e` of a scene named `fuzz.toml` starts `fuzz.toml:LINE:COLUMN:`.
fn located(e: tessera::Error) -> Result<Outcome, String> {
    let message = e.to_string();
    let mut fields = message.splitn(4, ':');
    let placed = fields.next() == Some("fuzz.toml")
        && fields.next().is_some_and(|l| l.parse::<u32>().is_ok())
        && fields.next().is_some_and(|c| c.parse::<u32>().is_ok());
    if placed {
        Ok(Outcome::Refused)
    } else {
        Err(format!("a refusal without file:line:column: {message}"))
    }
}

/// Checks one scene file: reading it never panics; a refusal names the file, line and
/// column; an accepted scene renders small without panicking.
fn check_scene_case(bytes: &[u8]) -> Result<Outcome, String> {
    let path = Path::new("fuzz.toml");
    let Ok(text) = std::str::from_utf8(bytes) else {
        // Only loading a file meets invalid UTF-8.
        let dir = temp_dir("fuzz-utf8");
        std::fs::write(dir.join(path), bytes).unwrap();
        let e = Scene::load(&dir.join(path), &Overrides::default())
            .err()
            .ok_or("invalid UTF-8 accepted")?;
        let message = e.to_string().replace(&format!("{}/", dir.display()), "");
        return if message.starts_with("fuzz.toml:") && message.contains("UTF-8") {
            Ok(Outcome::Refused)
        } else {
            Err(format!(
                "invalid UTF-8 refused without its place: {message}"
            ))
        };
    };
    if let Err(e) = Scene::parse(text, path, &Overrides::default()) {
        return located(e);
    }
    // Accepted: render it tiny (a few pixels, one sample, short paths).
    let small = Overrides {
        width: Some(8),
        samples_per_pixel: Some(1),
        max_depth: Some(4),
        seed: None,
    };
    let scene = match Scene::parse(text, path, &small) {
        Ok(scene) => scene,
        // The new width can be what is refused (8 wide makes a tall file too tall).
        Err(tessera::Error::Setting { .. }) => return Ok(Outcome::Refused),
        Err(e) => return located(e),
    };
    let options = RenderOptions {
        threads: Some(1),
        tile: 8,
        ..RenderOptions::default()
    };
    let (film, stats) = render::render(&scene, &options, &|_| {}).map_err(|e| e.to_string())?;
    let window = scene.settings.window;
    if film.sums.len() as u64 != window.area() || stats.samples != window.area() {
        return Err(format!(
            "rendered {} pixels of a {window:?} window",
            film.sums.len()
        ));
    }
    Ok(Outcome::Accepted)
}

#[test]
fn mutated_scene_files_never_panic_and_refusals_say_where() {
    let corpus = scene_corpus();
    run_family(
        "scene",
        20_000,
        // Nothing a scene file says needs more than this at once, rendered 8 pixels wide.
        1 << 30,
        |g| {
            let mut text = corpus[g.below(corpus.len())].as_bytes().to_vec();
            let keep_syntax = g.chance(70);
            for _ in 0..1 + g.below(4) {
                mutate_scene(g, &mut text, keep_syntax);
            }
            let shown = String::from_utf8_lossy(&text).into_owned();
            (text, shown)
        },
        |text| check_scene_case(text),
    );
}
