//! The discontinuity buffer (Wald, Kollig, Benthin, Keller & Slusallek 2002; papers/002 §7.2):
//! each pixel averages gathered / albedo over the n×m window around it, using only neighbours
//! on the same continuous surface (normals within an angle, depths within a relative tolerance),
//! then multiplies by its own albedo. With an n×m interleave pattern every window holds each VPL
//! subset once, so a pixel inside a continuous surface sees all VPLs; texture detail stays sharp
//! (it is in the albedo), and nothing leaks across edges.

use glam::Vec3;
use rayon::prelude::*;

use crate::simd::{F16, Lanes};

/// Lanes of the filter: window centres filtered at once.
type L = F16;

/// Thresholds of the discontinuity buffer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DiscontinuitySettings {
    /// Window width (the interleave tile width n).
    pub n: u32,
    /// Window height (the interleave tile height m).
    pub m: u32,
    /// Largest angle between neighbour normals, degrees.
    pub max_normal_angle_deg: f32,
    /// Largest relative depth difference |d − d'| / d.
    pub max_relative_depth: f32,
}

impl DiscontinuitySettings {
    /// Default thresholds for an n×m pattern: 20°, 5 %.
    pub fn new(n: u32, m: u32) -> Self {
        DiscontinuitySettings { n, m, max_normal_angle_deg: 20.0, max_relative_depth: 0.05 }
    }
}

/// The filter's structure-of-arrays copy of the G-buffer: per image row, [`PLANES`] planes of
/// `pw` floats — normal x, y, z, depth, and the irradiance-like ratio gathered / albedo (x, y,
/// z) — with pixel x at `x + pad`. A pixel that neither gives nor takes (a zero albedo channel)
/// has depth NaN, which fails every depth test, and so do the pads: windows reaching past the
/// image edge simply find no neighbours there.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PlaneLayout {
    /// Image width.
    pub width: usize,
    /// Floats per plane row.
    pub pw: usize,
    /// Pad before pixel 0.
    pub pad: usize,
}

impl PlaneLayout {
    /// The layout for `width`-pixel rows and the windows of `s`.
    pub fn new(width: u32, s: &DiscontinuitySettings) -> Self {
        let (x_lo, x_hi) = (s.n as usize / 2, (s.n as usize - 1) / 2);
        let pad = x_lo.max(x_hi) + L::LANES;
        PlaneLayout { width: width as usize, pw: width as usize + 2 * pad, pad }
    }

    /// Floats of one image row's planes.
    pub fn row_len(&self) -> usize {
        PLANES * self.pw
    }

    /// Fills `row` (one image row's planes, [`PlaneLayout::row_len`] floats, holding anything:
    /// zeros, an earlier frame's planes, or planes of another layout) from that row's pixels.
    /// The depth plane is rewritten whole, NaN where there is no pixel (pads included), and the
    /// filter takes a neighbour only where its depth passes, so what the other planes hold there
    /// never reaches a sum (tested with planes full of garbage).
    #[inline]
    pub fn fill_row(&self, row: &mut [f32], gathered: &[Vec3], albedo: &[Vec3], normal: &[Vec3], depth: &[f32]) {
        let (pw, pad, w) = (self.pw, self.pad, self.width);
        row[3 * pw..4 * pw].fill(f32::NAN);
        // Each plane's span and each input sliced to the row's width once, so the loop below
        // carries no bounds checks (they and their reloaded bases were most of its time).
        let mut spans = row.chunks_exact_mut(pw).map(|p| &mut p[pad..pad + w]);
        let [nx, ny, nz, dp, rx, ry, rz]: [&mut [f32]; PLANES] = std::array::from_fn(|_| spans.next().unwrap());
        let (gathered, albedo, normal, depth) = (&gathered[..w], &albedo[..w], &normal[..w], &depth[..w]);
        for x in 0..w {
            let a = albedo[x];
            if a.min_element() <= 0.0 {
                continue;
            }
            let (n, r) = (normal[x], gathered[x] / a);
            (nx[x], ny[x], nz[x], dp[x]) = (n.x, n.y, n.z, depth[x]);
            (rx[x], ry[x], rz[x]) = (r.x, r.y, r.z);
        }
    }
}

