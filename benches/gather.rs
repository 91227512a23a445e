//! One gather (G-buffer + interleaved shadow rays + shading, no filter) at 512×512 with 256
//! and 1024 VPLs on cornell and the 1M-triangle sphere field, for each ray grouping: single
//! rays; 8-wide primary packets with single shadow rays; primary packets with shadow packets
//! sharing a VPL, or sharing a pixel. Throughput is shadow
//! rays. `cargo bench --bench gather`.

use criterion::{Criterion, SamplingMode, Throughput, criterion_group, criterion_main};
use mirage::accel::Accel;
use mirage::frame::{FrameSettings, gather_frame};
use mirage::gather::Tracing;
use mirage::load::builtin;
use mirage::scene::{CameraSettings, Scene};
use mirage::vpl::VplSampler;
use mirage::vpl::sir::Sir;

fn bench_gather(c: &mut Criterion) {
    let mut group = c.benchmark_group("gather");
    group.sample_size(10).sampling_mode(SamplingMode::Flat);
    for (name, desc) in [("cornell", builtin::cornell()), ("sphere-field-1M", builtin::sphere_field(28))] {
        let settings = CameraSettings { width: Some(512), height: Some(512), ..Default::default() };
        let scene = Scene::from_desc(desc, &settings).unwrap();
        let accel = Accel::build(&scene.mesh);
        for m in [256usize, 1024] {
            let (vpls, _) = Sir::new(64).sample(&scene, &accel, &scene.camera, m, 7);
            for (label, tracing) in [
                ("single", Tracing::Single),
                ("primary-packets", Tracing::PrimaryPackets),
                ("shared-end", Tracing::SharedEnd),
                ("shared-origin", Tracing::SharedOrigin),
            ] {
                let fs = FrameSettings { vpls: m, filter: None, tracing, ..FrameSettings::interactive() };
                // Count shadow rays once for the throughput.
                let probe = gather_frame(&scene, &accel, &scene.camera, vpls.clone(), &fs, 1, Default::default());
                group.throughput(Throughput::Elements(probe.stats.rays.shadow.max(1)));
                group.bench_function(format!("{name}/512x512/m{m}/{label}"), |b| {
                    b.iter(|| gather_frame(&scene, &accel, &scene.camera, vpls.clone(), &fs, 1, Default::default()))
                });
            }
        }
    }
    group.finish();
}

criterion_group!(benches, bench_gather);
criterion_main!(benches);
