//! Bidirectional path tracing: analytic furnace, agreement with the path tracer, every
//! strategy alone, light tracing alone, and stability at geometric singularities.

mod common;

use common::{Estimate, assert_agree};
use glam::{Vec3, vec2, vec3};
use mirage::accel::Accel;
use mirage::film::{FilmTile, Image};
use mirage::load::SceneDesc;
use mirage::load::builtin::{self, Builder, cuboid, quad};
use mirage::offline::bdpt::{self, BdptOptions, StrategyFilter};
use mirage::offline::{self, Budget, OfflineSettings};
use mirage::progress::NoProgress;
use mirage::sampling::{IndependentSampler, PixelSamplerKind};
use mirage::scene::{CameraSettings, Scene};
use mirage::stats::RayStats;

fn scene(desc: SceneDesc, w: u32, h: u32) -> (Scene, Accel) {
    let s = Scene::from_desc(desc, &CameraSettings { width: Some(w), height: Some(h), ..Default::default() }).unwrap();
    let a = Accel::build(&s.mesh);
    (s, a)
}

/// Independent numbers: these tests check the estimator, strategy by strategy, and several
/// unweighted strategies have unbounded variance (the 1/d² of a connection near a corner; s = 0
/// finding the small light by chance), so their block statistic is calibrated on i.i.d. streams.
/// The Sobol sampler is checked against independent numbers for bdpt as a whole in
/// `tests/agreement.rs`.
fn settings(seed: u64, spp: u32, max_depth: u32) -> OfflineSettings {
    OfflineSettings {
        budget: Budget::Samples(spp),
        seed,
        max_depth,
        sampler: PixelSamplerKind::Independent,
        ..OfflineSettings::preview()
    }
}

fn batches(k: u64, mut render: impl FnMut(u64) -> Image) -> Estimate {
    let imgs: Vec<Image> = (0..k)
        .map(|b| {
            let img = render(b);
            assert_eq!(img.non_finite_count(), 0, "NaN/Inf pixel");
            img
        })
        .collect();
    Estimate::from_batches(&imgs)
}

fn bdpt_estimate(s: &Scene, a: &Accel, seed: u64, k: u64, spp: u32, opts: BdptOptions) -> Estimate {
    batches(k, |b| {
        offline::render_bdpt(s, a, &settings(seed + b, spp, opts.max_depth), &opts, &NoProgress).film.image()
    })
}

fn pt_estimate(
    s: &Scene,
    a: &Accel,
    seed: u64,
    k: u64,
    spp: u32,
    max_depth: u32,
    edges: Option<(u32, u32)>,
) -> Estimate {
    batches(k, |b| {
        offline::render_pt_of_length(s, a, &settings(seed + b, spp, max_depth), edges, &NoProgress).film.image()
    })
}

fn all(max_depth: u32) -> BdptOptions {
    BdptOptions { max_depth, only: None, path_edges: None }
}

#[test]
fn bdpt_furnace_radiance_is_le_over_one_minus_albedo() {
    let (s, a) = scene(builtin::furnace(), 32, 32);
    let out = offline::render_bdpt(&s, &a, &settings(7, 64, 128), &all(128), &NoProgress);
    let mean = out.film.image().mean();
    for c in 0..3 {
        assert!((mean[c] - 2.0).abs() < 0.02, "channel {c}: {} (expected 2 within 1 %)", mean[c]);
    }
}

#[test]
fn bdpt_agrees_with_pt_on_cornell_glass_sphere_and_direct_indirect() {
    for (name, desc) in [
        ("cornell", builtin::cornell()),
        ("glass-sphere", builtin::glass_sphere()),
        ("direct-indirect", builtin::direct_indirect()),
    ] {
        let (s, a) = scene(desc, 64, 64);
        let b = bdpt_estimate(&s, &a, 100, 12, 8, all(16));
        let p = pt_estimate(&s, &a, 200, 12, 32, 16, None);
        assert_agree(&format!("{name}-bdpt-vs-pt"), &b, &p, 8);
    }
}

