//! Bad scene files: each is refused with its file, line, column and field, exit status 2,
//! and the old output left intact; values f32 cannot represent are refused by name, and the
//! largest ones allowed render right.

use crate::common::*;
use std::path::PathBuf;

/// Writes `text` as a scene, renders it over an existing output, and checks the failure:
/// exit status 2, every expected fragment in the message, no panic, the old output intact.
fn assert_rejected(name: &str, text: &str, expected: &[&str]) {
    let dir = temp_dir(&format!("bad-{name}"));
    let scene = dir.join("scene.toml");
    std::fs::write(&scene, text).unwrap();
    let out = dir.join("out.png");
    std::fs::write(&out, b"precious").unwrap();
    let o = run(&["render", "scene.toml", "-o", "out.png"], &dir);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{name}: {err}");
    assert!(!err.contains("panicked"), "{name}: {err}");
    for e in expected {
        assert!(err.contains(e), "{name}: expected `{e}` in: {err}");
    }
    assert_eq!(
        std::fs::read(&out).unwrap(),
        b"precious",
        "{name} damaged the old output"
    );
    let leftovers: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(
        leftovers.len(),
        2,
        "{name} left files behind: {leftovers:?}"
    );
}

#[test]
fn the_good_scene_renders() {
    let dir = dir_with_scene("good", GOOD);
    let o = run(&["render", "scene.toml", "-o", "out.png", "-q"], &dir);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn unknown_key_is_named_with_its_line_and_column() {
    let text = GOOD.replace("max_depth = 5", "max_depth = 5\nwidht = 3");
    assert_rejected(
        "unknown-key",
        &text,
        &[
            "scene.toml:6:1",
            "field `image.widht`: unknown field `widht`",
        ],
    );
}

#[test]
fn a_value_of_the_wrong_shape_names_its_field() {
    for (name, from, to, expected) in [
        (
            "short-center",
            "center = [0.0, 0.0, -1.0]",
            "center = [0.0, -1.0]",
            "scene.toml:12:10: field `spheres[0].center`: invalid length 2",
        ),
        (
            "text-radius",
            "radius = 0.5",
            "radius = \"half\"",
            "scene.toml:13:10: field `spheres[0].radius`: invalid type: string",
        ),
        (
            "float-width",
            "width = 16",
            "width = 16.5",
            "scene.toml:2:9: field `image.width`: invalid type: floating point",
        ),
    ] {
        assert_rejected(name, &GOOD.replace(from, to), &[expected]);
    }
}

#[test]
fn unknown_material_name_lists_the_defined_ones() {
    let text = GOOD.replace("material = \"red\"", "material = \"blue\"");
    assert_rejected(
        "unknown-material",
        &text,
        &[
            "scene.toml:14:12",
            "spheres[0].material",
            "unknown material `blue`",
            "red",
        ],
    );
}

/// A scene of many materials (or textures) and one misspelt name is told the first few
/// names and how many more: every name once went into the message, 2.9 MB for 100,000
/// materials, which the terminal showed cut in the middle of a name.
#[test]
fn an_unknown_name_among_many_lists_a_few_and_counts_the_rest() {
    let long = format!("a{}", "n".repeat(100_000));
    let mut materials =
        format!("[materials.{long}]\ntype = \"lambertian\"\nalbedo = [0.5, 0.5, 0.5]\n");
    let mut textures = String::new();
    for i in 0..2000 {
        materials +=
            &format!("[materials.m{i:04}]\ntype = \"lambertian\"\nalbedo = [0.5, 0.5, 0.5]\n");
        textures += &format!("[textures.t{i:04}]\ntype = \"solid\"\ncolor = [0.5, 0.5, 0.5]\n");
    }
    for (name, text, expected) in [
        (
            "many-materials",
            GOOD.replace("material = \"red\"", "material = \"blue\"") + &materials,
            &format!(
                "unknown material `blue` (defined materials: a{}…, m0000, m0001,",
                "n".repeat(63)
            ),
        ),
        (
            "many-textures",
            GOOD.replace("albedo = [0.9, 0.1, 0.1]", "albedo = \"blue\"") + &textures,
            &"unknown texture `blue` (defined textures: t0000, t0001,".to_owned(),
        ),
    ] {
        let dir = dir_with_scene(name, &text);
        let o = run(&["render", "scene.toml", "-o", "out.png"], &dir);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains(expected), "{err}");
        assert!(!err.contains("characters left out"), "{err}");
        let more = if name == "many-materials" { 1986 } else { 1984 };
        assert!(err.contains(&format!(", and {more} more)")), "{err}");
        assert!(err.len() < 1000, "a message of {} bytes", err.len());
    }
}

