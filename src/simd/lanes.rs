//! The lane types code is written with: values of an [`Isa`]'s vectors that carry their
//! (zero-sized) token, so arithmetic reads as arithmetic; and the aligned arrays they are
//! stored as, the same on every path.

use super::Isa;
use std::ops::{Add, BitAnd, Div, Mul, Neg, Sub};

/// Eight `f32`s as stored (in a tree node, a sphere pack): aligned for one 256-bit load.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(32))]
pub struct F32x8(pub [f32; 8]);

/// Sixteen `f32`s as stored: two eight-lane halves, aligned for one 512-bit load.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct F32x16(pub [F32x8; 2]);

impl F32x16 {
    pub const ZERO: Self = Self([F32x8::ZERO; 2]);
}

/// Eight `u32`s as stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C, align(32))]
pub struct U32x8(pub [u32; 8]);

impl F32x8 {
    pub const ZERO: Self = Self([0.0; 8]);
}

/// Eight `f32` lanes on the path of `I`.
#[derive(Clone, Copy, Debug)]
pub struct Lanes<I: Isa> {
    v: I::F,
    isa: I,
}

/// A comparison's result, lane by lane.
#[derive(Clone, Copy, Debug)]
pub struct Mask<I: Isa> {
    m: I::M,
    isa: I,
}

/// Eight `u32` lanes (sphere ids).
#[derive(Clone, Copy, Debug)]
pub struct Ids<I: Isa> {
    u: I::U,
    isa: I,
}

impl<I: Isa> Lanes<I> {
    #[inline(always)]
    pub fn splat(isa: I, x: f32) -> Self {
        Self {
            v: isa.splat(x),
            isa,
        }
    }

    #[inline(always)]
    pub fn load(isa: I, v: &F32x8) -> Self {
        Self {
            v: isa.load(v),
            isa,
        }
    }

    /// The token of the path these lanes are on.
    #[inline(always)]
    pub fn isa(self) -> I {
        self.isa
    }

    #[inline(always)]
    fn with(self, v: I::F) -> Self {
        Self { v, isa: self.isa }
    }

    #[inline(always)]
    fn mask(self, m: I::M) -> Mask<I> {
        Mask { m, isa: self.isa }
    }

    #[inline(always)]
    pub fn to_array(self) -> [f32; 8] {
        self.isa.to_array(self.v)
    }

    /// `self < other ? self : other` per lane.
    #[inline(always)]
    pub fn fast_min(self, other: Self) -> Self {
        self.with(self.isa.min(self.v, other.v))
    }

    /// `self > other ? self : other` per lane.
    #[inline(always)]
    pub fn fast_max(self, other: Self) -> Self {
        self.with(self.isa.max(self.v, other.v))
    }

    #[inline(always)]
    pub fn sqrt(self) -> Self {
        self.with(self.isa.sqrt(self.v))
    }

    #[inline(always)]
    pub fn simd_lt(self, other: Self) -> Mask<I> {
        self.mask(self.isa.lt(self.v, other.v))
    }

    #[inline(always)]
    pub fn simd_le(self, other: Self) -> Mask<I> {
        self.mask(self.isa.le(self.v, other.v))
    }

    #[inline(always)]
    pub fn simd_ge(self, other: Self) -> Mask<I> {
        self.mask(self.isa.ge(self.v, other.v))
    }

    #[inline(always)]
    pub fn simd_eq(self, other: Self) -> Mask<I> {
        self.mask(self.isa.eq(self.v, other.v))
    }
}

impl<I: Isa> Mask<I> {
    /// Bit `i` set when lane `i` is.
    #[inline(always)]
    pub fn to_bitmask(self) -> u32 {
        self.isa.bitmask(self.m)
    }

    /// Per lane, `if_true` where the mask is set, else `if_false`.
    #[inline(always)]
    pub fn select(self, if_true: Lanes<I>, if_false: Lanes<I>) -> Lanes<I> {
        if_true.with(self.isa.select(self.m, if_true.v, if_false.v))
    }
}

impl<I: Isa> BitAnd for Mask<I> {
    type Output = Self;
    #[inline(always)]
    fn bitand(self, other: Self) -> Self {
        Self {
            m: self.isa.and(self.m, other.m),
            isa: self.isa,
        }
    }
}

impl<I: Isa> Ids<I> {
    #[inline(always)]
    pub fn splat(isa: I, x: u32) -> Self {
        Self {
            u: isa.splat_u(x),
            isa,
        }
    }

    #[inline(always)]
    pub fn load(isa: I, v: &U32x8) -> Self {
        Self {
            u: isa.load_u(v),
            isa,
        }
    }

    /// Bit `i` set when lane `i` equals that of `other`.
    #[inline(always)]
    pub fn eq_bitmask(self, other: Self) -> u32 {
        self.isa.eq_u_bitmask(self.u, other.u)
    }
}

macro_rules! lanewise {
    ($trait:ident, $method:ident) => {
        impl<I: Isa> $trait for Lanes<I> {
            type Output = Self;
            #[inline(always)]
            fn $method(self, other: Self) -> Self {
                self.with(self.isa.$method(self.v, other.v))
            }
        }
    };
}

lanewise!(Add, add);
lanewise!(Sub, sub);
lanewise!(Mul, mul);
lanewise!(Div, div);

impl<I: Isa> Neg for Lanes<I> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        self.with(self.isa.neg(self.v))
    }
}
