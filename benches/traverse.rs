//! Traversal throughput (Mrays/s): obvhs's own single-ray CWBVH traversal against our
//! single-ray, 4-, 8- and 16-wide packet traversals, closest hit and occlusion, on 1 and 2
//! threads, for the gather's ray kinds at 1024×1024 (the scenes and ray sets are in
//! `benches/rays/mod.rs`, shared with the Embree comparison `benches/embree.rs`).
//!
//! `cargo bench --bench traverse`; results in benches/results/*-traverse.md.

use std::time::Duration;

use criterion::{Criterion, SamplingMode, Throughput, criterion_group, criterion_main};
use glam::Vec3;
use mirage::accel::Accel;
use mirage::scene::{CameraSettings, Scene};
use mirage::simd::{Lanes, RayPacket};
use rayon::prelude::*;

mod rays;
use rays::{ray_sets, scenes};

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
            let (p4, p8, p16) = (set.packets4(), set.packets8(), set.packets16());
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
                bench_packets(&mut group, &pool, &accel, &p16, &id("packet16"));
            }
        }
    }
    group.finish();
}

criterion_group!(benches, bench_traverse);
criterion_main!(benches);
