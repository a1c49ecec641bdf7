//! Turns a parsed scene description into a validated runtime `Scene`, reporting the file,
//! line, column and field of the first unacceptable value.

use super::check::Checker;
use super::desc::{self, ColorDesc, OffsetDesc, SceneDesc};
use super::draws::DrawSettings;
use super::settings::{Background, RenderSettings, SurfaceOffset};
use super::textures::{MAX_SCENE_TEXTURE_PIXELS, TextureSource, identity, load};
use super::{Scene, SceneContents, TextureFile, cover, shapes};
use crate::camera::{Camera, CameraSettings};
use crate::error::{Error, Result};
use crate::geometry::MaterialId;
use crate::material::{Material, Refraction};
use crate::math::{Color, PixelRect, Vec3, cross, unit};
use crate::texture::{ImageTexture, Noise, Texture, TextureId};
use std::collections::{BTreeMap, BTreeSet};
use std::ops::Range;
use std::path::Path;
use toml::Spanned;

/// The most pixels an image may have (2²⁸: 6 GiB of sums), so a typo cannot exhaust memory.
pub const MAX_PIXELS: u64 = 1 << 28;
/// The most ray segments a path may have: far beyond the books' 50, and a bound on what one
/// sample can cost (a path inside a closed mirror or an inside-out sphere goes on to it;
/// a render stops between pixels, not within a path).
pub const MAX_DEPTH: u32 = 1 << 16;
/// The most noise textures a scene may have: each draws its own tables (4.8 KB, some 1,500
/// draws), so 250,000 of them in a 12 MB scene once took 1 GB beside the parser's 0.5 GB.
/// The books' scenes have one or two; these take 20 MB at most.
pub const MAX_NOISE_TEXTURES: usize = 1 << 12;

/// The most checkers a hit may pass through to its colour: a checker's square may be another
/// checker, and each is evaluated at every hit (three sines), so a 9 MB chain of 150,000
/// once took 19 s for a 32×32 image of 2 samples a pixel, that renders in milliseconds with
/// one. The books nest none; a checker of checkers is two.
pub const MAX_CHECKER_DEPTH: usize = 16;

/// The most defined names a message about an unknown one lists: a scene of 100,000
/// materials and one misspelt name once built a message of 2.9 MB, every name in it, that
/// the terminal showed cut in the middle of a name.
pub const MAX_LISTED_NAMES: usize = 16;
/// The most characters of one listed name: a name may be megabytes long.
const MAX_LISTED_NAME_CHARS: usize = 64;

/// What a message about an unknown name says of the `count` defined `kind` (`materials`,
/// `textures`), `names` in order: the first `MAX_LISTED_NAMES`, each cut to
/// `MAX_LISTED_NAME_CHARS`, and how many more there are.
fn listed<'a>(kind: &str, count: usize, names: impl Iterator<Item = &'a str>) -> String {
    if count == 0 {
        return format!("no {kind} are defined");
    }
    let shown: Vec<String> = names
        .take(MAX_LISTED_NAMES)
        .map(
            |name| match name.char_indices().nth(MAX_LISTED_NAME_CHARS) {
                Some((cut, _)) => format!("{}…", &name[..cut]),
                None => name.to_owned(),
            },
        )
        .collect();
    let more = count.saturating_sub(shown.len());
    if more == 0 {
        format!("defined {kind}: {}", shown.join(", "))
    } else {
        format!("defined {kind}: {}, and {more} more", shown.join(", "))
    }
}

/// Settings given on the command line that replace the file's.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Overrides {
    /// New width; the height follows the file's aspect ratio.
    pub width: Option<u32>,
    pub samples_per_pixel: Option<u32>,
    pub max_depth: Option<u32>,
    pub seed: Option<u64>,
}

