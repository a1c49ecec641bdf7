//! `tessera render`'s arguments checked against each other and against the scene, and every
//! output checked writable, before any work starts: a `RenderPlan` that knows how to run.

use super::{Args, PreviewArgs, SceneArgs, SplitArg};
use crate::cli::output::note;
use crate::cli::writable::{check_output, same_file};
use anyhow::{Result, bail};
use std::net::{Ipv6Addr, SocketAddr, SocketAddrV6, TcpListener};
use std::path::{Path, PathBuf};
use std::time::Duration;
use tessera::image_file::Format;
use tessera::job::Job;
use tessera::math::PixelRect;
use tessera::partial::RenderId;
use tessera::recipe::{Recipe, Source};
use tessera::render::RenderOptions;
use tessera::scene::{Overrides, Scene};
use tessera::shard::{self, Shard, Split, parse_samples};
use tessera::text::{path_safe, terminal_safe};

/// The scene `render` renders when none is named.
pub const DEFAULT_SCENE: &str = "scenes/cover.toml";

/// Where a render's result goes.
pub enum Output {
    /// The finished image, in the format its extension names.
    Image(PathBuf),
    /// A part file for `tessera merge`: the render is one part (a shard or a sample range).
    Part(PathBuf),
}

impl Output {
    pub fn path(&self) -> &Path {
        match self {
            Output::Image(p) | Output::Part(p) => p,
        }
    }
}

/// Where and how often a render saves its progress.
pub struct CheckpointSettings {
    pub path: PathBuf,
    /// The longest time between saves; zero saves after every tile.
    pub every: Duration,
}

/// Seconds between writes of the preview file, unless `--preview-every` says otherwise.
const PREVIEW_EVERY_SECS: f64 = 2.0;

/// How a render is watched: a live viewer, a preview file, both or neither.
#[derive(Default)]
pub struct PreviewSettings {
    /// The viewer's listener, bound before the render starts.
    pub listener: Option<TcpListener>,
    /// Serve the final frame after the render until Ctrl-C.
    pub hold: bool,
    /// The preview file and the time between its writes.
    pub file: Option<(PathBuf, Duration)>,
}

impl PreviewSettings {
    pub fn is_on(&self) -> bool {
        self.listener.is_some() || self.file.is_some()
    }

    /// Checks `--preview`, `--preview-hold`, `--preview-file` and `--preview-every`, and
    /// binds the viewer.
    fn new(args: &PreviewArgs) -> Result<Self> {
        let file = match &args.preview_file {
            Some(path) => {
                // Any other extension, none included, gets this one answer: the advice for
                // `-o` (".png, .ppm or .exr") names formats a preview is not written in.
                if !matches!(Format::from_path(path), Ok(Format::Png)) {
                    bail!(
                        "--preview-file must name a .png file, not {}",
                        path_safe(path)
                    );
                }
                check_output("--preview-file", path)?;
                refuse_pipe(path)?;
                refuse_in_place(path)?;
                let every = seconds(
                    "--preview-every",
                    args.preview_every.unwrap_or(PREVIEW_EVERY_SECS),
                )?;
                if every.is_zero() {
                    bail!("--preview-every must be more than 0 seconds");
                }
                Some((path.clone(), every))
            }
            None => None,
        };
        if file.is_none() && args.preview_every.is_some() {
            bail!("--preview-every needs --preview-file");
        }
        let listener = match &args.preview {
            Some(_) if !cfg!(feature = "preview") => bail!(
                "--preview: this tessera was built without the live viewer (cargo feature \
                 `preview`); --preview-file writes the image so far to a file instead"
            ),
            Some(spec) => Some(bind_preview(spec)?),
            None => None,
        };
        Ok(Self {
            listener,
            hold: args.preview_hold,
            file,
        })
    }
}

/// Refuses a preview file that is a pipe (FIFO), or leads to one. A pipe is written in place,
/// and opening one for writing waits for a reader: with none, the preview's writer would wait
/// for ever and tessera, its image written, would never end; with one, it would get a PNG
/// only when it opened the pipe again for each. The preview is a file rewritten whole.
fn refuse_pipe(path: &Path) -> Result<()> {
    use std::os::unix::fs::FileTypeExt;
    if std::fs::metadata(path).is_ok_and(|m| m.file_type().is_fifo()) {
        bail!(
            "--preview-file: {} is a pipe (FIFO), which would hold tessera until something \
             reads it; the preview is a file rewritten every few seconds: name a file",
            path_safe(path)
        );
    }
    Ok(())
}

