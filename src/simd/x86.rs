//! The AVX paths on x86-64: the eight-lane operations as AVX intrinsics, and the functions that
//! run a kernel compiled for AVX2 or AVX-512.
//!
//! Soundness rests on one invariant: an [`Avx2`] or [`Avx512`] token exists only after its
//! `detect` has seen every feature its code uses on this CPU. Each intrinsic call
//! below is sound because it is reached through a token. The run functions are compiled with
//! those features; calling them is sound for the same reason.

use super::{F32x8, F32x16, Isa, Kernel, SlabRay, U32x8};
use std::arch::x86_64::*;

/// The token of the AVX2 path. Its private field keeps it from being made except by
/// detection.
#[derive(Clone, Copy, Debug)]
pub struct Avx2(());

impl Avx2 {
    /// The token, where this CPU has every feature of the AVX2 path.
    pub fn detect() -> Option<Self> {
        let has = is_x86_feature_detected!("avx2")
            && is_x86_feature_detected!("bmi1")
            && is_x86_feature_detected!("bmi2")
            && is_x86_feature_detected!("lzcnt")
            && is_x86_feature_detected!("popcnt");
        has.then_some(Avx2(()))
    }
}

/// The token of the AVX-512 path: the AVX2 path's eight-lane arithmetic, compiled with
/// AVX-512 enabled, with comparisons into mask registers, and sixteen-lane box tests. Made
/// only by detection, like [`Avx2`].
#[derive(Clone, Copy, Debug)]
pub struct Avx512(Avx2);

impl Avx512 {
    /// The token, where this CPU has every feature of the AVX2 and AVX-512 paths.
    pub fn detect() -> Option<Self> {
        let has = is_x86_feature_detected!("avx512f")
            && is_x86_feature_detected!("avx512vl")
            && is_x86_feature_detected!("avx512bw")
            && is_x86_feature_detected!("avx512dq");
        Avx2::detect().filter(|_| has).map(Avx512)
    }
}

/// The CPU's vendor (`GenuineIntel`, `AuthenticAMD`, …) and family, from CPUID.
pub fn vendor_and_family() -> ([u8; 12], u32) {
    // SAFETY: CPUID leaves 0 and 1 exist on every x86-64 CPU.
    #[allow(unused_unsafe)]
    let (leaf0, leaf1) = unsafe { (__cpuid(0), __cpuid(1)) };
    let mut vendor = [0u8; 12];
    vendor[..4].copy_from_slice(&leaf0.ebx.to_le_bytes());
    vendor[4..8].copy_from_slice(&leaf0.edx.to_le_bytes());
    vendor[8..].copy_from_slice(&leaf0.ecx.to_le_bytes());
    let base = (leaf1.eax >> 8) & 0xf;
    let family = if base == 0xf {
        base + ((leaf1.eax >> 20) & 0xff)
    } else {
        base
    };
    (vendor, family)
}

/// Runs `kernel` compiled for AVX2 (its generic body is inlined here, so it takes this
/// function's features).
#[target_feature(enable = "avx2,bmi1,bmi2,lzcnt,popcnt")]
pub(super) fn run_avx2<K: Kernel>(kernel: K, isa: Avx2) -> K::Output {
    kernel.run(isa)
}

/// Runs `kernel` compiled for AVX-512 as well.
#[target_feature(enable = "avx2,bmi1,bmi2,lzcnt,popcnt,avx512f,avx512vl,avx512bw,avx512dq")]
pub(super) fn run_avx512<K: Kernel>(kernel: K, isa: Avx512) -> K::Output {
    kernel.run(isa)
}

/// The body of one operation: an intrinsic call, sound because the token proves AVX2.
macro_rules! avx {
    ($e:expr) => {
        // SAFETY: an `Avx2` token exists only where the CPU has AVX2 (module invariant).
        unsafe { $e }
    };
}

/// The body of one AVX-512 operation, sound because an `Avx512` token proves AVX-512.
macro_rules! avx512 {
    ($e:expr) => {
        // SAFETY: an `Avx512` token exists only where the CPU has AVX-512 F/VL/BW/DQ and
        // every AVX2 feature (module invariant).
        unsafe { $e }
    };
}

