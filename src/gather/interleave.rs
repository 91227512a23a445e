//! Interleaved sampling (Keller & Heidrich 2001; papers/002 §7.2): the image is tiled n×m; the
//! VPL set is split into n·m disjoint subsets by group; the pixel at offset (i, j) of every tile
//! gathers subset i + n·j only, scaled so that each subset is an unbiased estimate on its own.
//!
//! Groups are the sampler's independent units (a light path and all its VPLs, a resampled VPL,
//! a chain location), so splitting by group keeps each subset unbiased: subset k holds the
//! groups g with g mod S = k and is scaled by G / (number of its groups), with S = min(n·m, G)
//! subsets for G groups (pixels share subsets when there are fewer groups than tile pixels).
//!
//! A VPL that lights only a few pixels (MIR puts equal power in every VPL, so such a VPL is
//! bright) would reach a handful of its subset's pixels, each scaled by the subset count: a
//! grid of bright dots that the discontinuity buffer turns into bright 8×8 squares. When the
//! set knows each VPL's footprint ([`VplSet::footprint`]), a group whose VPLs would each reach
//! fewer than [`EVERYWHERE_PIXELS`] pixels of a subset, and whose regions are each no larger
//! than a subset's pixels (so that gathering it there costs no more shadow rays than the
//! interleaved gather; larger regions doubled the gather's time on light-box-thick at the
//! paper's workload for the same error), is *regional* ([`Regional`]): every pixel
//! of its VPLs' screen regions ([`VplSet::footprint_rect`], where MIR's probes saw them)
//! gathers it with weight 1, and outside the region it stays in the split, gathered only by
//! the pixels of its home subset, with that subset's scale. The split itself (ranks, subsets'
//! group counts and scales) is that of [`Interleave::new`]; a regional group is only kept out
//! of its subset's list and evaluated where the region rule says. So a pixel's expected weight
//! for every VPL over the frame's random rotation ([`Interleave::rotated`]) is that of the
//! plain split outside the region and exactly 1 inside it: the expectation is unchanged
//! whatever the region, and the region only decides where rays are spent. Before regions
//! (a spread VPL gathered by every pixel of the image) the spread VPLs took 2–4× the
//! interleaved gather's shadow rays at the paper's workload (1024×768, 1024 VPLs): every pixel
//! that faces such a VPL traces a ray to it, though almost all are blocked. At most an eighth
//! of the groups are regional (those with the smallest footprints).

use super::super::vpl::VplSet;

/// A VPL gathered by every pixel of its screen region, and outside it by the pixels of its
/// home subset (module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Regional {
    /// The VPL's index in the set.
    pub vpl: u32,
    /// The subset whose pixels gather it outside its region, with that subset's scale.
    pub home: u32,
    /// The region, `[x0, y0, x1, y1]` in pixels, inclusive.
    pub rect: [u32; 4],
}

impl Regional {
    /// Whether pixel (x, y) lies in the region.
    #[inline]
    pub fn contains(&self, x: u32, y: u32) -> bool {
        let [x0, y0, x1, y1] = self.rect;
        x >= x0 && x <= x1 && y >= y0 && y <= y1
    }
}

/// The VPL subsets of an interleave pattern.
#[derive(Clone, Debug)]
pub struct Interleave {
    /// Tile width n.
    pub n: u32,
    /// Tile height m.
    pub m: u32,
    /// VPL indices of each subset (regional VPLs are not listed).
    pub subsets: Vec<Vec<u32>>,
    /// Scale of each subset's sum.
    pub scales: Vec<f32>,
    /// VPLs gathered over their screen regions (see the module doc).
    pub regional: Vec<Regional>,
}

/// A VPL that would light fewer pixels of its interleave subset than this is gathered by every
/// pixel of its region (module doc).
pub const EVERYWHERE_PIXELS: f32 = 16.0;

/// Whether a VPL seen by `footprint` of the image's `pixels` would light fewer than
/// [`EVERYWHERE_PIXELS`] pixels of one of `subsets` interleave subsets.
fn lights_few_pixels(footprint: f32, pixels: usize, subsets: f32) -> bool {
    footprint * pixels as f32 / subsets < EVERYWHERE_PIXELS
}