#[test]
fn unknown_material_type_is_rejected() {
    let text = GOOD.replace("type = \"lambertian\"", "type = \"plastic\"");
    assert_rejected(
        "material-type",
        &text,
        &["scene.toml:8:8", "materials.red.type", "plastic"],
    );
}

#[test]
fn missing_field_is_named() {
    assert_rejected(
        "missing-height",
        &GOOD.replace("height = 9\n", ""),
        &["scene.toml:1:1", "[image]: missing key `height`"],
    );
    let no_albedo = GOOD.replace("albedo = [0.9, 0.1, 0.1]\n", "");
    assert_rejected(
        "missing-albedo",
        &no_albedo,
        &["scene.toml:7:1", "materials.red.albedo", "missing"],
    );
}

#[test]
fn negative_and_zero_sizes_are_rejected() {
    assert_rejected(
        "negative-width",
        &GOOD.replace("width = 16", "width = -16"),
        &["scene.toml:2:9", "image.width", "must be positive, got -16"],
    );
    assert_rejected(
        "zero-spp",
        &GOOD.replace("samples_per_pixel = 1", "samples_per_pixel = 0"),
        &[
            "scene.toml:4:21",
            "image.samples_per_pixel",
            "must be positive",
        ],
    );
    assert_rejected(
        "zero-radius",
        &GOOD.replace("radius = 0.5", "radius = 0.0"),
        &["scene.toml:13:10", "spheres[0].radius", "non-zero"],
    );
}

#[test]
fn t_min_is_auto_or_a_distance() {
    let with = |value: &str| {
        GOOD.replace(
            "max_depth = 5\n",
            &format!("max_depth = 5\n[render]\nt_min = {value}\n"),
        )
    };
    for good in ["\"auto\"", "0", "0.001", "2"] {
        let dir = dir_with_scene("t-min-good", with(good));
        let o = run(&["render", "scene.toml", "-o", "out.png", "-q"], &dir);
        assert!(o.status.success(), "t_min = {good}: {}", stderr(&o));
    }
    assert_rejected(
        "t-min-word",
        &with("\"automatic\""),
        &["scene.toml:7:9", "\"auto\" or a distance", "automatic"],
    );
    assert_rejected(
        "t-min-negative",
        &with("-0.5"),
        &[
            "scene.toml:7:9",
            "render.t_min",
            "must be \"auto\" or zero or positive, got -0.5",
        ],
    );
    assert_rejected(
        "t-min-array",
        &with("[0.001]"),
        &["scene.toml:7:9", "\"auto\" or a distance"],
    );
}

#[test]
fn nan_and_infinity_are_rejected() {
    assert_rejected(
        "nan-radius",
        &GOOD.replace("radius = 0.5", "radius = nan"),
        &["scene.toml:13:10", "spheres[0].radius", "finite", "NaN"],
    );
    assert_rejected(
        "inf-center",
        &GOOD.replace("[0.0, 0.0, -1.0]", "[0.0, inf, -1.0]"),
        &["scene.toml:12:10", "spheres[0].center", "finite"],
    );
    // A range's message reads as one sentence, without a run of the source's indentation.
    assert_rejected(
        "inf-move-times",
        &GOOD.replace(
            "radius = 0.5",
            "radius = 0.5\ncenter2 = [0.0, 1.0, -1.0]\nmove_times = [0.0, inf]",
        ),
        &[
            "spheres[0].move_times",
            "within ±1e18, low at most high, got [0, inf]",
        ],
    );
}

