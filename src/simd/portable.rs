//! The portable path: `wide`'s eight-lane types, which compile to two SSE2 halves on any
//! x86-64, NEON on aarch64 and plain arrays elsewhere. Safe code only.

use super::{F32x8, Isa, U32x8};
use wide::{f32x8, u32x8};

/// The token of the portable path: every CPU runs it.
#[derive(Clone, Copy, Debug, Default)]
pub struct Portable;

impl Isa for Portable {
    type F = f32x8;
    type M = f32x8;
    type U = u32x8;

    #[inline(always)]
    fn load(self, v: &F32x8) -> f32x8 {
        f32x8::from(v.0)
    }
    #[inline(always)]
    fn splat(self, x: f32) -> f32x8 {
        f32x8::splat(x)
    }
    #[inline(always)]
    fn to_array(self, v: f32x8) -> [f32; 8] {
        v.to_array()
    }
    #[inline(always)]
    fn add(self, a: f32x8, b: f32x8) -> f32x8 {
        a + b
    }
    #[inline(always)]
    fn sub(self, a: f32x8, b: f32x8) -> f32x8 {
        a - b
    }
    #[inline(always)]
    fn mul(self, a: f32x8, b: f32x8) -> f32x8 {
        a * b
    }
    #[inline(always)]
    fn div(self, a: f32x8, b: f32x8) -> f32x8 {
        a / b
    }
    #[inline(always)]
    fn neg(self, a: f32x8) -> f32x8 {
        -a
    }
    #[inline(always)]
    fn min(self, a: f32x8, b: f32x8) -> f32x8 {
        a.fast_min(b)
    }
    #[inline(always)]
    fn max(self, a: f32x8, b: f32x8) -> f32x8 {
        a.fast_max(b)
    }
    #[inline(always)]
    fn sqrt(self, a: f32x8) -> f32x8 {
        a.sqrt()
    }
    #[inline(always)]
    fn lt(self, a: f32x8, b: f32x8) -> f32x8 {
        a.simd_lt(b)
    }
    #[inline(always)]
    fn le(self, a: f32x8, b: f32x8) -> f32x8 {
        a.simd_le(b)
    }
    #[inline(always)]
    fn ge(self, a: f32x8, b: f32x8) -> f32x8 {
        a.simd_ge(b)
    }
    #[inline(always)]
    fn eq(self, a: f32x8, b: f32x8) -> f32x8 {
        a.simd_eq(b)
    }
    #[inline(always)]
    fn and(self, a: f32x8, b: f32x8) -> f32x8 {
        a & b
    }
    #[inline(always)]
    fn select(self, m: f32x8, if_true: f32x8, if_false: f32x8) -> f32x8 {
        m.select(if_true, if_false)
    }
    #[inline(always)]
    fn bitmask(self, m: f32x8) -> u32 {
        m.to_bitmask()
    }
    #[inline(always)]
    fn load_u(self, v: &U32x8) -> u32x8 {
        u32x8::from(v.0)
    }
    #[inline(always)]
    fn splat_u(self, x: u32) -> u32x8 {
        u32x8::splat(x)
    }
    #[inline(always)]
    fn eq_u_bitmask(self, a: u32x8, b: u32x8) -> u32 {
        a.simd_eq(b).to_bitmask()
    }
}
