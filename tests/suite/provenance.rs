//! Every image carries its recipe: render → `info` → `reproduce` gives `identical` for whole
//! renders, crops, merged shards and resumed checkpoints, with other thread counts and SIMD
//! paths; an edited pixel gives `differs`, a stripped image `no recipe`; and hostile
//! metadata (bombs, nesting, newer schemas, absurd renders, lies about lengths) is refused
//! by name, exit 2. The PNG is read back with the `png` crate's own decoder too.

use crate::common::*;
use std::path::{Path, PathBuf};
use std::process::Output;
use tessera::recipe::{self, Recipe};

fn out_text(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// `tessera reproduce` of `image` with one thread on the portable path (the renders below
/// use every core and the widest path).
fn reproduce(image: &Path, dir: &Path) -> Output {
    run(
        &[
            "reproduce",
            image.to_str().unwrap(),
            "--threads",
            "1",
            "--simd",
            "portable",
            "-q",
        ],
        dir,
    )
}

fn assert_identical(image: &Path, dir: &Path) {
    let o = reproduce(image, dir);
    assert_eq!(o.status.code(), Some(0), "{}{}", out_text(&o), stderr(&o));
    assert!(out_text(&o).starts_with("identical: "), "{}", out_text(&o));
}

/// The recipe text in a PNG, read with the `png` crate (not tessera's reader).
fn png_recipe_text(path: &Path) -> Option<String> {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    reader.next_frame(&mut buf).unwrap();
    reader.finish().unwrap();
    let info = reader.info();
    info.utf8_text
        .iter()
        .find(|c| c.keyword == recipe::KEY)
        .map(|c| c.get_text().unwrap())
}

/// The PNG's pixels (8-bit RGB) and size, read with the `png` crate.
fn png_pixels(path: &Path) -> (u32, u32, Vec<u8>) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let frame = reader.next_frame(&mut buf).unwrap();
    (frame.width, frame.height, buf)
}

/// Writes a PNG of `pixels` with `chunks` (keyword, text, compressed) as iTXt chunks, as
/// another program might.
fn write_png(path: &Path, (w, h, pixels): &(u32, u32, Vec<u8>), chunks: &[(&str, &str, bool)]) {
    let file = std::fs::File::create(path).unwrap();
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), *w, *h);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().unwrap();
    for &(key, text, compressed) in chunks {
        let mut chunk = png::text_metadata::ITXtChunk::new(key, text);
        chunk.compressed = compressed;
        writer.write_text_chunk(&chunk).unwrap();
    }
    writer.write_image_data(pixels).unwrap();
    writer.finish().unwrap();
}

/// A small cover render in `dir`, with `extra` arguments (its recipe unless they say not).
fn small_cover_with(dir: &Path, name: &str, extra: &[&str]) -> PathBuf {
    let mut args = vec!["render", "--width", "96", "--spp", "4", "-o", name, "-q"];
    args.extend(extra);
    let scene = cover();
    args.insert(1, &scene);
    ok(&args, dir);
    dir.join(name)
}

fn small_cover(dir: &Path, name: &str) -> PathBuf {
    small_cover_with(dir, name, &[])
}