pub(super) fn build(
    desc: &SceneDesc,
    text: &str,
    path: &Path,
    overrides: &Overrides,
    source: &TextureSource,
) -> Result<Scene> {
    let ck = Checker::new(text, path);
    let settings = render_settings(desc, &ck, overrides)?;
    let mut camera = match &desc.camera {
        Some(c) => camera_settings(c.get_ref(), &ck)?,
        None => CameraSettings {
            lookfrom: Vec3::ZERO,
            lookat: -Vec3::Z,
            vup: Vec3::Y,
            vfov_deg: 90.0,
            aspect_ratio: 1.0,
            aperture: 0.0,
            focus_dist: 1.0,
            shutter: (0.0, 0.0),
        },
    };
    // The viewport keeps the file's shape, whatever width the command line asks for.
    camera.aspect_ratio = *desc.image.width.get_ref() as f32 / *desc.image.height.get_ref() as f32;
    if !Camera::new(&camera).rays_are_finite() {
        let (span, field) = match &desc.camera {
            Some(c) => (c.span(), "camera"),
            None => (desc.image.width.span(), "image.width"),
        };
        return Err(ck.error(
            span,
            field,
            "the view is beyond f32 arithmetic: with this focus distance, field of view and \
             image shape, camera rays overflow or vanish; bring focus_dist (or lookat) and the \
             view's width nearer",
        ));
    }
    let background = match &desc.background {
        None => Background::Gradient {
            bottom: Color::ONE,
            top: Color::new(0.5, 0.7, 1.0),
        },
        Some(b) => background(b, &ck)?,
    };
    // The file's own seed, not `--seed`'s: what the scene is made of (its generators'
    // spheres, its noise) stays the same when only the samples change.
    let file_seed = desc.image.seed;
    let mut textures = Textures::build(desc, &ck, source, file_seed)?;

    let mut materials = Vec::with_capacity(desc.materials.len());
    let mut material_textures = Vec::with_capacity(desc.materials.len());
    let mut ids = BTreeMap::new();
    for (name, m) in &desc.materials {
        ids.insert(name.as_str(), MaterialId(materials.len() as u32));
        let (material, texture) = material(name, m, &ck, &mut textures)?;
        materials.push(material);
        material_textures.push(texture);
    }
    let lookup = |name: &Spanned<String>, field: &str| -> Result<MaterialId> {
        let wanted = name.get_ref();
        ids.get(wanted.as_str()).copied().ok_or_else(|| {
            let known = listed("materials", ids.len(), ids.keys().copied());
            ck.error(
                name.span(),
                field,
                format!("unknown material `{wanted}` ({known})"),
            )
        })
    };
    let mut primitives =
        shapes::primitives(desc, &ck, &lookup, &materials, camera.shutter, file_seed)?;

    if let Some(random) = &desc.random_spheres {
        let random = random.get_ref();
        let generator =
            cover::RandomSpheres::from_desc(random, settings.seed, camera.shutter, &ck)?;
        // Where the generated spheres go among the listed ones.
        let listed = desc.spheres.len();
        let at = match &random.after_spheres {
            None => primitives.spheres.len(),
            Some(n) => match usize::try_from(*n.get_ref()) {
                // The first `k` listed spheres, as still spheres among them.
                Ok(k) if k <= listed => desc.spheres[..k]
                    .iter()
                    .filter(|s| s.get_ref().center2.is_none())
                    .count(),
                _ => {
                    return Err(ck.error(
                        n.span(),
                        "random_spheres.after_spheres",
                        format!(
                            "must be between 0 and the {listed} listed spheres, got {}",
                            n.get_ref()
                        ),
                    ));
                }
            },
        };
        // The grid's spheres are weighed before any is drawn (a grid of 1000 would be four
        // million, each with a material of its own).
        let side = 2 * random.grid.get_ref().unsigned_abs();
        let grid_spheres = usize::try_from(side * side).unwrap_or(usize::MAX);
        shapes::check_held(
            &ck,
            shapes::held(&primitives).saturating_add(grid_spheres),
            random.grid.span(),
            "random_spheres.grid",
        )?;
        let generated = generator.generate(&mut materials, camera.shutter);
        material_textures.resize(materials.len(), None);
        primitives.spheres.splice(at..at, generated.still);
        primitives.moving_spheres.extend(generated.moving);
    }
    // The clouds' spheres after every other.
    shapes::sphere_clouds(desc, &ck, &lookup, file_seed, &mut primitives)?;

    let (textures, texture_files) = textures.finish();
    let contents = SceneContents {
        materials,
        material_textures,
        textures,
        primitives,
        texture_files,
    };
    Ok(Scene::assemble(settings, camera, background, contents))
}

