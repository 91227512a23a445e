//! Our traversal against Intel Embree's on the same triangles and the same rays, in one process:
//! single rays (`rtcIntersect1` / `rtcOccluded1`), 8-wide (`rtcIntersect8` / `rtcOccluded8`)
//! and 16-wide packets (`rtcIntersect16` / `rtcOccluded16`), closest hit and occlusion, on 1 and
//! 2 threads, for the ray sets of `benches/rays/mod.rs` (the traverse bench's), plus the BVH
//! build time of each.
//!
//! Benchmark-only. It needs Debian's Embree 3 (`apt-get install libembree-dev`) and is compiled
//! only with the `embree` feature:
//!
//! ```sh
//! cargo bench --bench embree --features embree > benches/results/DATE-embree.md
//! ```
//!
//! Timing: every measurement traces the whole set once; the methods of one (scene, set, thread
//! count) run interleaved, `MIRAGE_EMBREE_REPS` rounds (default 5), and the table gives the
//! median Mrays/s of each and the ratio ours / Embree. Embree gets its best settings for the
//! set: the coherent context flag for camera rays and rays to one point, incoherent otherwise,
//! build quality medium (its default), and rays in world space exactly as ours (same origins,
//! directions and intervals, t_near 0). Hit/miss agreement with our single rays is counted per
//! set (the closest hit's triangle too).
//!
//! `MIRAGE_BENCH_SCENES=igea,sphere-field-1M` limits the scenes, `MIRAGE_BENCH_SETS=primary,bounce`
//! the ray sets, `MIRAGE_BENCH_QUERIES=occluded` the queries and `MIRAGE_BENCH_THREADS=1` the
//! thread counts (for quick measurements while working on one kernel).

#![allow(unsafe_code, missing_docs)]

use std::ffi::{c_char, c_int, c_uint, c_void};
use std::time::{Duration, Instant};

use mirage::accel::Accel;
use mirage::scene::{CameraSettings, Mesh, Scene};
use mirage::simd::{LaneRay, Lanes, RayPacket};
use rayon::prelude::*;

mod rays;
use rays::{RaySet, ray_sets, scenes};

/// Embree 3's C API: the handful of calls and structures this bench uses, declared from
/// `embree3/rtcore*.h` (3.13, `RTC_MAX_INSTANCE_LEVEL_COUNT` 1, no `RTC_MIN_WIDTH`).
mod ffi {
    use super::*;

    pub type Device = *mut c_void;
    pub type SceneHandle = *mut c_void;
    pub type Geometry = *mut c_void;

    pub const GEOMETRY_TYPE_TRIANGLE: c_uint = 0;
    pub const BUFFER_TYPE_INDEX: c_uint = 0;
    pub const BUFFER_TYPE_VERTEX: c_uint = 1;
    pub const FORMAT_UINT3: c_uint = 0x5003;
    pub const FORMAT_FLOAT3: c_uint = 0x9003;
    pub const BUILD_QUALITY_MEDIUM: c_uint = 1;
    pub const CONTEXT_FLAG_INCOHERENT: c_uint = 0;
    pub const CONTEXT_FLAG_COHERENT: c_uint = 1;
    pub const INVALID_ID: c_uint = u32::MAX;
    pub const PROPERTY_NATIVE_RAY8: c_int = 33;
    pub const PROPERTY_NATIVE_RAY16: c_int = 34;

    #[repr(C)]
    pub struct Context {
        pub flags: c_uint,
        pub filter: *const c_void,
        pub inst_id: [c_uint; 1],
    }

    #[repr(C, align(16))]
    #[derive(Clone, Copy)]
    pub struct Ray {
        pub org: [f32; 3],
        pub tnear: f32,
        pub dir: [f32; 3],
        pub time: f32,
        pub tfar: f32,
        pub mask: c_uint,
        pub id: c_uint,
        pub flags: c_uint,
    }

    #[repr(C, align(16))]
    #[derive(Clone, Copy)]
    pub struct Hit {
        pub ng: [f32; 3],
        pub u: f32,
        pub v: f32,
        pub prim_id: c_uint,
        pub geom_id: c_uint,
        pub inst_id: [c_uint; 1],
    }