/// The VPLs of `vpls` with their strong ones split (a VPL alone in its group whose path count
/// k exceeds `bound` times the set's median count, and that is not small enough to be
/// regional): each becomes ⌈k / (bound · median)⌉ copies, at most one per subset of an n×m
/// pattern, with equal shares of its radiance, each in a group of its own numbered so that the
/// copies fall in consecutive subsets. None when no VPL is strong.
///
/// MIR's locations bring power in proportion to k, the chain states spent there: a chain that
/// stays long at one location makes one VPL worth many. In the interleaved gather that power
/// reaches only the pixels of one subset, at the subset's scale: the brightest copy of the
/// tile in a frame, for the filter to average or, once it has faded out, a grid of bright
/// dots. A pixel's variance from a VPL of image power P gathered by one subset in S is
/// ∝ (S − 1)P²; split over s subsets it is ∝ (S/s − 1)P², for s − 1 more VPLs to gather. For a
/// given number of gathered VPLs the variance is least when every copy brings the same power,
/// MIR's own principle, which the counts had broken.
///
/// The expectation is unchanged: the group numbers are padded to a multiple of S (the new
/// numbers no copy took are empty groups), so every subset holds the same number of groups
/// and has scale S, and each VPL, copy or not, has expected weight 1 at every pixel over the
/// frame's rotation ([`Interleave::rotated`]).
pub fn split_strong(vpls: &VplSet, bound: f32, (n, m): (u32, u32), (width, height): (u32, u32)) -> Option<VplSet> {
    let tile = (n * m).max(1);
    if !(bound >= 1.0) || vpls.is_empty() || tile <= 1 {
        return None;
    }
    let mut counts: Vec<u32> = vpls.count.clone();
    let mid = counts.len() / 2;
    let cap = bound * (*counts.select_nth_unstable(mid).1).max(1) as f32;
    let mut members = vec![0u32; vpls.groups as usize];
    vpls.group.iter().for_each(|&g| members[g as usize] += 1);
    let pixels = width as usize * height as usize;
    let s = (tile as usize).min(vpls.groups.max(1) as usize) as f32;
    let copies = |i: usize| -> u32 {
        let k = vpls.count[i] as f32;
        let small = vpls.footprint.get(i).is_some_and(|&f| lights_few_pixels(f, pixels, s));
        if k <= cap || members[vpls.group[i] as usize] != 1 || small { 1 } else { ((k / cap).ceil() as u32).min(tile) }
    };
    if (0..vpls.len()).all(|i| copies(i) == 1) {
        return None;
    }
    let with_footprints = vpls.footprint.len() == vpls.len() && vpls.footprint_rect.len() == vpls.len();
    let g0 = vpls.groups;
    // Per residue r mod the tile, the next unused group number ≥ g0 with that residue.
    let mut next: Vec<u32> = (0..tile).map(|r| g0 + (r + tile - g0 % tile) % tile).collect();
    let mut out = VplSet::default();
    for i in 0..vpls.len() {
        let c = copies(i);
        let mut v = vpls.get(i);
        v.radiance /= c as f32;
        v.count = vpls.count[i].div_ceil(c);
        let home = v.group % tile;
        for j in 0..c {
            if j > 0 {
                let r = ((home + j) % tile) as usize;
                v.group = next[r];
                next[r] += tile;
            }
            out.push(v);
            if with_footprints {
                out.footprint.push(vpls.footprint[i]);
                out.footprint_rect.push(vpls.footprint_rect[i]);
            }
        }
    }
    out.groups = out.groups.max(g0).next_multiple_of(tile);
    Some(out)
}

impl Interleave {
    /// Splits `vpls` for an n×m pattern, none regional.
    pub fn new(vpls: &VplSet, n: u32, m: u32) -> Self {
        Self::split(vpls, n, m, &[])
    }