/// A range's bound is the one its message writes, as a point's: 1e18 itself is within it.
#[test]
fn a_range_at_the_bound_its_message_writes_is_within_it() {
    let moving = |times: &str| {
        GOOD.replace(
            "radius = 0.5",
            &format!("radius = 0.5\ncenter2 = [0.0, 1.0, -1.0]\nmove_times = {times}"),
        )
    };
    let dir = dir_with_scene("range-at-bound", moving("[-1e18, 1e18]"));
    let o = run(&["render", "scene.toml", "-o", "out.png", "-q"], &dir);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_rejected(
        "range-past-bound",
        &moving("[0.0, 2e18]"),
        &[
            "spheres[0].move_times",
            "within ±1e18, low at most high, got [0, 2e18]",
        ],
    );
}

#[test]
fn malformed_toml_is_located() {
    assert_rejected(
        "syntax",
        &GOOD.replace("width = 16", "width = = 16"),
        &["scene.toml:2:"],
    );
    assert_rejected(
        "wrong-type",
        &GOOD.replace("width = 16", "width = \"wide\""),
        &["scene.toml:2:9", "integer"],
    );
}

#[test]
fn fields_of_another_material_type_are_rejected() {
    let text = GOOD.replace(
        "albedo = [0.9, 0.1, 0.1]",
        "albedo = [0.9, 0.1, 0.1]\nir = 1.5",
    );
    assert_rejected(
        "foreign-field",
        &text,
        &["scene.toml:10:6", "materials.red.ir", "does not apply"],
    );
}

#[test]
fn arrays_of_the_wrong_length_are_rejected() {
    assert_rejected(
        "long-center",
        &GOOD.replace("[0.0, 0.0, -1.0]", "[0, 0, -1, \"junk\", [1, 2]]"),
        &["scene.toml:12:10", "invalid length 5", "array of 3"],
    );
    assert_rejected(
        "short-center",
        &GOOD.replace("[0.0, 0.0, -1.0]", "[0, 0]"),
        &["scene.toml:12:10", "invalid length 2", "array of 3"],
    );
    assert_rejected(
        "long-albedo",
        &GOOD.replace("[0.9, 0.1, 0.1]", "[0.9, 0.1, 0.1, 0.5, 0.5]"),
        &["scene.toml:9:10", "invalid length 5"],
    );
    assert_rejected(
        "long-crop",
        &GOOD.replace("max_depth = 5", "max_depth = 5\ncrop = [0, 0, 4, 4, 1, 1]"),
        &["scene.toml:6:8", "invalid length 6", "array of 4"],
    );
}

#[test]
fn a_crop_not_inside_the_image_is_rejected_without_overflow() {
    // x + width overflows i64: it must not wrap round to a small right edge.
    let text = GOOD
        .replace("width = 16", "width = 32")
        .replace("height = 9", "height = 18")
        .replace(
            "max_depth = 5",
            "max_depth = 5\ncrop = [1, 0, 9223372036854775807, 4]",
        );
    assert_rejected(
        "crop-overflow",
        &text,
        &["scene.toml:6:8", "image.crop", "inside the 32x18 image"],
    );
    assert_rejected(
        "crop-outside",
        &GOOD.replace("max_depth = 5", "max_depth = 5\ncrop = [10, 0, 7, 4]"),
        &["scene.toml:6:8", "image.crop"],
    );
}

#[test]
fn invalid_utf8_is_located() {
    let dir = temp_dir("bad-utf8");
    let mut text = GOOD.as_bytes().to_vec();
    let at = GOOD.find("[materials").unwrap();
    text.splice(at..at, b"# caf\xe9\n".iter().copied());
    std::fs::write(dir.join("scene.toml"), &text).unwrap();
    let o = run(&["render", "scene.toml", "-o", "out.png"], &dir);
    assert_eq!(o.status.code(), Some(2));
    let err = stderr(&o);
    assert!(
        err.contains("scene.toml:7:6") && err.contains("UTF-8"),
        "{err}"
    );
}

/// The scene `GOOD` seen from inside a sphere of `radius` and `material` around the camera.
fn inside_sphere(radius: &str, camera: &str) -> String {
    format!(
        "{GOOD}\n[materials.black]\ntype = \"lambertian\"\nalbedo = [0, 0, 0]\n\n\
         [[spheres]]\ncenter = [0, 0, 0]\nradius = {radius}\nmaterial = \"black\"\n\n\
         [camera]\n{camera}\n"
    )
}