    #[repr(C)]
    #[derive(Clone, Copy)]
    pub struct RayHit {
        pub ray: Ray,
        pub hit: Hit,
    }

    /// `RTCRayN` for N = 4, 8, 16 (`RTCRay8` is 32-byte, `RTCRay16` 64-byte aligned; 64 serves
    /// all, and every field block is a multiple of 64 bytes, so the layout is the header's).
    #[repr(C, align(64))]
    #[derive(Clone, Copy)]
    pub struct RayN<const N: usize> {
        pub org_x: [f32; N],
        pub org_y: [f32; N],
        pub org_z: [f32; N],
        pub tnear: [f32; N],
        pub dir_x: [f32; N],
        pub dir_y: [f32; N],
        pub dir_z: [f32; N],
        pub time: [f32; N],
        pub tfar: [f32; N],
        pub mask: [c_uint; N],
        pub id: [c_uint; N],
        pub flags: [c_uint; N],
    }

    #[repr(C, align(64))]
    #[derive(Clone, Copy)]
    pub struct HitN<const N: usize> {
        pub ng_x: [f32; N],
        pub ng_y: [f32; N],
        pub ng_z: [f32; N],
        pub u: [f32; N],
        pub v: [f32; N],
        pub prim_id: [c_uint; N],
        pub geom_id: [c_uint; N],
        pub inst_id: [c_uint; N],
    }

    #[repr(C)]
    #[derive(Clone, Copy)]
    pub struct RayHitN<const N: usize> {
        pub ray: RayN<N>,
        pub hit: HitN<N>,
    }

    #[link(name = "embree3")]
    unsafe extern "C" {
        pub fn rtcNewDevice(config: *const c_char) -> Device;
        pub fn rtcReleaseDevice(device: Device);
        pub fn rtcGetDeviceError(device: Device) -> c_int;
        pub fn rtcGetDeviceProperty(device: Device, prop: c_int) -> isize;
        pub fn rtcNewScene(device: Device) -> SceneHandle;
        pub fn rtcReleaseScene(scene: SceneHandle);
        pub fn rtcSetSceneBuildQuality(scene: SceneHandle, quality: c_uint);
        pub fn rtcNewGeometry(device: Device, kind: c_uint) -> Geometry;
        pub fn rtcSetNewGeometryBuffer(
            geometry: Geometry,
            kind: c_uint,
            slot: c_uint,
            format: c_uint,
            stride: usize,
            count: usize,
        ) -> *mut c_void;
        pub fn rtcCommitGeometry(geometry: Geometry);
        pub fn rtcAttachGeometry(scene: SceneHandle, geometry: Geometry) -> c_uint;
        pub fn rtcReleaseGeometry(geometry: Geometry);
        pub fn rtcCommitScene(scene: SceneHandle);
        pub fn rtcIntersect1(scene: SceneHandle, context: *mut Context, rayhit: *mut RayHit);
        pub fn rtcOccluded1(scene: SceneHandle, context: *mut Context, ray: *mut Ray);
        pub fn rtcIntersect8(valid: *const c_int, scene: SceneHandle, context: *mut Context, rayhit: *mut RayHitN<8>);
        pub fn rtcOccluded8(valid: *const c_int, scene: SceneHandle, context: *mut Context, ray: *mut RayN<8>);
        pub fn rtcIntersect16(valid: *const c_int, scene: SceneHandle, context: *mut Context, rayhit: *mut RayHitN<16>);
        pub fn rtcOccluded16(valid: *const c_int, scene: SceneHandle, context: *mut Context, ray: *mut RayN<16>);
    }
}

/// An Embree device and committed scene over a mesh's triangles (geometry 0, primID = our
/// triangle index).
struct Embree {
    device: ffi::Device,
    scene: ffi::SceneHandle,
}

// SAFETY: Embree's traversal calls on a committed scene are thread-safe (its documentation:
// rtcIntersect*/rtcOccluded* may be called from any number of threads at once); the handles
// are only read after construction.
unsafe impl Sync for Embree {}
unsafe impl Send for Embree {}

