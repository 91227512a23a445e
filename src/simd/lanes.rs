//! Lane types: `f32` vectors of 4, 8 and 16 lanes behind one trait, so that every kernel is
//! written once and instantiated for the widths it needs.
//!
//! A *mask* has the same type as the values it selects (all bits of a lane set = true), as in
//! `wide`; [`Lanes::bitmask`] turns it into one bit per lane. Comparisons are IEEE ordered
//! comparisons: any NaN operand gives false. [`Lanes::vmin`] and [`Lanes::vmax`] are the plain
//! x86 instructions (`minps` / `maxps`): when either operand is NaN the *second* one is
//! returned, so `x.vmin(acc)` ignores a NaN `x`; the slab tests rely on this (see
//! `accel::single`). (They are not called `min` / `max` because `wide`'s inherent methods of
//! those names, which check for NaN and cost two more instructions, would shadow them.)

use std::fmt::Debug;
use std::ops::{Add, Div, Mul, Sub};

use wide::{f32x4, f32x8, f32x16, u32x4, u32x8, u32x16};

/// Four `f32` lanes (SSE).
pub type F4 = f32x4;
/// Eight `f32` lanes (AVX).
pub type F8 = f32x8;

/// Sixteen `f32` lanes (one AVX-512 register; two AVX registers elsewhere), for image-space
/// kernels such as the discontinuity buffer.
pub type F16 = f32x16;

/// Width of [`F4`].
pub const LANES_4: usize = 4;
/// Width of [`F8`].
pub const LANES_8: usize = 8;

/// An `f32` SIMD vector of [`Lanes::LANES`] lanes.
pub trait Lanes:
    Copy + Debug + Send + Sync + 'static + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Div<Output = Self>
{
    /// Number of lanes.
    const LANES: usize;
    /// Bitmask with one bit per lane set.
    const ALL: u32;
    /// `[f32; LANES]`.
    type Array: Copy + Debug + AsRef<[f32]> + AsMut<[f32]>;

    /// All lanes `x`.
    fn splat(x: f32) -> Self;
    /// Lanes from an array.
    fn from_array(a: Self::Array) -> Self;
    /// The lanes as an array.
    fn to_array(self) -> Self::Array;
    /// The first `LANES` values of `s` (panics when `s` is shorter).
    fn load(s: &[f32]) -> Self;
    /// Lane `i` is `f(i)`.
    #[inline(always)]
    fn from_fn(mut f: impl FnMut(usize) -> f32) -> Self {
        let mut a = Self::splat(0.0).to_array();
        for (i, x) in a.as_mut().iter_mut().enumerate() {
            *x = f(i);
        }
        Self::from_array(a)
    }
    /// Lane `i` (panics when out of range).
    #[inline(always)]
    fn lane(self, i: usize) -> f32 {
        self.to_array().as_ref()[i]
    }
    /// Lanewise square root (correctly rounded, as `f32::sqrt`).
    fn sqrt(self) -> Self;
    /// Lanewise absolute value.
    fn abs(self) -> Self;
    /// Lanewise minimum (`minps`: returns `rhs` where either is NaN).
    fn vmin(self, rhs: Self) -> Self;
    /// Lanewise maximum (`maxps`: returns `rhs` where either is NaN).
    fn vmax(self, rhs: Self) -> Self;
    /// Mask of `self < rhs`.
    fn lt(self, rhs: Self) -> Self;
    /// Mask of `self <= rhs`.
    fn le(self, rhs: Self) -> Self;
    /// Mask of `self > rhs`.
    fn gt(self, rhs: Self) -> Self;
    /// Mask of `self >= rhs`.
    fn ge(self, rhs: Self) -> Self;
    /// Mask of `self == rhs`.
    fn eq(self, rhs: Self) -> Self;
    /// Bitwise and (of masks).
    fn and(self, rhs: Self) -> Self;
    /// Bitwise or (of masks).
    fn or(self, rhs: Self) -> Self;
    /// `self & !rhs` (of masks).
    fn and_not(self, rhs: Self) -> Self;
    /// Bitwise complement (of a mask).
    fn mask_not(self) -> Self;
    /// Where the mask `self` is set, `a`, else `b` (bitwise blend: exact, NaN-safe).
    fn select(self, a: Self, b: Self) -> Self;
    /// One bit per lane of a mask (bit i = lane i).
    fn bitmask(self) -> u32;
    /// The mask of lanes `0..n`.
    #[inline(always)]
    fn first_lanes(n: usize) -> Self {
        Self::splat(n as f32).gt(Self::from_fn(|i| i as f32))
    }
    /// The mask with lane i set where bit i of `bits` is.
    fn mask_from_bits(bits: u32) -> Self;
    /// A lane holding the bit pattern `bits` (to carry integer ids through [`Lanes::select`]).
    #[inline(always)]
    fn splat_bits(bits: u32) -> Self {
        Self::splat(f32::from_bits(bits))
    }
    /// The bit pattern of lane `i`.
    #[inline(always)]
    fn lane_bits(self, i: usize) -> u32 {
        self.lane(i).to_bits()
    }
    /// Mask of the finite lanes.
    #[inline(always)]
    fn finite(self) -> Self {
        self.abs().lt(Self::splat(f32::INFINITY))
    }
    /// Smallest of the lanes selected by `bits` (+∞ when none).
    #[inline(always)]
    fn min_lanes(self, bits: u32) -> f32 {
        let a = Self::mask_from_bits(bits).select(self, Self::splat(f32::INFINITY)).to_array();
        tree_reduce(a, |x, y| if y < x { y } else { x })
    }
    /// Largest of the lanes selected by `bits` (−∞ when none).
    #[inline(always)]
    fn max_lanes(self, bits: u32) -> f32 {
        let a = Self::mask_from_bits(bits).select(self, Self::splat(f32::NEG_INFINITY)).to_array();
        tree_reduce(a, |x, y| if y > x { y } else { x })
    }
    /// Sum of the lanes selected by `bits`.
    #[inline(always)]
    fn sum_lanes(self, bits: u32) -> f32 {
        tree_reduce(Self::mask_from_bits(bits).select(self, Self::splat(0.0)).to_array(), |x, y| x + y)
    }
}