#[test]
fn the_cover_reproduces_identically_from_its_recipe_alone() {
    let dir = temp_dir("provenance-cover");
    let image = small_cover(&dir, "cover.png");
    // The recipe, as a standard decoder reads it: tessera's JSON with the whole scene.
    let text = png_recipe_text(&image).expect("a recipe chunk");
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(json["schema"], recipe::SCHEMA);
    assert_eq!(json["scene"]["name"], "cover.toml");
    assert_eq!(
        json["scene"]["text"],
        std::fs::read_to_string(scene_path("cover.toml")).unwrap()
    );
    assert_eq!(json["overrides"]["width"], 96);
    assert_eq!(json["image"]["samples_per_pixel"], 4);
    assert!(
        text.len() < 4096,
        "the cover's recipe is {} bytes",
        text.len()
    );

    let o = run(&["info", "cover.png"], &dir);
    assert!(o.status.success(), "{}", stderr(&o));
    let info = out_text(&o);
    for expected in [
        "cover.png: PNG 96x64, with a recipe (tessera-recipe/1)",
        "scene      cover.toml",
        "settings   96x64, 4 spp, depth 50, seed 1, gamma 2",
        "overrides  --width 96 --spp 4",
        "[random_spheres]",
    ] {
        assert!(info.contains(expected), "`{expected}` not in:\n{info}");
    }
    let o = run(&["info", "cover.png", "--json"], &dir);
    let parsed = Recipe::parse(out_text(&o).trim(), Path::new("x")).unwrap();
    assert_eq!(parsed.sums, json["sums"].as_str().unwrap());

    // Again from the recipe alone: the scene file is elsewhere and unused.
    let elsewhere = temp_dir("provenance-cover-elsewhere");
    std::fs::copy(&image, elsewhere.join("copy.png")).unwrap();
    assert_identical(&elsewhere.join("copy.png"), &elsewhere);
    let o = run(
        &["reproduce", "copy.png", "-o", "again.png", "-q"],
        &elsewhere,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        std::fs::read(&image).unwrap(),
        std::fs::read(elsewhere.join("again.png")).unwrap(),
        "the re-render, recipe and all, is the same file"
    );
    ok(
        &["reproduce", "copy.png", "--extract-scene", "scene.toml"],
        &elsewhere,
    );
    assert_eq!(
        std::fs::read(elsewhere.join("scene.toml")).unwrap(),
        std::fs::read(scene_path("cover.toml")).unwrap()
    );
}

#[test]
fn a_cropped_figure_in_exr_reproduces_identically() {
    let dir = temp_dir("provenance-crop");
    let scene = scene_path("img-1.06-antialias-before-after.toml");
    ok(
        &[
            "render",
            scene.to_str().unwrap(),
            "--spp",
            "16",
            "-o",
            "crop.exr",
            "-q",
        ],
        &dir,
    );
    let info = out_text(&run(&["info", "crop.exr"], &dir));
    assert!(info.contains("crop 40x40 at (116, 105)"), "{info}");
    assert_identical(&dir.join("crop.exr"), &dir);
}

#[test]
fn merged_shards_and_resumed_checkpoints_carry_the_single_renders_recipe() {
    let dir = temp_dir("provenance-parts");
    let single = small_cover(&dir, "single.png");
    for i in 0..3 {
        let shard = format!("{i}/3");
        let extra = ["--split", "rows", "--shard", &shard];
        small_cover_with(&dir, &format!("p{i}.part"), &extra);
    }
    ok(
        &["merge", "p0.part", "p1.part", "p2.part", "-o", "merged.png"],
        &dir,
    );
    assert_eq!(
        std::fs::read(&single).unwrap(),
        std::fs::read(dir.join("merged.png")).unwrap()
    );
    assert_identical(&dir.join("merged.png"), &dir);

    // A render continued from a checkpoint of fewer samples.
    for spp in ["2", "4"] {
        ok(
            &[
                "render",
                &cover(),
                "--width",
                "96",
                "--spp",
                spp,
                "--checkpoint",
                "c.part",
                "-o",
                "resumed.png",
                "-q",
            ],
            &dir,
        );
    }
    assert_eq!(
        std::fs::read(&single).unwrap(),
        std::fs::read(dir.join("resumed.png")).unwrap()
    );
    assert_identical(&dir.join("resumed.png"), &dir);

    // --no-provenance leaves it out of parts and images, and a merge of such parts.
    small_cover_with(&dir, "bare.png", &["--no-provenance"]);
    assert_eq!(png_recipe_text(&dir.join("bare.png")), None);
    let o = run(&["reproduce", "bare.png"], &dir);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("no recipe"), "{}", stderr(&o));
    ok(
        &[
            "merge",
            "p0.part",
            "p1.part",
            "p2.part",
            "-o",
            "m.png",
            "--no-provenance",
        ],
        &dir,
    );
    assert_eq!(png_recipe_text(&dir.join("m.png")), None);
}

