//! The primitives of a scene file, checked and built: spheres (still or moving), quads, the
//! book's rectangles and boxes, media, and *The Next Week*'s generators of boxes and sphere
//! clouds; each placed where its `rotate_y_deg` and `translate` say (the book's instances,
//! applied to the primitive itself, so a placed box is six quads like any other).

use super::Primitives;
use super::check::{Checker, MAX_LENGTH};
use super::desc::{
    self, AxisDesc, BoundaryBoxDesc, BoundarySphereDesc, Exactly, RandomBoxesDesc, SphereCloudDesc,
    Vec3Desc,
};
use super::draws::DrawSettings;
use crate::error::Result;
use crate::geometry::{Boundary, MaterialId, Medium, MovingSphere, Quad, Sphere};
use crate::material::Material;
use crate::math::{Vec3, cross, sin};
use std::ops::Range;
use toml::Spanned;

/// The most spheres a cloud may hold.
pub const MAX_CLOUD: i64 = 1 << 20;
/// The most primitives a scene may hold in all, spheres (listed, generated, in clouds,
/// still or moving) and quads (a box is six), a medium's boundary among them: far above the
/// books' (the final scene has about 2,400 quads and 1,100 spheres), and within about 300 MB
/// with their tree.
pub const MAX_PRIMITIVES: usize = 1 << 20;

/// The primitives `prims` holds so far, each medium's boundary counted as the spheres or
/// quads it is made of (a box medium holds six quads, and a ray that reaches it tests them
/// all): media went uncounted, and some 500,000 box media fit in a file's values beside
/// the most other primitives a scene may hold.
pub(super) fn held(prims: &Primitives) -> usize {
    let media = prims.media.iter().map(boundary_primitives).sum::<usize>();
    prims.spheres.len() + prims.moving_spheres.len() + prims.quads.len() + media
}

/// The primitives a medium's boundary is made of: a sphere, or a box's quads.
fn boundary_primitives(medium: &Medium) -> usize {
    match &medium.boundary {
        Boundary::Sphere(_) | Boundary::MovingSphere(_) => 1,
        Boundary::Quads(quads) => quads.len(),
    }
}

/// A rotation about the y axis through the origin, then a translation: the book's
/// `translate(rotate_y(object, angle), offset)`, in `f64`.
#[derive(Clone, Copy, Debug)]
pub(super) struct Placement {
    sin: f64,
    cos: f64,
    offset: [f64; 3],
}

impl Placement {
    pub(super) const NONE: Placement = Placement {
        sin: 0.0,
        cos: 1.0,
        offset: [0.0; 3],
    };

    /// The placement `rotate_y_deg` and `translate` give (`field` is the table's name).
    pub(super) fn check(
        ck: &Checker,
        field: &str,
        rotate_y_deg: Option<&Spanned<f64>>,
        translate: Option<&Vec3Desc>,
    ) -> Result<Self> {
        let degrees = match rotate_y_deg {
            None => 0.0,
            Some(a) => f64::from(ck.in_range(
                a,
                &format!("{field}.rotate_y_deg"),
                |a| a.abs() <= 1e6,
                "an angle in degrees of at most 10⁶ in size",
            )?),
        };
        let offset = match translate {
            None => [0.0; 3],
            Some(t) => {
                let t = ck.point(t, &format!("{field}.translate"))?;
                [t.x, t.y, t.z].map(f64::from)
            }
        };
        // Whole turns first, so the angle stays small and exact multiples of 90° come out
        // exact.
        let radians = (degrees % 360.0).to_radians();
        Ok(Self {
            sin: sin(radians),
            cos: sin(radians + std::f64::consts::FRAC_PI_2),
            offset,
        })
    }

    /// A direction (an edge) rotated: `x' = cos x + sin z`, `z' = cos z - sin x`.
    fn vector(&self, v: [f64; 3]) -> [f64; 3] {
        [
            self.cos * v[0] + self.sin * v[2],
            v[1],
            self.cos * v[2] - self.sin * v[0],
        ]
    }