/// The scene's textures as they are built: the named ones first (in name order, so each
/// name's id is known before any refers to it), then the colours that checkers and materials
/// give in place of a name.
struct Textures {
    table: Vec<Texture>,
    names: BTreeMap<String, TextureId>,
    files: Vec<TextureFile>,
    /// The names in `files`, looked up as each texture is built: a scene may spell one file
    /// a hundred thousand ways (`./a.png`, `.//a.png`), each a name the recipe lists.
    file_names: BTreeSet<String>,
    /// The image files read so far with their hashes, by file (`textures::identity`): one
    /// named by many textures, however spelt, is read once.
    images: BTreeMap<String, (ImageTexture, u128)>,
    /// What the files read so far leave of `MAX_SCENE_TEXTURE_PIXELS`.
    pixels_left: u64,
    /// The noise textures built so far, at most `MAX_NOISE_TEXTURES`.
    noises: usize,
}

impl Textures {
    fn build(
        desc: &SceneDesc,
        ck: &Checker,
        source: &TextureSource,
        file_seed: u64,
    ) -> Result<Self> {
        let names: BTreeMap<String, TextureId> = desc
            .textures
            .keys()
            .enumerate()
            .map(|(i, name)| (name.clone(), TextureId(i as u32)))
            .collect();
        let mut t = Textures {
            table: Vec::with_capacity(names.len()),
            names,
            files: Vec::new(),
            file_names: BTreeSet::new(),
            images: BTreeMap::new(),
            pixels_left: MAX_SCENE_TEXTURE_PIXELS,
            noises: 0,
        };
        // Placeholders, so checkers may name any texture; each is replaced below.
        t.table
            .resize(desc.textures.len(), Texture::Solid(Color::ZERO));
        for (i, (name, d)) in desc.textures.iter().enumerate() {
            let texture = t.texture(name, d, ck, source, file_seed)?;
            t.table[i] = texture;
        }
        t.check_cycles(desc, ck)?;
        t.check_depth(desc, ck)?;
        Ok(t)
    }

    /// The id of the texture `c` gives: a named one, or a solid colour added for it.
    fn id_of(&mut self, c: &Spanned<ColorDesc>, field: &str, ck: &Checker) -> Result<TextureId> {
        match c.get_ref() {
            ColorDesc::Texture(name) => self.names.get(name).copied().ok_or_else(|| {
                let names = self.names.keys().map(String::as_str);
                let known = listed("textures", self.names.len(), names);
                ck.error(
                    c.span(),
                    field,
                    format!("unknown texture `{name}` ({known})"),
                )
            }),
            ColorDesc::Rgb(rgb) => {
                let color = ck.color(&Spanned::new(c.span(), desc::Exactly(*rgb)), field)?;
                self.table.push(Texture::Solid(color));
                Ok(TextureId(self.table.len() as u32 - 1))
            }
        }
    }

