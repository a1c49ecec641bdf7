//! Every path's operations against the same arithmetic on one `f32` at a time.

use super::*;

const A: [f32; 8] = [0.0, -0.0, 1.5, -2.25, f32::INFINITY, f32::NAN, 3.0, 1e-38];
const B: [f32; 8] = [-0.0, 0.0, 1.5, 7.0, -1.0, 2.0, f32::NAN, -1e38];

/// Each operation of `Lanes` applied to `A` and `B`: eight float results, then six masks.
struct AllOps;

impl Kernel for AllOps {
    type Output = (Vec<[f32; 8]>, Vec<u32>);
    fn run<I: Isa>(self, isa: I) -> Self::Output {
        let x = Lanes::load(isa, &F32x8(A));
        let y = Lanes::load(isa, &F32x8(B));
        let floats = vec![
            (x + y).to_array(),
            (x - y).to_array(),
            (x * y).to_array(),
            (x / y).to_array(),
            (-x).to_array(),
            x.sqrt().to_array(),
            x.fast_min(y).to_array(),
            x.fast_max(y).to_array(),
            x.simd_lt(y).select(x, y).to_array(),
            Lanes::splat(isa, 2.5).to_array(),
        ];
        let ids = Ids::load(isa, &U32x8([0, 1, 2, 3, 4, 5, 6, 7]));
        let masks = vec![
            x.simd_lt(y).to_bitmask(),
            x.simd_le(y).to_bitmask(),
            x.simd_ge(y).to_bitmask(),
            x.simd_eq(y).to_bitmask(),
            (x.simd_le(y) & x.simd_ge(y)).to_bitmask(),
            ids.eq_bitmask(Ids::splat(isa, 5)),
        ];
        (floats, masks)
    }
}

fn scalar() -> (Vec<[f32; 8]>, Vec<u32>) {
    let f = |op: &dyn Fn(f32, f32) -> f32| std::array::from_fn(|i| op(A[i], B[i]));
    let m =
        |op: &dyn Fn(f32, f32) -> bool| (0..8).fold(0, |m, i| m | (u32::from(op(A[i], B[i])) << i));
    let floats = vec![
        f(&|a, b| a + b),
        f(&|a, b| a - b),
        f(&|a, b| a * b),
        f(&|a, b| a / b),
        f(&|a, _| -a),
        f(&|a, _| a.sqrt()),
        f(&|a, b| if a < b { a } else { b }),
        f(&|a, b| if a > b { a } else { b }),
        f(&|a, b| if a < b { a } else { b }),
        [2.5; 8],
    ];
    let masks = vec![
        m(&|a, b| a < b),
        m(&|a, b| a <= b),
        m(&|a, b| a >= b),
        m(&|a, b| a == b),
        m(&|a, b| a == b),
        1 << 5,
    ];
    (floats, masks)
}

#[test]
fn every_path_matches_scalar_arithmetic_bit_for_bit() {
    // Bit for bit, but any NaN as any other: which NaN an invalid operation makes is the
    // hardware's (and the constant folder's) choice, and no NaN reaches an image.
    let bits = |v: &[[f32; 8]]| -> Vec<[u32; 8]> {
        let canonical = |x: f32| if x.is_nan() { u32::MAX } else { x.to_bits() };
        v.iter().map(|a| a.map(canonical)).collect()
    };
    let (want_f, want_m) = scalar();
    for path in Path::supported() {
        let (got_f, got_m) = dispatch(path, AllOps);
        assert_eq!(bits(&got_f), bits(&want_f), "{path}");
        assert_eq!(got_m, want_m, "{path}");
    }
}

#[test]
fn paths_parse_and_refuse_what_the_cpu_lacks() {
    assert_eq!(Path::choose("portable"), Ok(Path::Portable));
    assert_eq!(Path::choose("auto"), Ok(Path::best()));
    assert!(
        Path::choose("sse9")
            .unwrap_err()
            .contains("unknown SIMD path")
    );
    for path in Path::ALL {
        assert_eq!(path.name().parse::<Path>(), Ok(path));
        assert_eq!(Path::choose(path.name()).is_ok(), path.is_supported());
    }
    assert!(Path::best().is_supported());
}

#[test]
fn auto_takes_the_widest_path_but_avx2_on_intel() {
    let (path, why) = Path::auto();
    assert!(path.is_supported() && !why.is_empty());
    let widest = *Path::supported().last().unwrap();
    let intel = super::cpu_identity().is_some_and(|c| c.starts_with("GenuineIntel"));
    if intel && widest == Path::Avx512 {
        assert_eq!(path, Path::Avx2, "{why}");
    } else {
        assert_eq!(path, widest, "{why}");
    }
}

