//! The SIMD paths, chosen at run time: the one place that knows instruction sets, and the only
//! module with `unsafe` code (the `x86` submodule and `dispatch`).
//!
//! The hierarchy's node and sphere tests are written once, generic over an [`Isa`]: eight
//! `f32` lanes with the handful of operations they need. A render runs that code through
//! [`dispatch`], which calls it inside a function compiled for the chosen [`Path`]:
//!
//! - `portable`: any CPU of the architecture (`wide`'s SSE2 halves on x86-64, NEON on
//!   aarch64, plain arrays elsewhere);
//! - `avx2`: x86-64 with AVX2, BMI1/2, LZCNT and POPCNT; one AVX instruction per operation;
//! - `avx512`: the same eight-lane code compiled with AVX-512 F/VL/BW/DQ enabled as well (32
//!   vector registers), its comparisons made straight into mask registers, and sixteen-lane
//!   box tests (`Isa::slab16`), with which a small tree is walked flat.
//!
//! Every operation is exact IEEE arithmetic with the same rule on every path (no fused
//! multiply-add, `min`/`max` as the SSE instructions define them), so every path gives the
//! same bits; `tests` check each against one `f32` at a time, and the CLI tests check whole
//! images. A path runs only where the CPU has it: the AVX code needs an [`x86::Avx2`] token,
//! which only detection makes.

#![allow(unsafe_code)]

mod lanes;
mod portable;
#[cfg(test)]
mod tests;
#[cfg(target_arch = "x86_64")]
mod x86;

pub use lanes::{F32x8, F32x16, Ids, Lanes, Mask, U32x8};
pub use portable::Portable;

use std::fmt;
use std::str::FromStr;

/// One instruction set's eight-lane operations. Implemented by zero-sized tokens: holding one
/// proves the CPU runs its instructions. Code uses it through [`Lanes`], [`Mask`] and [`Ids`].
pub trait Isa: Copy + fmt::Debug + Send + Sync + 'static {
    /// Eight `f32` lanes.
    type F: Copy;
    /// The result of a comparison, lane by lane.
    type M: Copy;
    /// Eight `u32` lanes.
    type U: Copy;

    fn load(self, v: &F32x8) -> Self::F;
    fn splat(self, x: f32) -> Self::F;
    fn to_array(self, v: Self::F) -> [f32; 8];
    fn add(self, a: Self::F, b: Self::F) -> Self::F;
    fn sub(self, a: Self::F, b: Self::F) -> Self::F;
    fn mul(self, a: Self::F, b: Self::F) -> Self::F;
    fn div(self, a: Self::F, b: Self::F) -> Self::F;
    fn neg(self, a: Self::F) -> Self::F;
    /// `a < b ? a : b` per lane (the SSE `min` rule: `b` when either is NaN or both zero).
    fn min(self, a: Self::F, b: Self::F) -> Self::F;
    /// `a > b ? a : b` per lane.
    fn max(self, a: Self::F, b: Self::F) -> Self::F;
    fn sqrt(self, a: Self::F) -> Self::F;
    fn lt(self, a: Self::F, b: Self::F) -> Self::M;
    fn le(self, a: Self::F, b: Self::F) -> Self::M;
    fn ge(self, a: Self::F, b: Self::F) -> Self::M;
    fn eq(self, a: Self::F, b: Self::F) -> Self::M;
    fn and(self, a: Self::M, b: Self::M) -> Self::M;
    /// `if_true` where `m` is set, else `if_false`.
    fn select(self, m: Self::M, if_true: Self::F, if_false: Self::F) -> Self::F;
    /// Bit `i` set when lane `i` of `m` is.
    fn bitmask(self, m: Self::M) -> u32;
    fn load_u(self, v: &U32x8) -> Self::U;
    fn splat_u(self, x: u32) -> Self::U;
    /// Bit `i` set when lane `i` of `a` equals that of `b`.
    fn eq_u_bitmask(self, a: Self::U, b: Self::U) -> u32;

    /// Whether `slab16` is one set of sixteen-lane instructions (not two of eight), which
    /// makes testing every pack box of a small tree at once faster than walking it.
    const WIDE_SLABS: bool = false;

    /// The slab test of `ray` against sixteen boxes (`planes`: min x, y, z, max x, y, z):
    /// each box's entry parameter, and bit `i` set when the ray meets box `i` within
    /// `(ray.t_min, ray.t_max)`. The same arithmetic, lane by lane, on every path: here two
    /// halves of eight lanes; the AVX-512 path does all sixteen at once.
    #[inline(always)]
    fn slab16(self, planes: &[F32x16; 6], ray: &SlabRay) -> (u32, [f32; 16]) {
        let lanes = ray.lanes(self);
        let (lo, near_lo) = slab8(planes.each_ref().map(|p| &p.0[0]), &lanes, ray.t_max);
        let (hi, near_hi) = slab8(planes.each_ref().map(|p| &p.0[1]), &lanes, ray.t_max);
        let mut near = [0.0; 16];
        near[..8].copy_from_slice(&near_lo);
        near[8..].copy_from_slice(&near_hi);
        (lo | hi << 8, near)
    }
}