    fn texture(
        &mut self,
        name: &str,
        t: &Spanned<desc::TextureDesc>,
        ck: &Checker,
        source: &TextureSource,
        file_seed: u64,
    ) -> Result<Texture> {
        let d = t.get_ref();
        let prefix = format!("textures.{name}");
        let field = |f: &str| format!("{prefix}.{f}");
        let kind = d.kind.get_ref().as_str();
        let present = [
            ("color", d.color.as_ref().map(Spanned::span)),
            ("even", d.even.as_ref().map(Spanned::span)),
            ("odd", d.odd.as_ref().map(Spanned::span)),
            ("frequency", d.frequency.as_ref().map(Spanned::span)),
            ("noise", d.noise.as_ref().map(Spanned::span)),
            ("scale", d.scale.as_ref().map(Spanned::span)),
            ("generator", d.generator.as_ref().map(Spanned::span)),
            ("seed", d.seed.as_ref().map(Spanned::span)),
            ("skip", d.skip.as_ref().map(Spanned::span)),
            ("draw_order", d.draw_order.as_ref().map(Spanned::span)),
            ("file", d.file.as_ref().map(Spanned::span)),
        ];
        Ok(match kind {
            "solid" => {
                only_fields(ck, &prefix, kind, &["color"], &present)?;
                let c = required(ck, d.color.as_ref(), t.span(), &field("color"), kind)?;
                Texture::Solid(ck.color(c, &field("color"))?)
            }
            "checker" => {
                only_fields(ck, &prefix, kind, &["even", "odd", "frequency"], &present)?;
                let even = required(ck, d.even.as_ref(), t.span(), &field("even"), kind)?;
                let odd = required(ck, d.odd.as_ref(), t.span(), &field("odd"), kind)?;
                let frequency = match &d.frequency {
                    None => 10.0,
                    Some(f) => ck.in_range(
                        f,
                        &field("frequency"),
                        |f| f > 0.0 && f <= 1e6,
                        "positive, at most 10⁶",
                    )?,
                };
                Texture::Checker {
                    even: self.id_of(even, &field("even"), ck)?,
                    odd: self.id_of(odd, &field("odd"), ck)?,
                    frequency,
                }
            }
            "noise" => {
                let allowed = ["noise", "scale", "generator", "seed", "skip", "draw_order"];
                only_fields(ck, &prefix, kind, &allowed, &present)?;
                let noise = required(ck, d.noise.as_ref(), t.span(), &field("noise"), kind)?;
                if self.noises == MAX_NOISE_TEXTURES {
                    return Err(ck.error(
                        t.span(),
                        &prefix,
                        format!(
                            "is one noise texture more than the {MAX_NOISE_TEXTURES} a scene \
                             may have (each draws its own tables)"
                        ),
                    ));
                }
                self.noises += 1;
                let scale = match &d.scale {
                    None => 1.0,
                    Some(s) => ck.in_range(
                        s,
                        &field("scale"),
                        |s| s > 0.0 && s <= 1e6,
                        "positive, at most 10⁶",
                    )?,
                };
                let generator = d
                    .generator
                    .as_ref()
                    .map_or(desc::SphereGenerator::Pcg, |g| *g.get_ref());
                let draws = DrawSettings::check(
                    ck,
                    &prefix,
                    generator,
                    d.seed.as_ref(),
                    d.skip.as_ref(),
                    d.draw_order.as_ref().map(|o| *o.get_ref()),
                    file_seed,
                )?;
                Texture::Noise(Noise::new(*noise.get_ref(), scale, &mut draws.draws()))
            }
            "image" => {
                only_fields(ck, &prefix, kind, &["file"], &present)?;
                let file = required(ck, d.file.as_ref(), t.span(), &field("file"), kind)?;
                let name = file.get_ref();
                let key = identity(name, source);
                if let Some((image, hash)) = key.as_ref().and_then(|k| self.images.get(k)) {
                    // The recipe lists every name given, each with its file's hash.
                    if self.file_names.insert(name.clone()) {
                        self.files.push(TextureFile {
                            name: name.clone(),
                            hash: *hash,
                        });
                    }
                    return Ok(Texture::Image(image.clone()));
                }
                let loaded = load(name, source, self.pixels_left)
                    .map_err(|e| ck.error(file.span(), &field("file"), e))?;
                let _ = loaded.found;
                let image = loaded.image;
                self.pixels_left -= u64::from(image.width) * u64::from(image.height);
                if let Some(key) = key {
                    self.images.insert(key, (image.clone(), loaded.file.hash));
                }
                self.file_names.insert(name.clone());
                self.files.push(loaded.file);
                Texture::Image(image)
            }
            other => {
                return Err(ck.error(
                    d.kind.span(),
                    &field("type"),
                    format!(
                        "unknown texture type `{other}`; expected `solid`, `checker`, `noise` \
                         or `image`"
                    ),
                ));
            }
        })
    }

    /// Refuses a checker whose squares lead back to itself, naming the first texture of the
    /// file that lies on a cycle. Linear in the textures (a chain of thousands is a stranger's
    /// scene too): the cycles are the strongly connected components found by `on_cycles`.
    fn check_cycles(&self, desc: &SceneDesc, ck: &Checker) -> Result<()> {
        let on_cycle = self.on_cycles();
        for (start, (name, t)) in desc.textures.iter().enumerate() {
            if on_cycle[start] {
                return Err(ck.error(
                    t.span(),
                    &format!("textures.{name}"),
                    "a checker's squares lead back to itself: textures must not form a cycle",
                ));
            }
        }
        Ok(())
    }

