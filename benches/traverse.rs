//! Traversal throughput (Mrays/s): obvhs's own single-ray CWBVH traversal against our
//! single-ray, 4-wide and 8-wide packet traversals, closest hit and occlusion, on 1 and 2
//! threads, for the gather's ray kinds at 1024×1024:
//!
//! - `primary`: camera rays, 8×8 tiles, packets of 2×2 / 4×2 pixel blocks;
//! - `shadow-point`: from every primary hit to one point near the light;
//! - `vpl64-block`: interleaved shadow rays to 64 VPLs (pixel (i, j) of each 8×8 tile to VPL
//!   i + 8j) packed by pixel blocks (each lane a different VPL);
//! - `vpl64-grouped`: the same rays packed by VPL (the same interleave cell of 2×2 / 4×2
//!   neighbouring tiles: one end point per packet);
//! - `bounce`: one cosine-sampled bounce ray from every primary hit (incoherent), packed by
//!   pixel blocks.
//!
//! Scenes: cornell, the 1M-triangle sphere field, and the real models in ../shared/models
//! (Sponza with a ceiling light and a camera in the atrium; the Igea scan scaled up inside a
//! closed room) — skipped when the file is absent. `MIRAGE_BENCH_SCENES=igea,cornell` limits
//! the scenes (criterion's own filter still builds them all).
//!
//! `cargo bench --bench traverse`; results in benches/results/*-traverse.md.

use std::path::Path;
use std::time::Duration;

use criterion::{Criterion, SamplingMode, Throughput, criterion_group, criterion_main};
use glam::{Vec2, Vec3, vec2, vec3};
use mirage::accel::{Accel, offset_origin, rays};
use mirage::bsdf::Frame;
use mirage::load::builtin::{self, Builder, cuboid, quad};
use mirage::load::{self, SceneDesc};
use mirage::sampling::{Pcg32, warp};
use mirage::scene::{CameraSettings, NO_LIGHT, Scene, SurfacePoint};
use mirage::simd::{F4, F8, LaneRay, Lanes, RayPacket};
use rayon::prelude::*;

const RES: u32 = 1024;

/// Triangles of an OBJ model (positions and indices of all its meshes).
fn obj_geometry(path: &Path) -> Option<(Vec<Vec3>, Vec<u32>)> {
    if !path.exists() {
        eprintln!("skipping {}: not found", path.display());
        return None;
    }
    let desc = load::load(path).map_err(|e| eprintln!("skipping {}: {e}", path.display())).ok()?;
    let (mut positions, mut indices) = (Vec::new(), Vec::new());
    for m in desc.meshes {
        let base = positions.len() as u32;
        positions.extend(m.positions);
        indices.extend(m.indices.iter().map(|i| base + i));
    }
    Some((positions, indices))
}

/// The Igea scan (~0.1 units) scaled to 2 units, standing in a closed 6×4×6 room with a
/// ceiling light, the camera looking at its face from 2.6 units.
fn igea_room(path: &Path) -> Option<SceneDesc> {
    let (positions, indices) = obj_geometry(path)?;
    let mut b = Builder::new("igea");
    let grey = b.diffuse("igea", Vec3::splat(0.7));
    let wall = b.diffuse("wall", Vec3::splat(0.6));
    let light = b.emitter("ceiling light", Vec3::splat(10.0));
    let positions = positions.iter().map(|p| *p * 20.0 + vec3(0.0, 1.0, 0.0)).collect();
    b.indexed("igea", grey, positions, Vec::new(), indices);
    b.triangles("room", wall, &cuboid(vec3(-3.0, 0.0, -3.0), vec3(3.0, 4.0, 3.0), true));
    let y = 3.99;
    b.triangles("light", light, &quad(vec3(-1.0, y, -1.0), vec3(1.0, y, -1.0), vec3(1.0, y, 1.0), vec3(-1.0, y, 1.0)));
    b.camera(vec3(0.0, 1.1, 2.6), vec3(0.0, 1.0, 0.0), 45.0, RES, RES);
    Some(b.finish())
}

