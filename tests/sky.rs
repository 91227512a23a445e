//! The sun and the sky (lights at infinity) in every mode: analytic values on a plane under a
//! constant sky (ρL) and under a sun (ρE/π), the sky seen directly, and agreement with the path
//! tracer on the sunlit room.

mod common;

use common::{Estimate, assert_agree_blocks};
use glam::{Vec3, vec3};
use mirage::accel::Accel;
use mirage::film::Image;
use mirage::frame::{self, FrameSettings};
use mirage::load::SceneDesc;
use mirage::load::builtin::{self, Builder, quad};
use mirage::offline::{self, Budget, OfflineSettings, bdpt::BdptOptions};
use mirage::options::{SamplerConfig, VplSamplerArg};
use mirage::progress::NoProgress;
use mirage::scene::{CameraSettings, Scene};

fn scene(desc: SceneDesc, w: u32, h: u32) -> (Scene, Accel) {
    let s = Scene::from_desc(desc, &CameraSettings { width: Some(w), height: Some(h), ..Default::default() }).unwrap();
    let a = Accel::build(&s.mesh);
    (s, a)
}

/// A 40 m square plane of albedo `rho` at y = 0 (nothing else), seen from 1.5 m above looking
/// down, so that every pixel sees the plane; lit by what `light` adds.
fn plane(rho: Vec3, light: impl FnOnce(&mut Builder)) -> SceneDesc {
    let mut b = Builder::new("plane");
    let m = b.diffuse("plane", rho);
    b.triangles(
        "plane",
        m,
        &quad(vec3(-20.0, 0.0, -20.0), vec3(-20.0, 0.0, 20.0), vec3(20.0, 0.0, 20.0), vec3(20.0, 0.0, -20.0)),
    );
    light(&mut b);
    b.camera(vec3(0.0, 1.5, 0.0), vec3(0.0, 0.0, 0.01), 40.0, 16, 16);
    b.finish()
}

/// The modes that must give the analytic values, each as a list of independent images.
#[derive(Clone, Copy, Debug)]
enum Mode {
    Pt,
    Bdpt,
    Ir,
    /// MTMH with the bidirectional kernel, unclamped and unfiltered.
    Mir,
    /// MTMH, the gather clamped at the chains' target bound and compensated (unbiased with
    /// finite variance: `FrameSettings::compensated`).
    MirCompensated,
    /// Primary-sample-space MLT over the bidirectional sampler (its default settings, a
    /// 20 000-path bootstrap).
    Pssmlt,
}

fn render(s: &Scene, a: &Accel, mode: Mode, batches: u64, passes: u32) -> Vec<Image> {
    (0..batches)
        .map(|b| {
            let st = OfflineSettings {
                budget: Budget::Samples(passes),
                seed: 17 + b,
                max_depth: 16,
                ..OfflineSettings::preview()
            };
            let img = match mode {
                Mode::Pt => offline::render_pt(s, a, &st, &NoProgress).film.image(),
                Mode::Bdpt => {
                    let o = BdptOptions { max_depth: 16, only: None, path_edges: None };
                    offline::render_bdpt(s, a, &st, &o, &NoProgress).film.image()
                }
                Mode::Pssmlt => {
                    use mirage::offline::pssmlt::{PssmltSettings, render_pssmlt};
                    let p = PssmltSettings { bootstrap: 20_000, ..PssmltSettings::default() };
                    render_pssmlt(s, a, &st, &p, &NoProgress).0.film.image()
                }
                Mode::Ir | Mode::Mir | Mode::MirCompensated => {
                    let (kind, settings) = match mode {
                        Mode::Ir => (VplSamplerArg::Sir, FrameSettings::unbiased(64)),
                        Mode::Mir => (VplSamplerArg::Mtmh, FrameSettings::unbiased(64)),
                        _ => (VplSamplerArg::Mtmh, FrameSettings::compensated(64)),
                    };
                    let settings = FrameSettings { interleave: (4, 4), ..settings };
                    let mut sampler = kind.build_with(&SamplerConfig::default());
                    let acc = frame::Accumulation {
                        budget: Budget::Samples(passes),
                        seed: 31 + 1000 * b,
                        aovs: false,
                        filter_fade: None,
                    };
                    frame::render_progressive(s, a, sampler.as_mut(), &settings, acc, &NoProgress).0.film.image()
                }
            };
            assert_eq!(img.non_finite_count(), 0, "{mode:?}");
            img
        })
        .collect()
}