    /// Refuses a checker whose squares lead through more than `MAX_CHECKER_DEPTH` checkers,
    /// naming the first texture of the file that does. After `check_cycles`: the checkers'
    /// squares form no cycle.
    fn check_depth(&self, desc: &SceneDesc, ck: &Checker) -> Result<()> {
        let depths = self.checker_depths();
        for (i, (name, t)) in desc.textures.iter().enumerate() {
            if depths[i] > MAX_CHECKER_DEPTH {
                return Err(ck.error(
                    t.span(),
                    &format!("textures.{name}"),
                    format!(
                        "its squares lead through {} checkers, more than the \
                         {MAX_CHECKER_DEPTH} a texture may nest (each is evaluated at every hit)",
                        depths[i]
                    ),
                ));
            }
        }
        Ok(())
    }

    /// How many checkers each texture passes through to a colour at most: 0 for a texture
    /// of another kind, one more than the deeper of its squares for a checker. Iterative (no
    /// recursion however long a chain), each texture's depth found once; the squares must
    /// form no cycle.
    fn checker_depths(&self) -> Vec<usize> {
        const UNKNOWN: usize = usize::MAX;
        let n = self.table.len();
        let mut depth = vec![UNKNOWN; n];
        let mut stack = Vec::new();
        for root in 0..n {
            stack.push(root);
            while let Some(&id) = stack.last() {
                if depth[id] != UNKNOWN {
                    stack.pop();
                    continue;
                }
                let Texture::Checker { even, odd, .. } = &self.table[id] else {
                    depth[id] = 0;
                    stack.pop();
                    continue;
                };
                let squares = [even.0 as usize, odd.0 as usize];
                let before = stack.len();
                stack.extend(squares.iter().filter(|&&s| depth[s] == UNKNOWN));
                if stack.len() == before {
                    depth[id] = 1 + depth[squares[0]].max(depth[squares[1]]);
                    stack.pop();
                }
            }
        }
        depth
    }

    /// The textures a cycle of checkers' squares passes through: Tarjan's strongly connected
    /// components, iteratively (no recursion however long a chain), where a texture is on a
    /// cycle when its component has more than one texture or it leads to itself.
    fn on_cycles(&self) -> Vec<bool> {
        let n = self.table.len();
        let next = |id: usize| -> [usize; 2] {
            match &self.table[id] {
                Texture::Checker { even, odd, .. } => [even.0 as usize, odd.0 as usize],
                _ => [usize::MAX; 2],
            }
        };
        const UNSEEN: usize = usize::MAX;
        let (mut index, mut low) = (vec![UNSEEN; n], vec![0; n]);
        let mut on_stack = vec![false; n];
        let (mut stack, mut on_cycle) = (Vec::new(), vec![false; n]);
        let mut counter = 0;
        for root in 0..n {
            if index[root] != UNSEEN {
                continue;
            }
            // Each frame: a texture and which of its two squares comes next.
            let mut frames = vec![(root, 0usize)];
            index[root] = counter;
            low[root] = counter;
            counter += 1;
            stack.push(root);
            on_stack[root] = true;
            while let Some(&mut (id, ref mut edge)) = frames.last_mut() {
                if *edge < 2 {
                    let to = next(id)[*edge];
                    *edge += 1;
                    if to >= n {
                        continue;
                    }
                    if index[to] == UNSEEN {
                        index[to] = counter;
                        low[to] = counter;
                        counter += 1;
                        stack.push(to);
                        on_stack[to] = true;
                        frames.push((to, 0));
                    } else if on_stack[to] {
                        low[id] = low[id].min(index[to]);
                    }
                    continue;
                }
                frames.pop();
                if let Some(&(parent, _)) = frames.last() {
                    low[parent] = low[parent].min(low[id]);
                }
                if low[id] == index[id] {
                    let mut component = Vec::new();
                    while let Some(member) = stack.pop() {
                        on_stack[member] = false;
                        component.push(member);
                        if member == id {
                            break;
                        }
                    }
                    let cyclic = component.len() > 1 || next(id).contains(&id);
                    for member in component {
                        on_cycle[member] = cyclic;
                    }
                }
            }
        }
        on_cycle
    }

