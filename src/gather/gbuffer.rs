//! The G-buffer: per pixel, the first non-specular surface seen through a jittered position in
//! the pixel (following mirror and glass bounces), the emission seen on the way, and the AOVs
//! the discontinuity buffer needs (albedo, normal, depth).

use glam::{Vec2, Vec3, vec2};
use rayon::prelude::*;

use super::Tracing;
use crate::accel::rays::{CameraLanes, block_size};
use crate::accel::{Accel, Hit, PacketView};
use crate::sampling::{IndependentSampler, Sampler};
use crate::scene::{Camera, Scene};
use crate::simd::{LaneRay, Lanes, RayPacket};
use crate::stats::RayStats;
use crate::vpl::kernel::Prepared;
use crate::vpl::transfer::{Receiver, receiver_with};

/// Stream tag of G-buffer jitter.
const TAG_GBUFFER: u64 = 0x4742_5546;
/// Stream tag of the per-pixel rotations of [`JitterSequence`].
const TAG_JITTER_ROTATION: u64 = 0x0052_3252_4f54;

/// Sub-pixel positions for the successive jittered G-buffers of a still camera, drawn per pixel
/// from one low-discrepancy sequence instead of independently: the R2 sequence (Roberts 2018:
/// point n is n·(1/g, 1/g²) mod 1, g the plastic number) shifted by a random rotation of the
/// pixel's own (Cranley & Patterson 1976). Each position is uniform in the pixel, as an
/// independent jitter is, so the running mean converges to the same image; but the first n
/// positions of a pixel cover it evenly, so the mean of a pixel an edge crosses settles sooner.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct JitterSequence {
    /// Seed of the per-pixel rotations (a run's seed: they stay fixed while frames accumulate).
    pub seed: u64,
    /// Position in the sequence (the jittered G-buffers traced before this one).
    pub index: u32,
}

impl JitterSequence {
    /// The sub-pixel offset of `pixel` (in [0, 1)²). In 32-bit fixed point: exact for every
    /// index.
    pub fn offset(&self, pixel: u64) -> Vec2 {
        // 2³² / g and 2³² / g², rounded.
        const STEP: [u32; 2] = [3_242_174_889, 2_447_445_414];
        let h = crate::sampling::rng::hash_words(&[self.seed, TAG_JITTER_ROTATION, pixel]);
        let rotation = [h as u32, (h >> 32) as u32];
        let unit =
            |k: usize| (rotation[k].wrapping_add(STEP[k].wrapping_mul(self.index)) >> 8) as f32 / (1u32 << 24) as f32;
        vec2(unit(0), unit(1))
    }
}

/// A pixel's G-buffer stream ([`IndependentSampler::for_stream`] of the seed, the G-buffer tag
/// and the pixel), or what is needed to make it when first asked.
enum PixelStream {
    Made(IndependentSampler),
    /// Not made yet; `skip` numbers are drawn from it first.
    Deferred {
        pixel: u64,
        skip: u32,
    },
}

impl PixelStream {
    /// The stream's next number.
    #[inline]
    fn next_1d(&mut self, seed: u64) -> f32 {
        if let PixelStream::Deferred { pixel, skip } = *self {
            let mut s = IndependentSampler::for_stream(seed, TAG_GBUFFER, pixel);
            for _ in 0..skip {
                s.next_1d();
            }
            *self = PixelStream::Made(s);
        }
        match self {
            PixelStream::Made(s) => s.next_1d(),
            PixelStream::Deferred { .. } => unreachable!("made above"),
        }
    }
}

/// One frame's G-buffer.
#[derive(Clone, Debug, Default)]
pub struct GBuffer {
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// Receiver of each pixel (None: the ray left the scene or ended on specular surfaces).
    /// Empty when the frame was traced and gathered in one pass ([`super::trace_and_gather`]),
    /// which keeps each band's receivers only while it gathers them.
    pub receivers: Vec<Option<Receiver>>,
    /// Emission seen directly (and through specular bounces).
    pub emitted: Vec<Vec3>,
    /// Diffuse albedo at the receiver (zero when none).
    pub albedo: Vec<Vec3>,
    /// Shading normal at the receiver (facing the camera).
    pub normal: Vec<Vec3>,
    /// Distance from the camera to the receiver along the first ray (0 when none).
    pub depth: Vec<f32>,
}