/// Folds the lanes of `a` pairwise (lane i with lane i + n/2, then again on the first half):
/// log₂ n dependent steps and no branch per lane. The minimum and maximum compare plainly (a NaN
/// lane is not skipped as by `f32::min`; their callers, the packet frusta, see no NaN: inactive
/// lanes are masked first), and the sum rounds in another order than a left-to-right sum (the
/// frusta are conservative either way).
#[inline(always)]
fn tree_reduce<A: AsMut<[f32]>>(mut a: A, f: impl Fn(f32, f32) -> f32) -> f32 {
    let s = a.as_mut();
    let mut n = s.len();
    while n > 1 {
        n /= 2;
        for i in 0..n {
            s[i] = f(s[i], s[i + n]);
        }
    }
    s[0]
}

macro_rules! impl_lanes {
    ($t:ty, $u:ty, $n:expr) => {
        impl Lanes for $t {
            const LANES: usize = $n;
            const ALL: u32 = (1u32 << $n) - 1;
            type Array = [f32; $n];

            #[inline(always)]
            fn splat(x: f32) -> Self {
                <$t>::splat(x)
            }
            #[inline(always)]
            fn from_array(a: [f32; $n]) -> Self {
                <$t>::new(a)
            }
            #[inline(always)]
            fn to_array(self) -> [f32; $n] {
                <$t>::to_array(self)
            }
            #[inline(always)]
            fn load(s: &[f32]) -> Self {
                let a: [f32; $n] = s[..$n].try_into().unwrap();
                <$t>::new(a)
            }
            #[inline(always)]
            fn sqrt(self) -> Self {
                <$t>::sqrt(self)
            }
            #[inline(always)]
            fn abs(self) -> Self {
                <$t>::abs(self)
            }
            #[inline(always)]
            fn vmin(self, rhs: Self) -> Self {
                self.fast_min(rhs)
            }
            #[inline(always)]
            fn vmax(self, rhs: Self) -> Self {
                self.fast_max(rhs)
            }
            #[inline(always)]
            fn lt(self, rhs: Self) -> Self {
                self.simd_lt(rhs)
            }
            #[inline(always)]
            fn le(self, rhs: Self) -> Self {
                self.simd_le(rhs)
            }
            #[inline(always)]
            fn gt(self, rhs: Self) -> Self {
                self.simd_gt(rhs)
            }
            #[inline(always)]
            fn ge(self, rhs: Self) -> Self {
                self.simd_ge(rhs)
            }
            #[inline(always)]
            fn eq(self, rhs: Self) -> Self {
                self.simd_eq(rhs)
            }
            #[inline(always)]
            fn and(self, rhs: Self) -> Self {
                self & rhs
            }
            #[inline(always)]
            fn or(self, rhs: Self) -> Self {
                self | rhs
            }
            #[inline(always)]
            fn and_not(self, rhs: Self) -> Self {
                self & !rhs
            }
            #[inline(always)]
            fn mask_not(self) -> Self {
                !self
            }
            #[inline(always)]
            fn select(self, a: Self, b: Self) -> Self {
                wide::Select::select(self, a, b)
            }
            #[inline(always)]
            fn bitmask(self) -> u32 {
                self.to_bitmask()
            }
            #[inline(always)]
            fn mask_from_bits(bits: u32) -> Self {
                let lane_bits = <$u>::new(std::array::from_fn(|i| 1 << i));
                <$t>::from_bits((<$u>::splat(bits) & lane_bits).simd_eq(lane_bits))
            }
        }
    };
}