/// Lights no ray can hit: the Cornell box lit by a point light and by a spot light under its
/// ceiling instead of its area light. Next-event estimation is one of the strategies of every
/// longer path there, and before light vertices stopped counting as scattering events in the
/// MIS weights it was left out of the longer strategies' weights, which then summed to more
/// than one (bdpt came out brighter than pt; under a delta sun, twice the analytic value).
#[test]
fn bdpt_agrees_with_pt_under_point_and_spot_lights() {
    use mirage::load::PunctualDesc;
    for (name, light) in [
        ("point", PunctualDesc::Point { position: vec3(2.78, 5.2, 2.8), intensity: Vec3::splat(30.0) }),
        (
            "spot",
            PunctualDesc::Spot {
                position: vec3(2.78, 5.2, 2.8),
                direction: -Vec3::Y,
                intensity: Vec3::splat(30.0),
                inner_cone: 0.6,
                outer_cone: 0.9,
            },
        ),
    ] {
        let mut desc = builtin::cornell();
        for m in &mut desc.materials {
            m.emission = Vec3::ZERO;
        }
        desc.lights.push(light);
        let (s, a) = scene(desc, 48, 48);
        let b = bdpt_estimate(&s, &a, 300, 12, 8, all(16));
        let p = pt_estimate(&s, &a, 400, 12, 32, 16, None);
        assert_agree(&format!("cornell-{name}-light-bdpt-vs-pt"), &b, &p, 8);
    }
}

/// Each strategy (s, t) alone, unweighted, is an unbiased estimator of the paths of its length
/// that it can sample: for lengths 2–4 on cornell (all Lambertian, area light, pinhole camera)
/// every strategy with t ≥ 1 can, so each must converge to pt restricted to that length.
#[test]
fn every_strategy_alone_converges_to_pt_of_the_same_length() {
    let (s, a) = scene(builtin::cornell(), 48, 48);
    for edges in 2..=4usize {
        let reference = pt_estimate(&s, &a, 300 + edges as u64, 12, 32, 8, Some((edges as u32, edges as u32)));
        for t in 1..=edges + 1 {
            let sv = edges + 1 - t;
            if sv == 1 && t == 1 {
                continue;
            }
            let opts = BdptOptions {
                max_depth: 8,
                only: Some(StrategyFilter { s: Some(sv), t: Some(t), weighted: false }),
                path_edges: Some(edges),
            };
            // Strategy s = 0 finds the small light by chance only: give it more samples.
            let spp = if sv == 0 { 64 } else { 16 };
            let e = bdpt_estimate(&s, &a, 400 + 10 * edges as u64 + t as u64, 12, spp, opts);
            assert_agree(&format!("cornell-length{edges}-s{sv}-t{t}"), &e, &reference, 8);
        }
    }
}

/// Light tracing alone (all t = 1 strategies, unweighted, splatted) reproduces the path tracer
/// for every path it can sample (all but the directly visible light): the splat normalisation
/// and the camera importance are right.
#[test]
fn light_tracing_alone_matches_pt() {
    let (s, a) = scene(builtin::cornell(), 48, 48);
    let opts = BdptOptions {
        max_depth: 6,
        only: Some(StrategyFilter { s: None, t: Some(1), weighted: false }),
        path_edges: None,
    };
    let lt = bdpt_estimate(&s, &a, 500, 12, 16, opts);
    // pt without paths of one edge (the light seen directly): sum over lengths 2..=7.
    let parts: Vec<Estimate> =
        (2..=7).map(|k| pt_estimate(&s, &a, 600 + k, 12, 16, 6, Some((k as u32, k as u32)))).collect();
    // Independent lengths: batch b of the reference is the sum of batch b of every length.
    let sums: Vec<Image> = (0..12)
        .map(|b| {
            let mut img = Image::new(48, 48);
            for p in &parts {
                for (d, x) in img.data.iter_mut().zip(&p.images[b].data) {
                    *d += *x;
                }
            }
            img
        })
        .collect();
    let reference = Estimate::from_batches(&sums);
    assert_agree("cornell-light-tracing-vs-pt", &lt, &reference, 8);
}

