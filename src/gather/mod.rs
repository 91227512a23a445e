//! ⑥ The gather: G-buffer from primary rays, interleaved VPL subsets, shadow rays, and the
//! clamped contribution `L·f·G·V` (papers/002 §7.2; docs/design.md §4). Reads a [`crate::vpl::VplSet`];
//! never changes it.

pub mod compensate;
pub mod gbuffer;
pub mod interleave;
pub mod shade;

use std::time::{Duration, Instant};

use glam::Vec3;
use rayon::prelude::*;

pub use gbuffer::{GBuffer, JitterSequence};
pub use interleave::{Interleave, split_strong};
pub use shade::{GatherEnergy, gather, power_ratio};

use crate::accel::Accel;
use crate::filter::PlaneLayout;
use crate::scene::{Camera, Scene};
use crate::stats::RayStats;
use crate::vpl::VplSet;
use crate::vpl::kernel::Prepared;
use crate::vpl::transfer::Receiver;
use gbuffer::{BandSlices, PreparedBand, PrimaryRays};
use shade::Gatherer;

/// What [`trace_and_gather`] needs besides the scene and the VPLs.
#[derive(Clone, Copy, Debug)]
pub struct OnePass<'a> {
    /// The camera.
    pub camera: &'a Camera,
    /// Seed of the jitter and of specular bounces.
    pub seed: u64,
    /// Jitter camera rays inside their pixels.
    pub jitter: bool,
    /// Take the jittered positions from this sequence (else from the seed's stream).
    pub sequence: Option<JitterSequence>,
    /// Specular bounces followed by camera rays.
    pub max_specular: u32,
    /// Ray grouping.
    pub tracing: Tracing,
    /// The interleave pattern of the VPLs.
    pub interleave: &'a Interleave,
    /// Bound on G.
    pub g_max: f32,
    /// VPLs closer than this to a receiver are skipped.
    pub min_distance: f32,
    /// Add the clamp compensation ([`compensate`]) when `g_max` is finite.
    pub compensate: bool,
    /// Also return each pixel's compensation term alone ([`Gathered::compensation`]).
    pub compensation_aov: bool,
    /// Compensate one pixel in this many ([`crate::frame::FrameSettings::compensation_stride`]).
    pub compensation_stride: u32,
    /// Fill the discontinuity buffer's planes of this layout too (see [`Gathered::planes`]).
    pub planes: Option<PlaneLayout>,
    /// Trace the G-buffer, or reuse one held from an earlier pass ([`GBufferUse`]).
    pub gbuffer: GBufferUse,
    /// When the pass reuses a held G-buffer, fill only the planes of the light's ratio to the
    /// albedo ([`PlaneLayout::fill_ratio_row`]): the discontinuity buffer will take its windows'
    /// neighbours from a record ([`crate::filter::Masks::Apply`]) and read no other plane.
    pub ratio_planes_on_reuse: bool,
    /// Sum the luminance each VPL brings to the image ([`Gathered::vpl_power`]): a few per cent
    /// of the gather's time (an add per contribution), so only when asked.
    pub vpl_power: bool,
}

/// How a frame gets its camera rays: whether it traces, holds or reuses its G-buffer, and
/// where in their pixels jittered rays start.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CameraRays {
    /// Trace, hold or reuse.
    pub gbuffer: GBufferUse,
    /// Jittered positions from this sequence (else from the frame seed's stream).
    pub sequence: Option<JitterSequence>,
}

/// Where a pass's G-buffer comes from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum GBufferUse {
    /// Camera rays traced for this pass.
    #[default]
    Trace,
    /// Camera rays traced for this pass, and the receivers kept ([`Held`]) for later passes
    /// through the same camera.
    TraceAndHold,
    /// The G-buffer and receivers held by an earlier `TraceAndHold` pass, when they were traced
    /// through the same camera with the same settings (its seed, hence its jitter, is kept);
    /// otherwise as `TraceAndHold`. A still camera's frames differ only in their VPLs then.
    Reuse,
}

