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