/// A ray as the slab test takes it: origin, `1 / direction` (finite) and the parameter
/// interval.
#[derive(Clone, Copy, Debug)]
pub struct SlabRay {
    pub origin: [f32; 3],
    pub inv_dir: [f32; 3],
    pub t_min: f32,
    pub t_max: f32,
}

impl SlabRay {
    /// The ray's origin, `1 / direction` and `t_min` in lanes, for `slab8`.
    #[inline(always)]
    pub fn lanes<I: Isa>(&self, isa: I) -> SlabLanes<I> {
        SlabLanes {
            origin: self.origin.map(|x| Lanes::splat(isa, x)),
            inv_dir: self.inv_dir.map(|x| Lanes::splat(isa, x)),
            t_min: Lanes::splat(isa, self.t_min),
        }
    }
}

/// A `SlabRay`'s fixed part in lanes: made once per ray, used for every group of boxes.
#[derive(Clone, Copy)]
pub struct SlabLanes<I: Isa> {
    pub origin: [Lanes<I>; 3],
    pub inv_dir: [Lanes<I>; 3],
    pub t_min: Lanes<I>,
}

/// The slab test against eight boxes, within `(ray.t_min, t_max)`: per axis, the ray's
/// parameters at the min and max planes; the nearer of each pair enters the slab, the
/// farther leaves it. The entry is the latest entry and `t_min`, the exit the earliest exit
/// and `t_max`, combined in this order on every path.
#[inline(always)]
pub fn slab8<I: Isa>(p: [&F32x8; 6], ray: &SlabLanes<I>, t_max: f32) -> (u32, [f32; 8]) {
    let (o, inv) = (&ray.origin, &ray.inv_dir);
    let isa = ray.t_min.isa();
    let t0 = [
        (Lanes::load(isa, p[0]) - o[0]) * inv[0],
        (Lanes::load(isa, p[1]) - o[1]) * inv[1],
        (Lanes::load(isa, p[2]) - o[2]) * inv[2],
    ];
    let t1 = [
        (Lanes::load(isa, p[3]) - o[0]) * inv[0],
        (Lanes::load(isa, p[4]) - o[1]) * inv[1],
        (Lanes::load(isa, p[5]) - o[2]) * inv[2],
    ];
    let t_near = t0[0]
        .fast_min(t1[0])
        .fast_max(t0[1].fast_min(t1[1]))
        .fast_max(t0[2].fast_min(t1[2]).fast_max(ray.t_min));
    let t_far = t0[0]
        .fast_max(t1[0])
        .fast_min(t0[1].fast_max(t1[1]))
        .fast_min(t0[2].fast_max(t1[2]).fast_min(Lanes::splat(isa, t_max)));
    (t_near.simd_le(t_far).to_bitmask(), t_near.to_array())
}

/// Whether `0 ≤ x < limit`, and if so `x` rounded toward zero (else 0): a grid cell's index
/// along one axis. `limit` must be at most 2²⁴. One conversion instruction, where `as`
/// (which saturates, and maps NaN to 0) takes several more on x86-64; NaN is out of range.
#[inline(always)]
pub fn index_below(x: f32, limit: f32) -> (bool, usize) {
    const MAX: f32 = (1u32 << 24) as f32;
    let inside = (x >= 0.0) & (x < limit.min(MAX));
    let x = if inside { x } else { 0.0 };
    // SAFETY: `x` is in [0, 2²⁴), so it is finite and its truncation fits a `u32`.
    let index = unsafe { x.to_int_unchecked::<u32>() };
    (inside, index as usize)
}

/// Work generic over the instruction set, for [`dispatch`] to run on a chosen path. (A
/// closure cannot be generic over its argument's type, hence a trait.)
pub trait Kernel {
    type Output;
    fn run<I: Isa>(self, isa: I) -> Self::Output;
}

/// A SIMD path: which instructions the hot code is compiled for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Path {
    Portable,
    Avx2,
    Avx512,
}

impl Path {
    /// Every path, slowest first.
    pub const ALL: [Path; 3] = [Path::Portable, Path::Avx2, Path::Avx512];