#[test]
fn a_scene_too_long_for_a_recipe_renders_without_one_and_says_so() {
    // The red sphere and 1.1 MB of comments: its recipe would pass the 1 MiB every reader of
    // recipes refuses, `info` first.
    let mut text = std::fs::read_to_string(scene_path("img-1.03-red-sphere.toml")).unwrap();
    text.push_str(&format!("# {}\n", "x".repeat(100)).repeat(11_000));
    let dir = dir_with_scene("provenance-too-long", &text);
    let size = ["--width", "32", "--spp", "2"];
    for image in ["long.png", "long.exr"] {
        let o = run(
            &[&["render", "scene.toml", "-o", image][..], &size].concat(),
            &dir,
        );
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        assert!(
            stderr(&o).contains("more than the 1048576 an image may carry")
                && stderr(&o).contains(&format!("so {image} carries none")),
            "{}",
            stderr(&o)
        );
        let o = run(&["info", image], &dir);
        assert_eq!(o.status.code(), Some(2), "{image}: {}", stderr(&o));
        assert!(stderr(&o).contains("no recipe"), "{}", stderr(&o));
    }
    assert_eq!(png_recipe_text(&dir.join("long.png")), None);
    // Parts carry none either, and their merge says it has none to carry.
    for shard in ["0/2", "1/2"] {
        let part = format!("p{}.part", &shard[..1]);
        let o = run(
            &[
                &["render", "scene.toml", "--shard", shard, "-o", &part][..],
                &size,
            ]
            .concat(),
            &dir,
        );
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        assert!(stderr(&o).contains("carries none"), "{}", stderr(&o));
    }
    let o = run(&["merge", "p0.part", "p1.part", "-o", "m.png"], &dir);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("carry no common recipe"),
        "{}",
        stderr(&o)
    );
    assert_eq!(png_recipe_text(&dir.join("m.png")), None);
    // A PPM carries none in any case, and --no-provenance leaves it out: no warning.
    for extra in [
        &["-o", "long.ppm"][..],
        &["-o", "bare.png", "--no-provenance"],
    ] {
        let o = run(
            &[&["render", "scene.toml"][..], &size, extra].concat(),
            &dir,
        );
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        assert!(!stderr(&o).contains("warning"), "{}", stderr(&o));
    }
}