    fn finish(self) -> (Vec<Texture>, Vec<TextureFile>) {
        (self.table, self.files)
    }
}

/// The settings `build` gives the scene of `desc` (whose text is `text`), and nothing else
/// built: one function, so the settings checked without the scene are the scene's.
pub(super) fn settings(
    desc: &SceneDesc,
    text: &str,
    path: &Path,
    overrides: &Overrides,
) -> Result<RenderSettings> {
    render_settings(desc, &Checker::new(text, path), overrides)
}

fn render_settings(desc: &SceneDesc, ck: &Checker, ov: &Overrides) -> Result<RenderSettings> {
    let img = &desc.image;
    let file_width = ck.positive_int(&img.width, "image.width")?;
    let file_height = ck.positive_int(&img.height, "image.height")?;
    let positive = |v: Option<u32>, field: &str| match v {
        Some(0) => Err(Error::Setting {
            field: field.to_owned(),
            message: "must be positive, got 0".to_owned(),
        }),
        other => Ok(other),
    };
    let (width, height) = match positive(ov.width, "width")? {
        None => (file_width, file_height),
        // Keep the file's aspect ratio, rounding the height down as the book does.
        Some(w) => {
            let h = u64::from(w) * u64::from(file_height) / u64::from(file_width);
            let h = u32::try_from(h.max(1)).map_err(|_| Error::Setting {
                field: "width".to_owned(),
                message: format!("{w} makes the height too large"),
            })?;
            (w, h)
        }
    };
    if u64::from(width) * u64::from(height) > MAX_PIXELS {
        let message =
            format!("{width}x{height} is more than the {MAX_PIXELS} pixels an image may have");
        return Err(match ov.width {
            Some(_) => Error::Setting {
                field: "width".to_owned(),
                message,
            },
            None => ck.error(img.width.span(), "image.width", message),
        });
    }
    let samples_per_pixel = match positive(ov.samples_per_pixel, "spp")? {
        Some(n) => n,
        None => ck.positive_int(&img.samples_per_pixel, "image.samples_per_pixel")?,
    };
    let max_depth = match positive(ov.max_depth, "depth")? {
        Some(n) => n,
        None => ck.positive_int(&img.max_depth, "image.max_depth")?,
    };
    if max_depth > MAX_DEPTH {
        let message = format!("must be at most {MAX_DEPTH}, got {max_depth}");
        return Err(match ov.max_depth {
            Some(_) => Error::Setting {
                field: "depth".to_owned(),
                message,
            },
            None => ck.error(img.max_depth.span(), "image.max_depth", message),
        });
    }
    let window = match &img.crop {
        None => PixelRect::full(width, height),
        Some(c) => crop(c, ck, (file_width, file_height), (width, height))?,
    };
    let r = &desc.render;
    Ok(RenderSettings {
        width,
        height,
        window,
        samples_per_pixel,
        max_depth,
        seed: ov.seed.unwrap_or(img.seed),
        shading: r.shading,
        diffuse: r.diffuse,
        gamma: ck.in_range(&r.gamma, "render.gamma", |g| g > 0.0, "positive")?,
        surface_offset: match *r.t_min.get_ref() {
            OffsetDesc::Auto => SurfaceOffset::Auto,
            OffsetDesc::Distance(d) => SurfaceOffset::Fixed(ck.in_range(
                &Spanned::new(r.t_min.span(), d),
                "render.t_min",
                |t| t >= 0.0,
                "\"auto\" or zero or positive",
            )?),
        },
        jitter: r.jitter,
    })
}