    /// A point rotated, then moved.
    fn point(&self, p: [f64; 3]) -> [f64; 3] {
        let r = self.vector(p);
        [
            r[0] + self.offset[0],
            r[1] + self.offset[1],
            r[2] + self.offset[2],
        ]
    }
}

/// Refuses a primitive whose `points` (a sphere's centre, a box's or a quad's corners), once
/// placed, lie beyond `±MAX_LENGTH`: the bound is on where a primitive ends up, as for a
/// moving sphere, and rotating a point within it by 45° and moving it by the most a
/// translation may took a sphere's centre to 2.4e18.
fn check_placed(
    ck: &Checker,
    place: &Placement,
    points: &[[f64; 3]],
    span: Range<usize>,
    field: &str,
) -> Result<()> {
    let reach = points
        .iter()
        .flat_map(|&p| place.point(p))
        .fold(0.0, |m: f64, c| m.max(c.abs()));
    if reach > f64::from(MAX_LENGTH) {
        return Err(ck.error(
            span,
            field,
            format!(
                "is placed (rotate_y_deg, then translate) {reach:e} from the origin: \
                 coordinates must lie within ±{MAX_LENGTH:e} where the primitive ends up \
                 (beyond, f32 arithmetic overflows)"
            ),
        ));
    }
    Ok(())
}

/// Refuses a box from `lo` to `hi` (its `max` at `span`, of the table `field`) whose
/// corners, once placed, lie beyond `±MAX_LENGTH` (`check_placed`).
fn check_placed_box(
    ck: &Checker,
    place: &Placement,
    (lo, hi): (Vec3, Vec3),
    span: Range<usize>,
    field: &str,
) -> Result<()> {
    check_placed(ck, place, &corners(lo, hi), span, &format!("{field}.max"))
}

/// The eight corners of the box from `lo` to `hi`.
fn corners(lo: Vec3, hi: Vec3) -> [[f64; 3]; 8] {
    let (a, b) = (f64s(lo), f64s(hi));
    std::array::from_fn(|i| std::array::from_fn(|k| if i >> k & 1 == 0 { a[k] } else { b[k] }))
}

/// The four vertices of the quad `corner + a u + b v`.
fn vertices(corner: [f64; 3], u: [f64; 3], v: [f64; 3]) -> [[f64; 3]; 4] {
    std::array::from_fn(|i| {
        let (a, b) = ((i & 1) as f64, (i >> 1) as f64);
        std::array::from_fn(|k| corner[k] + a * u[k] + b * v[k])
    })
}

fn f64s(v: Vec3) -> [f64; 3] {
    [v.x, v.y, v.z].map(f64::from)
}

fn vec3(v: [f64; 3]) -> Vec3 {
    Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32)
}

/// The quad `corner + a u + b v` placed; `None` when its edges are too short, too long or
/// parallel for f32 arithmetic.
fn placed_quad(
    place: &Placement,
    corner: [f64; 3],
    u: [f64; 3],
    v: [f64; 3],
    material: MaterialId,
) -> Option<Quad> {
    let (corner, u, v) = (
        vec3(place.point(corner)),
        vec3(place.vector(u)),
        vec3(place.vector(v)),
    );
    let edge_ok = |e: Vec3| (1e-6..=1e9).contains(&e.length());
    let n = cross(u, v).length();
    let sound =
        corner.is_finite() && edge_ok(u) && edge_ok(v) && n >= 1e-6 * u.length() * v.length();
    sound.then(|| Quad::new(corner, u, v, material))
}