#[test]
fn an_edited_or_stripped_image_is_never_called_identical() {
    let dir = temp_dir("provenance-edits");
    let image = small_cover(&dir, "cover.png");
    let recipe_text = png_recipe_text(&image).unwrap();
    let (w, h, pixels) = png_pixels(&image);

    // Re-saved by another program, recipe kept: still identical.
    write_png(
        &dir.join("resaved.png"),
        &(w, h, pixels.clone()),
        &[(recipe::KEY, &recipe_text, false)],
    );
    assert_identical(&dir.join("resaved.png"), &dir);

    // One pixel changed by one level.
    let mut edited = pixels.clone();
    let at = 3 * (17 * w as usize + 40);
    edited[at + 1] ^= 1;
    write_png(
        &dir.join("edited.png"),
        &(w, h, edited),
        &[(recipe::KEY, &recipe_text, true)],
    );
    let o = reproduce(&dir.join("edited.png"), &dir);
    assert_eq!(o.status.code(), Some(1), "{}", out_text(&o));
    let text = out_text(&o);
    assert!(text.starts_with("differs: "), "{text}");
    assert!(
        text.contains("1 of 6144 pixels differ, the first at (40, 17)"),
        "{text}"
    );

    // Stripped of its metadata.
    write_png(&dir.join("stripped.png"), &(w, h, pixels.clone()), &[]);
    let o = reproduce(&dir.join("stripped.png"), &dir);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("no recipe"), "{}", stderr(&o));

    // A recipe edited to claim other sums: the pixels are right, the claim is not.
    let mut lying: serde_json::Value = serde_json::from_str(&recipe_text).unwrap();
    lying["sums"] = serde_json::Value::from(format!("xxh3-128:{}", "0".repeat(32)));
    write_png(
        &dir.join("lying.png"),
        &(w, h, pixels.clone()),
        &[(recipe::KEY, &lying.to_string(), true)],
    );
    let o = reproduce(&dir.join("lying.png"), &dir);
    assert_eq!(o.status.code(), Some(1), "{}", out_text(&o));
    assert!(
        out_text(&o).contains("the recipe says xxh3-128:000"),
        "{}",
        out_text(&o)
    );

    // A recipe whose settings its scene does not give (the seed changed in one place only).
    let mut seeded: serde_json::Value = serde_json::from_str(&recipe_text).unwrap();
    seeded["image"]["seed"] = serde_json::Value::from(2);
    write_png(
        &dir.join("seeded.png"),
        &(w, h, pixels.clone()),
        &[(recipe::KEY, &seeded.to_string(), true)],
    );
    let o = reproduce(&dir.join("seeded.png"), &dir);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("not what its scene and overrides give"),
        "{}",
        stderr(&o)
    );

    // Cropped by another program: another size than the recipe makes.
    let cropped: Vec<u8> = pixels[..3 * w as usize * (h as usize - 1)].to_vec();
    write_png(
        &dir.join("cropped.png"),
        &(w, h - 1, cropped),
        &[(recipe::KEY, &recipe_text, true)],
    );
    let o = reproduce(&dir.join("cropped.png"), &dir);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        out_text(&o).contains("is 96x63, its recipe makes 96x64"),
        "{}",
        out_text(&o)
    );
}

/// `info` printed whatever settings a recipe claimed, where `reproduce` refused them as not
/// what its own scene gives: a stranger's image claiming 500 samples and seed 9 of a scene of
/// 4 and seed 1 was shown as such. Both now run one check (`Recipe::checked`) and
/// refuse it alike, naming each setting that differs; no texture file is needed for it.
#[test]
fn info_refuses_a_recipe_whose_settings_its_scene_does_not_give() {
    let dir = temp_dir("provenance-info-lying");
    let image = small_cover(&dir, "cover.png");
    let recipe_text = png_recipe_text(&image).unwrap();
    let pixels = png_pixels(&image);
    let mut lying: serde_json::Value = serde_json::from_str(&recipe_text).unwrap();
    lying["image"]["seed"] = serde_json::Value::from(9);
    lying["image"]["samples_per_pixel"] = serde_json::Value::from(500);
    write_png(
        &dir.join("lying.png"),
        &pixels,
        &[(recipe::KEY, &lying.to_string(), true)],
    );
    for args in [
        &["info", "lying.png"][..],
        &["info", "--json", "lying.png"],
        &["reproduce", "lying.png", "-q"],
    ] {
        let o = run(args, &dir);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(out_text(&o).is_empty(), "{args:?}: {}", out_text(&o));
        for expected in [
            "lying.png: its recipe's settings (96x64, 500 spp, depth 50, seed 9, gamma 2) are \
             not what its scene and overrides give (96x64, 4 spp, depth 50, seed 1, gamma 2)",
            "samples_per_pixel 500, the scene gives 4; seed 9, the scene gives 1",
        ] {
            assert!(
                err.contains(expected),
                "{args:?}: `{expected}` not in {err}"
            );
        }
    }
    // A recipe whose scene is not a scene is refused by `info` as by `reproduce`.
    let mut broken = lying.clone();
    broken["image"] =
        serde_json::from_str::<serde_json::Value>(&recipe_text).unwrap()["image"].clone();
    broken["scene"]["text"] = serde_json::Value::from("[image]\nwidth = 0\n");
    write_png(
        &dir.join("broken.png"),
        &pixels,
        &[(recipe::KEY, &broken.to_string(), true)],
    );
    let o = run(&["info", "broken.png"], &dir);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("broken.png (recipe scene cover.toml)"),
        "{}",
        stderr(&o)
    );
    // The recipe as rendered still prints, with its settings.
    let o = run(&["info", "cover.png"], &dir);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(out_text(&o).contains("settings   96x64, 4 spp, depth 50, seed 1, gamma 2"));
}

