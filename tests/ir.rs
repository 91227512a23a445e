//! Instant radiosity: unbiasedness of every VPL sampler with clamp 0 and no filter, edge-keeping
//! of the discontinuity buffer, honest clamping, and stability at the extremes.

mod common;

use common::{Estimate, assert_agree_blocks};
use glam::{Vec3, vec3};
use mirage::accel::Accel;
use mirage::film::Image;
use mirage::filter::{DiscontinuitySettings, discontinuity_filter};
use mirage::frame::{self, FrameSettings};
use mirage::load::SceneDesc;
use mirage::load::builtin::{self, Builder, cuboid, quad};
use mirage::offline::{self, Budget, OfflineSettings};
use mirage::options::VplSamplerArg;
use mirage::progress::NoProgress;
use mirage::scene::{CameraSettings, Scene};

fn scene(desc: SceneDesc, w: u32, h: u32) -> (Scene, Accel) {
    let s = Scene::from_desc(desc, &CameraSettings { width: Some(w), height: Some(h), ..Default::default() }).unwrap();
    let a = Accel::build(&s.mesh);
    (s, a)
}

fn ir_estimate(
    s: &Scene,
    a: &Accel,
    kind: VplSamplerArg,
    settings: &FrameSettings,
    batches: u64,
    frames: u32,
    seed: u64,
) -> Estimate {
    let imgs: Vec<Image> = (0..batches)
        .map(|b| {
            let mut sampler = kind.build(64);
            let (out, _) = frame::render_progressive(
                s,
                a,
                sampler.as_mut(),
                settings,
                frame::Accumulation {
                    budget: Budget::Samples(frames),
                    seed: seed + 1000 * b,
                    aovs: false,
                    filter_fade: None,
                },
                &NoProgress,
            );
            let img = out.film.image();
            assert_eq!(img.non_finite_count(), 0);
            img
        })
        .collect();
    Estimate::from_batches(&imgs)
}

fn pt_estimate(s: &Scene, a: &Accel, batches: u64, spp: u32, seed: u64) -> Estimate {
    let imgs: Vec<Image> = (0..batches)
        .map(|b| {
            let st = OfflineSettings {
                budget: Budget::Samples(spp),
                seed: seed + b,
                max_depth: 64,
                ..OfflineSettings::preview()
            };
            offline::render_pt(s, a, &st, &NoProgress).film.image()
        })
        .collect();
    Estimate::from_batches(&imgs)
}

/// With clamp 0 and no filter, accumulating independent VPL sets converges to the path tracer:
/// the VPL machinery (samplers, interleaving, gather) is unbiased.
#[test]
fn unclamped_unfiltered_ir_converges_to_pt_for_every_sampler() {
    let settings = FrameSettings { interleave: (4, 4), ..FrameSettings::unbiased(256) };
    for (name, desc) in [
        ("cornell", builtin::cornell()),
        ("direct-indirect", builtin::direct_indirect()),
        ("furnace", builtin::furnace()),
    ] {
        let (s, a) = scene(desc, 48, 48);
        let reference = pt_estimate(&s, &a, 12, 32, 77);
        for kind in [VplSamplerArg::Sir, VplSamplerArg::SirCdf, VplSamplerArg::Bir] {
            let e = ir_estimate(&s, &a, kind, &settings, 12, 8, 5);
            assert_agree_blocks(&format!("{name}-ir-{kind:?}-vs-pt"), &e, &reference, 8);
        }
    }
}