/// `Isa` methods of `Avx512` that are `Avx2`'s.
macro_rules! same_as_avx2 {
    ($($name:ident($($arg:ident: $ty:ty),*) -> $out:ty;)*) => {
        $(
            #[inline(always)]
            fn $name(self, $($arg: $ty),*) -> $out {
                self.0.$name($($arg),*)
            }
        )*
    };
}

impl Isa for Avx512 {
    type F = __m256;
    type M = __mmask8;
    type U = __m256i;
    const WIDE_SLABS: bool = true;

    same_as_avx2! {
        load(v: &F32x8) -> __m256;
        splat(x: f32) -> __m256;
        to_array(v: __m256) -> [f32; 8];
        add(a: __m256, b: __m256) -> __m256;
        sub(a: __m256, b: __m256) -> __m256;
        mul(a: __m256, b: __m256) -> __m256;
        div(a: __m256, b: __m256) -> __m256;
        neg(a: __m256) -> __m256;
        min(a: __m256, b: __m256) -> __m256;
        max(a: __m256, b: __m256) -> __m256;
        sqrt(a: __m256) -> __m256;
        load_u(v: &U32x8) -> __m256i;
        splat_u(x: u32) -> __m256i;
    }

    // Comparisons straight into mask registers, and selects by them: one instruction each
    // where the AVX2 forms take a vector mask and a move out of it.
    #[inline(always)]
    fn lt(self, a: __m256, b: __m256) -> __mmask8 {
        avx512!(_mm256_cmp_ps_mask::<_CMP_LT_OQ>(a, b))
    }
    #[inline(always)]
    fn le(self, a: __m256, b: __m256) -> __mmask8 {
        avx512!(_mm256_cmp_ps_mask::<_CMP_LE_OQ>(a, b))
    }
    #[inline(always)]
    fn ge(self, a: __m256, b: __m256) -> __mmask8 {
        avx512!(_mm256_cmp_ps_mask::<_CMP_GE_OQ>(a, b))
    }
    #[inline(always)]
    fn eq(self, a: __m256, b: __m256) -> __mmask8 {
        avx512!(_mm256_cmp_ps_mask::<_CMP_EQ_OQ>(a, b))
    }
    #[inline(always)]
    fn and(self, a: __mmask8, b: __mmask8) -> __mmask8 {
        a & b
    }
    #[inline(always)]
    fn select(self, m: __mmask8, if_true: __m256, if_false: __m256) -> __m256 {
        avx512!(_mm256_mask_blend_ps(m, if_false, if_true))
    }
    #[inline(always)]
    fn bitmask(self, m: __mmask8) -> u32 {
        u32::from(m)
    }
    #[inline(always)]
    fn eq_u_bitmask(self, a: __m256i, b: __m256i) -> u32 {
        u32::from(avx512!(_mm256_cmpeq_epi32_mask(a, b)))
    }

    /// All sixteen lanes at once, in `slab8`'s order of operations.
    #[inline(always)]
    fn slab16(self, planes: &[F32x16; 6], ray: &SlabRay) -> (u32, [f32; 16]) {
        // `F32x16` is 64-byte aligned, as the aligned load needs.
        let load = |i: usize| avx512!(_mm512_load_ps(planes[i].0.as_ptr().cast::<f32>()));
        let splat = |x: f32| avx512!(_mm512_set1_ps(x));
        let o = ray.origin.map(splat);
        let inv = ray.inv_dir.map(splat);
        let slope = |i: usize, axis: usize| {
            avx512!(_mm512_mul_ps(_mm512_sub_ps(load(i), o[axis]), inv[axis]))
        };
        let t0 = [slope(0, 0), slope(1, 1), slope(2, 2)];
        let t1 = [slope(3, 0), slope(4, 1), slope(5, 2)];
        let (min, max) = (
            |a, b| avx512!(_mm512_min_ps(a, b)),
            |a, b| avx512!(_mm512_max_ps(a, b)),
        );
        let t_near = max(
            max(min(t0[0], t1[0]), min(t0[1], t1[1])),
            max(min(t0[2], t1[2]), splat(ray.t_min)),
        );
        let t_far = min(
            min(max(t0[0], t1[0]), max(t0[1], t1[1])),
            min(max(t0[2], t1[2]), splat(ray.t_max)),
        );
        let hits = avx512!(_mm512_cmp_ps_mask::<_CMP_LE_OQ>(t_near, t_far));
        let mut near = [0.0; 16];
        // An unaligned store: sixteen `f32`s, the size of the vector.
        avx512!(_mm512_storeu_ps(near.as_mut_ptr(), t_near));
        (u32::from(hits), near)
    }
}

