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
}