/// Refuses a preview file that is written in place (`atomic_file::written_in_place`): a
/// device, or one of this process's open files (a link `p.png` to `/dev/stdout` with the
/// output redirected to a file). Each frame was added after the last, so a redirected
/// output grew by a PNG every 2 s and showed only the first frame, and a terminal was sent
/// PNG bytes. The preview is a file rewritten whole.
fn refuse_in_place(path: &Path) -> Result<()> {
    if tessera::atomic_file::written_in_place(path) {
        bail!(
            "--preview-file: {} is not a file of its own (a device, or standard output or \
             another file this process has open): each frame would be added after the last; \
             the preview is a file rewritten every few seconds: name a file",
            path_safe(path)
        );
    }
    Ok(())
}

/// A number of seconds from the command line, checked.
fn seconds(flag: &str, secs: f64) -> Result<Duration> {
    if !(secs >= 0.0 && secs.is_finite()) {
        bail!("{flag} must be a number of seconds, 0 or more");
    }
    // More seconds than a Duration holds (about 585 billion years) means never.
    Ok(Duration::try_from_secs_f64(secs).unwrap_or(Duration::MAX))
}

/// The address `--preview=SPEC` names: `ADDR:PORT` or `[IPv6]:PORT` with an IP address (a
/// link-local one with its zone as an interface's name or index, `[fe80::1%eth0]:8080`),
/// `localhost:PORT`, or a bare `PORT` (on 127.0.0.1). Host names are not looked up: a viewer
/// listens on this machine's own addresses.
pub fn preview_address(spec: &str) -> Result<SocketAddr> {
    let spec = spec.trim();
    if let Ok(port) = spec.parse::<u16>() {
        return Ok(SocketAddr::from(([127, 0, 0, 1], port)));
    }
    if let Ok(addr) = spec.parse::<SocketAddr>() {
        return Ok(addr);
    }
    if let Some(addr) = zoned_by_name(spec)? {
        return Ok(addr);
    }
    match spec.rsplit_once(':') {
        Some((host, port)) if host.eq_ignore_ascii_case("localhost") => {
            if let Ok(port) = port.parse::<u16>() {
                return Ok(SocketAddr::from(([127, 0, 0, 1], port)));
            }
        }
        _ => {}
    }
    bail!(
        "--preview: `{spec}` is not an address; write ADDR:PORT (127.0.0.1:8080), \
         [::1]:8080, localhost:8080 or a port alone"
    )
}

/// `[IPv6%NAME]:PORT`, an IPv6 address whose zone is a network interface's name (`ip addr`
/// shows link-local addresses so; the standard parser takes only an index), with the name
/// looked up as this machine's interface. `None` for anything else.
fn zoned_by_name(spec: &str) -> Result<Option<SocketAddr>> {
    let Some((inside, port)) = spec
        .strip_prefix('[')
        .and_then(|rest| rest.split_once("]:"))
    else {
        return Ok(None);
    };
    let Some((ip, zone)) = inside.split_once('%') else {
        return Ok(None);
    };
    let (Ok(ip), Ok(port)) = (ip.parse::<Ipv6Addr>(), port.parse::<u16>()) else {
        return Ok(None);
    };
    let index = interface_index(zone).map_err(|why| {
        anyhow::anyhow!(
            "--preview: the zone `{}` of {} is not a network interface of this machine \
             ({why}); `ip addr` lists them",
            terminal_safe(zone, 64),
            ip
        )
    })?;
    Ok(Some(SocketAddr::V6(SocketAddrV6::new(ip, port, 0, index))))
}

/// The index of the network interface named `name` (SIOCGIFINDEX).
fn interface_index(name: &str) -> std::io::Result<u32> {
    use rustix::net::{AddressFamily, SocketType, netdevice};
    // The kernel's interface names are at most 15 bytes, with no `/` or whitespace.
    if name.is_empty()
        || name.len() > 15
        || name
            .bytes()
            .any(|b| b == b'/' || b.is_ascii_whitespace() || b < 0x20)
    {
        return Err(std::io::ErrorKind::InvalidInput.into());
    }
    let socket = rustix::net::socket(AddressFamily::INET, SocketType::DGRAM, None)?;
    Ok(netdevice::name_to_index(&socket, name)?)
}