/// The six faces of the box from `min` to `max`, each facing out, placed.
fn box_quads(place: &Placement, min: Vec3, max: Vec3, material: MaterialId) -> Option<Vec<Quad>> {
    let (a, b) = (f64s(min), f64s(max));
    let (dx, dy, dz) = (
        [b[0] - a[0], 0.0, 0.0],
        [0.0, b[1] - a[1], 0.0],
        [0.0, 0.0, b[2] - a[2]],
    );
    let neg = |v: [f64; 3]| v.map(|c| -c);
    let faces = [
        ([a[0], a[1], b[2]], dx, dy),      // front, z = max
        ([b[0], a[1], b[2]], neg(dz), dy), // right, x = max
        ([b[0], a[1], a[2]], neg(dx), dy), // back, z = min
        ([a[0], a[1], a[2]], dz, dy),      // left, x = min
        ([a[0], b[1], b[2]], dx, neg(dz)), // top, y = max
        ([a[0], a[1], a[2]], dx, dz),      // bottom, y = min
    ];
    faces
        .iter()
        .map(|&(corner, u, v)| placed_quad(place, corner, u, v, material))
        .collect()
}

/// A box's corners, checked: `min` below `max` on every axis.
fn box_corners(ck: &Checker, field: &str, min: &Vec3Desc, max: &Vec3Desc) -> Result<(Vec3, Vec3)> {
    let lo = ck.point(min, &format!("{field}.min"))?;
    let hi = ck.point(max, &format!("{field}.max"))?;
    if !lo.cmplt(hi).all() {
        return Err(ck.error(
            max.span(),
            &format!("{field}.max"),
            format!("must exceed min on every axis, got min {lo} and max {hi}"),
        ));
    }
    Ok((lo, hi))
}

fn too_thin(ck: &Checker, span: Range<usize>, field: &str) -> crate::error::Error {
    ck.error(
        span,
        field,
        "its edges are too short (under 10⁻⁶), too long (over 10⁹) or parallel for f32 \
         arithmetic",
    )
}

/// Looks up a material by name for the primitive `field`, as `names` gives the ids.
pub(super) type MaterialLookup<'a> = dyn Fn(&Spanned<String>, &str) -> Result<MaterialId> + 'a;

