//! The scenes and ray sets of the traversal benchmarks (`traverse`, `embree`), shared so that
//! both trace exactly the same rays at 1024×1024:
//!
//! - `primary`: camera rays in 8×8 tiles, grouped by 4×4 pixel blocks;
//! - `shadow-point`: from every primary hit to one point near the light;
//! - `vpl64-block`: interleaved shadow rays to 64 VPLs (pixel (i, j) of each 8×8 tile to VPL
//!   i + 8j) grouped by pixel blocks (each lane a different VPL);
//! - `vpl64-grouped`: the same rays grouped by VPL (the same interleave cell of 4×4
//!   neighbouring tiles: one end point per group);
//! - `bounce`: one cosine-sampled bounce ray from every primary hit (incoherent), grouped by
//!   pixel blocks.
//!
//! A group has 16 lanes (lane k at column k mod 4, row k div 4 of its 4×4 block of pixels or
//! tiles): a 16-wide packet. Its halves (rows 0–1 and 2–3, i.e. 4×2) are the 8-wide packets and
//! their 2×2 halves the 4-wide ones; single rays are traced in the same order.
//!
//! Scenes: cornell, the 1M-triangle sphere field, and the real models in ../shared/models
//! (Sponza with a ceiling light and a camera in the atrium; the Igea scan scaled up inside a
//! closed room) — skipped when the file is absent. `MIRAGE_BENCH_SCENES=igea,cornell` limits
//! the scenes.

#![allow(dead_code)]

use std::path::Path;

use glam::{Vec2, Vec3, vec2, vec3};
use mirage::accel::{Accel, offset_origin, rays};
use mirage::bsdf::Frame;
use mirage::load::builtin::{self, Builder, cuboid, quad};
use mirage::load::{self, SceneDesc};
use mirage::sampling::{Pcg32, warp};
use mirage::scene::{NO_LIGHT, Scene, SurfacePoint};
use mirage::simd::{F4, F8, F16, LaneRay, RayPacket};
use rayon::prelude::*;

/// Image width and height of the ray sets.
pub const RES: u32 = 1024;

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

/// The benchmark scenes that exist here and `MIRAGE_BENCH_SCENES` asks for.
pub fn scenes() -> Vec<(&'static str, SceneDesc)> {
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

/// The rays of one kind in groups of 16 lanes (see the module doc).
pub struct RaySet {
    /// The set's name.
    pub name: &'static str,
    /// Whether neighbouring lanes are coherent (pixel blocks of camera rays, or one end point).
    pub coherent: bool,
    /// The groups.
    pub groups: Vec<[Option<LaneRay>; 16]>,
}

/// Lanes of the 4-wide packets within a group of 16.
const QUARTERS: [[usize; 4]; 4] = [[0, 1, 4, 5], [2, 3, 6, 7], [8, 9, 12, 13], [10, 11, 14, 15]];
/// Lanes of the 8-wide packets within a group of 16.
const HALVES: [[usize; 8]; 2] = [[0, 1, 2, 3, 4, 5, 6, 7], [8, 9, 10, 11, 12, 13, 14, 15]];
/// The 16-wide packet.
const WHOLE: [[usize; 16]; 1] = [[0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15]];

impl RaySet {
    /// Every ray, in group order.
    pub fn single(&self) -> Vec<LaneRay> {
        self.groups.iter().flatten().flatten().copied().collect()
    }
    /// The groups' lanes as packets of `lanes.len()` (inactive lanes: no ray).
    fn packets<const N: usize>(&self, parts: &[[usize; N]]) -> Vec<[Option<LaneRay>; N]> {
        let split = self.groups.iter().flat_map(|g| parts.iter().map(|p| p.map(|i| g[i])));
        split.filter(|h| h.iter().any(Option::is_some)).collect()
    }
    /// 4-wide packets (2×2 blocks).
    pub fn packets4(&self) -> Vec<RayPacket<F4>> {
        self.packets(&QUARTERS).iter().map(|h| RayPacket::from_fn(|i| h[i])).collect()
    }
    /// 8-wide packets (4×2 blocks).
    pub fn packets8(&self) -> Vec<RayPacket<F8>> {
        self.packets(&HALVES).iter().map(|h| RayPacket::from_fn(|i| h[i])).collect()
    }
    /// 16-wide packets (4×4 blocks).
    pub fn packets16(&self) -> Vec<RayPacket<F16>> {
        self.packets(&WHOLE).iter().map(|h| RayPacket::from_fn(|i| h[i])).collect()
    }
    /// The lanes of the packets of width `n` (4, 8 or 16), for a peer tracing the same packets.
    pub fn lanes(&self, n: usize) -> Vec<Vec<Option<LaneRay>>> {
        match n {
            4 => self.packets(&QUARTERS).iter().map(|h| h.to_vec()).collect(),
            8 => self.packets(&HALVES).iter().map(|h| h.to_vec()).collect(),
            _ => self.packets(&WHOLE).iter().map(|h| h.to_vec()).collect(),
        }
    }
}

/// Pixel positions of the 4×4 blocks of 8×8 tiles, tiles in scanline order (lane k of a block
/// at column k mod 4, row k div 4).
fn tile_blocks(w: u32, h: u32) -> Vec<[(u32, u32); 16]> {
    let mut out = Vec::new();
    for ty in (0..h).step_by(8) {
        for tx in (0..w).step_by(8) {
            for by in 0..2 {
                for bx in 0..2 {
                    out.push(std::array::from_fn(|k| (tx + bx * 4 + k as u32 % 4, ty + by * 4 + k as u32 / 4)));
                }
            }
        }
    }
    out
}

/// The five ray sets of a scene (see the module doc).
pub fn ray_sets(scene: &Scene, accel: &Accel) -> Vec<RaySet> {
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
    let by_blocks = |f: &dyn Fn(u32, u32) -> Option<LaneRay>| -> Vec<[Option<LaneRay>; 16]> {
        blocks.iter().map(|b| b.map(|(x, y)| f(x, y))).collect()
    };
    // VPL-grouped: lane k takes the same interleave cell of tile (4·sx + k mod 4, 4·sy + k div 4).
    let mut grouped = Vec::new();
    for sy in (0..RES).step_by(32) {
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
        RaySet { name: "primary", coherent: true, groups: by_blocks(&|x, y| Some(primary[px(x, y)])) },
        RaySet { name: "shadow-point", coherent: true, groups: by_blocks(&|x, y| shadow(x, y, light_point)) },
        RaySet { name: "vpl64-block", coherent: false, groups: by_blocks(&|x, y| shadow(x, y, vpl_of(x, y))) },
        RaySet { name: "vpl64-grouped", coherent: true, groups: grouped },
        RaySet { name: "bounce", coherent: false, groups: by_blocks(&|x, y| bounce[px(x, y)]) },
    ]
}