/// The crop window, checked against the file's image size and scaled with a width override.
fn crop(
    c: &Spanned<desc::Exactly<i64, 4>>,
    ck: &Checker,
    (file_w, file_h): (u32, u32),
    (w, h): (u32, u32),
) -> Result<PixelRect> {
    let [x0, y0, cw, ch] = c.get_ref().0;
    // Checked: a width near i64::MAX must not wrap round to a small right edge.
    let ends_inside = |start: i64, len: i64, size: u32| {
        start
            .checked_add(len)
            .is_some_and(|end| end <= i64::from(size))
    };
    let fits = x0 >= 0
        && y0 >= 0
        && cw > 0
        && ch > 0
        && ends_inside(x0, cw, file_w)
        && ends_inside(y0, ch, file_h);
    if !fits {
        return Err(ck.error(
            c.span(),
            "image.crop",
            format!("[{x0}, {y0}, {cw}, {ch}] is not a non-empty rectangle inside the {file_w}x{file_h} image"),
        ));
    }
    let scale = |v: i64, new: u32, old: u32| (v as u64 * u64::from(new) / u64::from(old)) as u32;
    let x0 = scale(x0, w, file_w).min(w - 1);
    let y0 = scale(y0, h, file_h).min(h - 1);
    Ok(PixelRect {
        x0,
        y0,
        width: scale(cw, w, file_w).clamp(1, w - x0),
        height: scale(ch, h, file_h).clamp(1, h - y0),
    })
}

fn camera_settings(c: &desc::CameraDesc, ck: &Checker) -> Result<CameraSettings> {
    let lookfrom = ck.point(&c.lookfrom, "camera.lookfrom")?;
    let lookat = ck.point(&c.lookat, "camera.lookat")?;
    let view = lookat - lookfrom;
    if view.length_squared() == 0.0 {
        return Err(ck.error(
            c.lookat.span(),
            "camera.lookat",
            "must differ from lookfrom",
        ));
    }
    let vup = match &c.vup {
        Some(v) => {
            let vup = ck.direction(v, "camera.vup")?;
            if cross(unit(view), vup).length_squared() < 1e-12 {
                return Err(ck.error(
                    v.span(),
                    "camera.vup",
                    "must not be zero or parallel to the view direction",
                ));
            }
            vup
        }
        None => Vec3::Y,
    };
    let vfov_deg = ck.in_range(
        &c.vfov_deg,
        "camera.vfov_deg",
        |v| v > 0.0 && v < 180.0,
        "between 0 and 180 degrees",
    )?;
    let aperture = match &c.aperture {
        Some(a) => ck.length(a, "camera.aperture", |a| a >= 0.0, "zero or positive")?,
        None => 0.0,
    };
    let focus_dist = match &c.focus_dist {
        Some(f) => ck.length(f, "camera.focus_dist", |f| f > 0.0, "positive")?,
        None => view.length(),
    };
    let shutter = match &c.shutter {
        None => (0.0, 0.0),
        Some(s) => {
            let (open, close) = ck.range(s, "camera.shutter")?;
            (open as f32, close as f32)
        }
    };
    Ok(CameraSettings {
        lookfrom,
        lookat,
        vup,
        vfov_deg,
        aspect_ratio: 1.0,
        aperture,
        focus_dist,
        shutter,
    })
}

/// Rejects the fields of a typed table that do not belong to its `type`.
fn only_fields(
    ck: &Checker,
    prefix: &str,
    kind: &str,
    allowed: &[&str],
    present: &[(&str, Option<Range<usize>>)],
) -> Result<()> {
    for (name, span) in present {
        if let Some(span) = span
            && !allowed.contains(name)
        {
            return Err(ck.error(
                span.clone(),
                &format!("{prefix}.{name}"),
                format!(
                    "does not apply to type `{kind}` (allowed: {})",
                    allowed.join(", ")
                ),
            ));
        }
    }
    Ok(())
}

/// The value of a field its table's `type` requires, or an error at the table.
fn required<'a, T>(
    ck: &Checker,
    value: Option<&'a T>,
    table: Range<usize>,
    field: &str,
    kind: &str,
) -> Result<&'a T> {
    value.ok_or_else(|| ck.error(table, field, format!("missing, required by type `{kind}`")))
}

