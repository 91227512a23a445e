//! Agreement of independent renders within the bound their variance predicts.

mod common;

use common::{Estimate, assert_agree};
use mirage::accel::Accel;
use mirage::film::Image;
use mirage::load::builtin;
use mirage::offline::{self, Budget, OfflineSettings};
use mirage::progress::NoProgress;
use mirage::scene::{CameraSettings, Scene};

fn cornell_scene(scale: f32) -> Scene {
    let settings = CameraSettings { width: Some(128), height: Some(128), ..Default::default() };
    Scene::from_desc(builtin::cornell().scaled(scale), &settings).unwrap()
}

fn pt_batches(scene: &Scene, seed0: u64, batches: u64, spp: u32) -> Estimate {
    let accel = Accel::build(&scene.mesh);
    let images: Vec<Image> = (0..batches)
        .map(|b| {
            let s = OfflineSettings { budget: Budget::Samples(spp), seed: seed0 + b, ..OfflineSettings::preview() };
            let img = offline::render_pt(scene, &accel, &s, &NoProgress).film.image();
            assert_eq!(img.non_finite_count(), 0, "NaN/Inf pixel");
            img
        })
        .collect();
    Estimate::from_batches(&images)
}

#[test]
fn independent_cornell_renders_agree_within_their_variance() {
    let scene = cornell_scene(1.0);
    let a = pt_batches(&scene, 1000, 16, 16);
    let b = pt_batches(&scene, 2000, 16, 16);
    assert_agree("cornell-pt-vs-pt", &a, &b, 8);
}

/// Geometry and camera scaled together by 1e-3 and 1e3 must give the same image: ray offsets
/// and epsilons are relative to the scene's scale.
#[test]
fn cornell_render_is_invariant_to_scene_scale() {
    let unit = pt_batches(&cornell_scene(1.0), 3000, 16, 16);
    for scale in [1e-3f32, 1e3] {
        let scaled = pt_batches(&cornell_scene(scale), 4000, 16, 16);
        assert_agree(&format!("cornell-scale-{scale}"), &scaled, &unit, 8);
    }
}

#[test]
fn same_seed_gives_bit_identical_images_with_one_and_two_threads() {
    let scene = cornell_scene(1.0);
    let accel = Accel::build(&scene.mesh);
    let s = OfflineSettings { budget: Budget::Samples(8), seed: 42, ..OfflineSettings::preview() };
    let render = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| offline::render_pt(&scene, &accel, &s, &NoProgress).film.image())
    };
    let one = render(1);
    let two = render(2);
    assert!(
        one.data.iter().zip(&two.data).all(|(a, b)| a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits))
    );
    // A different seed gives a different image (the seed is actually used).
    let other = offline::render_pt(&scene, &accel, &OfflineSettings { seed: 43, ..s.clone() }, &NoProgress);
    assert_ne!(other.film.image(), one);
}