/// The camera rays of a frame and how they are traced: what [`trace`] and the one-pass
/// [`super::trace_and_gather`] share.
#[derive(Clone, Copy)]
pub(crate) struct PrimaryRays<'a> {
    pub scene: &'a Scene,
    pub accel: &'a Accel,
    pub camera: &'a Camera,
    pub seed: u64,
    pub jitter: bool,
    /// Jittered positions from a sequence instead of the seed's stream.
    pub sequence: Option<JitterSequence>,
    pub max_specular: u32,
    pub tracing: Tracing,
}

/// A band's receivers prepared for the gather in the G-buffer's own loop, where the receiver
/// is at hand (preparing them in the gather read each one back through memory, and copying the
/// whole receiver into the band's buffer stalled on store forwarding). A receiver is then
/// written to [`BandSlices::receivers`] only when `keep_receiver` says the gather needs more
/// than its prepared form ([`super::shade::Gatherer::keeps_receiver`]).
pub(crate) struct PreparedBand<'b> {
    pub slots: &'b mut [Option<Prepared>],
    pub keep_receiver: fn(&Prepared) -> bool,
}

/// The G-buffer rows of one band, as slices of the frame's arrays (receivers may be a band-local
/// buffer).
pub(crate) struct BandSlices<'b> {
    pub receivers: &'b mut [Option<Receiver>],
    /// The receivers prepared for the gather, when the band is gathered at once.
    pub prepared: Option<PreparedBand<'b>>,
    pub emitted: &'b mut [Vec3],
    pub albedo: &'b mut [Vec3],
    pub normal: &'b mut [Vec3],
    pub depth: &'b mut [f32],
}