/// Dabrovic's Sponza with a light closing the open roof and the camera in the atrium.
fn sponza(path: &Path) -> Option<SceneDesc> {
    let (positions, indices) = obj_geometry(path)?;
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for p in &positions {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    let mut b = Builder::new("sponza");
    let grey = b.diffuse("sponza", Vec3::splat(0.7));
    let light = b.emitter("sky light", Vec3::splat(5.0));
    b.indexed("sponza", grey, positions, Vec::new(), indices);
    let y = hi.y + 0.01;
    b.triangles(
        "roof light",
        light,
        &quad(vec3(lo.x, y, lo.z), vec3(hi.x, y, lo.z), vec3(hi.x, y, hi.z), vec3(lo.x, y, hi.z)),
    );
    b.camera(vec3(-12.0, 3.0, -0.5), vec3(8.0, 5.0, 0.5), 60.0, RES, RES);
    Some(b.finish())
}

fn scenes() -> Vec<(&'static str, SceneDesc)> {
    let models = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/models");
    let wanted = std::env::var("MIRAGE_BENCH_SCENES").ok();
    let want = |name: &str| wanted.as_ref().is_none_or(|w| w.split(',').any(|x| x == name));
    let mut out = Vec::new();
    if want("cornell") {
        out.push(("cornell", builtin::cornell()));
    }
    if want("sphere-field-1M") {
        out.push(("sphere-field-1M", builtin::sphere_field(28)));
    }
    if want("sponza")
        && let Some(d) = sponza(&models.join("sponza.obj"))
    {
        out.push(("sponza", d));
    }
    if want("igea")
        && let Some(d) = igea_room(&models.join("igea.obj"))
    {
        out.push(("igea", d));
    }
    out
}

/// The rays of one kind in groups of at most 8 (the 8-wide packets); each group splits into
/// lanes {0, 1, 4, 5} and {2, 3, 6, 7} for 4-wide packets (2×2 of a 4×2 arrangement). Single
/// rays are traced in the same order.
struct RaySet {
    name: &'static str,
    groups: Vec<[Option<LaneRay>; 8]>,
}

impl RaySet {
    fn single(&self) -> Vec<LaneRay> {
        self.groups.iter().flatten().flatten().copied().collect()
    }
    fn packets8(&self) -> Vec<RayPacket<F8>> {
        self.groups.iter().filter(|g| g.iter().any(Option::is_some)).map(|g| RayPacket::from_fn(|i| g[i])).collect()
    }
    fn packets4(&self) -> Vec<RayPacket<F4>> {
        let halves = self.groups.iter().flat_map(|g| [[g[0], g[1], g[4], g[5]], [g[2], g[3], g[6], g[7]]]);
        halves.filter(|h| h.iter().any(Option::is_some)).map(|h| RayPacket::from_fn(|i| h[i])).collect()
    }
}

/// Pixel positions of 4×2 blocks in 8×8 tiles, tiles in scanline order.
fn tile_blocks(w: u32, h: u32) -> Vec<[(u32, u32); 8]> {
    let mut out = Vec::new();
    for ty in (0..h).step_by(8) {
        for tx in (0..w).step_by(8) {
            for by in 0..4 {
                for bx in 0..2 {
                    out.push(std::array::from_fn(|k| (tx + bx * 4 + k as u32 % 4, ty + by * 2 + k as u32 / 4)));
                }
            }
        }
    }
    out
}

fn ray_sets(scene: &Scene, accel: &Accel) -> Vec<RaySet> {
    let cam = scene.camera.clone().with_resolution(RES, RES);
    let px = |x: u32, y: u32| (y * RES + x) as usize;
    let primary: Vec<LaneRay> = (0..RES * RES)
        .map(|i| {
            let r = cam.generate_ray(vec2((i % RES) as f32 + 0.5, (i / RES) as f32 + 0.5), Vec2::splat(0.5));
            LaneRay::new(r.origin, r.dir, f32::INFINITY)
        })
        .collect();
    let hits: Vec<Option<SurfacePoint>> = primary
        .par_iter()
        .map(|r| accel.intersect(r.origin, r.dir, r.t_max).map(|h| scene.surface_point(h.tri, h.b1, h.b2)))
        .collect();
    let hit_share = hits.iter().filter(|h| h.is_some()).count() as f64 / hits.len() as f64;
    // One point just below the first light; 64 VPLs on surfaces hit by bounce rays.
    let mesh = &scene.mesh;
    let light_tri = (0..mesh.len() as u32).find(|&t| mesh.emitter[t as usize] != NO_LIGHT).unwrap_or(0);
    let lsp = scene.surface_point(light_tri, 1.0 / 3.0, 1.0 / 3.0);
    let light_point = lsp.p + lsp.ng * 1e-3 * scene.bounds.diagonal();
    let mut rng = Pcg32::new(7);
    let bounce: Vec<Option<LaneRay>> = hits
        .iter()
        .zip(&primary)
        .map(|(sp, r)| {
            let sp = sp.as_ref()?;
            let n = if sp.ng.dot(r.dir) < 0.0 { sp.ng } else { -sp.ng };
            let d =
                Frame::from_normal(n).to_world(warp::sample_cosine_hemisphere(vec2(rng.next_f32(), rng.next_f32())));
            Some(LaneRay::new(offset_origin(sp, &mesh.corners(sp.tri), d), d, f32::INFINITY))
        })
        .collect();
    let mut vpls = Vec::new();
    for r in bounce.iter().step_by(997).flatten() {
        if let Some(h) = accel.intersect(r.origin, r.dir, r.t_max) {
            vpls.push(scene.surface_point(h.tri, h.b1, h.b2).p);
        }
        if vpls.len() == 64 {
            break;
        }
    }
    while vpls.len() < 64 {
        vpls.push(light_point);
    }
    let shadow = |x: u32, y: u32, target: Vec3| hits[px(x, y)].as_ref().map(|sp| rays::shadow_ray(scene, sp, target));
    let vpl_of = |x: u32, y: u32| vpls[((x % 8) + 8 * (y % 8)) as usize];
    let blocks = tile_blocks(RES, RES);
    let by_blocks = |f: &dyn Fn(u32, u32) -> Option<LaneRay>| -> Vec<[Option<LaneRay>; 8]> {
        blocks.iter().map(|b| b.map(|(x, y)| f(x, y))).collect()
    };
    // VPL-grouped: lane k takes the same interleave cell of tile (4·sx + k mod 4, 2·sy + k div 4).
    let mut grouped = Vec::new();
    for sy in (0..RES).step_by(16) {
        for sx in (0..RES).step_by(32) {
            for j in 0..8 {
                for i in 0..8 {
                    grouped.push(std::array::from_fn(|k| {
                        let (x, y) = (sx + 8 * (k as u32 % 4) + i, sy + 8 * (k as u32 / 4) + j);
                        shadow(x, y, vpl_of(x, y))
                    }));
                }
            }
        }
    }
    eprintln!("  primary hit share {hit_share:.3}; {} VPLs", vpls.len());
    vec![
        RaySet { name: "primary", groups: by_blocks(&|x, y| Some(primary[px(x, y)])) },
        RaySet { name: "shadow-point", groups: by_blocks(&|x, y| shadow(x, y, light_point)) },
        RaySet { name: "vpl64-block", groups: by_blocks(&|x, y| shadow(x, y, vpl_of(x, y))) },
        RaySet { name: "vpl64-grouped", groups: grouped },
        RaySet { name: "bounce", groups: by_blocks(&|x, y| bounce[px(x, y)]) },
    ]
}

fn bench_packets<F: Lanes>(
    group: &mut criterion::BenchmarkGroup<criterion::measurement::WallTime>,
    pool: &rayon::ThreadPool,
    accel: &Accel,
    packets: &[RayPacket<F>],
    id: &str,
) {
    group.bench_function(format!("{id}/closest"), |b| {
        b.iter(|| {
            pool.install(|| {
                packets
                    .par_chunks(256)
                    .map(|c| c.iter().map(|p| accel.intersect_packet(p).hit.count_ones()).sum::<u32>())
                    .sum::<u32>()
            })
        })
    });
    group.bench_function(format!("{id}/occluded"), |b| {
        b.iter(|| {
            pool.install(|| {
                packets
                    .par_chunks(256)
                    .map(|c| c.iter().map(|p| accel.occluded_packet(p).count_ones()).sum::<u32>())
                    .sum::<u32>()
            })
        })
    });
}

fn bench_traverse(c: &mut Criterion) {
    let mut group = c.benchmark_group("traverse");
    // Flat sampling: the slowest sets (obvhs on 1M triangles, 1 thread) take ~0.5 s per pass, and
    // linear sampling would run 55 passes of each.
    group
        .sample_size(10)
        .sampling_mode(SamplingMode::Flat)
        .warm_up_time(Duration::from_millis(300))
        .measurement_time(Duration::from_secs(1));
    for (name, desc) in scenes() {
        let t0 = std::time::Instant::now();
        let scene = Scene::from_desc(desc, &CameraSettings::default()).unwrap();
        let accel = Accel::build_with_obvhs(&scene.mesh);
        eprintln!("{name}: {} triangles, {:?}, built in {:.2?}", scene.mesh.len(), accel, t0.elapsed());
        for set in ray_sets(&scene, &accel) {
            let single = set.single();
            let (p4, p8) = (set.packets4(), set.packets8());
            group.throughput(Throughput::Elements(single.len() as u64));
            for threads in [1usize, 2] {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                let id = |method: &str| format!("{name}/{}/{method}/{threads}t", set.name);
                type Closest = fn(&Accel, Vec3, Vec3, f32) -> bool;
                let singles: [(&str, Closest, Closest); 2] = [
                    (
                        "obvhs",
                        |a, o, d, t| a.intersect_obvhs(o, d, t).is_some(),
                        |a, o, d, t| a.occluded_obvhs(o, d, t),
                    ),
                    ("single", |a, o, d, t| a.intersect(o, d, t).is_some(), |a, o, d, t| a.occluded(o, d, t)),
                ];
                for (method, closest, occluded) in singles {
                    for (query, f) in [("closest", closest), ("occluded", occluded)] {
                        group.bench_function(format!("{}/{query}", id(method)), |b| {
                            b.iter(|| {
                                pool.install(|| {
                                    single
                                        .par_chunks(2048)
                                        .map(|c| c.iter().filter(|r| f(&accel, r.origin, r.dir, r.t_max)).count())
                                        .sum::<usize>()
                                })
                            })
                        });
                    }
                }
                bench_packets(&mut group, &pool, &accel, &p4, &id("packet4"));
                bench_packets(&mut group, &pool, &accel, &p8, &id("packet8"));
            }
        }
    }
    group.finish();
}

criterion_group!(benches, bench_traverse);
criterion_main!(benches);
