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
//! - `avx512`: the same eight-lane code compiled with AVX-512 F/VL/BW/DQ enabled as well (mask
//!   registers, 32 vector registers).
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

pub use lanes::{F32x8, Ids, Lanes, Mask, U32x8};
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
            Path::Avx512 => x86::Avx2::detect_avx512().is_some(),
            #[cfg(not(target_arch = "x86_64"))]
            Path::Avx2 | Path::Avx512 => false,
        }
    }

    /// The paths this CPU runs, slowest first.
    pub fn supported() -> Vec<Path> {
        Path::ALL.into_iter().filter(|p| p.is_supported()).collect()
    }

    /// The path a render takes unless told otherwise: AVX2 where the CPU has it, else
    /// portable. AVX-512 is not picked by itself: on the eight-lane code it measured no faster
    /// than AVX2 (`docs/performance.md`); `--simd avx512` forces it.
    pub fn best() -> Path {
        if Path::Avx2.is_supported() {
            Path::Avx2
        } else {
            Path::Portable
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
                format!("unknown SIMD path `{s}` (expected auto, portable, avx2 or avx512)")
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
        Path::Avx512 => match x86::Avx2::detect_avx512() {
            // SAFETY: `detect_avx512` checked every feature `run_avx512` enables.
            Some(isa) => unsafe { x86::run_avx512(kernel, isa) },
            None => kernel.run(Portable),
        },
        #[cfg(not(target_arch = "x86_64"))]
        Path::Avx2 | Path::Avx512 => kernel.run(Portable),
    }
}