impl PrimaryRays<'_> {
    /// Rows per band: the height of a packet's pixel block (1 for single rays).
    pub(crate) fn band_rows(&self) -> u32 {
        self.block().1
    }

    /// The pixel block traced together: a camera packet's ([`CameraLanes`]: 4×4 or 4×2), or one
    /// pixel for single rays.
    fn block(&self) -> (u32, u32) {
        if self.tracing == Tracing::Single { (1, 1) } else { block_size::<CameraLanes>() }
    }

    /// Traces the rows `y0..` of one band (`band_rows` rows, or fewer at the bottom) into `out`.
    pub(crate) fn band(&self, y0: u32, mut out: BandSlices<'_>) -> RayStats {
        let Self { scene, accel, camera, seed, jitter, sequence, max_specular, tracing } = *self;
        let w = camera.width;
        let (bw, bh) = self.block();
        let y_end = (y0 + bh).min(camera.height);
        // The raster position and lens sample of a pixel's camera ray, and the stream that
        // continues its specular bounces. A pinhole camera's ray whose position does not come
        // from the stream needs none of its numbers: the stream is then made only if a bounce
        // asks for one (most pixels never do), skipping the numbers the set-up would have drawn.
        let deferred = camera.lens_radius <= 0.0 && (!jitter || sequence.is_some());
        let setup = |x: u32, y: u32| {
            let pixel = y as u64 * w as u64 + x as u64;
            let corner = vec2(x as f32, y as f32);
            if deferred {
                // The pixel centre or the sequence's position; the stream will skip the set-up's
                // draws (the offset drawn and discarded for a sequence, and the lens sample).
                let off = sequence.filter(|_| jitter).map_or(vec2(0.5, 0.5), |q| q.offset(pixel));
                let skip = if jitter { 4 } else { 2 };
                return (PixelStream::Deferred { pixel, skip }, corner + off, Vec2::splat(0.5));
            }
            let mut s = IndependentSampler::for_stream(seed, TAG_GBUFFER, pixel);
            // (A sequence's position replaces the stream's, which is drawn all the same: the lens
            // and bounce samples stay those of the stream.)
            let off = match (jitter, sequence) {
                (false, _) => vec2(0.5, 0.5),
                (true, None) => s.next_2d(),
                (true, Some(q)) => {
                    s.next_2d();
                    q.offset(pixel)
                }
            };
            let lens = s.next_2d();
            (PixelStream::Made(s), corner + off, lens)
        };
        let mut st = RayStats::default();
        let mut primary = 0;
        // One block of camera rays: pixel, sampler, ray, first hit. Plain arrays and one call
        // site of `receiver_from_hit`: passed through closures, these values went through
        // memory and every pixel stalled on reading them back.
        const L: usize = CameraLanes::LANES;
        let mut samplers: [Option<PixelStream>; L] = Default::default();
        let (mut raster, mut lens) = ([Vec2::ZERO; L], [Vec2::ZERO; L]);
        let mut pixels = [(0u32, 0u32); L];
        let mut hits: [Option<Hit>; L] = [None; L];
        let mut rays = [crate::scene::Ray { origin: camera.position, dir: camera.forward }; L];
        for x0 in (0..w).step_by(bw as usize) {
            let mut n = 0;
            for i in 0..(bw * bh) {
                let (x, y) = (x0 + i % bw, y0 + i / bw);
                if x < w && y < y_end {
                    let (s, r, l) = setup(x, y);
                    (samplers[n], raster[n], lens[n], pixels[n]) = (Some(s), r, l, (x, y));
                    n += 1;
                }
            }
            // Eight at a time (the pinhole's normalisation in eight lanes; L is 8 or 16).
            let chunks = raster.as_chunks::<8>().0.iter().zip(lens.as_chunks::<8>().0);
            for (k, (r8, l8)) in chunks.enumerate().take(n.div_ceil(8)) {
                let m = (n - 8 * k).min(8);
                rays[8 * k..8 * k + m].copy_from_slice(&camera.generate_rays8(r8, l8, m)[..m]);
            }
            primary += n as u64;
            if tracing == Tracing::Single {
                for (hit, ray) in hits.iter_mut().zip(&rays).take(n) {
                    *hit = accel.intersect(ray.origin, ray.dir, f32::INFINITY);
                }
            } else {
                let packet = RayPacket::<CameraLanes>::from_fn(|i| {
                    (i < n).then(|| LaneRay::new(rays[i].origin, rays[i].dir, f32::INFINITY))
                });
                // The block's rays leave the eye through its raster rectangle: their frustum
                // from the camera, not from the lanes.
                let (x1, y1) = ((x0 + bw) as f32, (y0 + bh) as f32);
                let view = camera.raster_slopes((x0 as f32, x1), (y0 as f32, y1)).map(|slopes| PacketView {
                    apex: camera.position,
                    basis: [camera.right, camera.up, camera.forward],
                    slopes,
                });
                accel.intersect_packet_in(&packet, view.as_ref()).write_lanes(&mut hits[..n]);
            }
            for k in 0..n {
                // (Moving the sampler out, rather than borrowing it in place, measured 0.5 ms
                // faster over a 512² G-buffer.)
                let Some(mut s) = samplers[k].take() else { continue };
                let (x, y) = pixels[k];
                let i = ((y - y0) * w + x) as usize;
                let u = &mut || s.next_1d(seed);
                receiver_with(scene, accel, rays[k], hits[k], u, max_specular, &mut st, |r, e| {
                    out.albedo[i] = r.map_or(Vec3::ZERO, |r| r.bsdf.albedo() * r.beta);
                    out.normal[i] = r.map_or(Vec3::ZERO, |r| r.bsdf.frame.n);
                    out.depth[i] = r.map_or(0.0, |r| (r.sp.p - camera.position).length());
                    match &mut out.prepared {
                        Some(PreparedBand { slots, keep_receiver }) => {
                            let pt = r.map(|r| Prepared::new(scene, r));
                            // (A pixel without a receiver writes its None: the band's buffer holds
                            // the previous band's receivers.)
                            if pt.as_ref().is_none_or(*keep_receiver) {
                                out.receivers[i] = r.copied();
                            }
                            slots[i] = pt;
                        }
                        None => out.receivers[i] = r.copied(),
                    }
                    out.emitted[i] = e;
                });
            }
        }
        st.closest += primary;
        st
    }
}