/// Mean RGB over the images and pixels, with the standard error of each channel from the
/// spread of the per-image means (the images are independent).
fn mean_and_se(imgs: &[Image]) -> (Vec3, Vec3) {
    let means: Vec<Vec3> = imgs.iter().map(|i| i.mean()).collect();
    let k = means.len() as f32;
    let m = means.iter().copied().sum::<Vec3>() / k;
    let var = means.iter().map(|x| (*x - m) * (*x - m)).sum::<Vec3>() / (k - 1.0);
    (m, (var / k).map(f32::sqrt))
}

/// The images' mean is the analytic value within four standard errors (and 10⁻⁴ for float
/// sums), and within 1 % wherever four standard errors resolve 1 %.
fn assert_value(what: &str, imgs: &[Image], expected: Vec3) {
    let (m, se) = mean_and_se(imgs);
    eprintln!("{what}: {m} vs {expected} (s.e. {se})");
    for c in 0..3 {
        let d = (m[c] - expected[c]).abs();
        let tol = (4.0 * se[c]).max(1e-4 * expected[c]);
        assert!(d <= tol, "{what}, channel {c}: {} vs {} (s.e. {})", m[c], expected[c], se[c]);
        if 4.0 * se[c] < 0.01 * expected[c] {
            assert!(d <= 0.01 * expected[c], "{what}, channel {c}: {} more than 1 % from {}", m[c], expected[c]);
        }
    }
}

/// A diffuse plane of albedo ρ under a constant sky of radiance L, nothing else, has radiance
/// ρL on its upper face (the upper hemisphere is all sky; a plane cannot see itself), in every
/// mode ([`assert_value`]).
#[test]
fn a_plane_under_a_constant_sky_has_radiance_albedo_times_sky() {
    let (rho, l) = (vec3(0.5, 0.4, 0.3), vec3(0.8, 1.0, 1.2));
    let (s, a) = scene(plane(rho, |b| b.sky(l)), 16, 16);
    for mode in [Mode::Pt, Mode::Bdpt, Mode::Ir, Mode::Mir, Mode::Pssmlt] {
        let imgs = render(&s, &a, mode, 8, 64);
        assert_value(&format!("sky {mode:?}"), &imgs, rho * l);
    }
}

/// The same plane under an equirectangular map whose upper half (rows 0–3 of 8: the polar
/// angles 0…90°) has radiance L_up and whose lower half is ten times brighter: the plane's upper
/// face sees only the upper half, so its radiance is ρ·L_up, in every mode. Importance sampling
/// puts most samples on the hidden lower half; a wrong density there shows as a wrong mean.
#[test]
fn a_plane_under_an_environment_map_sees_only_its_upper_half() {
    let (rho, up, down) = (vec3(0.5, 0.5, 0.5), vec3(0.2, 0.4, 0.8), vec3(8.0, 4.0, 2.0));
    let (w, h) = (16u32, 8u32);
    let texels = (0..w * h).map(|i| if i / w < h / 2 { up } else { down }).collect();
    let map =
        mirage::load::EnvironmentDesc::Map { path: "test.exr".into(), width: w, height: h, texels, rotation: 0.3 };
    let (s, a) = scene(plane(rho, |b| b.light(mirage::load::PunctualDesc::Environment(map))), 16, 16);
    for mode in [Mode::Pt, Mode::Bdpt, Mode::Ir, Mode::Mir] {
        let imgs = render(&s, &a, mode, 8, 64);
        assert_value(&format!("map {mode:?}"), &imgs, rho * up);
    }
}

