//! Three-component vectors in structure-of-arrays form: one lane per ray.

use glam::Vec3;

use super::Lanes;

/// `LANES` three-component vectors, one per lane (x, y and z each in one SIMD register).
#[derive(Clone, Copy, Debug)]
pub struct Vec3x<F: Lanes> {
    /// x components.
    pub x: F,
    /// y components.
    pub y: F,
    /// z components.
    pub z: F,
}

impl<F: Lanes> Vec3x<F> {
    /// `v` in every lane.
    #[inline(always)]
    pub fn splat(v: Vec3) -> Self {
        Vec3x { x: F::splat(v.x), y: F::splat(v.y), z: F::splat(v.z) }
    }

    /// Lane `i` is `f(i)`.
    #[inline(always)]
    pub fn from_fn(mut f: impl FnMut(usize) -> Vec3) -> Self {
        let (mut x, mut y, mut z) = (F::splat(0.0).to_array(), F::splat(0.0).to_array(), F::splat(0.0).to_array());
        for i in 0..F::LANES {
            let v = f(i);
            x.as_mut()[i] = v.x;
            y.as_mut()[i] = v.y;
            z.as_mut()[i] = v.z;
        }
        Vec3x { x: F::from_array(x), y: F::from_array(y), z: F::from_array(z) }
    }

    /// Lane `i` as a scalar vector.
    #[inline(always)]
    pub fn lane(&self, i: usize) -> Vec3 {
        Vec3::new(self.x.lane(i), self.y.lane(i), self.z.lane(i))
    }

    /// Component `axis` (0 = x, 1 = y, 2 = z).
    #[inline(always)]
    pub fn axis(&self, axis: usize) -> F {
        match axis {
            0 => self.x,
            1 => self.y,
            _ => self.z,
        }
    }

    /// Lanewise dot product.
    #[inline(always)]
    pub fn dot(&self, o: &Self) -> F {
        self.x * o.x + self.y * o.y + self.z * o.z
    }

    /// Lanewise difference.
    #[inline(always)]
    pub fn sub(&self, o: &Self) -> Self {
        Vec3x { x: self.x - o.x, y: self.y - o.y, z: self.z - o.z }
    }

    /// Where `mask` is set `a`, else `b`.
    #[inline(always)]
    pub fn select(mask: F, a: &Self, b: &Self) -> Self {
        Vec3x { x: mask.select(a.x, b.x), y: mask.select(a.y, b.y), z: mask.select(a.z, b.z) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simd::F8;

    #[test]
    fn lanes_round_trip_and_dot_matches_scalar() {
        let v = Vec3x::<F8>::from_fn(|i| Vec3::new(i as f32, 1.0, -(i as f32)));
        let w = Vec3x::<F8>::splat(Vec3::new(2.0, 3.0, 4.0));
        for i in 0..8 {
            assert_eq!(v.lane(i), Vec3::new(i as f32, 1.0, -(i as f32)));
            assert_eq!(v.dot(&w).lane(i), v.lane(i).dot(w.lane(i)));
            assert_eq!(v.sub(&w).lane(i), v.lane(i) - w.lane(i));
        }
        assert_eq!(v.axis(2).lane(3), -3.0);
    }
}