/// `reproduce` says `differs` without rendering where an image is of another size than its
/// recipe makes (or holds what changes how it is shown), and `info` printed such an image's
/// recipe as any other's, with no word of it. It says so now, in a line and in a field
/// `differs` of its JSON, from the check `reproduce` makes (`verify::unrendered`).
#[test]
fn info_says_differs_where_reproduce_says_it_without_rendering() {
    let dir = temp_dir("provenance-info-differs");
    let image = small_cover(&dir, "cover.png");
    let recipe_text = png_recipe_text(&image).unwrap();
    let (w, h, pixels) = png_pixels(&image);
    let cropped = (
        w,
        h - 1,
        pixels[..3 * w as usize * (h as usize - 1)].to_vec(),
    );
    write_png(
        &dir.join("cropped.png"),
        &cropped,
        &[(recipe::KEY, &recipe_text, true)],
    );
    let said = "cropped.png is 96x63, its recipe makes 96x64";
    let o = run(&["info", "cropped.png"], &dir);
    assert!(o.status.success(), "{}", stderr(&o));
    let info = out_text(&o);
    assert!(info.contains(&format!("\n  differs    {said}\n")), "{info}");
    assert!(!info.contains("check      tessera reproduce"), "{info}");
    let o = run(&["info", "--json", "cropped.png"], &dir);
    assert!(o.status.success(), "{}", stderr(&o));
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(json["differs"]["summary"], said);
    assert_eq!(json["differs"]["details"], serde_json::json!([]));
    let written: serde_json::Value = serde_json::from_str(&recipe_text).unwrap();
    assert_eq!(json["sums"], written["sums"]);
    let o = reproduce(&dir.join("cropped.png"), &dir);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let text = out_text(&o);
    assert!(
        text.starts_with("differs: ") && text.ends_with(&format!("/{said}\n")),
        "{text}"
    );
    // The image whole: no `differs`, and the JSON is the recipe as written.
    let o = run(&["info", "--json", "cover.png"], &dir);
    let parsed = Recipe::parse(out_text(&o).trim(), Path::new("x")).unwrap();
    assert_eq!(parsed.sums, written["sums"].as_str().unwrap());
}

/// A recipe whose settings its scene does not give, on an image of another size than it
/// claims: Python's `reproduce` checked the image first and said `differs`, the command line
/// checked the recipe first and refused it. One function (`verify::unrendered`) checks both
/// for `info`, `reproduce` and Python, in one order, the recipe first: an error from each.
#[test]
fn a_lying_recipe_on_an_image_of_another_size_is_refused_by_each() {
    let dir = temp_dir("provenance-lying-cropped");
    let image = small_cover(&dir, "cover.png");
    let recipe_text = png_recipe_text(&image).unwrap();
    let (w, h, pixels) = png_pixels(&image);
    let cropped = (
        w,
        h - 1,
        pixels[..3 * w as usize * (h as usize - 1)].to_vec(),
    );
    let written: serde_json::Value = serde_json::from_str(&recipe_text).unwrap();
    let mut lying = written.clone();
    lying["image"]["seed"] = serde_json::Value::from(9);
    write_png(
        &dir.join("both.png"),
        &cropped,
        &[(recipe::KEY, &lying.to_string(), true)],
    );
    for args in [
        &["info", "both.png"][..],
        &["info", "--json", "both.png"],
        &["reproduce", "both.png", "-q"],
    ] {
        let o = run(args, &dir);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", out_text(&o));
        assert!(
            stderr(&o).contains("seed 9, the scene gives 1"),
            "{args:?}: {}",
            stderr(&o)
        );
    }
    let header = tessera::image_file::read_header(&dir.join("both.png")).unwrap();
    let recipe = Recipe::parse(header.recipe.as_deref().unwrap(), Path::new("both.png")).unwrap();
    let checked = tessera::verify::unrendered(Path::new("both.png"), &header, &recipe);
    assert!(checked.is_err());
}

