//! PSSMLT throughput: proposals (evaluate the proposed state, accept or reject) per second, per
//! mutation type — small steps alone and large steps alone — on cornell and glass-sphere at
//! path depths 1 and 4. `cargo bench --bench pssmlt`.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use mirage::accel::Accel;
use mirage::color::luminance;
use mirage::load::builtin;
use mirage::offline::pssmlt::{MltSampler, Paths, evaluate};
use mirage::sampling::Pcg32;
use mirage::scene::{CameraSettings, Scene};
use mirage::stats::RayStats;

const BATCH: u64 = 1000;

fn bench_pssmlt(c: &mut Criterion) {
    let mut group = c.benchmark_group("pssmlt");
    group.sample_size(10);
    group.throughput(Throughput::Elements(BATCH));
    for name in ["cornell", "glass-sphere"] {
        let settings = CameraSettings { width: Some(128), height: Some(128), ..Default::default() };
        let scene = Scene::from_desc(builtin::by_name(name).unwrap(), &settings).unwrap();
        let accel = Accel::build(&scene.mesh);
        for depth in [1usize, 4] {
            for (kind, p_large) in [("small", 1e-9f32), ("large", 1.0)] {
                let mut paths = Paths::default();
                let mut st = RayStats::default();
                // A state with a contribution to start from.
                let mut seed = 0;
                let (mut sampler, mut current) = loop {
                    let mut s = MltSampler::new(Pcg32::new(seed), 0.01, p_large);
                    let v = evaluate(&scene, &accel, &mut s, depth, false, &mut paths, &mut st);
                    seed += 1;
                    if luminance(v.value) > 0.0 {
                        break (s, luminance(v.value));
                    }
                };
                let mut rng = Pcg32::new(99);
                group.bench_function(format!("{name}/depth{depth}/{kind}"), |b| {
                    b.iter(|| {
                        for _ in 0..BATCH {
                            sampler.start_iteration();
                            let v = evaluate(&scene, &accel, &mut sampler, depth, false, &mut paths, &mut st);
                            let l = luminance(v.value);
                            if rng.next_f32() < (l / current).min(1.0) {
                                current = l;
                                sampler.accept();
                            } else {
                                sampler.reject();
                            }
                        }
                    })
                });
            }
        }
    }
    group.finish();
}

criterion_group!(benches, bench_pssmlt);
criterion_main!(benches);