    /// Splits `vpls` for an n×m pattern over a `width` × `height` image, making the VPLs with
    /// small footprints regional (module doc).
    pub fn for_image(vpls: &VplSet, n: u32, m: u32, (width, height): (u32, u32)) -> Self {
        let groups = vpls.groups.max(1) as usize;
        let pixels = width as usize * height as usize;
        if vpls.footprint.len() != vpls.len() || n * m <= 1 || pixels == 0 {
            return Self::new(vpls, n, m);
        }
        let s = ((n * m) as usize).min(groups) as f32;
        let whole = [0, 0, width - 1, height - 1];
        let rect = |i: usize| match vpls.footprint_rect.get(i) {
            Some(&[x0, y0, x1, y1]) => [x0.min(whole[2]), y0.min(whole[3]), x1.min(whole[2]), y1.min(whole[3])],
            None => whole,
        };
        let rects: Vec<[u32; 4]> = (0..vpls.len()).map(rect).collect();
        // A group is regional when every VPL of it is small and its region is no larger than
        // the pixels of a subset (so it costs no more shadow rays than its interleaved gather);
        // the group's footprint is its largest one.
        let subset_pixels = pixels as f32 / s;
        let mut small = vec![Some(0.0f32); groups];
        for (i, &g) in vpls.group.iter().enumerate() {
            let f = vpls.footprint[i];
            let [x0, y0, x1, y1] = rects[i];
            let area = (x1.saturating_sub(x0) + 1) as f32 * (y1.saturating_sub(y0) + 1) as f32;
            let slot = &mut small[g as usize];
            *slot = match *slot {
                Some(a) if lights_few_pixels(f, pixels, s) && area <= subset_pixels => Some(a.max(f)),
                _ => None,
            };
        }
        let mut spread: Vec<(f32, u32)> =
            small.iter().enumerate().filter_map(|(g, f)| f.map(|f| (f, g as u32))).collect();
        // Groups without VPLs keep Some(0) and are not in the set: drop them.
        let present: Vec<bool> = {
            let mut p = vec![false; groups];
            vpls.group.iter().for_each(|&g| p[g as usize] = true);
            p
        };
        spread.retain(|&(_, g)| present[g as usize]);
        spread.sort_by(|a, b| a.0.total_cmp(&b.0));
        spread.truncate(groups / 8);
        let mut flagged = vec![false; groups];
        spread.iter().for_each(|&(_, g)| flagged[g as usize] = true);
        Self::split(vpls, n, m, &flagged).regions(&rects)
    }

    /// Splits the groups into subsets; the VPLs of `flagged` groups are regional, with their
    /// subset as home (their region is set by [`Interleave::regions`]).
    fn split(vpls: &VplSet, n: u32, m: u32, flagged: &[bool]) -> Self {
        let groups = vpls.groups.max(1) as usize;
        let is_flagged = |g: usize| flagged.get(g).copied().unwrap_or(false);
        let s = ((n * m) as usize).min(groups).max(1);
        let mut subsets = vec![Vec::new(); s];
        let mut group_count = vec![0usize; s];
        for g in 0..groups {
            group_count[g % s] += 1;
        }
        let mut regional = Vec::new();
        for (i, &g) in vpls.group.iter().enumerate() {
            let home = g as usize % s;
            if is_flagged(g as usize) {
                regional.push(Regional { vpl: i as u32, home: home as u32, rect: [0, 0, u32::MAX, u32::MAX] });
            } else {
                subsets[home].push(i as u32);
            }
        }
        let scales = group_count.iter().map(|&c| if c > 0 { groups as f32 / c as f32 } else { 0.0 }).collect();
        Interleave { n, m, subsets, scales, regional }
    }

    /// Sets the regional VPLs' regions from `rects` (indexed by VPL).
    fn regions(mut self, rects: &[[u32; 4]]) -> Self {
        for r in &mut self.regional {
            r.rect = rects[r.vpl as usize];
        }
        self
    }