impl Embree {
    /// Builds the scene on `threads` threads; returns it with the commit time.
    fn new(mesh: &Mesh, threads: usize) -> (Embree, Duration) {
        let config = std::ffi::CString::new(format!("threads={threads}")).unwrap();
        // SAFETY: plain calls of the C API with valid arguments; the buffers Embree returns
        // have room for exactly the items written (count × stride as requested), and every
        // handle is checked before use.
        unsafe {
            let device = ffi::rtcNewDevice(config.as_ptr());
            assert!(!device.is_null(), "rtcNewDevice failed");
            let scene = ffi::rtcNewScene(device);
            ffi::rtcSetSceneBuildQuality(scene, ffi::BUILD_QUALITY_MEDIUM);
            let geometry = ffi::rtcNewGeometry(device, ffi::GEOMETRY_TYPE_TRIANGLE);
            let n_v = mesh.positions.len();
            let vertices =
                ffi::rtcSetNewGeometryBuffer(geometry, ffi::BUFFER_TYPE_VERTEX, 0, ffi::FORMAT_FLOAT3, 12, n_v);
            let vertices = std::slice::from_raw_parts_mut(vertices.cast::<[f32; 3]>(), n_v);
            for (v, p) in vertices.iter_mut().zip(&mesh.positions) {
                *v = p.to_array();
            }
            let n_t = mesh.triangles.len();
            let indices = ffi::rtcSetNewGeometryBuffer(geometry, ffi::BUFFER_TYPE_INDEX, 0, ffi::FORMAT_UINT3, 12, n_t);
            std::slice::from_raw_parts_mut(indices.cast::<[u32; 3]>(), n_t).copy_from_slice(&mesh.triangles);
            ffi::rtcCommitGeometry(geometry);
            ffi::rtcAttachGeometry(scene, geometry);
            ffi::rtcReleaseGeometry(geometry);
            let t0 = Instant::now();
            ffi::rtcCommitScene(scene);
            let built = t0.elapsed();
            assert_eq!(ffi::rtcGetDeviceError(device), 0, "Embree reported an error building the scene");
            (Embree { device, scene }, built)
        }
    }

    fn property(&self, prop: c_int) -> isize {
        // SAFETY: a valid device and a property id from the header.
        unsafe { ffi::rtcGetDeviceProperty(self.device, prop) }
    }

    fn context(coherent: bool) -> ffi::Context {
        ffi::Context {
            flags: if coherent { ffi::CONTEXT_FLAG_COHERENT } else { ffi::CONTEXT_FLAG_INCOHERENT },
            filter: std::ptr::null(),
            inst_id: [ffi::INVALID_ID],
        }
    }

    fn ray(r: &LaneRay) -> ffi::Ray {
        ffi::Ray {
            org: r.origin.to_array(),
            tnear: 0.0,
            dir: r.dir.to_array(),
            time: 0.0,
            tfar: r.t_max,
            mask: u32::MAX,
            id: 0,
            flags: 0,
        }
    }

    /// The closest hit's triangle.
    fn intersect1(&self, r: &LaneRay, coherent: bool) -> Option<u32> {
        let hit = ffi::Hit { ng: [0.0; 3], u: 0.0, v: 0.0, prim_id: 0, geom_id: ffi::INVALID_ID, inst_id: [0] };
        let mut rh = ffi::RayHit { ray: Self::ray(r), hit };
        let mut ctx = Self::context(coherent);
        // SAFETY: a committed scene, an initialised context and ray/hit.
        unsafe { ffi::rtcIntersect1(self.scene, &mut ctx, &mut rh) };
        (rh.hit.geom_id != ffi::INVALID_ID).then_some(rh.hit.prim_id)
    }

    fn occluded1(&self, r: &LaneRay, coherent: bool) -> bool {
        let mut ray = Self::ray(r);
        let mut ctx = Self::context(coherent);
        // SAFETY: as in intersect1.
        unsafe { ffi::rtcOccluded1(self.scene, &mut ctx, &mut ray) };
        ray.tfar == f32::NEG_INFINITY
    }