impl_lanes!(f32x4, u32x4, 4);
impl_lanes!(f32x8, u32x8, 8);
impl_lanes!(f32x16, u32x16, 16);

#[cfg(test)]
mod tests {
    use super::*;

    fn check<F: Lanes>() {
        let a = F::from_fn(|i| i as f32);
        let b = F::splat(2.0);
        assert_eq!(a.lt(b).bitmask(), 0b11);
        assert_eq!(a.le(b).bitmask(), 0b111);
        assert_eq!(a.ge(b).bitmask(), F::ALL & !0b11);
        assert_eq!(a.eq(b).bitmask(), 0b100);
        assert_eq!(F::mask_from_bits(0b101).bitmask(), 0b101);
        for bits in 0..=F::ALL {
            assert_eq!(F::mask_from_bits(bits).bitmask(), bits);
        }
        assert_eq!(F::first_lanes(3).bitmask(), 0b111);
        assert_eq!(F::first_lanes(0).bitmask(), 0);
        assert_eq!(a.lt(b).select(a, b).lane(3), 2.0);
        assert_eq!(F::splat_bits(7).lane_bits(1), 7);
        assert_eq!(a.sum_lanes(0b110), 3.0);
        assert_eq!(a.min_lanes(0b110), 1.0);
        assert_eq!(a.max_lanes(0b110), 2.0);
        assert_eq!(a.max_lanes(0), f32::NEG_INFINITY);
        assert_eq!(F::splat(2.0).sqrt().lane(0), 2f32.sqrt());
        assert_eq!(F::splat(-2.0).abs().lane(0), 2.0);
        let v = F::from_fn(|i| [1.0, f32::INFINITY, f32::NAN, -3.0][i % 4]);
        assert_eq!(v.finite().bitmask() & 0b1111, 0b1001);
        assert_eq!(F::load(&[5.0; 17]).lane(F::LANES - 1), 5.0);
        assert_eq!(a.vmin(b).lane(3), 2.0);
        assert_eq!(a.vmax(b).lane(0), 2.0);
    }

    #[test]
    fn four_eight_and_sixteen_lane_types_agree_with_scalar_semantics() {
        check::<F4>();
        check::<F8>();
        check::<F16>();
        // The discontinuity buffer relies on NaN failing every comparison in 16 lanes too.
        assert_eq!(F16::splat(f32::NAN).ge(F16::splat(-1.0)).bitmask(), 0);
        let nan = F8::splat(f32::NAN);
        assert_eq!(nan.le(F8::splat(1.0)).bitmask(), 0);
        // NaN in `self` is ignored by vmin / vmax (the slab tests depend on it).
        assert_eq!(nan.vmin(F8::splat(1.0)).lane(0), 1.0);
        assert_eq!(nan.vmax(F8::splat(1.0)).lane(0), 1.0);
    }
}