/// Two surfaces at different depths and orientations side by side: no filtered pixel takes
/// any value from the other surface.
#[test]
fn discontinuity_buffer_never_mixes_surfaces_across_an_edge() {
    let (w, h) = (32u32, 16u32);
    let n = (w * h) as usize;
    let mut gathered = vec![Vec3::ZERO; n];
    let mut normal = vec![Vec3::ZERO; n];
    let mut depth = vec![0.0f32; n];
    let albedo = vec![Vec3::splat(0.5); n];
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            if x < 16 {
                // Near wall facing the camera, gathered values in [1, 2).
                gathered[i] = Vec3::splat(1.0 + ((x * 7 + y * 3) % 10) as f32 / 10.0);
                normal[i] = Vec3::Z;
                depth[i] = 2.0;
            } else {
                // Far floor, tilted, values in [10, 11).
                gathered[i] = Vec3::splat(10.0 + ((x * 5 + y) % 10) as f32 / 10.0);
                normal[i] = vec3(0.0, 0.8, 0.6);
                depth[i] = 5.0;
            }
        }
    }
    let out = discontinuity_filter(w, h, &gathered, &albedo, &normal, &depth, &DiscontinuitySettings::new(8, 8));
    for y in 0..h {
        for x in 0..w {
            let v = out[(y * w + x) as usize].x;
            if x < 16 {
                assert!((1.0..2.0).contains(&v), "near pixel ({x},{y}) = {v}");
            } else {
                assert!((10.0..11.0).contains(&v), "far pixel ({x},{y}) = {v}");
            }
        }
    }
}

/// Clamp 0 removes nothing; a clamp removes a positive, reported share of the energy.
#[test]
fn clamping_is_reported_honestly() {
    let (s, a) = scene(builtin::cornell(), 64, 64);
    let mut sampler = VplSamplerArg::Sir.build(64);
    let unclamped = FrameSettings::unbiased(256);
    let f0 = frame::render_frame(&s, &a, &s.camera, sampler.as_mut(), &unclamped, 3);
    assert_eq!(f0.stats.energy.removed, 0.0);
    assert!(f0.stats.energy.kept > 0.0);
    let clamped = FrameSettings { clamp: 50.0, ..unclamped };
    let f1 = frame::render_frame(&s, &a, &s.camera, sampler.as_mut(), &clamped, 3);
    let share = f1.stats.energy.removed_share();
    eprintln!("clamp 50: removed {:.2} %", 100.0 * share);
    assert!(share > 0.0 && share < 1.0);
    // Kept + removed equals the unclamped energy of the same VPL set.
    let total = f1.stats.energy.kept + f1.stats.energy.removed;
    assert!((total - f0.stats.energy.kept).abs() <= 1e-3 * total, "{total} vs {}", f0.stats.energy.kept);
}

/// A strong clamp (5, i.e. G ≤ 5 / diagonal²: at 300 the clamp removes ~1.6 % of Cornell's
/// light, too little to tell from noise here) with compensation converges to the path tracer,
/// per pixel block, on Cornell's corners and on direct-indirect (a lamp in a shade). On
/// Cornell the same clamp without compensation is darker by many standard errors (6.5 %, z ≈ 10:
/// the test shows the loss; direct-indirect's loss, 8 %, is within its noise here), so a
/// compensation that added nothing, or the wrong amount, fails.
#[test]
fn compensated_clamp_converges_to_pt_and_the_bare_clamp_is_darker() {
    for (name, desc, size) in [("cornell", builtin::cornell(), 48), ("direct-indirect", builtin::direct_indirect(), 48)]
    {
        let (s, a) = scene(desc, size, size);
        let reference = pt_estimate(&s, &a, 12, 32, 77);
        let bare = FrameSettings { interleave: (4, 4), clamp: 5.0, ..FrameSettings::unbiased(256) };
        let compensated = FrameSettings { compensate: true, ..bare };
        let e = ir_estimate(&s, &a, VplSamplerArg::Sir, &compensated, 12, 8, 5);
        assert_agree_blocks(&format!("{name}-ir-compensated-vs-pt"), &e, &reference, 8);
        let loss = ir_estimate(&s, &a, VplSamplerArg::Sir, &bare, 12, 8, 5);
        let (m, se) = whole_mean(&loss);
        let (r, se_r) = whole_mean(&reference);
        let z = (r - m) / (se * se + se_r * se_r).sqrt();
        eprintln!("{name}: bare clamp 5 mean {m:.5} vs pt {r:.5} ({:+.2} %, z = {z:.1})", 100.0 * (m / r - 1.0));
        if name == "cornell" {
            assert!(z > 6.0, "{name}: the bare clamp should be visibly darker (z = {z:.1})");
        }
    }
}