    fn packet<const N: usize>(lanes: &[Option<LaneRay>]) -> ([c_int; N], ffi::RayN<N>) {
        let mut valid = [0; N];
        let mut p = ffi::RayN::<N> {
            org_x: [0.0; N],
            org_y: [0.0; N],
            org_z: [0.0; N],
            tnear: [0.0; N],
            dir_x: [1.0; N],
            dir_y: [0.0; N],
            dir_z: [0.0; N],
            time: [0.0; N],
            tfar: [0.0; N],
            mask: [u32::MAX; N],
            id: [0; N],
            flags: [0; N],
        };
        for (i, r) in lanes.iter().enumerate() {
            if let Some(r) = r {
                valid[i] = -1;
                [p.org_x[i], p.org_y[i], p.org_z[i]] = r.origin.to_array();
                [p.dir_x[i], p.dir_y[i], p.dir_z[i]] = r.dir.to_array();
                p.tfar[i] = r.t_max;
            }
        }
        (valid, p)
    }

    /// Lanes with a hit.
    fn intersect_n<const N: usize>(&self, lanes: &[Option<LaneRay>], coherent: bool) -> u32 {
        let (valid, ray) = Self::packet::<N>(lanes);
        let hit = ffi::HitN::<N> {
            ng_x: [0.0; N],
            ng_y: [0.0; N],
            ng_z: [0.0; N],
            u: [0.0; N],
            v: [0.0; N],
            prim_id: [0; N],
            geom_id: [ffi::INVALID_ID; N],
            inst_id: [ffi::INVALID_ID; N],
        };
        let mut rh = ffi::RayHitN { ray, hit };
        let mut ctx = Self::context(coherent);
        // SAFETY: a committed scene, an aligned packet of the width of the call.
        unsafe {
            match N {
                8 => ffi::rtcIntersect8(valid.as_ptr(), self.scene, &mut ctx, (&raw mut rh).cast()),
                16 => ffi::rtcIntersect16(valid.as_ptr(), self.scene, &mut ctx, (&raw mut rh).cast()),
                _ => unreachable!(),
            }
        }
        (0..N).filter(|&i| valid[i] != 0 && rh.hit.geom_id[i] != ffi::INVALID_ID).fold(0, |m, i| m | 1 << i)
    }

    /// Lanes blocked.
    fn occluded_n<const N: usize>(&self, lanes: &[Option<LaneRay>], coherent: bool) -> u32 {
        let (valid, mut ray) = Self::packet::<N>(lanes);
        let mut ctx = Self::context(coherent);
        // SAFETY: as in intersect_n.
        unsafe {
            match N {
                8 => ffi::rtcOccluded8(valid.as_ptr(), self.scene, &mut ctx, (&raw mut ray).cast()),
                16 => ffi::rtcOccluded16(valid.as_ptr(), self.scene, &mut ctx, (&raw mut ray).cast()),
                _ => unreachable!(),
            }
        }
        (0..N).filter(|&i| valid[i] != 0 && ray.tfar[i] == f32::NEG_INFINITY).fold(0, |m, i| m | 1 << i)
    }
}

impl Drop for Embree {
    fn drop(&mut self) {
        // SAFETY: handles made by new, released once.
        unsafe {
            ffi::rtcReleaseScene(self.scene);
            ffi::rtcReleaseDevice(self.device);
        }
    }
}

/// A timed method: traces the whole set once and returns the number of hits (or blocked rays).
type Method<'a> = (String, Box<dyn Fn() -> usize + Sync + 'a>);

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 { v[n / 2] } else { 0.5 * (v[n / 2 - 1] + v[n / 2]) }
}

fn ours_packets<'a, F: Lanes>(
    accel: &'a Accel,
    packets: &'a [RayPacket<F>],
    occlusion: bool,
) -> impl Fn() -> usize + Sync + 'a {
    move || {
        packets
            .par_chunks(256)
            .map(|c| {
                c.iter()
                    .map(|p| if occlusion { accel.occluded_packet(p) } else { accel.intersect_packet(p).hit })
                    .map(|m| m.count_ones() as usize)
                    .sum::<usize>()
            })
            .sum()
    }
}