/// Binds the viewer's listener now, so that an address in use, one that is not this
/// machine's or a port without permission is an error before the render starts.
fn bind_preview(spec: &str) -> Result<TcpListener> {
    let addr = preview_address(spec)?;
    TcpListener::bind(addr).map_err(|e| {
        use std::io::ErrorKind;
        let why = match e.kind() {
            ErrorKind::AddrInUse => {
                "is in use by another program; choose another port, or leave it out for a free one"
                    .to_owned()
            }
            ErrorKind::PermissionDenied => {
                format!("needs a permission this user lacks (ports below 1024 need root): {e}")
            }
            ErrorKind::AddrNotAvailable => format!("is not an address of this machine: {e}"),
            _ => format!("cannot be listened on: {e}"),
        };
        anyhow::anyhow!("--preview: {addr} {why}")
    })
}

/// A render, checked and ready to run.
pub struct RenderPlan {
    pub scene: Scene,
    pub options: RenderOptions,
    /// What this process renders: the scene's window over all its samples, or one part.
    pub job: Job,
    /// The render the job belongs to (the whole image's samples per pixel included).
    pub render: RenderId,
    pub output: Output,
    pub checkpoint: Option<CheckpointSettings>,
    pub preview: PreviewSettings,
    /// What the job is, in a few words: the whole image, a crop, a shard or samples.
    pub job_label: String,
    /// The scene file as given.
    pub scene_file: PathBuf,
    pub quiet: bool,
}

impl RenderPlan {
    pub fn new(args: Args) -> Result<Self> {
        // `--preview 8080` takes 8080 as the scene file: say what was meant.
        let scene_arg = args.scene.scene.to_string_lossy();
        if !args.scene.scene.exists() && preview_address(&scene_arg).is_ok() {
            bail!(
                "`{scene_arg}` looks like an address, not a scene file; to choose the viewer's \
                 address write --preview={scene_arg}"
            );
        }
        let options = RenderOptions {
            threads: args.scene.threads,
            tile: args.tile,
            simd: args.scene.simd.path()?,
        };
        let every = seconds("--checkpoint-every", args.checkpoint_every)?;
        let (scene, source) = load(&args.scene, args.depth, args.seed)?;
        let shard = match &args.shard {
            Some(spec) => Some(Shard::parse(spec, |k| std::env::var(k).ok())?),
            None => None,
        };
        let samples = args.samples.as_deref().map(parse_samples).transpose()?;
        let split = match args.split {
            SplitArg::Samples => Split::Samples,
            SplitArg::Rows => Split::Rows,
        };
        let job = shard::job(&scene, shard, split, samples)?;
        let job_label = match (shard, samples) {
            (Some(s), _) => format!("shard {}/{}", s.index, s.count),
            (None, Some(r)) => format!("samples {}..{}", r.start, r.end),
            (None, None)
                if job.region != PixelRect::full(scene.settings.width, scene.settings.height) =>
            {
                let r = job.region;
                format!("crop {}x{} at ({}, {})", r.width, r.height, r.x0, r.y0)
            }
            (None, None) => "whole image".to_owned(),
        };
        // Every part is a piece of the image of the scene's samples per pixel.
        let target = scene.settings.samples_per_pixel;
        if let Some(r) = samples
            && r.end > target
        {
            bail!(
                "--samples {}..{} goes past the {target} samples per pixel of the image; raise --spp",
                r.start,
                r.end
            );
        }
        let path = args
            .output
            .unwrap_or_else(|| default_output(&args.scene.scene));
        // A shard or sample range always writes a part, even one that happens to be the
        // whole render (a Slurm array of one task), so a merge can take it.
        let output = if shard.is_some() || samples.is_some() {
            Output::Part(path)
        } else {
            Format::from_path(&path)?;
            Output::Image(path)
        };
        // Refuse an output that cannot be written before spending minutes on the render.
        check_output("-o", output.path())?;
        let checkpoint = args
            .checkpoint
            .map(|path| CheckpointSettings { path, every });
        // A checkpoint that exists is read to resume and then saved over, so it is checked
        // as an output too: one that leads to a descriptor held only for reading
        // (`--checkpoint /dev/stdin < own.ckpt`) was resumed, then each save failed with a
        // warning and the render went on with none saved, exit 0.
        if let Some(c) = &checkpoint {
            check_output("--checkpoint", &c.path)?;
        }
        // No two of the render's files may be one: a preview written where the image goes
        // would replace an earlier image with part of a render, and leave it so if the render
        // stops; a checkpoint written where the image or the preview goes would be replaced
        // by it, and a resume would then read an image as a checkpoint.
        let files = [
            ("-o", Some(output.path())),
            ("--preview-file", args.preview.preview_file.as_deref()),
            (
                "--checkpoint",
                checkpoint.as_ref().map(|c| c.path.as_path()),
            ),
        ];
        let scene_dir = (args.scene.scene.parent()).unwrap_or(Path::new(""));
        for (i, (flag, path)) in files.iter().enumerate() {
            // Nor the scene file: a part is written whatever -o's extension, and
            // `--shard 0/2 -o cover.toml` replaced the scene with it.
            if let Some(path) = path
                && same_file(path, &args.scene.scene)
            {
                bail!(
                    "{flag} {} names the scene file being rendered: give the output a name of \
                     its own",
                    path.display()
                );
            }
            // Nor an image the scene reads as a texture: the render would replace it.
            if let Some(path) = path
                && let Some(texture) =
                    (scene.texture_files.iter()).find(|t| same_file(path, &scene_dir.join(&t.name)))
            {
                bail!(
                    "{flag} {} names the texture file `{}` the scene reads: give the output a \
                     name of its own",
                    path.display(),
                    texture.name
                );
            }
            for (earlier, earlier_path) in &files[..i] {
                if let (Some(path), Some(earlier_path)) = (path, earlier_path)
                    && same_file(path, earlier_path)
                {
                    bail!(
                        "{flag} {} names the same file as {earlier}: give each of the render's \
                         files a name of its own",
                        path.display()
                    );
                }
            }
        }
        // A recipe too long for any reader to take is left out of the image and its parts
        // before the render, with a word, rather than refused once the render is done.
        // A PPM carries none in any case.
        let recipe = (!args.no_provenance).then_some(source).filter(|source| {
            let why = Recipe::unrendered(source, &scene).why_not_carried();
            let carries = !matches!(&output, Output::Image(p) if Format::from_path(p).ok() == Some(Format::Ppm));
            if let Some(why) = why.as_ref().filter(|_| carries) {
                note(format_args!(
                    "tessera: warning: {}: {why}, so {} carries none (--no-provenance leaves \
                     it out without this warning)",
                    path_safe(&args.scene.scene),
                    path_safe(output.path())
                ));
            }
            why.is_none()
        });
        // Last, so that the port is taken only once everything else is known to be right.
        let preview = PreviewSettings::new(&args.preview)?;
        Ok(Self {
            render: RenderId {
                recipe,
                ..RenderId::of(&scene, target)
            },
            scene,
            options,
            job,
            output,
            checkpoint,
            preview,
            job_label,
            scene_file: args.scene.scene,
            quiet: args.quiet,
        })
    }
}

