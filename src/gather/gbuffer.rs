//! The G-buffer: per pixel, the first non-specular surface seen through a jittered position in
//! the pixel (following mirror and glass bounces), the emission seen on the way, and the AOVs
//! the discontinuity buffer needs (albedo, normal, depth).

use glam::{Vec2, Vec3, vec2};
use rayon::prelude::*;

use crate::accel::Accel;
use crate::sampling::{IndependentSampler, Sampler};
use crate::scene::{Camera, Scene};
use crate::stats::RayStats;
use crate::vpl::transfer::{Receiver, primary_receiver};

/// Stream tag of G-buffer jitter.
const TAG_GBUFFER: u64 = 0x4742_5546;

/// One frame's G-buffer.
#[derive(Clone, Debug, Default)]
pub struct GBuffer {
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// Receiver of each pixel (None: the ray left the scene or ended on specular surfaces).
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

/// Traces one ray per pixel through a position jittered by `(seed, pass)` (pixel centres when
/// `jitter` is false), following up to `max_specular` specular bounces.
pub fn trace(
    scene: &Scene,
    accel: &Accel,
    camera: &Camera,
    seed: u64,
    jitter: bool,
    max_specular: u32,
    stats: &mut RayStats,
) -> GBuffer {
    let (w, h) = (camera.width, camera.height);
    type Row = Vec<(Option<Receiver>, Vec3, f32)>;
    let rows: Vec<(Row, RayStats)> = (0..h)
        .into_par_iter()
        .map(|y| {
            let mut st = RayStats::default();
            let row = (0..w)
                .map(|x| {
                    let pixel = y as u64 * w as u64 + x as u64;
                    let mut s = IndependentSampler::for_stream(seed, TAG_GBUFFER, pixel);
                    let off: Vec2 = if jitter { s.next_2d() } else { vec2(0.5, 0.5) };
                    let lens = s.next_2d();
                    let raster = vec2(x as f32, y as f32) + off;
                    let (r, e) = primary_receiver(
                        scene,
                        accel,
                        camera,
                        raster,
                        lens,
                        &mut || s.next_1d(),
                        max_specular,
                        &mut st,
                    );
                    let depth = r.map(|r| (r.sp.p - camera.position).length()).unwrap_or(0.0);
                    (r, e, depth)
                })
                .collect();
            (row, st)
        })
        .collect();
    let n = (w * h) as usize;
    let mut g = GBuffer {
        width: w,
        height: h,
        receivers: Vec::with_capacity(n),
        emitted: Vec::with_capacity(n),
        albedo: Vec::with_capacity(n),
        normal: Vec::with_capacity(n),
        depth: Vec::with_capacity(n),
    };
    for (row, st) in rows {
        *stats += st;
        for (r, e, d) in row {
            g.albedo.push(r.map(|r| r.bsdf.albedo() * r.beta).unwrap_or(Vec3::ZERO));
            g.normal.push(r.map(|r| r.bsdf.frame.n).unwrap_or(Vec3::ZERO));
            g.depth.push(d);
            g.receivers.push(r);
            g.emitted.push(e);
        }
    }
    g
}