/// `slab16` of random rays against random boxes (and inverted, flat and infinite ones).
struct Slabs(Vec<([F32x16; 6], SlabRay)>);

impl Kernel for Slabs {
    type Output = Vec<(u32, [u32; 16])>;
    fn run<I: Isa>(self, isa: I) -> Self::Output {
        (self.0.iter())
            .map(|(planes, ray)| {
                let (hits, near) = isa.slab16(planes, ray);
                (hits, near.map(f32::to_bits))
            })
            .collect()
    }
}

/// The slab test of one box, one `f32` at a time, in `slab8`'s order of operations.
fn slab_scalar(min: [f32; 3], max: [f32; 3], ray: &SlabRay) -> (bool, f32) {
    let lo = |a: f32, b: f32| if a < b { a } else { b };
    let hi = |a: f32, b: f32| if a > b { a } else { b };
    let t0: [f32; 3] = std::array::from_fn(|k| (min[k] - ray.origin[k]) * ray.inv_dir[k]);
    let t1: [f32; 3] = std::array::from_fn(|k| (max[k] - ray.origin[k]) * ray.inv_dir[k]);
    let near = hi(
        hi(lo(t0[0], t1[0]), lo(t0[1], t1[1])),
        hi(lo(t0[2], t1[2]), ray.t_min),
    );
    let far = lo(
        lo(hi(t0[0], t1[0]), hi(t0[1], t1[1])),
        lo(hi(t0[2], t1[2]), ray.t_max),
    );
    (near <= far, near)
}

#[test]
fn sixteen_lane_box_tests_match_scalar_arithmetic_on_every_path() {
    let mut rng = crate::sampling::Sampler::from_seed(3);
    let mut cases = Vec::new();
    for case in 0..2000 {
        let mut planes = [F32x16::ZERO; 6];
        for lane in 0..16 {
            let c: [f32; 3] = std::array::from_fn(|_| rng.range(-10.0, 10.0));
            let h: [f32; 3] = std::array::from_fn(|_| rng.range(0.0, 3.0));
            for k in 0..3 {
                let (mut lo, mut hi) = (c[k] - h[k], c[k] + h[k]);
                match (case + lane) % 7 {
                    0 => (lo, hi) = (f32::INFINITY, f32::NEG_INFINITY), // an unused lane
                    1 => hi = lo,                                       // a flat box
                    _ => {}
                }
                planes[k].0[lane / 8].0[lane % 8] = lo;
                planes[k + 3].0[lane / 8].0[lane % 8] = hi;
            }
        }
        let d: [f32; 3] = std::array::from_fn(|_| rng.range(-1.0, 1.0));
        let inv = d.map(|x| {
            if case % 5 == 0 {
                1e30
            } else {
                (1.0 / x).clamp(-1e30, 1e30)
            }
        });
        let ray = SlabRay {
            origin: std::array::from_fn(|_| rng.range(-12.0, 12.0)),
            inv_dir: inv,
            t_min: if case % 3 == 0 { 0.0 } else { 1e-3 },
            t_max: if case % 4 == 0 {
                f32::INFINITY
            } else {
                rng.range(0.0, 30.0)
            },
        };
        cases.push((planes, ray));
    }
    let want: Vec<(u32, [u32; 16])> = (cases.iter())
        .map(|(planes, ray)| {
            let mut hits = 0;
            let near = std::array::from_fn(|lane| {
                let at = |p: &F32x16| p.0[lane / 8].0[lane % 8];
                let min = [0, 1, 2].map(|k| at(&planes[k]));
                let max = [3, 4, 5].map(|k| at(&planes[k]));
                let (meets, near) = slab_scalar(min, max, ray);
                hits |= u32::from(meets) << lane;
                near.to_bits()
            });
            (hits, near)
        })
        .collect();
    assert!(want.iter().any(|(h, _)| *h != 0) && want.iter().any(|(h, _)| *h != 0xffff));
    for path in Path::supported() {
        assert_eq!(dispatch(path, Slabs(cases.clone())), want, "{path}");
    }
}

#[test]
fn grid_indices_truncate_inside_the_range_and_refuse_the_rest() {
    let cases = [
        (0.0, 5.0, (true, 0)),
        (-0.0, 5.0, (true, 0)),
        (0.999, 5.0, (true, 0)),
        (4.999, 5.0, (true, 4)),
        (5.0, 5.0, (false, 0)),
        (-1e-30, 5.0, (false, 0)),
        (f32::NAN, 5.0, (false, 0)),
        (f32::INFINITY, f32::INFINITY, (false, 0)),
        (3e7, f32::INFINITY, (false, 0)),
        (16_777_215.0, f32::INFINITY, (true, 16_777_215)),
    ];
    for (x, limit, want) in cases {
        assert_eq!(index_below(x, limit), want, "{x} below {limit}");
    }
}