/// The methods of one query kind on one set, ours then Embree's at each width.
fn methods<'a>(accel: &'a Accel, embree: &'a Embree, set: &'a Prepared, occlusion: bool) -> Vec<Method<'a>> {
    let coherent = set.coherent;
    let single = &set.single;
    let mut out: Vec<Method<'a>> = Vec::new();
    out.push((
        "ours 1".into(),
        Box::new(move || {
            single
                .par_chunks(2048)
                .map(|c| {
                    c.iter()
                        .filter(|r| {
                            if occlusion {
                                accel.occluded(r.origin, r.dir, r.t_max)
                            } else {
                                accel.intersect(r.origin, r.dir, r.t_max).is_some()
                            }
                        })
                        .count()
                })
                .sum()
        }),
    ));
    out.push((
        "Embree 1".into(),
        Box::new(move || {
            single
                .par_chunks(2048)
                .map(|c| {
                    c.iter()
                        .filter(|r| {
                            if occlusion {
                                embree.occluded1(r, coherent)
                            } else {
                                embree.intersect1(r, coherent).is_some()
                            }
                        })
                        .count()
                })
                .sum()
        }),
    ));
    out.push(("ours 8".into(), Box::new(ours_packets(accel, &set.p8, occlusion))));
    let l8 = &set.l8;
    out.push((
        "Embree 8".into(),
        Box::new(move || {
            l8.par_chunks(256)
                .map(|c| {
                    c.iter()
                        .map(|p| {
                            let m = if occlusion {
                                embree.occluded_n::<8>(p, coherent)
                            } else {
                                embree.intersect_n::<8>(p, coherent)
                            };
                            m.count_ones() as usize
                        })
                        .sum::<usize>()
                })
                .sum()
        }),
    ));
    out.push(("ours 16".into(), Box::new(ours_packets(accel, &set.p16, occlusion))));
    let l16 = &set.l16;
    out.push((
        "Embree 16".into(),
        Box::new(move || {
            l16.par_chunks(128)
                .map(|c| {
                    c.iter()
                        .map(|p| {
                            let m = if occlusion {
                                embree.occluded_n::<16>(p, coherent)
                            } else {
                                embree.intersect_n::<16>(p, coherent)
                            };
                            m.count_ones() as usize
                        })
                        .sum::<usize>()
                })
                .sum()
        }),
    ));
    out
}

/// A ray set in every form the methods trace.
struct Prepared {
    coherent: bool,
    single: Vec<LaneRay>,
    p8: Vec<RayPacket<mirage::simd::F8>>,
    p16: Vec<RayPacket<mirage::simd::F16>>,
    l8: Vec<Vec<Option<LaneRay>>>,
    l16: Vec<Vec<Option<LaneRay>>>,
}

impl Prepared {
    fn new(set: &RaySet) -> Prepared {
        Prepared {
            coherent: set.coherent,
            single: set.single(),
            p8: set.packets8(),
            p16: set.packets16(),
            l8: set.lanes(8),
            l16: set.lanes(16),
        }
    }
}

/// Rays on which our single-ray answer differs from Embree's: (closest hit/miss, closest
/// triangle among rays both hit, occlusion).
fn agreement(accel: &Accel, embree: &Embree, set: &Prepared) -> (usize, usize, usize) {
    set.single
        .par_iter()
        .map(|r| {
            let ours = accel.intersect(r.origin, r.dir, r.t_max).map(|h| h.tri);
            let theirs = embree.intersect1(r, set.coherent);
            let hit_miss = (ours.is_some() != theirs.is_some()) as usize;
            let tri = matches!((ours, theirs), (Some(a), Some(b)) if a != b) as usize;
            let occ = (accel.occluded(r.origin, r.dir, r.t_max) != embree.occluded1(r, set.coherent)) as usize;
            (hit_miss, tri, occ)
        })
        .reduce(|| (0, 0, 0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2))
}

/// Whether the comma-separated list in environment variable `var` (absent: everything) has `x`.
fn wanted(var: &str, x: &str) -> bool {
    std::env::var(var).ok().is_none_or(|w| w.split(',').any(|y| y == x))
}