impl PlaneLayout {
    /// The ratio planes of [`PlaneLayout::fill_row`] alone (gathered / albedo, where the albedo
    /// is positive), for a frame whose windows take their neighbours from a record
    /// ([`Masks::Apply`]), which reads no other plane. The same values as `fill_row` writes.
    #[inline]
    pub fn fill_ratio_row(&self, row: &mut [f32], gathered: &[Vec3], albedo: &[Vec3]) {
        let (pw, pad, w) = (self.pw, self.pad, self.width);
        let mut spans = row.chunks_exact_mut(pw).skip(4).map(|p| &mut p[pad..pad + w]);
        let [rx, ry, rz]: [&mut [f32]; 3] = std::array::from_fn(|_| spans.next().unwrap());
        let (gathered, albedo) = (&gathered[..w], &albedo[..w]);
        for x in 0..w {
            let a = albedo[x];
            if a.min_element() <= 0.0 {
                continue;
            }
            let r = gathered[x] / a;
            (rx[x], ry[x], rz[x]) = (r.x, r.y, r.z);
        }
    }
}

/// Filters `gathered` (per-pixel VPL light) using the G-buffer's albedo, normals and depths.
pub fn filter(
    width: u32,
    height: u32,
    gathered: &[Vec3],
    albedo: &[Vec3],
    normal: &[Vec3],
    depth: &[f32],
    s: &DiscontinuitySettings,
) -> Vec<Vec3> {
    let layout = PlaneLayout::new(width, s);
    let w = width as usize;
    let mut planes = vec![0.0f32; layout.row_len() * height as usize];
    planes.par_chunks_mut(layout.row_len()).enumerate().for_each(|(y, row)| {
        let r = y * w..(y + 1) * w;
        layout.fill_row(row, &gathered[r.clone()], &albedo[r.clone()], &normal[r.clone()], &depth[r]);
    });
    filter_planes(&layout, &planes, height, gathered, albedo, normal, depth, s, None, Vec::new(), Masks::Test)
}

/// Which neighbours a window takes: tested, tested and recorded, or as recorded.
pub enum Masks<'a> {
    /// Test every neighbour's normal and depth against the centre's.
    Test,
    /// Test, and record the outcome into the buffer ([`Masks::len`] entries, resized).
    Record(&'a mut Vec<u16>),
    /// Take the outcome recorded for the same G-buffer (normals, depths, albedos) and the same
    /// settings: no tests, and the normal and depth planes are not read. The same bits.
    Apply(&'a [u16]),
}

impl Masks<'_> {
    /// Entries of a record for a `width` × `height` image and the windows of `s`: per centre row,
    /// per group of [`L::LANES`] centres, per window offset, the lanes that take it.
    pub fn len(width: u32, height: u32, s: &DiscontinuitySettings) -> usize {
        height as usize * (width as usize).div_ceil(L::LANES) * (s.n * s.m) as usize
    }
}