/// Runs `info` and `reproduce` on a PNG whose recipe chunk holds `text` (compressed or
/// not), expecting a refusal naming `expected`.
fn assert_refused(dir: &Path, name: &str, text: &str, compressed: bool, expected: &str) {
    let pixels = (2, 2, vec![0u8; 12]);
    let path = dir.join(format!("{name}.png"));
    write_png(&path, &pixels, &[(recipe::KEY, text, compressed)]);
    for command in ["info", "reproduce"] {
        let o = run(&[command, path.to_str().unwrap()], dir);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{name} {command}: {err}");
        assert!(!err.contains("panicked"), "{name}: {err}");
        assert!(
            err.contains(expected),
            "{name} {command}: `{expected}` not in {err}"
        );
    }
}

#[test]
fn hostile_recipes_are_refused_by_name() {
    let dir = temp_dir("provenance-hostile");
    let image = small_cover(&dir, "cover.png");
    let good = png_recipe_text(&image).unwrap();
    let json: serde_json::Value = serde_json::from_str(&good).unwrap();

    // A decompression bomb: 64 MiB of spaces in a few kilobytes.
    let bomb = format!("{good}{}", " ".repeat(64 << 20));
    assert_refused(
        &dir,
        "bomb",
        &bomb,
        true,
        "inflates beyond the 1048576 bytes",
    );
    // Deep nesting, and text that is not JSON.
    let deep = format!("{}{}", "[".repeat(100_000), "]".repeat(100_000));
    assert_refused(&dir, "deep", &deep, true, "is not a tessera recipe");
    assert_refused(
        &dir,
        "junk",
        "not json at all",
        false,
        "is not a tessera recipe",
    );
    // A newer tessera's recipe, and one with a field this tessera does not know.
    let newer = good.replace(recipe::SCHEMA, "tessera-recipe/2");
    assert_refused(&dir, "newer", &newer, true, "needs tessera-recipe/2");
    let mut extra = json.clone();
    extra["image"]["tonemap"] = serde_json::Value::from("aces");
    assert_refused(
        &dir,
        "unknown-field",
        &extra.to_string(),
        true,
        "does not know",
    );
    // An absurd render: checked as a scene file is, before anything is allocated for it.
    let mut absurd = json.clone();
    let text = absurd["scene"]["text"].as_str().unwrap().replace(
        "width = 1200\nheight = 800",
        "width = 65536\nheight = 65536",
    );
    absurd["scene"]["text"] = serde_json::Value::from(text);
    absurd["overrides"] = serde_json::json!({"samples_per_pixel": 1000000});
    let path = dir.join("absurd.png");
    write_png(
        &path,
        &(2, 2, vec![0; 12]),
        &[(recipe::KEY, &absurd.to_string(), true)],
    );
    let o = run(&["reproduce", "absurd.png"], &dir);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("more than the 268435456 pixels"),
        "{}",
        stderr(&o)
    );
    assert!(
        stderr(&o).contains("absurd.png (recipe scene cover.toml)"),
        "{}",
        stderr(&o)
    );

    // Not UTF-8 inside the chunk: written by hand, with a correct CRC.
    let bytes = itxt_png(b"tessera-recipe\0\0\0\0\0{\"schema\":\"\xff\xfe\"}");
    std::fs::write(dir.join("latin.png"), &bytes).unwrap();
    let o = run(&["info", "latin.png"], &dir);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("not UTF-8"), "{}", stderr(&o));
    // A chunk claiming more bytes than the file has, and a damaged CRC.
    let mut long = itxt_png(b"tessera-recipe\0\0\0\0\0{}");
    long[33..37].copy_from_slice(&0x7fff_0000u32.to_be_bytes());
    std::fs::write(dir.join("long.png"), &long).unwrap();
    let o = run(&["info", "long.png"], &dir);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("past the file's end"), "{}", stderr(&o));
    let mut damaged = itxt_png(b"tessera-recipe\0\0\0\0\0{}");
    // In the text, after the keyword: a chunk of another keyword is skipped unread.
    damaged[61] ^= 1;
    std::fs::write(dir.join("damaged.png"), &damaged).unwrap();
    let o = run(&["info", "damaged.png"], &dir);
    assert!(stderr(&o).contains("bad CRC"), "{}", stderr(&o));
    // A terminal escape in the scene's name is shown escaped.
    let mut named = json.clone();
    named["scene"]["name"] = serde_json::Value::from("evil\u{1b}[2J.toml");
    write_png(
        &dir.join("named.png"),
        &(2, 2, vec![0; 12]),
        &[(recipe::KEY, &named.to_string(), true)],
    );
    let o = run(&["info", "named.png"], &dir);
    assert!(!out_text(&o).contains('\u{1b}'), "{}", out_text(&o));
    assert!(
        out_text(&o).contains("evil\\u{1b}[2J.toml"),
        "{}",
        out_text(&o)
    );
}

