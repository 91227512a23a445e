//! Every lane of a 4- or 8-wide packet gets exactly the single ray's answer: same hit or miss,
//! same triangle, t within 1e-4 relative (in fact bit-identical), for closest hit and
//! occlusion, on every scene in scenes/, for at least 10⁵ rays of each kind: random, coherent
//! primary, shadow rays to one point, and the degenerate kinds (axis-parallel, zero-length and
//! invalid, grazing, starting on a surface).

use std::sync::OnceLock;

use glam::{Vec2, Vec3, vec2};
use mirage::accel::{Accel, PacketView, SHADOW_T_MAX, offset_origin, rays};
use mirage::load::builtin;
use mirage::sampling::Pcg32;
use mirage::scene::{CameraSettings, NO_LIGHT, Scene, SurfacePoint};
use mirage::simd::{F4, F8, F16, LaneRay, Lanes, RayPacket};
use rayon::prelude::*;

const RAYS_PER_KIND: usize = 100_000;

struct Case {
    name: &'static str,
    scene: Scene,
    accel: Accel,
}

fn cases() -> &'static [Case] {
    static CASES: OnceLock<Vec<Case>> = OnceLock::new();
    CASES.get_or_init(|| {
        builtin::NAMES
            .par_iter()
            .map(|&name| {
                let scene = Scene::from_desc(builtin::by_name(name).unwrap(), &CameraSettings::default()).unwrap();
                let accel = Accel::build_with_obvhs(&scene.mesh);
                Case { name, scene, accel }
            })
            .collect()
    })
}

/// Disagreements between the packet lanes and single rays (messages, at most a few).
fn compare<F: Lanes>(case: &Case, packets: &[RayPacket<F>]) -> (usize, Vec<String>) {
    let accel = &case.accel;
    packets
        .par_iter()
        .map(|p| {
            let mut errors = Vec::new();
            let hits = accel.intersect_packet(p);
            let blocked = accel.occluded_packet(p);
            assert_eq!(hits.hit & !p.active, 0);
            assert_eq!(blocked & !p.active, 0);
            for (i, r) in p.rays() {
                let single = accel.intersect(r.origin, r.dir, r.t_max);
                let lane = hits.lane(i);
                let same = match (single, lane) {
                    (None, None) => true,
                    (Some(s), Some(l)) => s.tri == l.tri && (s.t - l.t).abs() <= 1e-4 * s.t.abs(),
                    _ => false,
                };
                if !same {
                    errors.push(format!("{} closest {r:?}: single {single:?} lane {lane:?}", case.name));
                }
                let occluded = accel.occluded(r.origin, r.dir, r.t_max);
                if occluded != (blocked >> i & 1 != 0) {
                    errors.push(format!("{} occluded {r:?}: single {occluded} lane {}", case.name, !occluded));
                }
            }
            (p.count() as usize, errors)
        })
        .reduce(
            || (0, Vec::new()),
            |mut a, b| {
                a.0 += b.0;
                a.1.extend(b.1);
                a
            },
        )
}

/// Checks a ray list packed into consecutive packets of 4, 8 and 16 lanes.
fn check_rays(case: &Case, kind: &str, rays: &[Option<LaneRay>]) {
    assert!(rays.len() >= RAYS_PER_KIND);
    check_packets::<F4>(case, kind, &packets_of(rays));
    check_packets::<F8>(case, kind, &packets_of(rays));
    check_packets::<F16>(case, kind, &packets_of(rays));
}

fn packets_of<F: Lanes>(rays: &[Option<LaneRay>]) -> Vec<RayPacket<F>> {
    rays.chunks(F::LANES).map(|c| RayPacket::from_fn(|i| c.get(i).copied().flatten())).collect()
}

fn check_packets<F: Lanes>(case: &Case, kind: &str, packets: &[RayPacket<F>]) {
    let (count, errors) = compare(case, packets);
    assert!(
        errors.is_empty(),
        "{kind}, {} lanes: {} of {count} rays disagree; first: {:#?}",
        F::LANES,
        errors.len(),
        &errors[..errors.len().min(5)]
    );
}