/// Receivers kept from a [`GBufferUse::TraceAndHold`] pass, prepared for the gather, for later
/// passes to gather from instead of tracing camera rays again. They belong to the G-buffer
/// arrays lent with them ([`Lent::gbuffer`]); a pass that traces anew without holding forgets
/// them, since it overwrites those arrays.
#[derive(Debug, Default)]
pub struct Held {
    /// What they were traced for; None when nothing is held.
    key: Option<HeldKey>,
    /// Per pixel.
    prepared: Vec<Option<Prepared>>,
    /// Per band of rows: the receivers the gather reads besides their prepared form (pixel in
    /// the band, receiver).
    kept: Vec<Vec<(u32, Receiver)>>,
}

/// The camera and settings a held G-buffer was traced with.
#[derive(Clone, Debug, PartialEq)]
struct HeldKey {
    camera: Camera,
    jitter: bool,
    max_specular: u32,
    tracing: Tracing,
    /// Every receiver was kept (else only those [`shade::Gatherer::keeps_receiver`] keeps for a
    /// gather with the eight-VPL kernel).
    all_receivers: bool,
}

impl Held {
    /// Whether a pass with `key` over `pixels` pixels in `bands` bands can gather from these.
    fn serves(&self, key: &HeldKey, pixels: usize, bands: usize) -> bool {
        self.key.as_ref().is_some_and(|k| {
            let HeldKey { camera, jitter, max_specular, tracing, all_receivers } = k;
            (camera, jitter, max_specular, tracing) == (&key.camera, &key.jitter, &key.max_specular, &key.tracing)
                && (*all_receivers || !key.all_receivers)
        }) && self.prepared.len() == pixels
            && self.kept.len() == bands
    }

    /// Whether a G-buffer is held.
    pub fn is_held(&self) -> bool {
        self.key.is_some()
    }
}

/// Allocations lent to [`trace_and_gather`] by an earlier pass (a frame loop's previous frame),
/// each used when its size matches and replaced by a fresh one otherwise. They need no
/// clearing: the pass writes every entry it reads (tested with garbage in them), except the
/// G-buffer and the receivers that [`GBufferUse::Reuse`] gathers from.
#[derive(Debug, Default)]
pub struct Lent {
    /// The G-buffer ([`GBuffer::reusing`]).
    pub gbuffer: GBuffer,
    /// The light ([`Gathered::light`]).
    pub light: Vec<Vec3>,
    /// The filter's planes ([`Gathered::planes`]).
    pub planes: Vec<f32>,
    /// The receivers of the G-buffer above, when an earlier pass held them.
    pub held: Held,
}

/// The result of [`trace_and_gather`].
#[derive(Debug)]
pub struct Gathered {
    /// The G-buffer, without receivers (see [`GBuffer::receivers`]).
    pub gbuffer: GBuffer,
    /// VPL-transported light per pixel, as [`gather`] gives it.
    pub light: Vec<Vec3>,
    /// Energy kept and removed by the clamp.
    pub energy: GatherEnergy,
    /// Per VPL, the luminance it brought to the image ([`power_ratio`]), when
    /// [`OnePass::vpl_power`] asked; empty otherwise.
    pub vpl_power: Vec<f32>,
    /// The pass's wall time split between camera rays (G-buffer) and gathering, in proportion to
    /// the thread time each took.
    pub primary_time: Duration,
    /// See `primary_time`.
    pub shadow_time: Duration,
    /// The part of `shadow_time` the clamp compensation took (split the same way).
    pub compensation_time: Duration,
    /// Each pixel's clamp-compensation term (included in `light`), when
    /// [`OnePass::compensation_aov`] asked; empty otherwise.
    pub compensation: Vec<Vec3>,
    /// The discontinuity buffer's planes ([`crate::filter::filter_planes`]), filled band by
    /// band while the band's G-buffer and light are in cache, when [`OnePass::planes`] asks.
    pub planes: Option<Vec<f32>>,
    /// The receivers held for later passes (see [`GBufferUse`]).
    pub held: Held,
    /// The pass gathered from a held G-buffer instead of tracing camera rays.
    pub reused: bool,
}