impl Isa for Avx2 {
    type F = __m256;
    type M = __m256;
    type U = __m256i;

    #[inline(always)]
    fn load(self, v: &F32x8) -> __m256 {
        // `F32x8` is 32-byte aligned, as the aligned load needs.
        avx!(_mm256_load_ps(v.0.as_ptr()))
    }
    #[inline(always)]
    fn splat(self, x: f32) -> __m256 {
        avx!(_mm256_set1_ps(x))
    }
    #[inline(always)]
    fn to_array(self, v: __m256) -> [f32; 8] {
        let mut out = F32x8::ZERO;
        avx!(_mm256_store_ps(out.0.as_mut_ptr(), v));
        out.0
    }
    #[inline(always)]
    fn add(self, a: __m256, b: __m256) -> __m256 {
        avx!(_mm256_add_ps(a, b))
    }
    #[inline(always)]
    fn sub(self, a: __m256, b: __m256) -> __m256 {
        avx!(_mm256_sub_ps(a, b))
    }
    #[inline(always)]
    fn mul(self, a: __m256, b: __m256) -> __m256 {
        avx!(_mm256_mul_ps(a, b))
    }
    #[inline(always)]
    fn div(self, a: __m256, b: __m256) -> __m256 {
        avx!(_mm256_div_ps(a, b))
    }
    #[inline(always)]
    fn neg(self, a: __m256) -> __m256 {
        avx!(_mm256_xor_ps(a, _mm256_set1_ps(-0.0)))
    }
    #[inline(always)]
    fn min(self, a: __m256, b: __m256) -> __m256 {
        avx!(_mm256_min_ps(a, b))
    }
    #[inline(always)]
    fn max(self, a: __m256, b: __m256) -> __m256 {
        avx!(_mm256_max_ps(a, b))
    }
    #[inline(always)]
    fn sqrt(self, a: __m256) -> __m256 {
        avx!(_mm256_sqrt_ps(a))
    }
    #[inline(always)]
    fn lt(self, a: __m256, b: __m256) -> __m256 {
        avx!(_mm256_cmp_ps::<_CMP_LT_OQ>(a, b))
    }
    #[inline(always)]
    fn le(self, a: __m256, b: __m256) -> __m256 {
        avx!(_mm256_cmp_ps::<_CMP_LE_OQ>(a, b))
    }
    #[inline(always)]
    fn ge(self, a: __m256, b: __m256) -> __m256 {
        avx!(_mm256_cmp_ps::<_CMP_GE_OQ>(a, b))
    }
    #[inline(always)]
    fn eq(self, a: __m256, b: __m256) -> __m256 {
        avx!(_mm256_cmp_ps::<_CMP_EQ_OQ>(a, b))
    }
    #[inline(always)]
    fn and(self, a: __m256, b: __m256) -> __m256 {
        avx!(_mm256_and_ps(a, b))
    }
    #[inline(always)]
    fn select(self, m: __m256, if_true: __m256, if_false: __m256) -> __m256 {
        avx!(_mm256_blendv_ps(if_false, if_true, m))
    }
    #[inline(always)]
    fn bitmask(self, m: __m256) -> u32 {
        avx!(_mm256_movemask_ps(m)) as u32
    }
    #[inline(always)]
    fn load_u(self, v: &U32x8) -> __m256i {
        // `U32x8` is 32-byte aligned, as the aligned load needs.
        avx!(_mm256_load_si256(v.0.as_ptr().cast()))
    }
    #[inline(always)]
    fn splat_u(self, x: u32) -> __m256i {
        avx!(_mm256_set1_epi32(x as i32))
    }
    #[inline(always)]
    fn eq_u_bitmask(self, a: __m256i, b: __m256i) -> u32 {
        avx!(_mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpeq_epi32(
            a, b
        )))) as u32
    }
}
