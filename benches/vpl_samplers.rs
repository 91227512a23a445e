//! VPL generation time of every strategy (papers/002 Table 2 analogue) for m = 256 and 1024 on
//! cornell, ajar-door, left-right, direct-indirect and light-box (256×192 camera).
//! `cargo bench --bench vpl_samplers`. The image-error side of the comparison is the
//! `mirage samplers` report.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use mirage::accel::Accel;
use mirage::load::builtin;
use mirage::report::Method;
use mirage::scene::{CameraSettings, Scene};

fn bench_samplers(c: &mut Criterion) {
    let mut group = c.benchmark_group("vpl_samplers");
    group.sample_size(10);
    let methods = ["sir", "sir-cdf", "bir", "mh", "mtmh", "mtmh-pss", "mtmh-cdf"];
    for name in ["cornell", "ajar-door", "left-right", "direct-indirect", "light-box"] {
        let settings = CameraSettings { width: Some(256), height: Some(192), ..Default::default() };
        let scene = Scene::from_desc(builtin::by_name(name).unwrap(), &settings).unwrap();
        let accel = Accel::build(&scene.mesh);
        for m in [256usize, 1024] {
            group.throughput(Throughput::Elements(m as u64));
            for method in methods {
                let Method::Vpl { sampler, config, .. } = Method::parse(method).unwrap() else { unreachable!() };
                let mut s = sampler.build_with(&config);
                let mut seed = 0u64;
                group.bench_function(format!("{name}/{method}/m{m}"), |b| {
                    b.iter(|| {
                        // A fresh sampler state every time: the cost of one independent VPL set.
                        s.reset();
                        seed += 1;
                        s.sample(&scene, &accel, &scene.camera, m, seed)
                    })
                });
            }
        }
    }
    group.finish();
}

criterion_group!(benches, bench_samplers);
criterion_main!(benches);