/// Builds every listed and generated primitive but the first book's `[random_spheres]`
/// (which the caller splices among the listed spheres), in the file's order within each
/// kind.
pub(super) fn primitives(
    d: &desc::SceneDesc,
    ck: &Checker,
    material: &MaterialLookup,
    materials: &[Material],
    shutter: (f32, f32),
    file_seed: u64,
) -> Result<Primitives> {
    let mut prims = Primitives::default();
    for (i, s) in d.spheres.iter().enumerate() {
        let field = format!("spheres[{i}]");
        let s = s.get_ref();
        let id = material(&s.material, &format!("{field}.material"))?;
        let placed = Placement::check(ck, &field, s.rotate_y_deg.as_ref(), s.translate.as_ref())?;
        let ball = Ball {
            center: &s.center,
            radius: &s.radius,
            center2: s.center2.as_ref(),
            move_times: s.move_times.as_ref(),
        };
        match ball.build(ck, &field, &placed, id, shutter)? {
            Shape::Still(sphere) => prims.spheres.push(sphere),
            Shape::Moving(sphere) => prims.moving_spheres.push(sphere),
        }
    }
    for (i, q) in d.quads.iter().enumerate() {
        let field = format!("quads[{i}]");
        let q = q.get_ref();
        let id = material(&q.material, &format!("{field}.material"))?;
        let placed = Placement::check(ck, &field, q.rotate_y_deg.as_ref(), q.translate.as_ref())?;
        let corner = ck.point(&q.corner, &format!("{field}.corner"))?;
        let u = ck.point(&q.u, &format!("{field}.u"))?;
        let v = ck.point(&q.v, &format!("{field}.v"))?;
        let vertices = vertices(f64s(corner), f64s(u), f64s(v));
        check_placed(
            ck,
            &placed,
            &vertices,
            q.corner.span(),
            &format!("{field}.corner"),
        )?;
        let quad = placed_quad(&placed, f64s(corner), f64s(u), f64s(v), id)
            .ok_or_else(|| too_thin(ck, q.v.span(), &format!("{field}.v")))?;
        prims.quads.push(quad);
    }
    for (i, r) in d.rects.iter().enumerate() {
        let field = format!("rects[{i}]");
        let span = r.span();
        let r = r.get_ref();
        let id = material(&r.material, &format!("{field}.material"))?;
        let placed = Placement::check(ck, &field, r.rotate_y_deg.as_ref(), r.translate.as_ref())?;
        let quad = rect(ck, &field, span, r, &placed, id)?;
        prims.quads.push(quad);
    }
    for (i, b) in d.boxes.iter().enumerate() {
        let field = format!("boxes[{i}]");
        let b = b.get_ref();
        let id = material(&b.material, &format!("{field}.material"))?;
        let placed = Placement::check(ck, &field, b.rotate_y_deg.as_ref(), b.translate.as_ref())?;
        let (lo, hi) = box_corners(ck, &field, &b.min, &b.max)?;
        check_placed_box(ck, &placed, (lo, hi), b.max.span(), &field)?;
        let quads = box_quads(&placed, lo, hi, id)
            .ok_or_else(|| too_thin(ck, b.max.span(), &format!("{field}.max")))?;
        prims.quads.extend(quads);
        check_quads(ck, &prims, b.max.span(), &field)?;
    }
    // Every generator's boxes are weighed before any is drawn, as the clouds' spheres are: a
    // second generator of 100,000 boxes was refused only once its 600,000 quads were built.
    let mut weighed = held(&prims);
    for (i, g) in d.random_boxes.iter().enumerate() {
        let count = &g.get_ref().count;
        let [nx, nz] = count.get_ref().0;
        // A count out of its range is refused by `random_boxes`, which says the range.
        let boxes = if count_ok(nx, nz) { nx * nz } else { 0 };
        weighed = weighed.saturating_add(6 * boxes as usize);
        check_held(
            ck,
            weighed,
            count.span(),
            &format!("random_boxes[{i}].count"),
        )?;
    }
    for (i, g) in d.random_boxes.iter().enumerate() {
        let field = format!("random_boxes[{i}]");
        let quads = random_boxes(ck, &field, g, material, file_seed)?;
        prims.quads.extend(quads);
        check_quads(ck, &prims, g.span(), &field)?;
    }
    // Counted as they are added: `held` walks every medium, and a walk for each of some
    // 170,000 media (the most the bound lets by) would take seconds.
    let mut held_so_far = held(&prims);
    for (i, m) in d.media.iter().enumerate() {
        let field = format!("media[{i}]");
        let made = medium(ck, &field, m, material, materials, shutter)?;
        held_so_far = held_so_far.saturating_add(boundary_primitives(&made));
        prims.media.push(made);
        check_held(ck, held_so_far, m.span(), &field)?;
    }
    Ok(prims)
}

/// Appends the spheres of every `[[random_sphere_clouds]]`.
pub(super) fn sphere_clouds(
    d: &desc::SceneDesc,
    ck: &Checker,
    material: &MaterialLookup,
    file_seed: u64,
    prims: &mut Primitives,
) -> Result<()> {
    // Every cloud's count is weighed before any is drawn: forty clouds of the most each
    // would take gigabytes.
    let mut held = held(prims);
    for (i, c) in d.random_sphere_clouds.iter().enumerate() {
        let count = usize::try_from(*c.get_ref().count.get_ref()).unwrap_or(0);
        held = held.saturating_add(count);
        check_held(
            ck,
            held,
            c.get_ref().count.span(),
            &format!("random_sphere_clouds[{i}].count"),
        )?;
    }
    for (i, c) in d.random_sphere_clouds.iter().enumerate() {
        let field = format!("random_sphere_clouds[{i}]");
        let spheres = sphere_cloud(ck, &field, c.get_ref(), material, file_seed)?;
        prims.spheres.extend(spheres);
    }
    Ok(())
}