fn main() {
    // `cargo bench` passes `--bench`; nothing else is taken.
    let reps: usize = std::env::var("MIRAGE_EMBREE_REPS").ok().and_then(|s| s.parse().ok()).unwrap_or(5);
    println!("# Traversal: mirage against Embree 3 on the same rays\n");
    println!("Median of {reps} interleaved rounds, Mrays/s; ratio = ours / Embree at the same width.\n");
    let mut build_rows = Vec::new();
    for (name, desc) in scenes() {
        let scene = Scene::from_desc(desc, &CameraSettings::default()).unwrap();
        let mesh = &scene.mesh;
        // Build times, interleaved, on 2 threads (both builders are parallel).
        let mut ours_build = Vec::new();
        let mut embree_build = Vec::new();
        let mut keep = None;
        for _ in 0..3 {
            let t0 = Instant::now();
            let accel = Accel::build(mesh);
            ours_build.push(t0.elapsed().as_secs_f64());
            let (e, t) = Embree::new(mesh, 2);
            embree_build.push(t.as_secs_f64());
            keep = Some((accel, e));
        }
        let (accel, embree) = keep.unwrap();
        let (ob, eb) = (median(ours_build), median(embree_build));
        eprintln!(
            "{name}: {} triangles; build ours {ob:.3} s, Embree {eb:.3} s; Embree native ray8 {} ray16 {}",
            mesh.len(),
            embree.property(ffi::PROPERTY_NATIVE_RAY8),
            embree.property(ffi::PROPERTY_NATIVE_RAY16)
        );
        build_rows.push(format!("| {name} | {} | {ob:.3} | {eb:.3} | {:.2}× |", mesh.len(), ob / eb));
        println!("## {name} ({} triangles)\n", mesh.len());
        println!(
            "| rays | query | threads | ours 1 | Embree 1 | ratio | ours 8 | Embree 8 | ratio | ours 16 | Embree 16 | ratio |"
        );
        println!("|---|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|");
        let mut notes = Vec::new();
        for set in ray_sets(&scene, &accel).into_iter().filter(|s| wanted("MIRAGE_BENCH_SETS", s.name)) {
            let prepared = Prepared::new(&set);
            let rays = prepared.single.len() as f64;
            let (hm, tri, occ) = agreement(&accel, &embree, &prepared);
            notes.push(format!(
                "- {}: {} rays; differ from Embree in closest hit/miss {hm}, closest triangle {tri}, occlusion {occ}",
                set.name,
                prepared.single.len()
            ));
            for threads in [1usize, 2].into_iter().filter(|t| wanted("MIRAGE_BENCH_THREADS", &t.to_string())) {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                for (query, occlusion) in
                    [("closest", false), ("occluded", true)].into_iter().filter(|q| wanted("MIRAGE_BENCH_QUERIES", q.0))
                {
                    let ms = methods(&accel, &embree, &prepared, occlusion);
                    let mut times = vec![Vec::new(); ms.len()];
                    let mut counts = vec![0; ms.len()];
                    pool.install(|| {
                        for (i, (_, f)) in ms.iter().enumerate() {
                            counts[i] = f(); // warm-up
                        }
                        for _ in 0..reps {
                            for (i, (_, f)) in ms.iter().enumerate() {
                                let t0 = Instant::now();
                                std::hint::black_box(f());
                                times[i].push(t0.elapsed().as_secs_f64());
                            }
                        }
                    });
                    let mrays: Vec<f64> = times.into_iter().map(|t| rays / median(t) * 1e-6).collect();
                    let cell =
                        |i: usize| format!("{:.2} | {:.2} | {:.2}×", mrays[i], mrays[i + 1], mrays[i] / mrays[i + 1]);
                    println!("| {} | {query} | {threads} | {} | {} | {} |", set.name, cell(0), cell(2), cell(4));
                    let names: Vec<&str> = ms.iter().map(|m| m.0.as_str()).collect();
                    // Ours at every width must agree (packets equal single rays), and Embree's.
                    if [2, 4].iter().any(|&i| counts[i] != counts[0]) || [3, 5].iter().any(|&i| counts[i] != counts[1])
                    {
                        notes.push(format!(
                            "- {} {query}: hit counts differ between methods: {:?}",
                            set.name,
                            names.iter().zip(&counts).collect::<Vec<_>>()
                        ));
                    }
                }
            }
        }
        println!("\n{}\n", notes.join("\n"));
    }
    println!("## BVH build (2 threads, median of 3, seconds)\n");
    println!("| scene | triangles | ours | Embree | ratio |\n|---|--:|--:|--:|--:|");
    println!("{}", build_rows.join("\n"));
}