/// [`filter`] from planes already filled ([`PlaneLayout::fill_row`] for every row; the frame
/// pipeline fills them while each band of rows is in cache), plus `plus` per pixel when given
/// (the frame adds the emission seen directly as it writes each pixel, instead of in another
/// pass over 9 MB at 512²), into the allocation of `reuse` when it has the image's size (every
/// pixel is written, so it needs no clearing).
///
/// Vectorised across window centres: sixteen neighbouring pixels of a row are filtered at once,
/// and each window offset costs one 16-wide load per plane and no horizontal sums (measured in
/// benches/results/2026-12-01-view.md against the earlier one-window-row-per-register form);
/// two rows of centres share those loads.
///
/// `masks` says whether each window's neighbours are tested, tested and recorded, or taken from
/// a record ([`Masks`]): a still camera's held G-buffer keeps its normals and depths for several
/// frames, and so does which neighbours each window takes; only the gathered light changes.
pub fn filter_planes(
    layout: &PlaneLayout,
    planes: &[f32],
    height: u32,
    gathered: &[Vec3],
    albedo: &[Vec3],
    normal: &[Vec3],
    depth: &[f32],
    s: &DiscontinuitySettings,
    plus: Option<&[Vec3]>,
    reuse: Vec<Vec3>,
    masks: Masks<'_>,
) -> Vec<Vec3> {
    assert_eq!(planes.len(), layout.row_len() * height as usize, "filter planes of another size");
    assert_eq!(*layout, PlaneLayout::new(layout.width as u32, s), "filter planes laid out for other windows");
    let cos_max = s.max_normal_angle_deg.to_radians().cos();
    let (w, h) = (layout.width, height as usize);
    let (x_lo, x_hi) = (s.n as usize / 2, (s.n as usize - 1) / 2);
    let (y_lo, y_hi) = (s.m as usize / 2, (s.m as usize - 1) / 2);
    let (pw, pad) = (layout.pw, layout.pad);
    // The record's layout (see `Masks::len`).
    let (groups, window) = (w.div_ceil(L::LANES), (s.n * s.m) as usize);
    let n_masks = Masks::len(w as u32, height, s);
    let (record, apply): (Option<&mut [u16]>, Option<&[u16]>) = match masks {
        Masks::Test => (None, None),
        Masks::Record(m) => {
            m.resize(n_masks, 0);
            (Some(&mut m[..]), None)
        }
        Masks::Apply(m) => {
            assert_eq!(m.len(), n_masks, "filter masks of another size");
            (None, Some(m))
        }
    };
    // Each pair of centre rows writes its own rows' records.
    let mut record_pairs: Vec<Option<&mut [u16]>> = match record {
        Some(m) => m.chunks_mut(2 * groups * window).map(Some).collect(),
        None => (0..h.div_ceil(2)).map(|_| None).collect(),
    };
    // Every pixel is written below; zeroed in parallel, not serially on the calling thread.
    let mut out = if reuse.len() == w * h { reuse } else { (0..w * h).into_par_iter().map(|_| Vec3::ZERO).collect() };
    let (one, cos, rel_depth) = (L::splat(1.0), L::splat(cos_max), L::splat(s.max_relative_depth));
    // Two centre rows at a time: their windows share all rows but one, so each neighbour
    // vector is loaded once for both.
    out.par_chunks_mut(2 * w).zip(record_pairs.par_iter_mut()).enumerate().for_each(|(pair, (rows, record))| {
        // The pair's rows (the last pair of an odd height has one).
        let n_rows = rows.len() / w;
        let ys = [2 * pair, 2 * pair + 1];
        let window_rows = |y: usize| (y.saturating_sub(y_lo), (y + y_hi).min(h - 1));
        let (first, last) = (window_rows(ys[0]).0, window_rows(ys[n_rows - 1]).1);
        for (g, xc) in (0..w).step_by(L::LANES).enumerate() {
            // L::LANES pixels of plane k of the row at `base`, from padded position `xs`.
            let at = |base: usize, k: usize, xs: usize| L::load(&planes[base + k * pw + xs..]);
            let c = pad + xc;
            let mut acc = ys.map(|y| {
                if y >= h {
                    // No such row: an empty window.
                    return Centre::new([L::splat(0.0); 3], L::splat(0.0), L::splat(0.0), (1, 0));
                }
                if apply.is_some() {
                    // (Normals and depths are not read: the record has the tests' outcome.)
                    return Centre::new([L::splat(0.0); 3], L::splat(0.0), L::splat(0.0), window_rows(y));
                }
                let base = y * PLANES * pw;
                let (nx, ny, nz, d0) = (at(base, 0, c), at(base, 1, c), at(base, 2, c), at(base, 3, c));
                Centre::new([nx, ny, nz], d0, rel_depth * d0, window_rows(y))
            });
            // The record of centre row k (0 or 1 of the pair) of this group, offset `o`.
            let slot = |k: usize, o: usize| (k * groups + g) * window + o;
            let applied = apply.map(|m| &m[(2 * pair * groups) * window..]);
            for yy in first..=last {
                let base = yy * PLANES * pw;
                let takers: u32 =
                    acc.iter().enumerate().fold(0, |m, (k, a)| m | ((a.rows.0 <= yy && yy <= a.rows.1) as u32) << k);
                // The window's span of each plane of row yy (pixels outside the image are pads):
                // lane l of offset dx reads pixel xc + l + dx − x_lo. Sliced once here, the
                // loads below need no bounds checks.
                let span = x_lo + x_hi + L::LANES;
                let plane: [&[f32]; PLANES] = std::array::from_fn(|k| &planes[base + k * pw + c - x_lo..][..span]);
                for dx in 0..=x_lo + x_hi {
                    let at = |k: usize| L::load(&plane[k][dx..]);
                    let v = [at(4), at(5), at(6)];
                    // Window offset of (yy, dx) for centre row k: (yy − y + y_lo)·n + dx.
                    let offset = |k: usize| (yy + y_lo - ys[k]) * (s.n as usize) + dx;
                    match applied {
                        Some(m) => {
                            for (k, a) in acc.iter_mut().enumerate() {
                                if takers >> k & 1 != 0 {
                                    a.add_kept(L::mask_from_bits(m[slot(k, offset(k))] as u32), &v, one);
                                }
                            }
                        }
                        None => {
                            let (n, d) = ([at(0), at(1), at(2)], at(3));
                            for (k, a) in acc.iter_mut().enumerate() {
                                if takers >> k & 1 != 0 {
                                    let keep = a.keep(&n, d, cos);
                                    if let Some(r) = record.as_deref_mut() {
                                        r[slot(k, offset(k))] = keep.bitmask() as u16;
                                    }
                                    a.add_kept(keep, &v, one);
                                }
                            }
                        }
                    }
                }
            }
            for (a, &y) in acc.iter().zip(&ys).take(n_rows) {
                let row = &mut rows[(y - 2 * pair) * w..][..w];
                let (sx, sy, sz, count) =
                    (a.sum[0].to_array(), a.sum[1].to_array(), a.sum[2].to_array(), a.count.to_array());
                for lane in 0..L::LANES.min(w - xc) {
                    let (x, i) = (xc + lane, y * w + xc + lane);
                    let (al, n0, d) = (albedo[i], normal[i], depth[i]);
                    let v = if al.min_element() <= 0.0 || n0 == Vec3::ZERO || d <= 0.0 || count[lane] == 0.0 {
                        gathered[i]
                    } else {
                        Vec3::new(sx[lane], sy[lane], sz[lane]) / count[lane] * al
                    };
                    row[x] = match plus {
                        Some(plus) => v + plus[i],
                        None => v,
                    };
                }
            }
        }
    });
    out
}