fn random_unit(rng: &mut Pcg32) -> Vec3 {
    let z = 2.0 * rng.next_f32() - 1.0;
    let phi = std::f32::consts::TAU * rng.next_f32();
    let r = (1.0 - z * z).max(0.0).sqrt();
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

fn random_point_in_bounds(scene: &Scene, rng: &mut Pcg32) -> Vec3 {
    let (lo, hi) = (scene.bounds.min, scene.bounds.max);
    let pad = (hi - lo) * 0.1;
    let u = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
    lo - pad + (hi - lo + 2.0 * pad) * u
}

fn random_surface_point(scene: &Scene, rng: &mut Pcg32) -> SurfacePoint {
    let tri = rng.next_below(scene.mesh.len() as u32);
    let (u, v) = (rng.next_f32(), rng.next_f32());
    let (b1, b2) = if u + v > 1.0 { (1.0 - u, 1.0 - v) } else { (u, v) };
    scene.surface_point(tri, b1, b2)
}

/// A camera with enough pixels for `RAYS_PER_KIND` rays.
fn camera(scene: &Scene) -> mirage::scene::Camera {
    let side = (RAYS_PER_KIND as f32).sqrt().ceil() as u32 + 8;
    scene.camera.clone().with_resolution(side, side)
}

/// Primary hits of the whole image (one per pixel that hits).
fn primary_hits(case: &Case) -> Vec<SurfacePoint> {
    let cam = camera(&case.scene);
    let mut out = Vec::new();
    for y in 0..cam.height {
        for x in 0..cam.width {
            let ray = cam.generate_ray(vec2(x as f32 + 0.5, y as f32 + 0.5), Vec2::splat(0.5));
            if let Some(h) = case.accel.intersect(ray.origin, ray.dir, f32::INFINITY) {
                out.push(case.scene.surface_point(h.tri, h.b1, h.b2));
            }
        }
    }
    out
}

#[test]
fn random_rays_match_single_rays() {
    for case in cases() {
        let mut rng = Pcg32::new(1);
        let diag = case.scene.bounds.diagonal();
        let rays: Vec<Option<LaneRay>> = (0..RAYS_PER_KIND)
            .map(|i| {
                let o = random_point_in_bounds(&case.scene, &mut rng);
                let d = random_unit(&mut rng) * (0.01 + 4.0 * rng.next_f32());
                let t_max = if i % 2 == 0 { f32::INFINITY } else { rng.next_f32() * diag };
                Some(LaneRay::new(o, d, t_max))
            })
            .collect();
        check_rays(case, "random", &rays);
    }
}

#[test]
fn coherent_primary_packets_match_single_rays() {
    fn check<F: Lanes>(case: &Case) {
        let cam = camera(&case.scene);
        let (bw, bh) = rays::block_size::<F>();
        let mut packets = Vec::new();
        for y in (0..cam.height).step_by(8) {
            for x in (0..cam.width).step_by(8) {
                packets.extend(rays::primary_tile::<F>(&cam, x, y, 8, 8, Vec2::splat(0.5)));
            }
        }
        assert!(packets.iter().map(|p| p.count() as usize).sum::<usize>() >= RAYS_PER_KIND);
        assert_eq!(packets[0].count(), bw * bh);
        check_packets(case, "primary", &packets);
    }
    for case in cases() {
        check::<F4>(case);
        check::<F8>(case);
        check::<F16>(case);
    }
}

#[test]
fn shadow_packets_to_one_point_match_single_rays() {
    fn check<F: Lanes>(case: &Case, receivers: &[SurfacePoint], target: Vec3) {
        let packets: Vec<RayPacket<F>> =
            receivers.chunks(F::LANES).map(|c| rays::shadow_to_point(&case.scene, c, target)).collect();
        check_packets(case, "shadow to a point", &packets);
    }
    for case in cases() {
        let mut receivers = primary_hits(case);
        let mut rng = Pcg32::new(2);
        while receivers.len() < RAYS_PER_KIND {
            receivers.push(random_surface_point(&case.scene, &mut rng));
        }
        // A point of the first light (or the scene's centre), as the gather's VPLs and lights.
        let mesh = &case.scene.mesh;
        let target = match (0..mesh.len() as u32).find(|&t| mesh.emitter[t as usize] != NO_LIGHT) {
            Some(t) => case.scene.surface_point(t, 0.3, 0.3).p,
            None => case.scene.bounds.center(),
        };
        check::<F4>(case, &receivers, target);
        check::<F8>(case, &receivers, target);
        check::<F16>(case, &receivers, target);
        // And the other pattern: one receiver to several targets.
        let targets: Vec<Vec3> = (0..64).map(|_| random_surface_point(&case.scene, &mut rng).p).collect();
        let packets: Vec<RayPacket<F8>> = receivers[..RAYS_PER_KIND / 8]
            .iter()
            .enumerate()
            .map(|(i, r)| rays::shadow_from_point(&case.scene, r, &targets[(i * 8) % 64..(i * 8) % 64 + 8]))
            .collect();
        check_packets(case, "shadow from a point", &packets);
    }
}

/// The shadow cache changes no answer: shadow rays from every primary hit (and random surface
/// points) to 64 targets, each target keeping the leaf that last blocked a ray to it, as the
/// gather does, agree with plain occlusion queries ray for ray.
#[test]
fn occlusion_with_a_shadow_cache_matches_plain_occlusion() {
    for case in cases() {
        let mut receivers = primary_hits(case);
        let mut rng = Pcg32::new(5);
        while receivers.len() < RAYS_PER_KIND / 4 {
            receivers.push(random_surface_point(&case.scene, &mut rng));
        }
        let targets: Vec<Vec3> = (0..64).map(|_| random_surface_point(&case.scene, &mut rng).p).collect();
        let mut hints = vec![mirage::accel::single::NO_OCCLUDER; targets.len()];
        // A second cache for the lanes of packets set up at once (one receiver, four targets,
        // as the gather traces them).
        let mut lane_hints = hints.clone();
        let (mut rays_traced, mut blocked) = (0, 0);
        for (k, r) in receivers.iter().enumerate() {
            let js = [k % 64, (k * 7 + 3) % 64, (k / 3) % 64, (k * 13) % 64];
            let mut rays = [None; 8];
            for (lane, &j) in js.iter().enumerate() {
                let target = targets[j];
                let origin = offset_origin(r, &case.scene.mesh.corners(r.tri), target - r.p);
                let plain = case.accel.occluded(origin, target - origin, SHADOW_T_MAX);
                let cached = case.accel.occluded_cached(origin, target - origin, SHADOW_T_MAX, &mut hints[j]);
                assert_eq!(plain, cached, "{}: receiver {k} ({:?}) to target {j}", case.name, r.p);
                rays_traced += 1;
                blocked += plain as usize;
                // Lanes 0, 2, 4, 6: idle lanes in between.
                rays[2 * lane] = Some((LaneRay::new(origin, target - origin, SHADOW_T_MAX), plain));
            }
            // Every lane starts from its target's cached leaf; each must end as occluded_cached
            // ends from that leaf: same answer, same leaf left in the cache. Alternately 8 lanes
            // with idle lanes between (lanes 0, 2, 4, 6) and 4 full lanes, as the gather uses.
            let start: Vec<u32> = js.iter().map(|&j| lane_hints[j]).collect();
            let expected: Vec<(bool, u32)> = js
                .iter()
                .enumerate()
                .map(|(lane, _)| {
                    let (ray, _) = rays[2 * lane].unwrap();
                    let mut h = start[lane];
                    (case.accel.occluded_cached(ray.origin, ray.dir, ray.t_max, &mut h), h)
                })
                .collect();
            let mut packet_hints = [mirage::accel::single::NO_OCCLUDER; 8];
            let (lanes, stride) = if k % 2 == 0 {
                for lane in 0..4 {
                    packet_hints[2 * lane] = start[lane];
                }
                let packet = RayPacket::<F8>::from_fn(|i| rays[i].map(|(ray, _)| ray));
                let lanes = case.accel.occluded_lanes_cached(&packet, &mut packet_hints);
                assert_eq!(lanes & 0b1010_1010, 0, "{}: idle lanes are never blocked", case.name);
                (lanes, 2)
            } else {
                packet_hints[..4].copy_from_slice(&start);
                let packet = RayPacket::<F4>::from_fn(|i| rays[2 * i].map(|(ray, _)| ray));
                (case.accel.occluded_lanes_cached(&packet, &mut packet_hints), 1)
            };
            for (lane, &j) in js.iter().enumerate() {
                let got = (lanes >> (stride * lane) & 1 != 0, packet_hints[stride * lane]);
                assert_eq!(got, expected[lane], "{}: lanes set up at once, receiver {k}, lane {lane}", case.name);
                assert_eq!(got.0, rays[2 * lane].unwrap().1, "{}: receiver {k}, lane {lane}", case.name);
                lane_hints[j] = got.1;
            }
        }
        assert!(rays_traced >= RAYS_PER_KIND, "{}: {rays_traced} rays", case.name);
        // Both answers occur, so the cache is exercised.
        assert!(blocked > 0 && blocked < rays_traced, "{}: {blocked} of {rays_traced} blocked", case.name);
    }
}

#[test]
fn axis_parallel_rays_match_single_rays() {
    for case in cases() {
        let mut rng = Pcg32::new(3);
        let rays: Vec<Option<LaneRay>> = (0..RAYS_PER_KIND)
            .map(|i| {
                // Half from random points, half from surface points (through corners and edges
                // of the axis-aligned walls).
                let o = if i % 2 == 0 {
                    random_point_in_bounds(&case.scene, &mut rng)
                } else {
                    let sp = random_surface_point(&case.scene, &mut rng);
                    offset_origin(&sp, &case.scene.mesh.corners(sp.tri), sp.ng)
                };
                let axis = rng.next_below(3) as usize;
                let mut d = Vec3::ZERO;
                d[axis] = if rng.next_below(2) == 0 { 1.0 } else { -1.0 };
                if i % 3 == 0 {
                    // One zero component only.
                    d[(axis + 1) % 3] = rng.next_f32() - 0.5;
                }
                Some(LaneRay::new(o, d, f32::INFINITY))
            })
            .collect();
        check_rays(case, "axis-parallel", &rays);
    }
}

#[test]
fn zero_length_and_invalid_rays_hit_nothing_in_single_rays_and_packets() {
    for case in cases() {
        let mut rng = Pcg32::new(4);
        let rays: Vec<Option<LaneRay>> = (0..RAYS_PER_KIND)
            .map(|i| {
                let o = random_point_in_bounds(&case.scene, &mut rng);
                let d = random_unit(&mut rng);
                Some(match i % 6 {
                    0 => LaneRay::new(o, Vec3::ZERO, 1.0),                    // zero-length shadow ray
                    1 => LaneRay::new(o, d, 0.0),                             // empty interval
                    2 => LaneRay::new(o, d, -1.0),                            // negative interval
                    3 => LaneRay::new(o, d, f32::NAN),                        // NaN interval
                    4 => LaneRay::new(Vec3::splat(f32::NAN), d, 1.0),         // NaN origin
                    _ => LaneRay::new(o, Vec3::new(f32::NAN, 0.0, 1.0), 1.0), // NaN direction
                })
            })
            .collect();
        for r in rays.iter().flatten() {
            assert!(case.accel.intersect(r.origin, r.dir, r.t_max).is_none(), "{r:?}");
            assert!(!case.accel.occluded(r.origin, r.dir, r.t_max), "{r:?}");
        }
        check_rays(case, "zero-length and invalid", &rays);
    }
}

#[test]
fn grazing_rays_match_single_rays() {
    for case in cases() {
        let mut rng = Pcg32::new(5);
        let rays: Vec<Option<LaneRay>> = (0..RAYS_PER_KIND)
            .map(|_| {
                let sp = random_surface_point(&case.scene, &mut rng);
                let t = sp.ng.cross(random_unit(&mut rng)).normalize_or(Vec3::X);
                let eps = [0.0, 1e-6, -1e-6, 1e-3, -1e-3][rng.next_below(5) as usize];
                let lift = [0.0, 1e-5, -1e-5][rng.next_below(3) as usize] * case.scene.bounds.diagonal();
                Some(LaneRay::new(sp.p + sp.ng * lift, t + sp.ng * eps, f32::INFINITY))
            })
            .collect();
        check_rays(case, "grazing", &rays);
    }
}

#[test]
fn rays_starting_on_a_surface_match_single_rays() {
    for case in cases() {
        let mut rng = Pcg32::new(6);
        let rays: Vec<Option<LaneRay>> = (0..RAYS_PER_KIND)
            .map(|i| {
                let sp = random_surface_point(&case.scene, &mut rng);
                let d = random_unit(&mut rng);
                // Exactly on the surface, or with the offset policy of rays leaving a surface.
                let o = if i % 2 == 0 { sp.p } else { offset_origin(&sp, &case.scene.mesh.corners(sp.tri), d) };
                let t_max = if i % 4 < 2 { f32::INFINITY } else { SHADOW_T_MAX };
                Some(LaneRay::new(o, d, t_max))
            })
            .collect();
        check_rays(case, "starting on a surface", &rays);
    }
}

/// Our single-ray traversal agrees with obvhs's on the same triangles: same hit or miss, same
/// t (the triangle may differ only at equal t).
#[test]
fn our_single_rays_match_obvhs_traversal() {
    for case in cases() {
        let mut rng = Pcg32::new(7);
        let mut differ = 0;
        for _ in 0..RAYS_PER_KIND {
            let o = random_point_in_bounds(&case.scene, &mut rng);
            let d = random_unit(&mut rng);
            let ours = case.accel.intersect(o, d, f32::INFINITY);
            let theirs = case.accel.intersect_obvhs(o, d, f32::INFINITY);
            match (ours, theirs) {
                (Some(a), Some(b)) => assert!((a.t - b.t).abs() <= 1e-4 * a.t, "{}: {a:?} vs {b:?}", case.name),
                (None, None) => {}
                _ => differ += 1,
            }
            assert_eq!(case.accel.occluded(o, d, 1.0), case.accel.occluded_obvhs(o, d, 1.0), "{}", case.name);
        }
        assert_eq!(differ, 0, "{}: hit/miss differs from obvhs", case.name);
    }
}

/// The gather traces the same rays whatever their grouping: single rays, packets sharing a VPL
/// and packets sharing a pixel give the same frame, bit for bit (G-buffer with packet primary
/// rays included; the packet groupings sum through another path than the default's batches).
#[test]
fn gather_image_is_the_same_for_every_ray_grouping() {
    use mirage::frame::{FrameSettings, gather_frame};
    use mirage::gather::Tracing;
    use mirage::vpl::VplSampler;
    use mirage::vpl::sir::Sir;
    // The glass sphere made matte: smooth-shaded Lambertian VPLs (lobes with a shading
    // correction), which the default grouping takes through its eight-VPL kernel.
    let mut matte = builtin::glass_sphere();
    for m in &mut matte.materials {
        if m.name == "glass" {
            m.scatter = mirage::load::desc::ScatterDesc::Diffuse;
        }
    }
    let matte_scene = Scene::from_desc(matte, &CameraSettings::default()).unwrap();
    let matte_accel = Accel::build(&matte_scene.mesh);
    let matte = Case { name: "matte-sphere", scene: matte_scene, accel: matte_accel };
    let chosen = cases().iter().filter(|c| ["cornell", "ajar-door", "glass-sphere"].contains(&c.name));
    for case in chosen.chain([&matte]) {
        let (vpls, _) = Sir::new(16).sample(&case.scene, &case.accel, &case.scene.camera, 256, 3);
        if case.name == "matte-sphere" {
            assert!(!vpls.all_diffuse(), "the matte sphere's VPLs carry lobes");
        }
        let frame = |tracing| {
            let fs = FrameSettings { tracing, ..FrameSettings::interactive() };
            gather_frame(&case.scene, &case.accel, &case.scene.camera, vpls.clone(), &fs, 5, Default::default())
        };
        let single = frame(Tracing::Single);
        for tracing in [Tracing::PrimaryPackets, Tracing::SharedEnd, Tracing::SharedOrigin] {
            let packed = frame(tracing);
            assert_eq!(single.stats.rays.shadow, packed.stats.rays.shadow, "{} {tracing:?}", case.name);
            assert_eq!(single.stats.rays.closest, packed.stats.rays.closest, "{} {tracing:?}", case.name);
            // Every grouping sums a pixel's contributions in its subset's order: the same bits.
            assert!(single.image == packed.image, "{} {tracing:?}: images differ", case.name);
        }
    }
}

/// Camera packets traced through the frustum of their pixel block's raster rectangle
/// (`Accel::intersect_packet_in`, what the G-buffer does) get the single rays' hits: from the
/// scene's camera and from random eyes inside the scene looking anywhere, with fields of view
/// from narrow to 120°, blocks at the image's edges, and sub-pixel positions at 0, ½, just
/// below 1 and random.
#[test]
fn camera_block_frustums_match_single_rays() {
    for case in cases() {
        let mut rng = Pcg32::new(5);
        let mut cameras = vec![case.scene.camera.clone().with_resolution(97, 61)];
        for _ in 0..6 {
            let eye = random_point_in_bounds(&case.scene, &mut rng);
            let fov = 0.2 + 1.9 * rng.next_f32();
            let (w, h) = (20 + (rng.next_f32() * 120.0) as u32, 20 + (rng.next_f32() * 90.0) as u32);
            cameras.push(mirage::scene::Camera::look_at(eye, eye + random_unit(&mut rng), Vec3::Y, fov, w, h));
        }
        let mut errors = Vec::new();
        let mut count = 0;
        for (k, cam) in cameras.iter().enumerate() {
            for y0 in (0..cam.height).step_by(2) {
                for x0 in (0..cam.width).step_by(4) {
                    let mut raster = [Vec2::ZERO; 8];
                    let mut n = 0;
                    for i in 0..8u32 {
                        let (x, y) = (x0 + i % 4, y0 + i / 4);
                        if x < cam.width && y < cam.height {
                            let jitter = match (x + y + k as u32) % 4 {
                                0 => Vec2::ZERO,
                                1 => Vec2::splat(0.5),
                                2 => Vec2::splat(1.0 - f32::EPSILON / 2.0),
                                _ => vec2(rng.next_f32(), rng.next_f32()),
                            };
                            raster[n] = vec2(x as f32, y as f32) + jitter;
                            n += 1;
                        }
                    }
                    let rays = cam.generate_rays8(&raster, &[Vec2::splat(0.5); 8], n);
                    let packet = RayPacket::<F8>::from_fn(|i| {
                        (i < n).then(|| LaneRay::new(rays[i].origin, rays[i].dir, f32::INFINITY))
                    });
                    let slopes = cam
                        .raster_slopes((x0 as f32, (x0 + 4) as f32), (y0 as f32, (y0 + 2) as f32))
                        .expect("a pinhole camera");
                    let view = PacketView { apex: cam.position, basis: [cam.right, cam.up, cam.forward], slopes };
                    let hits = case.accel.intersect_packet_in(&packet, Some(&view));
                    for (i, ray) in rays.iter().enumerate().take(n) {
                        let single = case.accel.intersect(ray.origin, ray.dir, f32::INFINITY);
                        let lane = hits.lane(i);
                        if single.map(|s| (s.tri, s.t)) != lane.map(|l| (l.tri, l.t)) {
                            errors.push(format!(
                                "{} camera {k} pixel block ({x0}, {y0}) lane {i}: {single:?} vs {lane:?}",
                                case.name
                            ));
                        }
                        count += 1;
                    }
                }
            }
        }
        assert!(count >= 20_000, "{count} rays");
        assert!(
            errors.is_empty(),
            "{} of {count} rays disagree; first: {:#?}",
            errors.len(),
            &errors[..errors.len().min(5)]
        );
    }
}