/// [`gbuffer::trace`] and [`gather`] in one pass: each band of rows is traced and then gathered
/// at once, while its receivers are in cache, instead of writing the whole frame's receivers
/// (~150 bytes a pixel, 40 MB at 512²) to memory and reading them back. The same image and
/// the same G-buffer arrays, bit for bit (tested). `lent` lends its allocations (see [`Lent`]).
/// With [`GBufferUse::Reuse`] and receivers held for this camera, no camera ray is traced: the
/// bands are gathered from the held receivers (≈ 90 bytes a pixel read back from memory, which
/// costs far less than tracing them).
pub fn trace_and_gather(
    scene: &Scene,
    accel: &Accel,
    vpls: &VplSet,
    pass: &OnePass<'_>,
    lent: Lent,
    stats: &mut RayStats,
) -> Gathered {
    let start = Instant::now();
    let OnePass {
        camera,
        seed,
        jitter,
        sequence,
        max_specular,
        tracing,
        interleave,
        g_max,
        min_distance,
        compensate,
        compensation_aov,
        compensation_stride,
        planes: layout,
        gbuffer: use_gbuffer,
        ratio_planes_on_reuse,
        vpl_power: keep_power,
    } = *pass;
    let rays = PrimaryRays { scene, accel, camera, seed, jitter, sequence, max_specular, tracing };
    let gatherer = Gatherer::new(scene, accel, vpls, interleave, g_max, min_distance, tracing)
        .compensating(compensate.then_some(seed), compensation_stride);
    let (w, h) = (camera.width, camera.height);
    let Lent { gbuffer, light, planes, mut held } = lent;
    let band_len = (rays.band_rows() * w) as usize;
    let n = (w * h) as usize;
    let n_bands = (h as usize).div_ceil(rays.band_rows() as usize);
    let key = HeldKey {
        camera: camera.clone(),
        jitter,
        max_specular,
        tracing,
        all_receivers: gatherer.keeps_all_receivers(),
    };
    let same_arrays = gbuffer.width == w && gbuffer.height == h && gbuffer.emitted.len() == n;
    let reuse = use_gbuffer == GBufferUse::Reuse && same_arrays && held.serves(&key, n, n_bands);
    let hold = !reuse && use_gbuffer != GBufferUse::Trace;
    if !reuse {
        // The G-buffer arrays are about to be traced anew: what was held no longer matches them.
        held.key = None;
    }
    if hold {
        if held.prepared.len() != n {
            held.prepared = fresh(n, None);
        }
        held.kept.resize_with(n_bands, Vec::new);
    }
    let mut g = GBuffer::reusing(gbuffer, w, h, false);
    // Fresh buffers are zeroed in parallel: a serial zeroing of the planes' 7.6 MB at 512² held
    // up both cores. Lent ones are not cleared at all (zeroing both each frame cost ~1 ms).
    let mut light = if light.len() == n { light } else { fresh(n, Vec3::ZERO) };
    let mut planes: Option<Vec<f32>> = layout.map(|l| {
        let len = l.row_len() * h as usize;
        if planes.len() == len { planes } else { fresh(len, 0.0) }
    });
    let mut compensation = if compensation_aov { fresh(n, Vec3::ZERO) } else { Vec::new() };
    let mut compensation_bands: Vec<Option<&mut [Vec3]>> = if compensation_aov {
        compensation.chunks_mut(band_len.max(1)).map(Some).collect()
    } else {
        (0..n_bands).map(|_| None).collect()
    };
    let mut plane_bands: Vec<Option<&mut [f32]>> = match (&mut planes, layout) {
        (Some(p), Some(l)) => p.chunks_mut(l.row_len() * rays.band_rows() as usize).map(Some).collect(),
        _ => (0..n_bands).map(|_| None).collect(),
    };
    // Each band's share of the held receivers, when the pass holds or reuses them.
    type HeldBand<'h> = Option<(&'h mut [Option<Prepared>], &'h mut Vec<(u32, Receiver)>)>;
    let mut held_bands: Vec<HeldBand<'_>> = if reuse || hold {
        held.prepared.chunks_mut(band_len.max(1)).zip(held.kept.iter_mut()).map(Some).collect()
    } else {
        (0..n_bands).map(|_| None).collect()
    };
    let keep_receiver = gatherer.keeps_receiver();
    // Per band: ray statistics, energy, thread time in each half, and the compensation's part
    // of the second.
    // Per band also the luminance each VPL brought to it.
    type Band = (RayStats, GatherEnergy, Duration, Duration, Duration, Vec<f32>);
    let bands: Vec<Band> = light
        .par_chunks_mut(band_len.max(1))
        .zip(g.emitted.par_chunks_mut(band_len.max(1)))
        .zip(g.albedo.par_chunks_mut(band_len.max(1)))
        .zip(g.normal.par_chunks_mut(band_len.max(1)))
        .zip(g.depth.par_chunks_mut(band_len.max(1)))
        .zip(plane_bands.par_iter_mut())
        .zip(held_bands.par_iter_mut())
        .zip(compensation_bands.par_iter_mut())
        .enumerate()
        .map_init(
            <(Vec<_>, Vec<_>)>::default,
            |(receivers, prepared),
             (band, (((((((light, emitted), albedo), normal), depth), plane_band), held_band), comp_band))| {
                let t = Instant::now();
                receivers.resize(light.len(), None);
                let y0 = band as u32 * rays.band_rows();
                macro_rules! slices {
                    ($slots:expr) => {
                        BandSlices {
                            receivers: &mut receivers[..],
                            prepared: Some(PreparedBand { slots: $slots, keep_receiver }),
                            emitted: &mut emitted[..],
                            albedo: &mut albedo[..],
                            normal: &mut normal[..],
                            depth: &mut depth[..],
                        }
                    };
                }
                let (mut st, prepared): (RayStats, &[Option<Prepared>]) = match held_band.take() {
                    // The held band: its receivers as the band's buffer holds traced ones (every
                    // one when all are kept, else those the gather reads).
                    Some((slots, kept)) if reuse => {
                        if key.all_receivers {
                            receivers.fill(None);
                        }
                        for &(i, r) in kept.iter() {
                            receivers[i as usize] = Some(r);
                        }
                        (RayStats::default(), slots)
                    }
                    Some((slots, kept)) => {
                        let st = rays.band(y0, slices!(&mut *slots));
                        kept.clear();
                        for (i, pt) in slots.iter().enumerate() {
                            if let (Some(pt), Some(r)) = (pt, &receivers[i])
                                && keep_receiver(pt)
                            {
                                kept.push((i as u32, *r));
                            }
                        }
                        (st, slots)
                    }
                    None => {
                        prepared.resize(light.len(), None);
                        (rays.band(y0, slices!(&mut prepared[..])), &prepared[..])
                    }
                };
                let t_primary = t.elapsed();
                let (mut energy, mut t_comp) = (GatherEnergy::default(), Duration::ZERO);
                let mut power = if keep_power { vec![0.0; vpls.len()] } else { Vec::new() };
                let row = w as usize;
                let mut comp_rows = comp_band.as_deref_mut().map(|c| c.chunks_mut(row));
                let rows = receivers.chunks(row).zip(prepared.chunks(row)).zip(light.chunks_mut(row));
                for (k, ((receivers, prepared), light)) in rows.enumerate() {
                    let comp = comp_rows.as_mut().and_then(|c| c.next());
                    let r = gatherer.row(y0 + k as u32, receivers, Some(prepared), light, comp, &mut power);
                    st += r.stats;
                    energy += r.energy;
                    t_comp += r.compensation_time;
                }
                if let (Some(l), Some(p)) = (layout, plane_band) {
                    for (k, plane_row) in p.chunks_mut(l.row_len()).enumerate() {
                        let r = k * row..(k + 1) * row;
                        if reuse && ratio_planes_on_reuse {
                            l.fill_ratio_row(plane_row, &light[r.clone()], &albedo[r]);
                        } else {
                            l.fill_row(plane_row, &light[r.clone()], &albedo[r.clone()], &normal[r.clone()], &depth[r]);
                        }
                    }
                }
                (st, energy, t_primary, t.elapsed() - t_primary, t_comp, power)
            },
        )
        .collect();
    drop(plane_bands);
    drop(compensation_bands);
    drop(held_bands);
    if hold {
        held.key = Some(key);
    }
    let (mut energy, mut primary, mut shadow, mut comp) =
        (GatherEnergy::default(), Duration::ZERO, Duration::ZERO, Duration::ZERO);
    let mut vpl_power = if keep_power { vec![0.0; vpls.len()] } else { Vec::new() };
    for (st, e, p, s, c, band_power) in bands {
        for (a, b) in vpl_power.iter_mut().zip(band_power) {
            *a += b;
        }
        *stats += st;
        energy += e;
        primary += p;
        shadow += s;
        comp += c;
    }
    let wall = start.elapsed();
    let thread = (primary + shadow).as_secs_f64().max(1e-12);
    let primary_time = wall.mul_f64(primary.as_secs_f64() / thread);
    let compensation_time = wall.mul_f64(comp.as_secs_f64() / thread);
    Gathered {
        gbuffer: g,
        light,
        energy,
        vpl_power,
        primary_time,
        shadow_time: wall - primary_time,
        compensation_time,
        compensation,
        planes,
        held,
        reused: reuse,
    }
}