/// The window sums of L::LANES centres of one row.
struct Centre {
    normal: [L; 3],
    depth: L,
    tol: L,
    /// Window rows (first, last).
    rows: (usize, usize),
    sum: [L; 3],
    count: L,
}

impl Centre {
    fn new(normal: [L; 3], depth: L, tol: L, rows: (usize, usize)) -> Self {
        let zero = L::splat(0.0);
        Centre { normal, depth, tol, rows, sum: [zero; 3], count: zero }
    }

    /// The lanes whose neighbour (normal `n`, depth `d`) passes the centre's tests.
    #[inline(always)]
    fn keep(&self, n: &[L; 3], d: L, cos: L) -> L {
        let dot = n[0] * self.normal[0] + n[1] * self.normal[1] + n[2] * self.normal[2];
        dot.ge(cos).and((d - self.depth).abs().le(self.tol))
    }

    /// Adds the neighbours' ratios `v` in the lanes of `keep`.
    #[inline(always)]
    fn add_kept(&mut self, keep: L, v: &[L; 3], one: L) {
        let zero = L::splat(0.0);
        for (s, &v) in self.sum.iter_mut().zip(v) {
            *s += keep.select(v, zero);
        }
        self.count += keep.select(one, zero);
    }
}

/// Planes per row of the filter's SoA copy of the G-buffer (normal xyz, depth, ratio xyz).
pub const PLANES: usize = 7;

