//! Path-space MLT throughput: proposals (propose, evaluate, accept or reject) per second for each
//! mutation type alone, on cornell and on glass-sphere, from a start state the type applies to
//! (a caustic path for the caustic perturbation). `cargo bench --bench mlt`.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use mirage::accel::Accel;
use mirage::load::builtin;
use mirage::offline::mlt::mutation::Context;
use mirage::offline::mlt::{MutationKind, find_state};
use mirage::sampling::Pcg32;
use mirage::scene::{CameraSettings, Scene};
use mirage::stats::RayStats;

const BATCH: u64 = 1000;

fn bench_mlt(c: &mut Criterion) {
    let mut group = c.benchmark_group("mlt");
    group.sample_size(10);
    group.throughput(Throughput::Elements(BATCH));
    for name in ["cornell", "glass-sphere"] {
        let settings = CameraSettings { width: Some(128), height: Some(128), ..Default::default() };
        let scene = Scene::from_desc(builtin::by_name(name).unwrap(), &settings).unwrap();
        let accel = Accel::build(&scene.mesh);
        let cx = Context { scene: &scene, accel: &accel, max_vertices: 130 };
        for kind in MutationKind::ALL {
            // A start the type applies to: a path with a bounce for bidir and lens, a caustic
            // path (… S+ D E) for the caustic perturbation.
            let caustic = |p: &[mirage::offline::mlt::path::PathVertex]| {
                let k = p.len();
                k >= 4 && !p[k - 2].is_specular() && p[k - 3].is_specular()
            };
            let wanted = |s: &mirage::offline::mlt::mutation::State| match kind {
                MutationKind::Caustic => caustic(&s.path),
                _ => s.path.len() >= 3,
            };
            let Some(mut state) = find_state(&scene, &accel, 1, 130, wanted) else { continue };
            let mutation = kind.mutation();
            let mut rng = Pcg32::new(99);
            let mut st = RayStats::default();
            group.bench_function(format!("{name}/{}", kind.name()), |b| {
                b.iter(|| {
                    for _ in 0..BATCH {
                        if let Some(p) = mutation.propose(&cx, &state, &mut rng, &mut st)
                            && rng.next_f64() < p.accept
                        {
                            state = p.state;
                        }
                    }
                })
            });
        }
    }
    group.finish();
}

criterion_group!(benches, bench_mlt);
criterion_main!(benches);
