//! Path-tracer throughput: camera samples per second on cornell and on the 1M-triangle
//! sphere field (2 threads, the machine's cores). `cargo bench --bench pt`.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use mirage::accel::Accel;
use mirage::load::builtin;
use mirage::offline::{self, Budget, OfflineSettings};
use mirage::progress::NoProgress;
use mirage::scene::{CameraSettings, Scene};

fn bench_pt(c: &mut Criterion) {
    let mut group = c.benchmark_group("pt");
    group.sample_size(10);
    for (name, desc) in [("cornell", builtin::cornell()), ("sphere-field-1M", builtin::sphere_field(28))] {
        let settings = CameraSettings { width: Some(128), height: Some(128), ..Default::default() };
        let scene = Scene::from_desc(desc, &settings).unwrap();
        let accel = Accel::build(&scene.mesh);
        let spp = 4;
        group.throughput(Throughput::Elements(128 * 128 * spp as u64));
        group.bench_function(format!("{name}/128x128x{spp}spp"), |b| {
            let s = OfflineSettings { budget: Budget::Samples(spp), ..OfflineSettings::preview() };
            b.iter(|| offline::render_pt(&scene, &accel, &s, &NoProgress))
        });
    }
    group.finish();
}

criterion_group!(benches, bench_pt);
criterion_main!(benches);