#[cfg(test)]
mod tests {
    use super::*;

    /// The filter written plainly: one centre and one neighbour at a time, clipped windows.
    fn filter_one_centre_at_a_time(
        width: u32,
        height: u32,
        gathered: &[Vec3],
        albedo: &[Vec3],
        normal: &[Vec3],
        depth: &[f32],
        s: &DiscontinuitySettings,
    ) -> Vec<Vec3> {
        let cos_max = s.max_normal_angle_deg.to_radians().cos();
        let (w, h) = (width as usize, height as usize);
        let (x_lo, x_hi) = (s.n as usize / 2, (s.n as usize - 1) / 2);
        let (y_lo, y_hi) = (s.m as usize / 2, (s.m as usize - 1) / 2);
        let mut out = vec![Vec3::ZERO; w * h];
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                let (n0, d0) = (normal[i], depth[i]);
                out[i] = gathered[i];
                if albedo[i].min_element() <= 0.0 || n0 == Vec3::ZERO || d0 <= 0.0 {
                    continue;
                }
                let (mut sum, mut count) = (Vec3::ZERO, 0.0f32);
                for yy in y.saturating_sub(y_lo)..=(y + y_hi).min(h - 1) {
                    for xx in x.saturating_sub(x_lo)..=(x + x_hi).min(w - 1) {
                        let j = yy * w + xx;
                        if albedo[j].min_element() > 0.0
                            && normal[j].dot(n0) >= cos_max
                            && (depth[j] - d0).abs() <= s.max_relative_depth * d0
                        {
                            sum += gathered[j] / albedo[j];
                            count += 1.0;
                        }
                    }
                }
                if count > 0.0 {
                    out[i] = sum / count * albedo[i];
                }
            }
        }
        out
    }

    /// Image sizes and window sizes of the tests below (windows wider and taller than the image
    /// among them).
    const SIZES: [(u32, u32, u32, u32); 5] = [(37, 11, 8, 8), (8, 8, 4, 4), (5, 3, 8, 8), (64, 9, 3, 5), (17, 2, 1, 1)];

    /// A random G-buffer of `w`×`h` pixels with edges: albedo, normal and depth per pixel, three
    /// surfaces in vertical stripes (one slightly bumpy), holes (a zero albedo channel, or no hit).
    fn random_surfaces(rng: &mut crate::sampling::Pcg32, w: u32, h: u32) -> (Vec<Vec3>, Vec<Vec3>, Vec<f32>) {
        let mut u = || rng.next_f32();
        let (mut albedo, mut normal, mut depth) = (Vec::new(), Vec::new(), Vec::new());
        for i in 0..(w * h) as usize {
            let surface = (i % w as usize) / 6 % 3;
            albedo.push(if u() < 0.1 { Vec3::new(0.5, 0.0, 0.5) } else { Vec3::new(0.2 + u(), 0.3, 0.9) });
            normal.push(match surface {
                0 => Vec3::Z,
                1 => Vec3::new(0.0, 0.6, 0.8),
                _ => Vec3::new(0.05 * u(), 0.0, 1.0).normalize(),
            });
            depth.push(if u() < 0.05 { 0.0 } else { 1.0 + surface as f32 + 0.04 * u() });
        }
        (albedo, normal, depth)
    }

    /// Random gathered light for `len` pixels.
    fn random_light(rng: &mut crate::sampling::Pcg32, len: usize) -> Vec<Vec3> {
        (0..len).map(|_| Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 4.0).collect()
    }

    /// Random surfaces with edges, holes (zero albedo, no hit) and every window size: the
    /// vectorised filter gives the straightforward one's values, bit for bit.
    #[test]
    fn vectorised_filter_matches_the_straightforward_one() {
        let mut rng = crate::sampling::Pcg32::new(7);
        for (w, h, n, m) in SIZES {
            let gathered = random_light(&mut rng, (w * h) as usize);
            let (albedo, normal, depth) = random_surfaces(&mut rng, w, h);
            let s = DiscontinuitySettings::new(n, m);
            let fast = filter(w, h, &gathered, &albedo, &normal, &depth, &s);
            let slow = filter_one_centre_at_a_time(w, h, &gathered, &albedo, &normal, &depth, &s);
            for (i, (a, b)) in fast.iter().zip(&slow).enumerate() {
                // Each lane adds its neighbours in the reference's order: the same bits.
                assert_eq!(a, b, "{w}x{h} {n}x{m} pixel {i}");
            }
        }
    }

    /// A record of which neighbours each window took ([`Masks`]), made while filtering one light,
    /// filters another light over the same G-buffer to the straightforward filter's values, bit
    /// for bit, from planes where only the ratio planes were filled for it
    /// ([`PlaneLayout::fill_ratio_row`]) and without reading the normal and depth planes (they
    /// are overwritten with garbage here); recording does not change the image. Random surfaces
    /// with edges and holes, and every window size of the test above.
    #[test]
    fn recorded_neighbour_masks_filter_another_light_as_the_tests_would() {
        let mut rng = crate::sampling::Pcg32::new(11);
        for (w, h, n, m) in SIZES {
            let (first, second) = (random_light(&mut rng, (w * h) as usize), random_light(&mut rng, (w * h) as usize));
            let (albedo, normal, depth) = random_surfaces(&mut rng, w, h);
            let s = DiscontinuitySettings::new(n, m);
            let layout = PlaneLayout::new(w, &s);
            let planes_of = |gathered: &[Vec3]| {
                let mut planes = vec![0.0f32; layout.row_len() * h as usize];
                for (y, row) in planes.chunks_mut(layout.row_len()).enumerate() {
                    let r = y * w as usize..(y + 1) * w as usize;
                    layout.fill_row(row, &gathered[r.clone()], &albedo[r.clone()], &normal[r.clone()], &depth[r]);
                }
                planes
            };
            let run = |gathered: &[Vec3], planes: &[f32], masks: Masks<'_>| {
                filter_planes(&layout, planes, h, gathered, &albedo, &normal, &depth, &s, None, Vec::new(), masks)
            };
            let mut record = Vec::new();
            let recorded = run(&first, &planes_of(&first), Masks::Record(&mut record));
            assert_eq!(record.len(), Masks::len(w, h, &s));
            let slow = |g: &[Vec3]| filter_one_centre_at_a_time(w, h, g, &albedo, &normal, &depth, &s);
            assert_eq!(recorded, slow(&first), "{w}x{h} {n}x{m}: recording changed the image");
            // The first light's planes with the second's ratios written over them
            // (`fill_ratio_row`, what a frame that applies a record fills), and the normal and
            // depth planes spoiled.
            let mut planes = planes_of(&first);
            for (y, row) in planes.chunks_mut(layout.row_len()).enumerate() {
                let r = y * w as usize..(y + 1) * w as usize;
                layout.fill_ratio_row(row, &second[r.clone()], &albedo[r]);
                row[..4 * layout.pw].fill(f32::NAN);
            }
            let applied = run(&second, &planes, Masks::Apply(&record));
            for (i, (a, b)) in applied.iter().zip(&slow(&second)).enumerate() {
                assert_eq!(a, b, "{w}x{h} {n}x{m} pixel {i}");
            }
        }
    }

    #[test]
    fn uniform_surface_averages_its_window() {
        let (w, h) = (8u32, 8u32);
        let n = (w * h) as usize;
        let gathered: Vec<Vec3> = (0..n).map(|i| Vec3::splat((i % 4) as f32)).collect();
        let albedo = vec![Vec3::ONE; n];
        let normal = vec![Vec3::Z; n];
        let depth = vec![1.0; n];
        let out = filter(w, h, &gathered, &albedo, &normal, &depth, &DiscontinuitySettings::new(4, 1));
        // An interior pixel's 4×1 window holds each of the values 0..4 once: mean 1.5.
        assert!((out[2 * 8 + 3].x - 1.5).abs() < 1e-6);
    }
}