/// `n` copies of `v`, written in parallel (a serial fill of a frame-sized buffer, and its page
/// faults, held up both cores).
pub(crate) fn fresh<T: Copy + Send + Sync>(n: usize, v: T) -> Vec<T> {
    (0..n).into_par_iter().map(|_| v).collect()
}

/// How the G-buffer and the gather trace their rays (all give the same image: packet lanes equal
/// single rays, `tests/packet_vs_scalar.rs`; the choice is speed only, `benches/gather.rs` and
/// benches/results/*-gather.md).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Tracing {
    /// No packets: camera rays one at a time, shadow rays traced one at a time (set up eight
    /// at a time, as in the default).
    Single,
    /// 8-wide packets for the primary rays of 4×2 pixel blocks, single shadow rays set up eight
    /// at a time: the fastest on every scene measured (shadow packets towards one VPL are
    /// 1.1× slower on the Cornell box and on the 1M-triangle sphere field;
    /// benches/results/2026-12-01-gather.md).
    #[default]
    PrimaryPackets,
    /// Primary packets, and shadow rays in 8-wide packets grouped by shared end point — the
    /// pixels of a row that gather the same VPL subset (every n-th pixel) towards one VPL of it.
    SharedEnd,
    /// Primary packets, and shadow rays in 8-wide packets grouped by shared origin — one pixel
    /// towards the VPLs of its subset (packets are only full with ≥ 8 VPLs per subset, i.e.
    /// m ≥ 8·n·m).
    SharedOrigin,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::filter::{DiscontinuitySettings, Masks, discontinuity_filter, filter_planes};
    use crate::load::builtin;
    use crate::scene::CameraSettings;
    use crate::vpl::VplSampler;
    use crate::vpl::set::{Vpl, VplLobe};
    use crate::vpl::sir::Sir;
    use crate::vpl::transfer::g_bound;

    /// The one-pass frame equals the G-buffer traced whole and then gathered, bit for bit, on an
    /// image whose size is not a multiple of the packet blocks or of the interleave tile: on the
    /// Cornell box (diffuse VPLs: the 8-VPL kernel), on the glass sphere (receivers behind
    /// specular bounces), with a spot VPL added (every pixel through the general kernels), and
    /// with a minimum VPL distance. The light is also checked against the shared-origin
    /// grouping, whose sums take another route (`RowSums`) in the same per-pixel order. One
    /// case views the box from outside, so bands mix pixels with and without receivers (a
    /// band's buffers hold the previous band's).
    #[test]
    fn one_pass_equals_trace_then_gather() {
        for (name, desc, spot, min_distance, outside) in [
            ("cornell", builtin::cornell(), false, 0.0, false),
            ("cornell", builtin::cornell(), false, 0.5, false),
            ("glass-sphere", builtin::glass_sphere(), false, 0.0, false),
            ("cornell", builtin::cornell(), true, 0.0, false),
            ("cornell", builtin::cornell(), false, 0.0, true),
        ] {
            let scene = Scene::from_desc(desc, &CameraSettings::default()).unwrap();
            let accel = Accel::build(&scene.mesh);
            let mut camera = scene.camera.clone();
            (camera.width, camera.height) = (45, 29);
            if outside {
                // Backed away along its view: the open box with background around it, at a size
                // whose bands rayon hands out several to a task (so a task's band buffers are
                // reused).
                let (eye, f) = (camera.position - camera.forward * scene.bounds.diagonal(), camera.forward);
                camera = Camera::look_at(eye, eye + f, Vec3::Y, 0.8, 160, 120);
            }
            let (mut vpls, _) = Sir::new(4).sample(&scene, &accel, &camera, 96, 3);
            if spot {
                let axis = Vec3::new(0.0, -1.0, 0.0);
                let lobe = Some(VplLobe::Spot { axis, cos_inner: 0.9, cos_outer: 0.7 });
                let position = scene.bounds.center() + Vec3::Y * 0.2 * scene.bounds.diagonal();
                let radiance = Vec3::splat(vpls.radiance.iter().map(|r| r.max_element()).sum::<f32>());
                vpls.push(Vpl {
                    position,
                    normal: Vec3::ZERO,
                    radiance,
                    lobe,
                    count: 1,
                    flags: 0,
                    length: 1,
                    group: 0,
                });
                assert!(!vpls.all_diffuse());
            }
            let inter = Interleave::new(&vpls, 4, 3);
            let g_max = g_bound(&scene, 300.0);
            let filter = DiscontinuitySettings::new(4, 3);
            let layout = PlaneLayout::new(camera.width, &filter);
            let reference = {
                let mut st = RayStats::default();
                let tracing = Tracing::SharedOrigin;
                let gbuf = gbuffer::trace(&scene, &accel, &camera, 5, true, 4, tracing, GBuffer::default(), &mut st);
                gather(&scene, &accel, &gbuf, &vpls, &inter, g_max, min_distance, tracing, &mut st).0
            };
            for tracing in [Tracing::Single, Tracing::PrimaryPackets, Tracing::SharedEnd, Tracing::SharedOrigin] {
                let case = format!("{name} spot {spot} min {min_distance} outside {outside} {tracing:?}");
                let mut st_a = RayStats::default();
                let gbuf = gbuffer::trace(&scene, &accel, &camera, 5, true, 4, tracing, GBuffer::default(), &mut st_a);
                let (light, energy) =
                    gather(&scene, &accel, &gbuf, &vpls, &inter, g_max, min_distance, tracing, &mut st_a);
                assert!(light == reference, "{case}: grouping changed the light");
                let pass = OnePass {
                    camera: &camera,
                    seed: 5,
                    jitter: true,
                    sequence: None,
                    max_specular: 4,
                    tracing,
                    interleave: &inter,
                    g_max,
                    min_distance,
                    compensate: false,
                    compensation_aov: false,
                    compensation_stride: 1,
                    planes: Some(layout),
                    gbuffer: GBufferUse::Trace,
                    ratio_planes_on_reuse: false,
                    vpl_power: false,
                };
                // Three times: fresh arrays, the first pass's arrays reused, and reused arrays
                // filled with garbage (NaN, infinities, huge and negative values): nothing a pass
                // reads may come from what its lent buffers held.
                let mut spare = (Lent::default(), Vec::new());
                for pass_no in 0..3 {
                    if pass_no == 2 {
                        let junk = |k: usize| [f32::NAN, f32::INFINITY, -3.0e38, -1.0, 7.5][k % 5];
                        let (lent, filtered) = &mut spare;
                        let g = &mut lent.gbuffer;
                        for (k, v) in lent.light.iter_mut().chain(filtered.iter_mut()).enumerate() {
                            *v = Vec3::splat(junk(k));
                        }
                        for (k, v) in g.emitted.iter_mut().chain(&mut g.albedo).chain(&mut g.normal).enumerate() {
                            *v = Vec3::splat(junk(k + 1));
                        }
                        for (k, v) in lent.planes.iter_mut().chain(&mut g.depth).enumerate() {
                            *v = junk(k + 2);
                        }
                    }
                    let mut st = RayStats::default();
                    let (lent, reuse_filtered) = spare;
                    let one = trace_and_gather(&scene, &accel, &vpls, &pass, lent, &mut st);
                    assert!(one.light.iter().any(|l| *l != Vec3::ZERO), "{case}: no light gathered");
                    assert!(one.light == light, "{case}");
                    assert_eq!(one.gbuffer.emitted, gbuf.emitted);
                    assert_eq!(one.gbuffer.albedo, gbuf.albedo);
                    assert_eq!(one.gbuffer.normal, gbuf.normal);
                    assert_eq!(one.gbuffer.depth, gbuf.depth);
                    assert!(one.gbuffer.receivers.is_empty());
                    // Energy sums are f64 sums of the same rows grouped differently (by band).
                    let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b.abs();
                    assert!(close(one.energy.kept, energy.kept) && close(one.energy.removed, energy.removed));
                    assert_eq!(st, st_a);
                    // The planes filled band by band filter to the standalone filter's image.
                    let (gb, h) = (&one.gbuffer, camera.height);
                    let planes = one.planes.expect("planes asked for");
                    let banded = filter_planes(
                        &layout,
                        &planes,
                        h,
                        &one.light,
                        &gb.albedo,
                        &gb.normal,
                        &gb.depth,
                        &filter,
                        None,
                        reuse_filtered,
                        Masks::Test,
                    );
                    let whole =
                        discontinuity_filter(camera.width, h, &light, &gbuf.albedo, &gbuf.normal, &gbuf.depth, &filter);
                    assert!(banded == whole, "{case} pass {pass_no}: filtered images differ");
                    // The emission added as the filter writes each pixel is the same sum as added after.
                    let (albedo, normal, depth) = (&gb.albedo, &gb.normal, &gb.depth);
                    let plus = filter_planes(
                        &layout,
                        &planes,
                        h,
                        &one.light,
                        albedo,
                        normal,
                        depth,
                        &filter,
                        Some(&gb.emitted),
                        Vec::new(),
                        Masks::Test,
                    );
                    let after: Vec<Vec3> = banded.iter().zip(&gb.emitted).map(|(f, e)| *f + *e).collect();
                    assert!(plus == after, "{case}: emission added in the filter differs");
                    spare = (Lent { gbuffer: one.gbuffer, light: one.light, planes, held: one.held }, banded);
                }
            }
        }
    }

    /// A held G-buffer gathers another VPL set as the pass that traced it would have: a pass
    /// with [`GBufferUse::Reuse`] (another seed, so traced afresh its jitter would differ, and
    /// lent light and planes full of garbage) gives the light, planes, energy and G-buffer of a
    /// traced pass with the holding pass's seed, bit for bit, and traces no camera ray. It falls
    /// back to tracing when the camera moved, when a traced pass overwrote the arrays since,
    /// and when the new VPLs need receivers the holding pass did not keep (a spot VPL: all of
    /// them). On the Cornell box, and on the glass sphere (receivers behind specular bounces,
    /// chosen by the seed's stream).
    #[test]
    fn held_gbuffer_gathers_as_the_pass_that_traced_it() {
        for (name, desc) in [("cornell", builtin::cornell()), ("glass-sphere", builtin::glass_sphere())] {
            let scene = Scene::from_desc(desc, &CameraSettings::default()).unwrap();
            let accel = Accel::build(&scene.mesh);
            let mut camera = scene.camera.clone();
            (camera.width, camera.height) = (45, 29);
            let moved = {
                let e = camera.position + Vec3::X * 0.01 * scene.bounds.diagonal();
                Camera::look_at(e, e + camera.forward, Vec3::Y, camera.fov_y_radians, 45, 29)
            };
            let sample = |seed: u64| Sir::new(4).sample(&scene, &accel, &camera, 96, seed).0;
            let (vpls_a, vpls_b) = (sample(3), sample(9));
            let mut vpls_spot = vpls_b.clone();
            let axis = Vec3::new(0.0, -1.0, 0.0);
            vpls_spot.push(Vpl {
                position: scene.bounds.center(),
                normal: Vec3::ZERO,
                radiance: Vec3::splat(0.5),
                lobe: Some(VplLobe::Spot { axis, cos_inner: 0.9, cos_outer: 0.7 }),
                count: 1,
                flags: 0,
                length: 1,
                group: 0,
            });
            let g_max = g_bound(&scene, 300.0);
            let filter = DiscontinuitySettings::new(4, 3);
            let layout = PlaneLayout::new(camera.width, &filter);
            let run = |camera: &Camera, vpls: &VplSet, seed: u64, gbuffer: GBufferUse, lent: Lent| {
                let inter = Interleave::new(vpls, 4, 3);
                let pass = OnePass {
                    camera,
                    seed,
                    jitter: true,
                    sequence: None,
                    max_specular: 4,
                    tracing: Tracing::PrimaryPackets,
                    interleave: &inter,
                    g_max,
                    min_distance: 0.0,
                    compensate: false,
                    compensation_aov: false,
                    compensation_stride: 1,
                    planes: Some(layout),
                    gbuffer,
                    ratio_planes_on_reuse: false,
                    vpl_power: false,
                };
                let mut st = RayStats::default();
                let out = trace_and_gather(&scene, &accel, vpls, &pass, lent, &mut st);
                (out, st)
            };
            let traced =
                |camera: &Camera, vpls: &VplSet, seed: u64| run(camera, vpls, seed, GBufferUse::Trace, Lent::default());
            let same = |case: &str, (a, sa): &(Gathered, RayStats), (b, sb): &(Gathered, RayStats)| {
                assert!(a.light == b.light, "{name} {case}: light");
                // (Planes hold NaN depths and unread entries: compared through the filter.)
                let filtered = |g: &Gathered| {
                    let gb = &g.gbuffer;
                    let planes = g.planes.as_ref().unwrap();
                    let (a, n, d) = (&gb.albedo, &gb.normal, &gb.depth);
                    filter_planes(&layout, planes, gb.height, &g.light, a, n, d, &filter, None, Vec::new(), Masks::Test)
                };
                assert!(filtered(a) == filtered(b), "{name} {case}: filtered image");
                assert_eq!((a.energy.kept, a.energy.removed), (b.energy.kept, b.energy.removed), "{name} {case}");
                let (ga, gb) = (&a.gbuffer, &b.gbuffer);
                assert!(ga.emitted == gb.emitted && ga.albedo == gb.albedo, "{name} {case}: G-buffer");
                assert!(ga.normal == gb.normal && ga.depth == gb.depth, "{name} {case}: G-buffer");
                assert_eq!(sa.shadow, sb.shadow, "{name} {case}: shadow rays");
            };
            let garbage = |mut lent: Lent| {
                lent.light.iter_mut().for_each(|v| *v = Vec3::splat(f32::NAN));
                lent.planes.iter_mut().for_each(|v| *v = f32::INFINITY);
                lent
            };
            let lend =
                |g: Gathered| Lent { gbuffer: g.gbuffer, light: g.light, planes: g.planes.unwrap(), held: g.held };

            // Hold at seed 5, then reuse at seeds 11 and 12 with other VPLs.
            let hold = run(&camera, &vpls_a, 5, GBufferUse::TraceAndHold, Lent::default());
            same("holding pass", &hold, &traced(&camera, &vpls_a, 5));
            assert!(!hold.0.reused && hold.0.held.is_held());
            let reused = run(&camera, &vpls_b, 11, GBufferUse::Reuse, garbage(lend(hold.0)));
            assert!(reused.0.reused, "{name}: the held G-buffer was not reused");
            assert_eq!(reused.1.closest, 0, "{name}: a reusing pass traced camera rays");
            same("reused", &reused, &traced(&camera, &vpls_b, 5));
            assert_ne!(traced(&camera, &vpls_b, 11).0.light, reused.0.light, "{name}: the seed changes a traced pass");
            let again = run(&camera, &vpls_a, 12, GBufferUse::Reuse, garbage(lend(reused.0)));
            assert!(again.0.reused);
            same("reused twice", &again, &traced(&camera, &vpls_a, 5));

            // A moved camera traces (and holds) anew.
            let after_move = run(&moved, &vpls_b, 13, GBufferUse::Reuse, lend(again.0));
            assert!(!after_move.0.reused && after_move.0.held.is_held());
            same("moved", &after_move, &traced(&moved, &vpls_b, 13));

            // A plain traced pass forgets what was held (it overwrote the arrays).
            let plain = run(&moved, &vpls_a, 14, GBufferUse::Trace, lend(after_move.0));
            assert!(!plain.0.held.is_held());
            let after_plain = run(&moved, &vpls_b, 15, GBufferUse::Reuse, lend(plain.0));
            assert!(!after_plain.0.reused);
            same("after a plain pass", &after_plain, &traced(&moved, &vpls_b, 15));

            // Diffuse VPLs keep only non-Lambertian receivers; a spot VPL needs them all.
            let spot = run(&moved, &vpls_spot, 16, GBufferUse::Reuse, lend(after_plain.0));
            assert!(!spot.0.reused, "{name}: reused without the receivers a spot VPL needs");
            same("spot after diffuse", &spot, &traced(&moved, &vpls_spot, 16));
            // Held with all receivers, it serves both.
            let diffuse = run(&moved, &vpls_a, 17, GBufferUse::Reuse, lend(spot.0));
            assert!(diffuse.0.reused);
            same("diffuse after spot", &diffuse, &traced(&moved, &vpls_a, 16));
            let spot_again = run(&moved, &vpls_spot, 18, GBufferUse::Reuse, garbage(lend(diffuse.0)));
            assert!(spot_again.0.reused);
            same("spot reused", &spot_again, &traced(&moved, &vpls_spot, 16));
        }
    }
}