    /// The same split with the subsets moved on by `k`: the groups of subset j go to subset
    /// (j + k) mod S, with their scale.
    ///
    /// A frame rotates its split by a number drawn from its seed, so that every group is as
    /// likely to land at any offset of the tile. Without it group g always lit the pixels at
    /// offset g mod S, and a sampler whose group order carries meaning prints a fixed pattern
    /// into the accumulated image: a Metropolis chain's first location is the state it carried
    /// over from the previous run, which is length-biased toward locations where the chain
    /// stays long (so strong VPLs), and with two chains of 128 locations both first locations
    /// fell in subset 0. Measured on ajar-door-thick (256×192, 256 frames of the viewer, mtmh):
    /// the tile offset (0, 0) averaged 2.86× the tile mean (the reference: 1.00), a lasting
    /// grid of bright dots once the discontinuity buffer fades out. Each pixel's expectation is
    /// unbiased only if the subset it gathers is a uniformly placed one.
    pub fn rotated(mut self, k: u64) -> Self {
        let s = self.subsets.len();
        let k = (k % s as u64) as usize;
        self.subsets.rotate_right(k);
        self.scales.rotate_right(k);
        for r in &mut self.regional {
            r.home = ((r.home as usize + k) % s) as u32;
        }
        self
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
    /// Rotating moves each subset, with its scale, by k places.
    #[test]
    fn rotation_moves_each_subset_with_its_scale() {
        let mut vpls = VplSet::default();
        for g in 0..70u32 {
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
        let plain = Interleave::new(&vpls, 8, 8);
        let turned = plain.clone().rotated(64 * 5 + 3);
        for j in 0..64 {
            assert_eq!(turned.subsets[(j + 3) % 64], plain.subsets[j]);
            assert_eq!(turned.scales[(j + 3) % 64], plain.scales[j]);
        }
        assert_ne!(plain.scales[0], plain.scales[10], "groups 0…5 share subsets with groups 64…69");
    }

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

    /// Splitting the strong VPLs keeps every VPL's expected weight at a pixel: over all S
    /// rotations, the radiance its copies bring to any pixel (their subset's scale times their
    /// share) averages to the VPL's radiance, exactly; the copies of one VPL fall in distinct
    /// subsets; and what was not strong, or was small enough to be regional, is not split.
    #[test]
    fn split_strong_keeps_each_vpls_expected_weight() {
        let (n, m) = (4, 4);
        let tile = 16;
        for groups in [5u32, 16, 37, 100] {
            let mut vpls = VplSet::default();
            for g in 0..groups {
                // Counts 1…3 with a few strong ones (40, 200) and one strong but small.
                let count = match g % 11 {
                    3 => 40,
                    7 => 200,
                    9 => 300,
                    _ => 1 + g % 3,
                };
                vpls.push(Vpl {
                    position: glam::Vec3::new(g as f32, 0.0, 0.0),
                    normal: glam::Vec3::Y,
                    radiance: glam::Vec3::splat(count as f32),
                    lobe: None,
                    count,
                    flags: 0,
                    length: 1,
                    group: g,
                });
                vpls.footprint.push(if g % 11 == 9 { 1e-6 } else { 0.5 });
                vpls.footprint_rect.push([0, 0, 63, 63]);
            }
            let split = split_strong(&vpls, 4.0, (n, m), (64, 64)).expect("strong VPLs to split");
            assert!(split.len() > vpls.len());
            assert_eq!(split.footprint.len(), split.len());
            let inter = Interleave::new(&split, n, m);
            let s = inter.subsets.len();
            // Expected radiance at pixel offset 0 over the S rotations, per original VPL
            // (identified by its position).
            let mut brought = vec![0.0f64; groups as usize];
            for k in 0..s as u64 {
                let turned = inter.clone().rotated(k);
                let sub = turned.subset_of(0, 0);
                for &i in &turned.subsets[sub] {
                    let orig = split.position[i as usize].x as usize;
                    brought[orig] += (split.radiance[i as usize].x * turned.scales[sub]) as f64 / s as f64;
                }
            }
            for (g, &got) in brought.iter().enumerate() {
                let want = vpls.radiance[g].x as f64;
                assert!((got - want).abs() < 1e-4 * want, "{groups} groups: VPL {g} brings {got} for {want}");
                let copies: Vec<usize> = (0..split.len()).filter(|&i| split.position[i].x as usize == g).collect();
                let strong = matches!(g % 11, 3 | 7);
                assert_eq!(copies.len() > 1, strong, "{groups} groups: VPL {g} split {} ways", copies.len());
                let mut subsets: Vec<u32> = copies.iter().map(|&i| split.group[i] % tile).collect();
                subsets.sort();
                subsets.dedup();
                assert_eq!(subsets.len(), copies.len(), "{groups} groups: copies of VPL {g} share a subset");
            }
        }
    }
}