/// The scene file, parsed with the command line's overrides, and its recipe source: the
/// text parsed is the text recorded.
fn load(args: &SceneArgs, depth: Option<u32>, seed: Option<u64>) -> Result<(Scene, Source)> {
    let overrides = Overrides {
        width: args.width,
        samples_per_pixel: args.spp,
        max_depth: depth,
        seed,
    };
    if !args.scene.exists() {
        bail!("{}", missing_scene(&args.scene));
    }
    let text = Scene::read_text(&args.scene)?;
    let scene = Scene::parse(&text, &args.scene, &overrides)?;
    Ok((scene, Source::new(&args.scene, &text, overrides)))
}

/// What to say of a scene file that does not exist: the nearest names among the scene files
/// beside where it was looked for, and in `scenes/`.
fn missing_scene(path: &Path) -> String {
    let mut said = format!("{}: no such scene file", path.display());
    let wanted = path
        .file_stem()
        .map_or(String::new(), |s| s.to_string_lossy().to_lowercase());
    let mut dirs = vec![match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_owned(),
        _ => PathBuf::from("."),
    }];
    dirs.push(PathBuf::from("scenes"));
    dirs.dedup();
    let mut candidates: Vec<(usize, PathBuf)> = Vec::new();
    for dir in dirs {
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        for entry in entries.flatten().take(10_000) {
            let file = entry.path();
            if file.extension().is_none_or(|e| e != "toml") {
                continue;
            }
            let stem = file
                .file_stem()
                .map_or(String::new(), |s| s.to_string_lossy().to_lowercase());
            if let Some(distance) = nearness(&wanted, &stem) {
                let shown = if dir == Path::new(".") {
                    PathBuf::from(entry.file_name())
                } else {
                    file
                };
                candidates.push((distance, shown));
            }
        }
    }
    candidates.sort();
    candidates.dedup_by(|a, b| a.1 == b.1);
    if !candidates.is_empty() {
        let names: Vec<String> = (candidates.iter().take(3))
            .map(|(_, p)| p.display().to_string())
            .collect();
        said.push_str(&format!("; did you mean {}?", names.join(" or ")));
    } else if !Path::new("scenes").is_dir() {
        said.push_str(
            "; the scene files are in the repository's scenes/ directory: run tessera from \
             there, or give the file's path",
        );
    }
    said
}