fn background(b: &Spanned<desc::BackgroundDesc>, ck: &Checker) -> Result<Background> {
    let d = b.get_ref();
    let kind = d.kind.get_ref().as_str();
    let present = [
        ("bottom", d.bottom.as_ref().map(Spanned::span)),
        ("top", d.top.as_ref().map(Spanned::span)),
        ("color", d.color.as_ref().map(Spanned::span)),
    ];
    let need = |v, f: &str| required(ck, v, b.span(), &format!("background.{f}"), kind);
    match kind {
        "gradient" => {
            only_fields(ck, "background", kind, &["bottom", "top"], &present)?;
            Ok(Background::Gradient {
                bottom: ck.color(need(d.bottom.as_ref(), "bottom")?, "background.bottom")?,
                top: ck.color(need(d.top.as_ref(), "top")?, "background.top")?,
            })
        }
        "uniform" => {
            only_fields(ck, "background", kind, &["color"], &present)?;
            let color = need(d.color.as_ref(), "color")?;
            Ok(Background::Uniform(ck.color(color, "background.color")?))
        }
        other => Err(ck.error(
            d.kind.span(),
            "background.type",
            format!("unknown background type `{other}`; expected `gradient` or `uniform`"),
        )),
    }
}

/// A material and the texture its colour comes from, if it names one.
fn material(
    name: &str,
    m: &Spanned<desc::MaterialDesc>,
    ck: &Checker,
    textures: &mut Textures,
) -> Result<(Material, Option<TextureId>)> {
    let d = m.get_ref();
    let prefix = format!("materials.{name}");
    let field = |f: &str| format!("{prefix}.{f}");
    let kind = d.kind.get_ref().as_str();
    let present = [
        ("albedo", d.albedo.as_ref().map(Spanned::span)),
        ("emit", d.emit.as_ref().map(Spanned::span)),
        ("fuzz", d.fuzz.as_ref().map(Spanned::span)),
        ("ir", d.ir.as_ref().map(Spanned::span)),
        ("refraction", d.refraction.as_ref().map(Spanned::span)),
    ];
    // A colour, or a texture: white, with the texture's value multiplied in where hit.
    let mut colour = |v: Option<&Spanned<ColorDesc>>,
                      key: &str|
     -> Result<(Color, Option<TextureId>)> {
        let v = required(ck, v, m.span(), &field(key), kind)?;
        match v.get_ref() {
            ColorDesc::Rgb(rgb) => {
                let c = ck.color(&Spanned::new(v.span(), desc::Exactly(*rgb)), &field(key))?;
                Ok((c, None))
            }
            ColorDesc::Texture(_) => Ok((Color::ONE, Some(textures.id_of(v, &field(key), ck)?))),
        }
    };
    Ok(match kind {
        "lambertian" => {
            only_fields(ck, &prefix, kind, &["albedo"], &present)?;
            let (albedo, texture) = colour(d.albedo.as_ref(), "albedo")?;
            (Material::Lambertian { albedo }, texture)
        }
        "metal" => {
            only_fields(ck, &prefix, kind, &["albedo", "fuzz"], &present)?;
            let fuzz = match &d.fuzz {
                Some(f) => {
                    ck.in_range(f, &field("fuzz"), |f| (0.0..=1.0).contains(&f), "in [0, 1]")?
                }
                None => 0.0,
            };
            let (albedo, texture) = colour(d.albedo.as_ref(), "albedo")?;
            (Material::Metal { albedo, fuzz }, texture)
        }
        "dielectric" => {
            only_fields(ck, &prefix, kind, &["ir", "refraction"], &present)?;
            let ir = required(ck, d.ir.as_ref(), m.span(), &field("ir"), kind)?;
            let material = Material::Dielectric {
                ir: ck.in_range(ir, &field("ir"), |i| i > 0.0, "positive")?,
                refraction: d
                    .refraction
                    .as_ref()
                    .map_or_else(Refraction::default, |r| *r.get_ref()),
            };
            (material, None)
        }
        "diffuse_light" => {
            only_fields(ck, &prefix, kind, &["emit"], &present)?;
            let (emit, texture) = colour(d.emit.as_ref(), "emit")?;
            (Material::DiffuseLight { emit }, texture)
        }
        "isotropic" => {
            only_fields(ck, &prefix, kind, &["albedo"], &present)?;
            let (albedo, texture) = colour(d.albedo.as_ref(), "albedo")?;
            (Material::Isotropic { albedo }, texture)
        }
        other => {
            return Err(ck.error(
                d.kind.span(),
                &field("type"),
                format!(
                    "unknown material type `{other}`; expected `lambertian`, `metal`, \
                     `dielectric`, `diffuse_light` or `isotropic`"
                ),
            ));
        }
    })
}