/// A Lambertian plane facing a sun of illuminance E (straight above, parallel light or a soft
/// 0.53° disk) has radiance ρE/π, in every mode.
#[test]
fn a_plane_facing_the_sun_has_radiance_albedo_times_illuminance_over_pi() {
    let (rho, e) = (vec3(0.6, 0.5, 0.4), vec3(3.0, 2.0, 1.0));
    for diameter in [0.0, 0.53] {
        let (s, a) = scene(plane(rho, |b| b.sun(Vec3::Y, e, diameter)), 16, 16);
        for mode in [Mode::Pt, Mode::Bdpt, Mode::Ir, Mode::Mir, Mode::Pssmlt] {
            let imgs = render(&s, &a, mode, 8, 32);
            assert_value(&format!("sun {diameter}° {mode:?}"), &imgs, rho * e / std::f32::consts::PI);
        }
    }
}

/// Where the camera sees the sky directly (an open box seen from inside, looking up through its
/// open top), the pixels have the sky's radiance exactly.
#[test]
fn the_sky_seen_directly_has_its_radiance() {
    let l = vec3(0.2, 0.5, 0.9);
    let mut b = Builder::new("open-box");
    let m = b.diffuse("walls", Vec3::splat(0.5));
    let mut walls = builtin::cuboid(vec3(-1.0, 0.0, -1.0), vec3(1.0, 2.0, 1.0), true);
    walls.drain(6..8); // no top
    b.triangles("walls", m, &walls);
    b.sky(l);
    b.camera(vec3(0.0, 0.5, 0.0), vec3(0.0, 2.0, 0.01), 40.0, 16, 16);
    let (s, a) = scene(b.finish(), 16, 16);
    let img = &render(&s, &a, Mode::Pt, 1, 4)[0];
    // The centre of the view goes out through the open top.
    for (x, y) in [(7, 7), (8, 8), (6, 9)] {
        let p = img.get(x, y);
        assert!((p - l).abs().max_element() < 1e-5, "pixel ({x}, {y}) = {p}, sky {l}");
    }
}

/// On the sunlit room (thick walls, two windows, sun and sky), bidirectional path tracing,
/// unclamped and unfiltered instant radiosity, and MIR (the gather clamped at the chains'
/// target bound and compensated: unbiased, finite variance) agree with the path tracer per 8×8
/// block and in image mean (within four standard errors of the difference, over 8 seeds).
#[test]
fn every_mode_agrees_with_pt_on_the_sunlit_room() {
    let (s, a) = scene(builtin::sunlit_room(), 32, 24);
    // Mean luminance over the images and its standard error.
    let lum = |imgs: &[Image]| {
        let v: Vec<f64> = imgs.iter().map(Image::mean_luminance).collect();
        let k = v.len() as f64;
        let m = v.iter().sum::<f64>() / k;
        (m, (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (k - 1.0) / k).sqrt())
    };
    let pt_imgs = render(&s, &a, Mode::Pt, 8, 512);
    let pt = Estimate::from_batches(&pt_imgs);
    let (pm, pse) = lum(&pt_imgs);
    for (mode, passes) in [(Mode::Bdpt, 64), (Mode::Ir, 32), (Mode::MirCompensated, 16), (Mode::Pssmlt, 64)] {
        let imgs = render(&s, &a, mode, 8, passes);
        let (m, se) = lum(&imgs);
        let z = (m - pm) / (se * se + pse * pse).sqrt();
        eprintln!("sunlit-room {mode:?}: mean/pt {:.4} ± {:.4} (z {z:.2})", m / pm, se / pm);
        assert!(z.abs() < 4.0, "sunlit-room {mode:?}: image mean {m} vs pt {pm} (z {z:.2})");
        assert_agree_blocks(&format!("sunlit-room-{mode:?}-vs-pt"), &Estimate::from_batches(&imgs), &pt, 8);
    }
}