fn check_quads(ck: &Checker, prims: &Primitives, span: Range<usize>, field: &str) -> Result<()> {
    check_held(ck, held(prims), span, field)
}

/// Refuses `held` primitives beyond `MAX_PRIMITIVES`, at the value that asks for them.
pub(super) fn check_held(ck: &Checker, held: usize, span: Range<usize>, field: &str) -> Result<()> {
    if held > MAX_PRIMITIVES {
        return Err(ck.error(
            span,
            field,
            format!(
                "would make the scene's primitives (spheres and quads; a box is six) {held}, \
                 more than the {MAX_PRIMITIVES} a scene may hold"
            ),
        ));
    }
    Ok(())
}

/// A still or a moving sphere.
enum Shape {
    Still(Sphere),
    Moving(MovingSphere),
}

/// The keys a sphere (or a medium's sphere boundary) is given.
struct Ball<'a> {
    center: &'a Vec3Desc,
    radius: &'a Spanned<f64>,
    center2: Option<&'a Vec3Desc>,
    move_times: Option<&'a Spanned<Exactly<f64, 2>>>,
}

impl Ball<'_> {
    fn build(
        &self,
        ck: &Checker,
        field: &str,
        place: &Placement,
        material: MaterialId,
        shutter: (f32, f32),
    ) -> Result<Shape> {
        let center = ck.point(self.center, &format!("{field}.center"))?;
        let radius = ck.radius(self.radius, &format!("{field}.radius"), false)?;
        let moved = |c: Vec3| vec3(place.point(f64s(c)));
        let Some(center2_desc) = self.center2 else {
            if let Some(t) = self.move_times {
                return Err(ck.error(
                    t.span(),
                    &format!("{field}.move_times"),
                    "applies to a moving sphere only: give its center2 too",
                ));
            }
            let span = self.center.span();
            check_placed(ck, place, &[f64s(center)], span, &format!("{field}.center"))?;
            return Ok(Shape::Still(Sphere::new(moved(center), radius, material)));
        };
        let center2 = ck.point(center2_desc, &format!("{field}.center2"))?;
        let (time0, time1) = match self.move_times {
            None => (0.0, 1.0),
            Some(t) => {
                let (a, b) = ck.range(t, &format!("{field}.move_times"))?;
                // As f32 holds them, as the sphere does: `[0, 1e-50]` is one time there, and
                // the sphere would stand still where the file asks it to move.
                if a as f32 == b as f32 {
                    return Err(ck.error(
                        t.span(),
                        &format!("{field}.move_times"),
                        "the two times must differ (as 32-bit floats hold them)",
                    ));
                }
                (a as f32, b as f32)
            }
        };
        let (start, end) = (moved(center), moved(center2));
        // Where the moved centre lies when the shutter opens and closes (the farthest any ray
        // meets it): beyond `MAX_LENGTH` its squares overflow and the sphere silently
        // vanishes, as it would for a far centre written out.
        let times = [time0, time1].map(f64::from);
        let (from, to) = (f64s(start), f64s(end));
        for (when, at) in [("opens", shutter.0), ("closes", shutter.1)] {
            let s = (f64::from(at) - times[0]) / (times[1] - times[0]);
            let reach = (0..3)
                .map(|k| (from[k] + s * (to[k] - from[k])).abs())
                .fold(0.0, f64::max);
            if reach > f64::from(MAX_LENGTH) {
                let (key, span) = match self.move_times {
                    Some(t) => ("move_times", t.span()),
                    None => ("center2", center2_desc.span()),
                };
                return Err(ck.error(
                    span,
                    &format!("{field}.{key}"),
                    format!(
                        "moves the centre to {reach:e} from the origin when the shutter {when} \
                         (time {at}): coordinates must lie within ±{MAX_LENGTH:e} (beyond, f32 \
                         arithmetic overflows and the sphere would vanish)"
                    ),
                ));
            }
        }
        Ok(Shape::Moving(MovingSphere::new(
            (start, time0),
            (end, time1),
            radius,
            material,
            shutter,
        )))
    }
}

