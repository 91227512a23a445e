//! Single-ray traversal throughput (closest hit and occlusion) for primary rays and incoherent
//! cosine-sampled bounce rays, on cornell and the 1M-triangle sphere field.
//! `cargo bench --bench traverse`.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glam::{Vec3, vec2};
use mirage::accel::{Accel, offset_origin};
use mirage::bsdf::Frame;
use mirage::load::builtin;
use mirage::sampling::{Pcg32, warp};
use mirage::scene::{CameraSettings, Scene};
use rayon::prelude::*;

struct RaySet {
    name: &'static str,
    rays: Vec<(Vec3, Vec3, f32)>,
}

/// Primary rays of a w×h image, and one cosine-sampled bounce ray from each primary hit.
fn ray_sets(scene: &Scene, accel: &Accel, w: u32, h: u32) -> Vec<RaySet> {
    let cam = scene.camera.clone().with_resolution(w, h);
    let mut primary = Vec::new();
    let mut bounce = Vec::new();
    let mut rng = Pcg32::new(1);
    for y in 0..h {
        for x in 0..w {
            let ray = cam.generate_ray(vec2(x as f32 + 0.5, y as f32 + 0.5), vec2(0.5, 0.5));
            primary.push((ray.origin, ray.dir, f32::INFINITY));
            if let Some(hit) = accel.intersect(ray.origin, ray.dir, f32::INFINITY) {
                let sp = scene.surface_point(hit.tri, hit.b1, hit.b2);
                let n = if sp.ng.dot(ray.dir) < 0.0 { sp.ng } else { -sp.ng };
                let d = Frame::from_normal(n).to_world(warp::sample_cosine_hemisphere(vec2(rng.next_f32(), rng.next_f32())));
                bounce.push((offset_origin(&sp, &scene.mesh.corners(hit.tri), d), d, f32::INFINITY));
            }
        }
    }
    vec![RaySet { name: "primary", rays: primary }, RaySet { name: "bounce", rays: bounce }]
}

fn bench_traverse(c: &mut Criterion) {
    let mut group = c.benchmark_group("traverse-single");
    group.sample_size(10);
    for (name, desc) in [("cornell", builtin::cornell()), ("sphere-field-1M", builtin::sphere_field(28))] {
        let scene = Scene::from_desc(desc, &CameraSettings::default()).unwrap();
        let accel = Accel::build(&scene.mesh);
        for set in ray_sets(&scene, &accel, 512, 512) {
            group.throughput(Throughput::Elements(set.rays.len() as u64));
            for threads in [1usize, 2] {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                group.bench_function(format!("{name}/{}/closest/{threads}t", set.name), |b| {
                    b.iter(|| {
                        pool.install(|| {
                            set.rays.par_chunks(4096).map(|c| c.iter().filter(|(o, d, t)| accel.intersect(*o, *d, *t).is_some()).count()).sum::<usize>()
                        })
                    })
                });
                group.bench_function(format!("{name}/{}/occluded/{threads}t", set.name), |b| {
                    b.iter(|| {
                        pool.install(|| {
                            set.rays.par_chunks(4096).map(|c| c.iter().filter(|(o, d, t)| accel.occluded(*o, *d, *t)).count()).sum::<usize>()
                        })
                    })
                });
            }
        }
    }
    group.finish();
}

criterion_group!(benches, bench_traverse);
criterion_main!(benches);
