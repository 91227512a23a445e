//! Bidirectional path tracing throughput: camera samples (each with a light sub-path and all
//! connections) per second on cornell and glass-sphere. `cargo bench --bench bdpt`.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use mirage::accel::Accel;
use mirage::load::builtin;
use mirage::offline::bdpt::BdptOptions;
use mirage::offline::{self, Budget, OfflineSettings};
use mirage::progress::NoProgress;
use mirage::scene::{CameraSettings, Scene};

fn bench_bdpt(c: &mut Criterion) {
    let mut group = c.benchmark_group("bdpt");
    group.sample_size(10);
    for name in ["cornell", "glass-sphere"] {
        let settings = CameraSettings { width: Some(128), height: Some(128), ..Default::default() };
        let scene = Scene::from_desc(builtin::by_name(name).unwrap(), &settings).unwrap();
        let accel = Accel::build(&scene.mesh);
        let spp = 2;
        group.throughput(Throughput::Elements(128 * 128 * spp as u64));
        group.bench_function(format!("{name}/128x128x{spp}spp"), |b| {
            let s = OfflineSettings { budget: Budget::Samples(spp), ..OfflineSettings::preview() };
            let o = BdptOptions { max_depth: s.max_depth, only: None, path_edges: None };
            b.iter(|| offline::render_bdpt(&scene, &accel, &s, &o, &NoProgress))
        });
    }
    group.finish();
}

criterion_group!(benches, bench_bdpt);
criterion_main!(benches);