    pub fn name(self) -> &'static str {
        match self {
            Path::Portable => "portable",
            Path::Avx2 => "avx2",
            Path::Avx512 => "avx512",
        }
    }

    /// Whether this CPU (and this build's architecture) runs the path.
    pub fn is_supported(self) -> bool {
        match self {
            Path::Portable => true,
            #[cfg(target_arch = "x86_64")]
            Path::Avx2 => x86::Avx2::detect().is_some(),
            #[cfg(target_arch = "x86_64")]
            Path::Avx512 => x86::Avx512::detect().is_some(),
            #[cfg(not(target_arch = "x86_64"))]
            Path::Avx2 | Path::Avx512 => false,
        }
    }

    /// The paths this CPU runs, slowest first.
    pub fn supported() -> Vec<Path> {
        Path::ALL.into_iter().filter(|p| p.is_supported()).collect()
    }

    /// The path a render takes unless told otherwise (`auto`); see [`Path::auto`].
    pub fn best() -> Path {
        Path::auto().0
    }

    /// The path `auto` takes on this CPU, and why. Every path gives the same image, so the
    /// rule only has to be fast: the widest path the CPU runs, except AVX-512 on Intel.
    /// Measured on the cover: AVX-512 led AVX2 by 2% on an AMD Zen 5 (its sixteen-lane box
    /// tests), while on an Intel Xeon with AVX-512 AVX2 was about 3% faster (512-bit code
    /// lowers its clock). `tessera bench --simd avx2` and `--simd avx512` check a CPU.
    pub fn auto() -> (Path, &'static str) {
        let avx512 = Path::Avx512.is_supported();
        let avx2 = Path::Avx2.is_supported();
        if avx512 && avx2 && cpu_vendor() == Some(*b"GenuineIntel") {
            return (
                Path::Avx2,
                "an Intel CPU: AVX2 measured about 3% faster than AVX-512 on a Xeon (512-bit code lowers its clock)",
            );
        }
        if avx512 {
            (
                Path::Avx512,
                "the widest this CPU runs (AVX-512 measured 2% faster than AVX2 on an AMD Zen 5)",
            )
        } else if avx2 {
            (Path::Avx2, "the widest this CPU runs (no AVX-512)")
        } else {
            (Path::Portable, "this CPU runs no wider path")
        }
    }

    /// The path named by `name` (`auto` is `best`), if this CPU runs it.
    pub fn choose(name: &str) -> Result<Path, String> {
        let path = match name {
            "auto" => return Ok(Path::best()),
            _ => name.parse::<Path>()?,
        };
        if !path.is_supported() {
            let have: Vec<_> = Path::supported().iter().map(|p| p.name()).collect();
            return Err(format!(
                "this CPU does not run the {} SIMD path (it runs: {})",
                path.name(),
                have.join(", ")
            ));
        }
        Ok(path)
    }
}

/// The CPU's vendor and family (`AuthenticAMD family 0x1a`), on x86-64.
#[cfg(target_arch = "x86_64")]
pub fn cpu_identity() -> Option<String> {
    let (vendor, family) = x86::vendor_and_family();
    let vendor: String = (vendor.iter())
        .map(|&b| if b.is_ascii_graphic() { b as char } else { '?' })
        .collect();
    Some(format!("{vendor} family {family:#x}"))
}

#[cfg(not(target_arch = "x86_64"))]
pub fn cpu_identity() -> Option<String> {
    None
}

/// The CPU's vendor string, on x86-64.
#[cfg(target_arch = "x86_64")]
fn cpu_vendor() -> Option<[u8; 12]> {
    Some(x86::vendor_and_family().0)
}

#[cfg(not(target_arch = "x86_64"))]
fn cpu_vendor() -> Option<[u8; 12]> {
    None
}

impl fmt::Display for Path {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Path {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Path::ALL
            .into_iter()
            .find(|p| p.name() == s)
            .ok_or_else(|| {
                format!(
                    "unknown SIMD path `{}` (expected auto, portable, avx2 or avx512)",
                    crate::text::terminal_safe(s, 32)
                )
            })
    }
}

/// Runs `kernel` on `path`, compiled for that path's instructions. A path this CPU does not
/// run (which `Path::choose` refuses to name) runs portable instead: never an illegal
/// instruction.
#[inline]
pub fn dispatch<K: Kernel>(path: Path, kernel: K) -> K::Output {
    match path {
        Path::Portable => kernel.run(Portable),
        #[cfg(target_arch = "x86_64")]
        Path::Avx2 => match x86::Avx2::detect() {
            // SAFETY: the token exists, so the CPU has every feature `run_avx2` enables.
            Some(isa) => unsafe { x86::run_avx2(kernel, isa) },
            None => kernel.run(Portable),
        },
        #[cfg(target_arch = "x86_64")]
        Path::Avx512 => match x86::Avx512::detect() {
            // SAFETY: the token exists, so the CPU has every feature `run_avx512` enables.
            Some(isa) => unsafe { x86::run_avx512(kernel, isa) },
            None => kernel.run(Portable),
        },
        #[cfg(not(target_arch = "x86_64"))]
        Path::Avx2 | Path::Avx512 => kernel.run(Portable),
    }
}