/// Scenes with geometric singularities: a light touching a wall (its edge 1e-6 of the room size
/// away), a corner where walls meet (path vertices arbitrarily close), and a light almost in the
/// plane of the floor (grazing connections).
fn singular_scenes() -> Vec<(&'static str, SceneDesc)> {
    let mut out = Vec::new();
    for variant in 0..3 {
        let mut b = Builder::new("singular");
        let wall = b.diffuse("wall", Vec3::splat(0.7));
        let le = 10.0;
        let light = b.emitter("light", Vec3::splat(le));
        b.triangles("room", wall, &cuboid(vec3(0.0, 0.0, 0.0), vec3(2.0, 2.0, 2.0), true));
        let panel = match variant {
            // Horizontal panel facing down, its edge 2e-6 from the x = 0 wall.
            0 => quad(vec3(2e-6, 1.5, 0.8), vec3(0.4, 1.5, 0.8), vec3(0.4, 1.5, 1.2), vec3(2e-6, 1.5, 1.2)),
            // Panel in the corner x = 0, z = 0 (vertical, turned to face +x below), touching the floor.
            1 => quad(vec3(1e-6, 1e-6, 1e-6), vec3(1e-6, 1e-6, 0.3), vec3(1e-6, 0.3, 0.3), vec3(1e-6, 0.3, 1e-6)),
            // Panel tilted 0.01° from the floor, 1 µm above it, facing up: grazing.
            _ => {
                let tilt = 0.01f32.to_radians().tan() * 0.4;
                quad(
                    vec3(0.8, 1e-6, 0.8),
                    vec3(0.8, 1e-6 + tilt, 1.2),
                    vec3(1.2, 1e-6 + tilt, 1.2),
                    vec3(1.2, 1e-6, 0.8),
                )
            }
        };
        // Emit from the side facing into the room.
        let panel = if variant == 1 {
            [[panel[0][0], panel[0][2], panel[0][1]], [panel[1][0], panel[1][2], panel[1][1]]]
        } else {
            panel
        };
        b.triangles("light", light, &panel);
        b.camera(vec3(1.8, 1.2, 1.8), vec3(0.2, 0.3, 0.2), 70.0, 32, 32);
        out.push((["light touching a wall", "corner", "grazing light"][variant], b.finish()));
    }
    out
}

/// No NaN or Inf, and no sample above the bound MIS guarantees near the geometry-term
/// singularity (papers/000 §4.3): with the power heuristic, the weighted contribution of
/// strategy i is `f p_i / Σ_j p_j² ≤ f / (2 p_0)` against the pure camera walk 0, whose
/// unweighted contribution `f / p_0 = Le Π ρ / q` is at most Le·(1/0.95)^depth here (Lambertian
/// albedo ≤ 1, Russian roulette survival capped at 0.95). Every strategy is therefore bounded by
/// Le·(1/0.95)^depth, and a camera sample sums at most Σ_k (k + 1) strategies. Without MIS (or
/// with broken densities) these scenes produce contributions ~1e6 Le.
#[test]
fn singular_geometry_gives_finite_samples_within_the_mis_bound() {
    let max_depth = 6u32;
    let inflation = (1.0f32 / 0.95).powi(max_depth as i32 + 2);
    let strategies: usize = (1..=max_depth as usize + 1).map(|k| k + 1).sum();
    for (name, desc) in singular_scenes() {
        let (s, a) = scene(desc, 32, 32);
        let le = 10.0f32;
        let per_strategy = le * inflation;
        let per_sample = per_strategy * strategies as f32;
        let opts = all(max_depth);
        let mut tile = FilmTile::new(0, 0, 32, 32, false);
        let mut stats = RayStats::default();
        let mut max_l = 0.0f32;
        let mut max_splat = 0.0f32;
        for i in 0..32 * 32 * 64u64 {
            let mut sampler = IndependentSampler::for_pixel_sample(9, i % 1024, i / 1024);
            let raster = vec2((i % 32) as f32 + 0.5, ((i / 32) % 32) as f32 + 0.5);
            tile.splats.clear();
            let (l, _) = bdpt::sample(&s, &a, raster, &mut sampler, &opts, &mut tile, &mut stats);
            assert!(l.is_finite(), "{name}: non-finite sample");
            max_l = max_l.max(l.max_element());
            for (_, v) in &tile.splats {
                assert!(v.is_finite(), "{name}: non-finite splat");
                max_splat = max_splat.max(v.max_element());
            }
            // pt on the same camera ray must stay finite too.
            let ray = s.camera.generate_ray(raster, vec2(0.5, 0.5));
            let (lp, _) = mirage::offline::pt::radiance(&s, &a, ray, &mut sampler, max_depth, &mut stats);
            assert!(lp.is_finite(), "{name}: non-finite pt sample");
            assert!(lp.max_element() <= per_sample, "{name}: pt sample {lp} above {per_sample}");
        }
        eprintln!("{name}: max sample {max_l}, max splat {max_splat} (bounds {per_sample}, {per_strategy})");
        assert!(max_l <= per_sample, "{name}: sample {max_l} above the MIS bound {per_sample}");
        assert!(max_splat <= per_strategy, "{name}: splat {max_splat} above the MIS bound {per_strategy}");
    }
}