/// Mean luminance over the image of an estimate's batches, and its standard error.
fn whole_mean(e: &Estimate) -> (f64, f64) {
    let v: Vec<f64> = e.images.iter().map(|i| i.mean_luminance()).collect();
    let k = v.len() as f64;
    let m = v.iter().sum::<f64>() / k;
    let var = v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (k - 1.0);
    (m, (var / k).sqrt())
}

/// A scene whose only light sits in a corner, so VPLs land on corners and edges.
fn corner_light() -> SceneDesc {
    let mut b = Builder::new("corner");
    let wall = b.diffuse("wall", Vec3::splat(0.8));
    let light = b.emitter("light", Vec3::splat(5.0));
    b.triangles("room", wall, &cuboid(Vec3::ZERO, Vec3::splat(2.0), true));
    // Facing into the room, in the corner x = 0, y = 2 (ceiling edge).
    b.triangles(
        "light",
        light,
        &quad(vec3(1e-5, 1.9, 0.9), vec3(1e-5, 1.9, 1.1), vec3(1e-5, 2.0 - 1e-5, 1.1), vec3(1e-5, 2.0 - 1e-5, 0.9)),
    );
    b.camera(vec3(1.8, 1.0, 1.8), vec3(0.0, 1.5, 0.5), 70.0, 16, 16);
    b.finish()
}

#[test]
fn extremes_give_finite_images_without_panics() {
    // (name, scene, width, height, VPLs, interleave)
    type Case = (&'static str, SceneDesc, u32, u32, usize, (u32, u32));
    let cases: Vec<Case> = vec![
        ("corner light", corner_light(), 16, 16, 256, (8, 8)),
        ("one vpl", builtin::cornell(), 16, 16, 1, (8, 8)),
        ("a million vpls", builtin::cornell(), 2, 2, 1_000_000, (1, 1)),
        ("1x1 image", builtin::cornell(), 1, 1, 64, (8, 8)),
        ("interleave 1x1", builtin::cornell(), 16, 16, 64, (1, 1)),
        ("interleave 16x16", builtin::cornell(), 20, 20, 300, (16, 16)),
        ("scale 1e-3", builtin::cornell().scaled(1e-3), 16, 16, 64, (4, 4)),
        ("scale 1e3", builtin::cornell().scaled(1e3), 16, 16, 64, (4, 4)),
    ];
    for (name, desc, w, h, vpls, inter) in cases {
        let (s, a) = scene(desc, w, h);
        for kind in [VplSamplerArg::Sir, VplSamplerArg::SirCdf, VplSamplerArg::Bir] {
            if vpls >= 1_000_000 && kind == VplSamplerArg::Bir {
                continue; // BIR would draw 10⁷ candidates: covered by SIR at this size.
            }
            let mut sampler = kind.build(64);
            for (clamp, compensate) in [(0.0, false), (1000.0, false), (1000.0, true), (10.0, true)] {
                let settings =
                    FrameSettings { vpls, interleave: inter, clamp, compensate, ..FrameSettings::interactive() };
                let f = frame::render_frame(&s, &a, &s.camera, sampler.as_mut(), &settings, 1);
                assert!(
                    f.image.iter().all(|p| p.is_finite() && p.min_element() >= 0.0),
                    "{name} {kind:?} clamp {clamp} compensate {compensate}: non-finite or negative pixel"
                );
                let e = f.stats.energy;
                assert!(e.kept.is_finite() && e.removed.is_finite() && e.recovered.is_finite(), "{name} {kind:?}");
                assert!(f.vpls.radiance.iter().all(|r| r.is_finite()), "{name} {kind:?}: non-finite VPL");
            }
        }
    }
}