const LOOK_DOWN_Z: &str = "lookfrom = [0, 0, 0]\nlookat = [0, 0, -1]\nvfov_deg = 90";

/// Renders `text` as a small PPM; returns its pixel values, or the failure.
fn render_ppm(name: &str, text: &str) -> Result<Vec<u8>, String> {
    let dir = dir_with_scene(name, text);
    let o = run(&["render", "scene.toml", "-o", "out.ppm", "-q"], &dir);
    if !o.status.success() {
        return Err(stderr(&o));
    }
    Ok(std::fs::read(dir.join("out.ppm")).unwrap())
}

#[test]
fn geometry_beyond_f32_is_refused_and_within_it_renders_right() {
    // A black sphere around the camera renders black at the largest radius allowed...
    let black = render_ppm("huge-sphere", &inside_sphere("1e18", LOOK_DOWN_Z)).unwrap();
    let text = String::from_utf8(black).unwrap();
    assert!(
        text.lines().skip(3).all(|l| l == "0 0 0"),
        "a camera inside a black sphere sees light"
    );
    // ...and beyond it the radius is refused, not silently lost to overflow.
    let err = render_ppm("huger-sphere", &inside_sphere("1e20", LOOK_DOWN_Z)).unwrap_err();
    assert!(
        err.contains("spheres[1].radius") && err.contains("1e18") && err.contains("1e20"),
        "{err}"
    );
    let err = render_ppm("tiny-sphere", &inside_sphere("1e-30", LOOK_DOWN_Z)).unwrap_err();
    assert!(
        err.contains("spheres[1].radius") && err.contains("1e-18"),
        "{err}"
    );
    let far = "lookfrom = [3e38, 0, 0]\nlookat = [-3e38, 0, 0]\nvfov_deg = 90";
    let err = render_ppm(
        "far-camera",
        &GOOD.replace("[image]", &format!("[camera]\n{far}\n\n[image]")),
    )
    .unwrap_err();
    assert!(
        err.contains("scene.toml:2:12") && err.contains("camera.lookfrom") && err.contains("1e18"),
        "{err}"
    );
    let wide = "lookfrom = [0, 0, 0]\nlookat = [0, 0, -1]\nvfov_deg = 90\nfocus_dist = 1e18";
    let err = render_ppm(
        "wide-view",
        &GOOD
            .replace("width = 16", "width = 200000000")
            .replace("height = 9", "height = 1")
            .replace("[image]", &format!("[camera]\n{wide}\n\n[image]")),
    )
    .unwrap_err();
    assert!(
        err.contains("field `camera`") && err.contains("f32"),
        "{err}"
    );
}

#[test]
fn vup_is_a_direction_whatever_its_length() {
    let camera = |vup: &str| {
        GOOD.replace(
            "[image]",
            &format!(
                "[camera]\nlookfrom = [0, 1, 2]\nlookat = [0, 0, -1]\nvfov_deg = 60\nvup = {vup}\n\n[image]"
            ),
        )
    };
    let unit = render_ppm("vup-unit", &camera("[0, 1, 0]")).unwrap();
    for (name, vup) in [("vup-huge", "[0, 1e20, 0]"), ("vup-tiny", "[0, 1e-18, 0]")] {
        let other = render_ppm(name, &camera(vup)).unwrap_or_else(|e| panic!("{vup}: {e}"));
        assert!(
            other == unit,
            "vup = {vup} renders differently from [0, 1, 0]"
        );
    }
    let err = render_ppm("vup-zero", &camera("[0, 0, 0]")).unwrap_err();
    assert!(
        err.contains("camera.vup") && err.contains("non-zero"),
        "{err}"
    );
}

