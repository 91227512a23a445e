//! Interleaved sampling (Keller & Heidrich 2001; papers/002 §7.2): the image is tiled n×m; the
//! VPL set is split into n·m disjoint subsets by group; the pixel at offset (i, j) of every tile
//! gathers subset i + n·j only, scaled so that each subset is an unbiased estimate on its own.
//!
//! Groups are the sampler's independent units (a light path and all its VPLs, a resampled VPL,
//! a chain location), so splitting by group keeps each subset unbiased: subset k holds the
//! groups g with g mod S = k and is scaled by G / (number of its groups), with S = min(n·m, G)
//! subsets for G groups (pixels share subsets when there are fewer groups than tile pixels).

use super::super::vpl::VplSet;

/// The VPL subsets of an interleave pattern.
#[derive(Clone, Debug)]
pub struct Interleave {
    /// Tile width n.
    pub n: u32,
    /// Tile height m.
    pub m: u32,
    /// VPL indices of each subset.
    pub subsets: Vec<Vec<u32>>,
    /// Scale of each subset's sum.
    pub scales: Vec<f32>,
}

impl Interleave {
    /// Splits `vpls` for an n×m pattern.
    pub fn new(vpls: &VplSet, n: u32, m: u32) -> Self {
        let groups = vpls.groups.max(1) as usize;
        let s = ((n * m) as usize).min(groups).max(1);
        let mut subsets = vec![Vec::new(); s];
        let mut group_count = vec![0usize; s];
        for g in 0..groups {
            group_count[g % s] += 1;
        }
        for (i, &g) in vpls.group.iter().enumerate() {
            subsets[g as usize % s].push(i as u32);
        }
        let scales = group_count.iter().map(|&c| if c > 0 { groups as f32 / c as f32 } else { 0.0 }).collect();
        Interleave { n, m, subsets, scales }
    }

    /// The subset pixel (x, y) gathers.
    #[inline]
    pub fn subset_of(&self, x: u32, y: u32) -> usize {
        let k = (x % self.n + self.n * (y % self.m)) as usize;
        k % self.subsets.len()
    }

    /// [`Interleave::subset_of`] for the pixels of row `y`, with the row's part computed once
    /// and no division for a power-of-two tile width (three divisions a pixel were 2 % of the
    /// gather's row loop).
    #[inline]
    pub fn row(&self, y: u32) -> InterleaveRow {
        let mask = self.n.is_power_of_two().then(|| self.n - 1);
        InterleaveRow { n: self.n, mask, base: (self.n * (y % self.m)) as usize, len: self.subsets.len() }
    }
}

/// The subsets of one row's pixels ([`Interleave::row`]).
#[derive(Clone, Copy, Debug)]
pub struct InterleaveRow {
    n: u32,
    mask: Option<u32>,
    base: usize,
    len: usize,
}

impl InterleaveRow {
    /// The subset pixel x of the row gathers.
    #[inline(always)]
    pub fn of(&self, x: u32) -> usize {
        let i = match self.mask {
            Some(mask) => x & mask,
            None => x % self.n,
        };
        let k = i as usize + self.base;
        if k < self.len { k } else { k % self.len }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vpl::{Vpl, VplSet};

    /// The row form gives `subset_of`'s subset for every pixel, for power-of-two and other tile
    /// sizes and with fewer subsets than tile pixels.
    #[test]
    fn row_subsets_equal_subset_of() {
        for groups in [1u32, 5, 12, 64, 300] {
            let mut vpls = VplSet::default();
            for g in 0..groups {
                let v = Vpl {
                    position: glam::Vec3::ZERO,
                    normal: glam::Vec3::Y,
                    radiance: glam::Vec3::ONE,
                    lobe: None,
                    count: 1,
                    flags: 0,
                    length: 1,
                    group: g,
                };
                vpls.push(v);
            }
            for (n, m) in [(8, 8), (4, 3), (3, 5), (1, 1), (16, 2), (7, 1)] {
                let inter = Interleave::new(&vpls, n, m);
                for y in 0..2 * m + 1 {
                    let row = inter.row(y);
                    for x in 0..3 * n + 2 {
                        assert_eq!(row.of(x), inter.subset_of(x, y), "{groups} groups, {n}x{m}, pixel ({x}, {y})");
                    }
                }
            }
        }
    }
}
