//! Analytic checks of the reference path tracer.

mod common;

use mirage::accel::Accel;
use mirage::load::builtin;
use mirage::offline::{self, Budget, OfflineSettings};
use mirage::progress::NoProgress;
use mirage::scene::{CameraSettings, Scene};

/// In a closed diffuse enclosure where every surface emits Le and reflects ρ, the radiance is
/// Le / (1 − ρ) everywhere (DESIGN §6). Furnace: Le = 1, ρ = 0.5 → 2.
#[test]
fn furnace_radiance_is_le_over_one_minus_albedo() {
    let scene = Scene::from_desc(builtin::furnace(), &CameraSettings::default()).unwrap();
    let accel = Accel::build(&scene.mesh);
    let settings = OfflineSettings { budget: Budget::Samples(256), ..OfflineSettings::preview() };
    let out = offline::render_pt(&scene, &accel, &settings, &NoProgress);
    let img = out.film.image();
    let mean = img.mean();
    assert_eq!(img.non_finite_count(), 0);
    for c in 0..3 {
        assert!((mean[c] - 2.0).abs() < 0.02, "channel {c}: mean radiance {} (expected 2 within 1 %)", mean[c]);
    }
}