#[test]
fn a_bad_random_spheres_generator_is_rejected_with_its_line() {
    let with = |extra: &str| format!("{GOOD}\n[random_spheres]\ngrid = 1\n{extra}\n");
    // The table starts on line 16; its third line is 18.
    assert_rejected(
        "generator-unknown",
        &with("generator = \"mt19937\""),
        &["scene.toml:18", "mt19937", "pcg", "glibc"],
    );
    assert_rejected(
        "glibc-seed-too-big",
        &with("generator = \"glibc\"\nseed = 4294967296"),
        &["scene.toml:19", "random_spheres.seed", "4294967295"],
    );
    assert_rejected(
        "after-too-many",
        &with("after_spheres = 2"),
        &[
            "scene.toml:18",
            "random_spheres.after_spheres",
            "the 1 listed spheres",
        ],
    );
    assert_rejected(
        "after-negative",
        &with("after_spheres = -1"),
        &["random_spheres.after_spheres"],
    );
}

/// A grid keeps at most `MAX_KEEP_CLEAR` points clear: each of its spheres (up to 2^20) is
/// tested against every point before the first pixel, and 10,000 points (a 129 KB file) took
/// 27 s, the most a file's values allow some ten minutes. One point past the bound is
/// refused at that point, by line and field; the bound itself renders.
#[test]
fn a_grid_keeping_more_points_clear_than_the_bound_is_refused() {
    use tessera::scene::MAX_KEEP_CLEAR;
    let with = |n: usize| {
        let points = vec!["[100.0, 0.0, 100.0]"; n].join(", ");
        format!("{GOOD}\n[random_spheres]\ngrid = 1\nkeep_clear = [{points}]\n")
    };
    assert_rejected(
        "keep-clear-past-the-bound",
        &with(MAX_KEEP_CLEAR + 1),
        &[
            "scene.toml:18:",
            "random_spheres.keep_clear",
            &format!("holds {} points", MAX_KEEP_CLEAR + 1),
            &format!("the {MAX_KEEP_CLEAR} a grid may keep clear"),
        ],
    );
    let dir = dir_with_scene("keep-clear-at-the-bound", with(MAX_KEEP_CLEAR));
    let o = run(&["render", "scene.toml", "-o", "out.png", "-q"], &dir);
    assert!(o.status.success(), "{}", stderr(&o));
}

/// The bound on coordinates is on where a primitive ends up: a still sphere's centre within
/// it, rotated 45° and moved by the most a translation may, lay at 2.4e18 and was rendered
/// (a moving sphere's placed centre was already refused so). Each kind of placed primitive
/// is refused at the key that places it beyond, and one placed just within renders.
#[test]
fn a_primitive_placed_past_the_bound_is_refused() {
    const PLACE: &str = "rotate_y_deg = 45.0\ntranslate = [1e18, 0.0, 1e18]";
    let sphere = GOOD.replace(
        "center = [0.0, 0.0, -1.0]",
        &format!("center = [1e18, 0.0, 1e18]\n{PLACE}"),
    );
    assert_rejected(
        "placed-sphere",
        &sphere,
        &[
            "scene.toml:12:10",
            "spheres[0].center",
            "2.414",
            "within ±1e18",
        ],
    );
    let with = |table: &str| format!("{GOOD}\n{table}\n{PLACE}\n");
    for (name, table, expected) in [
        (
            "placed-box",
            "[[boxes]]\nmin = [0.0, 0.0, 0.0]\nmax = [1e18, 1.0, 1e18]\nmaterial = \"red\"",
            "boxes[0].max",
        ),
        (
            "placed-quad",
            "[[quads]]\ncorner = [1e18, 0.0, 1e18]\nu = [1.0, 0.0, 0.0]\nv = [0.0, 1.0, 0.0]\n\
             material = \"red\"",
            "quads[0].corner",
        ),
        (
            "placed-rect",
            "[[rects]]\nx = [0.0, 1.0]\ny = [0.0, 1.0]\nz = 1e18\nmaterial = \"red\"",
            "rects[0]",
        ),
        (
            "placed-cloud",
            "[[random_sphere_clouds]]\ncount = 2\nmin = [0.0, 0.0, 0.0]\nmax = [1e18, 1.0, 1e18]\n\
             radius = 1.0\nmaterial = \"red\"",
            "random_sphere_clouds[0].max",
        ),
    ] {
        assert_rejected(name, &with(table), &[expected, "within ±1e18"]);
    }
    let within = GOOD.replace(
        "center = [0.0, 0.0, -1.0]",
        "center = [1e17, 0.0, 1e17]\nrotate_y_deg = 45.0\ntranslate = [-5e17, 0.0, 0.0]",
    );
    let dir = dir_with_scene("placed-within", within);
    let o = run(&["render", "scene.toml", "-o", "out.png", "-q"], &dir);
    assert!(o.status.success(), "{}", stderr(&o));
}