/// The book's axis-aligned rectangle: two axes ranges, the third its plane.
fn rect(
    ck: &Checker,
    field: &str,
    span: Range<usize>,
    r: &desc::RectDesc,
    place: &Placement,
    material: MaterialId,
) -> Result<Quad> {
    let axes = [&r.x, &r.y, &r.z];
    let mut plane = None;
    let mut ranges = [[0.0f64; 2]; 3];
    for (axis, value) in axes.iter().enumerate() {
        let name = ["x", "y", "z"][axis];
        let Some(value) = value else {
            return Err(ck.error(
                span.clone(),
                &format!("{field}.{name}"),
                "missing: a rectangle gives x, y and z, two as ranges [a, b] and one as the \
                 coordinate of its plane",
            ));
        };
        let finite = |x: f64| x.is_finite() && x.abs() <= f64::from(super::MAX_LENGTH);
        match *value.get_ref() {
            AxisDesc::Plane(k) if finite(k) => {
                if plane.is_some() {
                    return Err(ck.error(
                        value.span(),
                        &format!("{field}.{name}"),
                        "a second plane coordinate: one axis is a number, the other two ranges",
                    ));
                }
                plane = Some((axis, k));
            }
            AxisDesc::Range([a, b]) if finite(a) && finite(b) && a < b => ranges[axis] = [a, b],
            _ => {
                return Err(ck.error(
                    value.span(),
                    &format!("{field}.{name}"),
                    format!(
                        "must be a finite number or a range [a, b] with a < b, within \
                         ±{:e}",
                        super::MAX_LENGTH
                    ),
                ));
            }
        }
    }
    let Some((axis, k)) = plane else {
        return Err(ck.error(
            span,
            field,
            "needs one axis given as the coordinate of its plane (e.g. `z = -2`), not three \
             ranges",
        ));
    };
    // The book's xy, xz and yz rectangles face +z, +y and +x: edges along (x, y), (z, x)
    // and (y, z).
    let (first, second) = match axis {
        2 => (0, 1),
        1 => (2, 0),
        _ => (1, 2),
    };
    let mut corner = [0.0; 3];
    corner[axis] = k;
    corner[first] = ranges[first][0];
    corner[second] = ranges[second][0];
    let mut u = [0.0; 3];
    u[first] = ranges[first][1] - ranges[first][0];
    let mut v = [0.0; 3];
    v[second] = ranges[second][1] - ranges[second][0];
    check_placed(ck, place, &vertices(corner, u, v), span.clone(), field)?;
    placed_quad(place, corner, u, v, material).ok_or_else(|| too_thin(ck, span, field))
}

/// Whether `[nx, nz]` is a box generator's count: each from 1 to 1000, at most 100,000 boxes.
fn count_ok(nx: i64, nz: i64) -> bool {
    (1..=1000).contains(&nx) && (1..=1000).contains(&nz) && nx * nz <= 100_000
}