/// A 1x1 PNG whose first chunk after IHDR is an iTXt chunk of `data` (CRC correct).
fn itxt_png(data: &[u8]) -> Vec<u8> {
    let mut out = vec![0x89, b'P', b'N', b'G', 0x0d, 0x0a, 0x1a, 0x0a];
    let mut chunk = |kind: &[u8], body: &[u8]| {
        out.extend((body.len() as u32).to_be_bytes());
        let mut crc = crc32fast::Hasher::new();
        crc.update(kind);
        crc.update(body);
        out.extend(kind);
        out.extend(body);
        out.extend(crc.finalize().to_be_bytes());
    };
    chunk(b"IHDR", &[0, 0, 0, 1, 0, 0, 0, 1, 8, 2, 0, 0, 0]);
    chunk(b"iTXt", data);
    chunk(b"IEND", &[]);
    out
}

/// An image of a textured scene records each texture file's name and hash; `reproduce` finds
/// the file next to the image or in `scenes/`, or where `--textures` says, and refuses, by
/// name, one that is missing or not the file the image was made with.
#[test]
fn a_textured_scenes_recipe_names_its_texture_and_reproduce_checks_it() {
    let dir = temp_dir("recipe-texture");
    let scene = dir.join("earth.toml");
    std::fs::copy(scene_path("img-2.15-earth-sphere.toml"), &scene).unwrap();
    std::fs::copy(scene_path("earthmap.jpg"), dir.join("earthmap.jpg")).unwrap();
    let args = [
        "render",
        "earth.toml",
        "--width",
        "60",
        "--spp",
        "4",
        "-q",
        "-o",
        "earth.png",
    ];
    ok(&args, &dir);
    let text = png_recipe_text(&dir.join("earth.png")).expect("a recipe");
    let recipe = Recipe::parse(&text, Path::new("earth.png")).unwrap();
    let hash = format!(
        "xxh3-128:{:032x}",
        xxhash_rust::xxh3::xxh3_128(&std::fs::read(dir.join("earthmap.jpg")).unwrap())
    );
    assert_eq!(recipe.textures.len(), 1);
    assert_eq!(
        (recipe.textures[0].name.as_str(), &recipe.textures[0].hash),
        ("earthmap.jpg", &hash)
    );
    let info = run(&["info", "earth.png"], &dir);
    assert!(
        out_text(&info).contains("texture    earthmap.jpg (xxh3-128:"),
        "{}",
        out_text(&info)
    );
    // Next to the image.
    assert_identical(&dir.join("earth.png"), &dir);
    // Moved away from its texture: found in a directory given, else refused by name.
    std::fs::create_dir_all(dir.join("elsewhere")).unwrap();
    std::fs::rename(dir.join("earth.png"), dir.join("elsewhere/earth.png")).unwrap();
    let missing = run(&["reproduce", "elsewhere/earth.png", "-q"], &dir);
    assert_eq!(missing.status.code(), Some(2), "{}", out_text(&missing));
    assert!(
        stderr(&missing).contains("texture file `earthmap.jpg` is not found")
            && stderr(&missing).contains("--textures"),
        "{}",
        stderr(&missing)
    );
    let o = run(
        &["reproduce", "elsewhere/earth.png", "-q", "--textures", "."],
        &dir,
    );
    assert_eq!(o.status.code(), Some(0), "{}{}", out_text(&o), stderr(&o));
    // A different file of the same name next to the image.
    std::fs::write(dir.join("elsewhere/earthmap.jpg"), b"not the earth").unwrap();
    let other = run(&["reproduce", "elsewhere/earth.png", "-q"], &dir);
    assert_eq!(other.status.code(), Some(2));
    assert!(
        stderr(&other).contains("is not the file the image was made with"),
        "{}",
        stderr(&other)
    );
}