impl GBuffer {
    /// The allocation of `reuse` when it is `w`×`h` (every pixel is written by the tracer, so it
    /// needs no clearing), or fresh arrays; receivers are sized only `with_receivers`.
    pub(crate) fn reusing(reuse: GBuffer, w: u32, h: u32, with_receivers: bool) -> GBuffer {
        let n = (w * h) as usize;
        // Filled in parallel (a serial fill and its page faults cost as much as tracing).
        let mut g = if reuse.width == w && reuse.height == h && reuse.emitted.len() == n {
            reuse
        } else {
            GBuffer {
                width: w,
                height: h,
                receivers: Vec::new(),
                emitted: super::fresh(n, Vec3::ZERO),
                albedo: super::fresh(n, Vec3::ZERO),
                normal: super::fresh(n, Vec3::ZERO),
                depth: super::fresh(n, 0.0),
            }
        };
        if !with_receivers {
            g.receivers = Vec::new();
        } else if g.receivers.len() != n {
            g.receivers = super::fresh(n, None);
        }
        g
    }
}

/// Traces one ray per pixel through a position jittered by `(seed, pass)` (pixel centres when
/// `jitter` is false), following up to `max_specular` specular bounces. With packet `tracing`
/// the camera rays of 4×4 (AVX-512) or 4×2 pixel blocks are traced as one packet (bounces stay single
/// rays); the result is the same G-buffer. `reuse` (the previous frame's G-buffer, or
/// `GBuffer::default()`) lends its allocation when the size matches: a 512² frame's receivers are
/// ~40 MB, and allocating them afresh each frame costs page faults on every frame.
pub fn trace(
    scene: &Scene,
    accel: &Accel,
    camera: &Camera,
    seed: u64,
    jitter: bool,
    max_specular: u32,
    tracing: Tracing,
    reuse: GBuffer,
    stats: &mut RayStats,
) -> GBuffer {
    let rays = PrimaryRays { scene, accel, camera, seed, jitter, sequence: None, max_specular, tracing };
    let (w, h) = (camera.width, camera.height);
    let mut g = GBuffer::reusing(reuse, w, h, true);
    let band_len = (rays.band_rows() * w) as usize;
    let band_stats: Vec<RayStats> = g
        .receivers
        .par_chunks_mut(band_len)
        .zip(g.emitted.par_chunks_mut(band_len))
        .zip(g.albedo.par_chunks_mut(band_len))
        .zip(g.normal.par_chunks_mut(band_len))
        .zip(g.depth.par_chunks_mut(band_len))
        .enumerate()
        .map(|(band, ((((receivers, emitted), albedo), normal), depth))| {
            rays.band(
                band as u32 * rays.band_rows(),
                BandSlices { receivers, prepared: None, emitted, albedo, normal, depth },
            )
        })
        .collect();
    for st in band_stats {
        *stats += st;
    }
    g
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deferred stream gives the numbers the made one gives after the set-up's draws.
    #[test]
    fn deferred_streams_continue_where_the_setup_left_off() {
        for (pixel, skip) in [(0u64, 2u32), (7, 4), (123_456, 2)] {
            let mut made = IndependentSampler::for_stream(9, TAG_GBUFFER, pixel);
            for _ in 0..skip {
                made.next_1d();
            }
            let mut deferred = PixelStream::Deferred { pixel, skip };
            for _ in 0..5 {
                assert_eq!(deferred.next_1d(9).to_bits(), made.next_1d().to_bits());
            }
        }
    }

    /// Every position lies in the pixel, and a pixel's first 64 cover it evenly: each of its
    /// 4×4 cells holds 4 ± 2 of them, for 2000 pixels and two seeds (64 independent positions
    /// would leave some pixel's cell with 0 or with 8 or more: P(a cell outside 2…6) ≈ 0.2),
    /// and the pixels' rotations differ.
    #[test]
    fn a_pixels_jitter_sequence_covers_it_evenly() {
        for seed in [0, 77] {
            let mut firsts = Vec::new();
            for pixel in 0..2000u64 {
                let mut cells = [0u32; 16];
                for index in 0..64 {
                    let o = JitterSequence { seed, index }.offset(pixel);
                    assert!((0.0..1.0).contains(&o.x) && (0.0..1.0).contains(&o.y), "{o}");
                    cells[(o.x * 4.0) as usize + 4 * (o.y * 4.0) as usize] += 1;
                }
                assert!(cells.iter().all(|c| (2..=6).contains(c)), "pixel {pixel}: {cells:?}");
                firsts.push(JitterSequence { seed, index: 0 }.offset(pixel));
            }
            let mean = firsts.iter().sum::<Vec2>() / firsts.len() as f32;
            assert!((mean - Vec2::splat(0.5)).abs().max_element() < 0.03, "rotations {mean}");
        }
    }
}