/// The final scene's ground: a grid of boxes whose tops are drawn at random.
fn random_boxes(
    ck: &Checker,
    field: &str,
    g: &Spanned<RandomBoxesDesc>,
    material: &MaterialLookup,
    file_seed: u64,
) -> Result<Vec<Quad>> {
    let d = g.get_ref();
    let id = material(&d.material, &format!("{field}.material"))?;
    let corner = ck.point(&d.corner, &format!("{field}.corner"))?;
    let [nx, nz] = d.count.get_ref().0;
    if !count_ok(nx, nz) {
        return Err(ck.error(
            d.count.span(),
            &format!("{field}.count"),
            format!("must be two counts from 1 to 1000, at most 100000 boxes, got [{nx}, {nz}]"),
        ));
    }
    let size = ck.length(&d.size, &format!("{field}.size"), |s| s > 0.0, "positive")?;
    let (low, high) = ck.range(&d.top, &format!("{field}.top"))?;
    if low <= f64::from(corner.y) {
        return Err(ck.error(
            d.top.span(),
            &format!("{field}.top"),
            format!(
                "must lie above the boxes' bottom (corner's y, {})",
                corner.y
            ),
        ));
    }
    let draws = DrawSettings::check(
        ck,
        field,
        d.generator,
        d.seed.as_ref(),
        d.skip.as_ref(),
        d.draw_order,
        file_seed,
    )?;
    let mut draws = draws.draws();
    let (x0, y0, z0) = (
        f64::from(corner.x),
        f64::from(corner.y),
        f64::from(corner.z),
    );
    let w = f64::from(size);
    let mut quads = Vec::with_capacity((nx * nz * 6) as usize);
    for i in 0..nx {
        for j in 0..nz {
            let (bx, bz) = (x0 + i as f64 * w, z0 + j as f64 * w);
            let top = draws.range(low..high);
            let lo = vec3([bx, y0, bz]);
            let hi = vec3([bx + w, top, bz + w]);
            let faces = box_quads(&Placement::NONE, lo, hi, id)
                .ok_or_else(|| too_thin(ck, d.size.span(), &format!("{field}.size")))?;
            quads.extend(faces);
        }
    }
    Ok(quads)
}

/// The final scene's cloud: spheres at uniform random points of a box, placed.
fn sphere_cloud(
    ck: &Checker,
    field: &str,
    d: &SphereCloudDesc,
    material: &MaterialLookup,
    file_seed: u64,
) -> Result<Vec<Sphere>> {
    let id = material(&d.material, &format!("{field}.material"))?;
    let count = *d.count.get_ref();
    if !(0..=MAX_CLOUD).contains(&count) {
        return Err(ck.error(
            d.count.span(),
            &format!("{field}.count"),
            format!("must be between 0 and {MAX_CLOUD}, got {count}"),
        ));
    }
    let (lo, hi) = box_corners(ck, field, &d.min, &d.max)?;
    let radius = ck.radius(&d.radius, &format!("{field}.radius"), true)?;
    let placed = Placement::check(ck, field, d.rotate_y_deg.as_ref(), d.translate.as_ref())?;
    check_placed_box(ck, &placed, (lo, hi), d.max.span(), field)?;
    let draws = DrawSettings::check(
        ck,
        field,
        d.generator,
        d.seed.as_ref(),
        d.skip.as_ref(),
        d.draw_order,
        file_seed,
    )?;
    let mut draws = draws.draws();
    let (lo, hi) = (f64s(lo), f64s(hi));
    let same_range = lo[0] == lo[1] && lo[1] == lo[2] && hi[0] == hi[1] && hi[1] == hi[2];
    Ok((0..count)
        .map(|_| {
            // `point3::random(min, max)`: three draws of one range (each axis its own when
            // the box is not a cube).
            let c = if same_range {
                draws.three(lo[0]..hi[0])
            } else {
                let u = draws.three(0.0..1.0);
                std::array::from_fn(|k| lo[k] + (hi[k] - lo[k]) * u[k])
            };
            Sphere::new(vec3(placed.point(c)), radius, id)
        })
        .collect())
}