/// `reproduce -o` and `--extract-scene` naming a texture file the recipe's scene reads (next
/// to the image: a file that came with it) are refused before anything is written, as
/// `render -o` refuses it: they replaced the texture, and the image no longer reproduced.
#[test]
fn reproduce_writes_over_no_texture_its_recipe_reads() {
    let dir = temp_dir("recipe-texture-output");
    // A texture that is a PNG, as `-o` may write: a small render of tessera's own.
    let first = scene_path("img-1.07-first-diffuse.toml");
    let args = [
        "render",
        first.to_str().unwrap(),
        "--width",
        "16",
        "--spp",
        "1",
        "-q",
        "-o",
    ];
    ok(&[&args[..], &["tex.png"]].concat(), &dir);
    let text = std::fs::read_to_string(scene_path("img-2.15-earth-sphere.toml")).unwrap();
    std::fs::write(
        dir.join("earth.toml"),
        text.replace("earthmap.jpg", "tex.png"),
    )
    .unwrap();
    let args = ["render", "earth.toml", "--width", "20", "--spp", "1", "-q"];
    ok(&[&args[..], &["-o", "earth.png"]].concat(), &dir);
    let texture = std::fs::read(dir.join("tex.png")).unwrap();
    for (flag, name) in [("-o", "tex.png"), ("--extract-scene", "./tex.png")] {
        let o = run(&["reproduce", "earth.png", "-q", flag, name], &dir);
        assert_eq!(o.status.code(), Some(2), "{flag}: {}", out_text(&o));
        assert!(
            stderr(&o).contains("names the texture file `tex.png` the recipe's scene reads"),
            "{flag}: {}",
            stderr(&o)
        );
        assert_eq!(
            std::fs::read(dir.join("tex.png")).unwrap(),
            texture,
            "{flag}"
        );
    }
    // Written elsewhere, and the texture unchanged: the image still reproduces.
    let o = run(&["reproduce", "earth.png", "-q", "-o", "again.png"], &dir);
    assert_eq!(o.status.code(), Some(0), "{}{}", out_text(&o), stderr(&o));
    assert_identical(&dir.join("earth.png"), &dir);
}