/// A moving sphere keeps moving outside its two times: where the shutter opens or closes, a
/// centre taken past the coordinates' bound squares to infinity and the sphere silently
/// vanished from the image (`move_times = [0, 1e-30]` under a shutter of [0, 1] rendered
/// nothing, exit 0). It is refused at the key that moves it so far, as a far centre is.
#[test]
fn a_moving_sphere_the_shutter_takes_past_the_bound_is_refused() {
    const CAMERA: &str = "[camera]\nlookfrom = [0.0, 0.0, 1.0]\nlookat = [0.0, 0.0, -1.0]\n\
                          vfov_deg = 90.0\n";
    let moving = |sphere: &str, shutter: &str| {
        format!(
            "{}\n{CAMERA}shutter = {shutter}\n",
            GOOD.replace("radius = 0.5", &format!("radius = 0.5\n{sphere}"))
        )
    };
    assert_rejected(
        "moving-fast",
        &moving(
            "center2 = [1.0, 0.0, -1.0]\nmove_times = [0.0, 1e-30]",
            "[0.0, 1.0]",
        ),
        &[
            "scene.toml:15:",
            "spheres[0].move_times",
            "when the shutter closes",
            "within ±1e18",
        ],
    );
    assert_rejected(
        "moving-late",
        &moving("center2 = [0.0, 10.0, -1.0]", "[0.0, 1e18]"),
        &[
            "scene.toml:14:",
            "spheres[0].center2",
            "when the shutter closes",
        ],
    );
    assert_rejected(
        "medium-moving-early",
        &format!(
            "{GOOD}\n[materials.fog]\ntype = \"isotropic\"\nalbedo = [1.0, 1.0, 1.0]\n\
             [[media]]\ndensity = 1.0\nmaterial = \"fog\"\nsphere = {{ center = [0.0, 0.0, 0.0], \
             radius = 1.0, center2 = [0.0, 1.0, 0.0], move_times = [0.5, 0.5000001] }}\n\
             {CAMERA}shutter = [-1e18, 0.0]\n"
        ),
        &["media[0].sphere.move_times", "when the shutter opens"],
    );
    // Two times that 32-bit floats hold as one would make a sphere stand still.
    assert_rejected(
        "moving-one-time",
        &moving(
            "center2 = [1.0, 0.0, -1.0]\nmove_times = [0.0, 1e-50]",
            "[0.0, 1.0]",
        ),
        &["spheres[0].move_times", "the two times must differ"],
    );
    // The book's bouncing spheres under a shutter that takes them past the bound.
    assert_rejected(
        "bounce-late",
        &format!(
            "{GOOD}\n[random_spheres]\ngrid = 1\ndiffuse_bounce = [0.0, 1e18]\n\n\
             {CAMERA}shutter = [0.0, 10.0]\n"
        ),
        &[
            "scene.toml:18:",
            "random_spheres.diffuse_bounce",
            "within ±1e18",
        ],
    );
    // Within the bound, both render.
    for (name, text) in [
        (
            "moving-within",
            moving(
                "center2 = [1.0, 0.0, -1.0]\nmove_times = [0.0, 1e-12]",
                "[0.0, 1e-6]",
            ),
        ),
        (
            "bounce-within",
            format!(
                "{GOOD}\n[random_spheres]\ngrid = 1\ndiffuse_bounce = [0.0, 1e17]\n\n\
                 {CAMERA}shutter = [0.0, 1.0]\n"
            ),
        ),
    ] {
        let dir = dir_with_scene(name, text);
        let o = run(&["render", "scene.toml", "-o", "out.png", "-q"], &dir);
        assert!(o.status.success(), "{name}: {}", stderr(&o));
    }
}