/// A constant-density medium and its boundary.
fn medium(
    ck: &Checker,
    field: &str,
    m: &Spanned<desc::MediumDesc>,
    material: &MaterialLookup,
    materials: &[Material],
    shutter: (f32, f32),
) -> Result<Medium> {
    let d = m.get_ref();
    let id = material(&d.material, &format!("{field}.material"))?;
    if !matches!(materials[id.0 as usize], Material::Isotropic { .. }) {
        return Err(ck.error(
            d.material.span(),
            &format!("{field}.material"),
            format!(
                "`{}` is not of type `isotropic`, the phase function a medium scatters by",
                d.material.get_ref()
            ),
        ));
    }
    let density = ck.in_range(
        &d.density,
        &format!("{field}.density"),
        // The bounds as f32 holds them, as it holds the density: 1e30 written is
        // 1.0000000150e30 in f32, which a bound of f64's 1e30 refused with "must be between
        // 1e-30 and 1e30, got 1e30".
        |x| (f64::from(1e-30f32)..=f64::from(1e30f32)).contains(&x),
        "positive, between 1e-30 and 1e30",
    )?;
    let boundary = match (&d.sphere, &d.cuboid) {
        (Some(s), None) => sphere_boundary(ck, &format!("{field}.sphere"), s.get_ref(), shutter)?,
        (None, Some(b)) => box_boundary(ck, &format!("{field}.box"), b.get_ref())?,
        (Some(_), Some(b)) => {
            return Err(ck.error(
                b.span(),
                &format!("{field}.box"),
                "a medium has one boundary: a sphere or a box, not both",
            ));
        }
        (None, None) => {
            return Err(ck.error(
                m.span(),
                field,
                "needs its boundary: `sphere = { center, radius }` or `box = { min, max }`",
            ));
        }
    };
    Ok(Medium::new(boundary, density, id))
}

fn sphere_boundary(
    ck: &Checker,
    field: &str,
    s: &BoundarySphereDesc,
    shutter: (f32, f32),
) -> Result<Boundary> {
    let placed = Placement::check(ck, field, s.rotate_y_deg.as_ref(), s.translate.as_ref())?;
    let ball = Ball {
        center: &s.center,
        radius: &s.radius,
        center2: s.center2.as_ref(),
        move_times: s.move_times.as_ref(),
    };
    // The boundary's own material is never used: a medium scatters by its own.
    let no_material = MaterialId(u32::MAX);
    Ok(
        match ball.build(ck, field, &placed, no_material, shutter)? {
            Shape::Still(sphere) => Boundary::Sphere(sphere),
            Shape::Moving(sphere) => Boundary::MovingSphere(sphere),
        },
    )
}

fn box_boundary(ck: &Checker, field: &str, b: &BoundaryBoxDesc) -> Result<Boundary> {
    let placed = Placement::check(ck, field, b.rotate_y_deg.as_ref(), b.translate.as_ref())?;
    let (lo, hi) = box_corners(ck, field, &b.min, &b.max)?;
    check_placed_box(ck, &placed, (lo, hi), b.max.span(), field)?;
    let quads = box_quads(&placed, lo, hi, MaterialId(u32::MAX))
        .ok_or_else(|| too_thin(ck, b.max.span(), &format!("{field}.max")))?;
    Ok(Boundary::Quads(quads))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn placing_rotates_about_y_then_moves() {
        let ck_text = "";
        let ck = Checker::new(ck_text, std::path::Path::new("t.toml"));
        let place = Placement::check(
            &ck,
            "t",
            Some(&Spanned::new(0..0, 90.0)),
            Some(&Spanned::new(0..0, Exactly([10.0, 0.0, 0.0]))),
        )
        .unwrap();
        // The book's rotate_y by +90°: x' = cos x + sin z = z, z' = cos z - sin x = -x.
        let p = place.point([1.0, 2.0, 3.0]);
        assert!(
            (p[0] - 13.0).abs() < 1e-12 && p[1] == 2.0 && (p[2] + 1.0).abs() < 1e-12,
            "{p:?}"
        );
    }

    #[test]
    fn a_box_is_six_quads_facing_out() {
        let quads = box_quads(
            &Placement::NONE,
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 2.0, 3.0),
            MaterialId(0),
        )
        .unwrap();
        let centre = Vec3::new(0.5, 1.0, 1.5);
        for q in &quads {
            let mid = q.corner + 0.5 * q.u + 0.5 * q.v;
            assert!(q.normal.dot(mid - centre) > 0.0, "{q:?}");
        }
    }
}