/// How near a typed name is to a file's name, when near enough to suggest: 0 when one
/// holds the other (`hollow` in `img-1.16-glass-hollow`), else one more than their edit
/// distance, up to two or a third of the longer name. The edit distance takes the product
/// of the lengths, and is at least their difference: names too unlike in length for it to
/// be within the bound are not measured, so a long name typed (or passed by a script) costs
/// no more than a short one; a name of 100,000 characters beside 10,000 scene files of 250
/// once took over a minute.
fn nearness(wanted: &str, name: &str) -> Option<usize> {
    if wanted.len() >= 3 && (name.contains(wanted) || wanted.contains(name)) {
        return Some(0);
    }
    let (a, b) = (wanted.chars().count(), name.chars().count());
    let most = (a.max(b) / 3).max(2);
    if a.abs_diff(b) > most {
        return None;
    }
    let distance = edit_distance(wanted, name);
    (distance <= most).then_some(distance + 1)
}

/// Levenshtein's distance between `a` and `b`, in characters.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diagonal = row[0];
        row[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let above = row[j + 1];
            row[j + 1] = (above + 1)
                .min(row[j] + 1)
                .min(diagonal + usize::from(ca != cb));
            diagonal = above;
        }
    }
    row[b.len()]
}

/// The scene's file name with `.png`.
fn default_output(scene: &Path) -> PathBuf {
    let stem = scene.file_stem().map_or("render".into(), |s| s.to_owned());
    let mut name = stem;
    name.push(".png");
    PathBuf::from(name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_near_a_missing_one_are_suggested() {
        assert_eq!(edit_distance("cover", "cover"), 0);
        assert_eq!(edit_distance("covr", "cover"), 1);
        assert_eq!(edit_distance("", "abc"), 3);
        assert_eq!(nearness("hollow", "img-1.16-glass-hollow"), Some(0));
        assert_eq!(nearness("cvoer", "cover"), Some(3));
        assert_eq!(nearness("zebra", "cover"), None);
        // Lengths too unlike for the distance to be within the bound are not measured.
        assert_eq!(nearness("cvoer-and-more", "cover"), None);
        assert_eq!(nearness("abxdefg", "abcdef"), Some(3));
    }

    /// A link-local address's zone, as `ip addr` names it: the interface's name (or its
    /// index, which the standard parser takes) gives the listener's scope. Named, it was
    /// refused as "not an address".
    #[test]
    fn a_zone_may_be_an_interface_s_name_or_index() {
        let by_name = preview_address("[fe80::1%lo]:8080").unwrap();
        let by_index = preview_address("[fe80::1%1]:8080").unwrap();
        let SocketAddr::V6(v6) = by_name else {
            panic!("{by_name}")
        };
        assert_eq!(v6.scope_id(), interface_index("lo").unwrap());
        assert_eq!(v6.port(), 8080);
        assert_eq!(by_index.to_string(), "[fe80::1%1]:8080");
        for (spec, why) in [
            ("[fe80::1%no-such-if]:8080", "not a network interface"),
            ("[fe80::1%a/b]:8080", "not a network interface"),
            ("[fe80::1%\u{1b}[2J]:8080", "\\u{1b}"),
            ("[fe80::1%]:8080", "not a network interface"),
            ("[fe80::1%lo]:99999", "is not an address"),
            ("[nonsense%lo]:8080", "is not an address"),
        ] {
            let e = preview_address(spec).unwrap_err().to_string();
            assert!(e.contains(why), "{spec}: {e}");
            assert!(!e.contains('\u{1b}'), "{spec}: {e}");
        }
    }
}
