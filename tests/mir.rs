//! Metropolis instant radiosity: camera power, unbiasedness of the VPL estimate, the share of
//! each room in left-right, and the extremes (invisible light, light through a tiny hole).

mod common;

use common::{Estimate, assert_agree_blocks};
use glam::{Vec3, vec3};
use mirage::accel::Accel;
use mirage::color::luminance;
use mirage::film::Image;
use mirage::frame::{self, Accumulation, FrameSettings};
use mirage::load::SceneDesc;
use mirage::load::builtin::{self, Builder, cuboid, quad, rect_with_holes};
use mirage::offline::pt::PathFilter;
use mirage::offline::{self, Budget, OfflineSettings};
use mirage::options::{KernelArg, SamplerConfig, VplSamplerArg};
use mirage::progress::NoProgress;
use mirage::sampling::Distribution1D;
use mirage::scene::{CameraSettings, Scene};
use mirage::stats::RayStats;
use mirage::vpl::VplSampler;
use mirage::vpl::metropolis::{Mir, MirSettings, estimate_pc};
use mirage::vpl::mutation::{Bidirectional, Context, PrimarySample};

fn scene(desc: SceneDesc, w: u32, h: u32) -> (Scene, Accel) {
    let s = Scene::from_desc(desc, &CameraSettings { width: Some(w), height: Some(h), ..Default::default() }).unwrap();
    let a = Accel::build(&s.mesh);
    (s, a)
}

fn pt(s: &Scene, a: &Accel, spp: u32, seed: u64, edges: Option<(u32, u32)>) -> Image {
    let st = OfflineSettings { budget: Budget::Samples(spp), seed, max_depth: 64, ..OfflineSettings::preview() };
    offline::render_pt_of_length(s, a, &st, edges, &NoProgress).film.image()
}

/// P_c, estimated from independent bidirectional samples, equals the total image luminance the
/// path tracer computes on the same path domain (paths with at least one vertex after the
/// visible point, at most `max_light + 1` edges) within 2 %.
#[test]
fn camera_power_matches_the_path_traced_image_luminance() {
    let (s, a) = scene(builtin::cornell(), 64, 64);
    let max_light = 16;
    let reference = pt(&s, &a, 256, 1, Some((2, max_light as u32 + 1)));
    let total = reference.mean_luminance() * (64.0 * 64.0);
    let dist: Distribution1D = s.lights.distribution.clone();
    let ctx = Context { scene: &s, accel: &a, camera: &s.camera, light_choice: &dist, max_light, screen: None };
    let mut rays = RayStats::default();
    let (pc_bidir, _) = estimate_pc(&Bidirectional::default(), &ctx, 200_000, 3, &mut rays);
    let (pc_pss, _) = estimate_pc(&PrimarySample::default(), &ctx, 100_000, 4, &mut rays);
    for (name, pc) in [("bidir", pc_bidir), ("pss", pc_pss)] {
        let rel = (pc - total) / total;
        eprintln!("P_c {name}: {pc:.4} vs pt {total:.4} ({:+.2} %)", 100.0 * rel);
        assert!(rel.abs() < 0.02, "{name}: P_c {pc} vs total image luminance {total}");
    }
}

/// The comparison domain: paths whose segment from the visible point to the next vertex is at
/// least 5 % of the scene diagonal. Unclamped VPL gathering has infinite variance as that
/// segment shrinks (G ∝ 1/d²), so a variance-based test is only valid away from it; pt
/// restricted the same way estimates the same integral (`offline::pt::PathFilter`).
fn min_segment(s: &Scene) -> f32 {
    0.05 * s.bounds.diagonal()
}

fn mir_estimate(
    s: &Scene,
    a: &Accel,
    kind: VplSamplerArg,
    kernel: KernelArg,
    batches: u64,
    frames: u32,
    seed: u64,
) -> Estimate {
    let settings = FrameSettings { interleave: (4, 4), min_distance: min_segment(s), ..FrameSettings::unbiased(256) };
    let imgs: Vec<Image> = (0..batches)
        .map(|b| {
            let mut sampler = kind.build_with(&SamplerConfig { kernel, ..Default::default() });
            let acc =
                Accumulation { budget: Budget::Samples(frames), seed: seed + 1000 * b, aovs: false, filter_fade: None };
            let (out, _) = frame::render_progressive(s, a, sampler.as_mut(), &settings, acc, &NoProgress);
            let img = out.film.image();
            assert_eq!(img.non_finite_count(), 0);
            img
        })
        .collect();
    Estimate::from_batches(&imgs)
}

/// With clamp 0 and no filter, MIR images averaged over many independent chains converge to the
/// path tracer (on the finite-variance domain of [`min_segment`]).
#[test]
fn unclamped_mir_converges_to_pt() {
    for (name, desc) in [("cornell", builtin::cornell()), ("direct-indirect", builtin::direct_indirect())] {
        let (s, a) = scene(desc, 48, 48);
        let filter = PathFilter { min_second_segment: min_segment(&s), ..Default::default() };
        let imgs: Vec<Image> = (0..16)
            .map(|b| {
                let st = OfflineSettings {
                    budget: Budget::Samples(32),
                    seed: 50 + b,
                    max_depth: 64,
                    ..OfflineSettings::preview()
                };
                offline::render_pt_filtered(&s, &a, &st, &filter, &NoProgress).film.image()
            })
            .collect();
        let reference = Estimate::from_batches(&imgs);
        for (kind, kernel) in [
            (VplSamplerArg::Mtmh, KernelArg::Bidir),
            (VplSamplerArg::Mtmh, KernelArg::Pss),
            (VplSamplerArg::Mh, KernelArg::Bidir),
        ] {
            let e = mir_estimate(&s, &a, kind, kernel, 16, 6, 9);
            assert_agree_blocks(&format!("{name}-mir-{kind:?}-{kernel:?}-vs-pt"), &e, &reference, 8);
        }
    }
}

/// Share of the camera power that left-right's left room brings, from pt renders with one
/// room's light switched off.
fn left_share_reference(desc: &SceneDesc) -> f64 {
    let lum = |off: &str| {
        let mut d = desc.clone();
        for m in &mut d.materials {
            if m.name == off {
                m.emission = Vec3::ZERO;
            }
        }
        let (s, a) = scene(d, 64, 48);
        pt(&s, &a, 64, 7, Some((2, 64))).mean_luminance()
    };
    let left = lum("right light");
    let right = lum("left light");
    left / (left + right)
}

/// MTMH with 256 VPLs gives each room's VPLs a share of camera power within ±15 % of the
/// reference share, averaged over 20 seeds (papers/002 §7.3, Fig. 4). MH's share is printed.
#[test]
fn mtmh_visits_both_rooms_in_left_right() {
    let desc = builtin::left_right();
    let reference = left_share_reference(&desc);
    let (s, a) = scene(desc, 64, 48);
    let left_lights: Vec<bool> = s
        .lights
        .list
        .iter()
        .map(|l| match l {
            mirage::scene::Light::Area { tri, .. } => s.material_of(*tri).name == "left light",
            _ => false,
        })
        .collect();
    for (chain, name) in [(MirSettings::mtmh(), "mtmh"), (MirSettings::mh(), "mh")] {
        let mut shares = Vec::new();
        for seed in 0..20u64 {
            let mut mir =
                Mir::new(Bidirectional::default(), MirSettings { pc_samples: 1024, probes: 256, ..chain.clone() });
            mir.sample(&s, &a, &s.camera, 256, 100 + seed);
            let p = &mir.last.power_by_light;
            let left: f64 = p.iter().zip(&left_lights).filter(|(_, l)| **l).map(|(p, _)| p).sum();
            let total: f64 = p.iter().sum();
            shares.push(left / total);
        }
        let mean = shares.iter().sum::<f64>() / shares.len() as f64;
        let spread = shares.iter().map(|x| (x - mean).abs()).fold(0.0f64, f64::max);
        eprintln!("{name}: left share {mean:.3} (max deviation of one seed {spread:.3}) vs reference {reference:.3}");
        if name == "mtmh" {
            assert!((mean - reference).abs() <= 0.15 * reference, "mtmh left share {mean} vs reference {reference}");
        }
    }
}

/// A light the camera cannot see by any path: P_c = 0, a clear report and a black image.
#[test]
fn invisible_light_gives_a_black_image_and_a_dark_report() {
    let mut b = Builder::new("sealed");
    let wall = b.diffuse("wall", Vec3::splat(0.7));
    let light = b.emitter("lamp", Vec3::splat(10.0));
    b.triangles("room", wall, &cuboid(vec3(0.0, 0.0, 0.0), vec3(4.0, 3.0, 4.0), true));
    // A closed box with 5 cm walls around the lamp (a wall of zero thickness would let rays
    // offset off a surface near an edge slip through at the 1e-13 level).
    b.triangles("box", wall, &cuboid(vec3(1.5, 0.0, 1.5), vec3(2.5, 1.0, 2.5), false));
    b.triangles("box inside", wall, &cuboid(vec3(1.55, 0.05, 1.55), vec3(2.45, 0.95, 2.45), true));
    b.triangles(
        "lamp",
        light,
        &quad(vec3(1.8, 0.9, 1.8), vec3(2.2, 0.9, 1.8), vec3(2.2, 0.9, 2.2), vec3(1.8, 0.9, 2.2)),
    );
    b.camera(vec3(0.5, 2.0, 3.5), vec3(2.0, 0.5, 2.0), 60.0, 32, 24);
    let (s, a) = scene(b.finish(), 32, 24);
    let mut mir = Mir::new(Bidirectional::default(), MirSettings { pc_samples: 2048, ..MirSettings::mtmh() });
    let (set, _) = mir.sample(&s, &a, &s.camera, 64, 1);
    assert!(mir.last.dark && set.is_empty() && mir.last.pc == 0.0, "{:?}, {} VPLs", mir.last, set.len());
    let mut sampler: Box<dyn VplSampler> = Box::new(mir);
    let f = frame::render_frame(&s, &a, &s.camera, sampler.as_mut(), &FrameSettings::interactive(), 1);
    assert!(f.image.iter().all(|p| *p == Vec3::ZERO), "the image must be black, not NaN");
}

/// The only light paths pass through one 2 cm hole: the chain still finds m locations, or stops
/// at its documented bound (max_steps_per_vpl · m states) and says so.
#[test]
fn light_through_a_tiny_hole_yields_vpls_or_a_truncation_report() {
    let mut b = Builder::new("pinhole");
    let wall = b.diffuse("wall", Vec3::splat(0.7));
    let light = b.emitter("lamp", Vec3::splat(200.0));
    b.triangles("room", wall, &cuboid(vec3(0.0, 0.0, 0.0), vec3(4.0, 3.0, 4.0), true));
    // A box over the lamp whose only opening is a 2 cm hole in its top.
    let (lo, hi) = (vec3(1.5, 0.0, 1.5), vec3(2.5, 1.0, 2.5));
    let mut shell = cuboid(lo, hi, false);
    shell.retain(|t| t.iter().any(|p| p.y < hi.y - 1e-4)); // drop the lid
    shell.extend(rect_with_holes(vec3(lo.x, hi.y, lo.z), Vec3::Z, Vec3::X, 1.0, 1.0, &[[0.49, 0.49, 0.51, 0.51]]));
    b.triangles("box", wall, &shell);
    b.triangles(
        "lamp",
        light,
        &quad(vec3(1.9, 0.01, 1.9), vec3(1.9, 0.01, 2.1), vec3(2.1, 0.01, 2.1), vec3(2.1, 0.01, 1.9)),
    );
    b.camera(vec3(0.5, 2.5, 3.5), vec3(2.0, 2.0, 2.0), 60.0, 32, 24);
    let (s, a) = scene(b.finish(), 32, 24);
    let mut mir = Mir::new(
        Bidirectional::default(),
        MirSettings { pc_samples: 8192, max_steps_per_vpl: 16, ..MirSettings::mtmh() },
    );
    let m = 64;
    let (set, stats) = mir.sample(&s, &a, &s.camera, m, 5);
    eprintln!(
        "tiny hole: P_c {:.4e}, {} locations from {} states, truncated {}, {} VPLs",
        mir.last.pc,
        mir.last.locations,
        mir.last.states,
        mir.last.truncated,
        set.len()
    );
    assert!(!mir.last.dark, "light does reach the camera through the hole");
    assert!(mir.last.locations == m || mir.last.truncated);
    assert!(mir.last.states <= 16 * m as u64);
    assert!(set.radiance.iter().all(|r| r.is_finite()));
    assert!(stats.proposed > 0);
    let _ = luminance(Vec3::ONE);
}

/// The chains run in parallel, but the chain count, not the thread count, fixes the result:
/// three consecutive runs give bit-identical VPL sets on one and on two threads, with the
/// default 64 chains started afresh each run and with two chains carried from run to run (as
/// `--carry-chains` does in the viewer), where the screen guide and the P_c sample count also
/// pass from one run to the next.
#[test]
fn parallel_chains_give_the_same_vpls_on_one_and_two_threads() {
    let (s, a) = scene(builtin::cornell(), 64, 64);
    let defaults = MirSettings::mtmh();
    assert_eq!((defaults.chains, defaults.carry), (64, false));
    for settings in [
        MirSettings { pc_samples: 512, probes: 256, ..MirSettings::mtmh() },
        MirSettings { pc_samples: 512, probes: 256, chains: 2, carry: true, ..MirSettings::mtmh() },
    ] {
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| {
                let mut mir = Mir::new(Bidirectional::default(), settings.clone());
                (0..3u64)
                    .map(|seed| {
                        let (set, _) = mir.sample(&s, &a, &s.camera, 64, seed);
                        let bits =
                            |v: &[Vec3]| v.iter().flat_map(|p| p.to_array().map(f32::to_bits)).collect::<Vec<_>>();
                        (bits(&set.position), bits(&set.radiance), set.count.clone(), set.group.clone())
                    })
                    .collect::<Vec<_>>()
            })
        };
        let one = run(1);
        // Not vacuous: every run gave VPLs (about 64; the count varies with the chains' moves).
        let counts: Vec<usize> = one.iter().map(|r| r.0.len() / 3).collect();
        assert!(counts.iter().all(|&c| c >= 16), "{} chains: {counts:?}", settings.chains);
        assert_eq!(one, run(2), "{} chains", settings.chains);
    }
}

/// `count` independent 16-frame renders (seeds `seed0 + 1000·b`), each with a fresh sampler
/// and the filter faded out with `fade` ([`Accumulation::filter_fade`]), checked finite, as
/// batches.
fn seed_runs(
    name: &str,
    s: &Scene,
    a: &Accel,
    sampler: impl Fn() -> Box<dyn VplSampler>,
    (settings, fade): (&FrameSettings, Option<u32>),
    seed0: u64,
    count: u64,
) -> Estimate {
    let imgs: Vec<Image> = (0..count)
        .map(|b| {
            let acc =
                Accumulation { budget: Budget::Samples(16), seed: seed0 + 1000 * b, aovs: false, filter_fade: fade };
            let (out, _) = frame::render_progressive(s, a, sampler().as_mut(), settings, acc, &NoProgress);
            let img = out.film.image();
            assert_eq!(img.non_finite_count(), 0, "{name}");
            img
        })
        .collect();
    Estimate::from_batches(&imgs)
}

/// Mean luminance of each batch image, its mean and standard error, median and range.
fn seed_spread(e: &Estimate) -> (f64, f64, f64, f64, f64) {
    let mut v: Vec<f64> = e.images.iter().map(|i| i.mean_luminance()).collect();
    let k = v.len() as f64;
    let m = v.iter().sum::<f64>() / k;
    let se = (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (k - 1.0) / k).sqrt();
    v.sort_by(f64::total_cmp);
    (m, se, v[v.len() / 2], v[0], v[v.len() - 1])
}

/// On the hard-visibility scenes (a slit in a thick wall, a lamp in a box with small tunnels,
/// a lamp at the top of a deep shaft) MIR without a bias of its own — the gather clamped at
/// the chain target's bound and compensated, no filter, no cap on VPL radiance — agrees with
/// the path tracer: per 8×8 block (the block test) and in image mean within four standard
/// errors of the difference, over 8 seeds, for MTMH and MH with both kernels. Before issue 19
/// the slit scene's MIR mean was 0.61 of pt's (the clamped target missed the short
/// connections next to the slit, and the radiance cap removed more); that the bare clamp is
/// darker there is checked once, with the default render's settings, by
/// `the_default_render_agrees_with_pt_on_every_diffuse_scene` (here it came out at 0.75 of pt,
/// z = 3.8 over 16 seeds; there z = 7.4 over 8: the same check at half the power and 10 s of
/// CI, so it was dropped here). At this budget the mean
/// test's bound of four standard errors alone would not reject a 25 % loss on the slit scene:
/// its resolution is the seeds' spread, ~9 % of the mean there and ~2 % on deep-shaft. pt needs its 8 × 1536 spp: at 384
/// its own heavy tail (light through the shaft is rare for camera paths too) put its mean 4–7 %
/// below every MIR configuration on deep-shaft and failed the block test on pt's side.
/// This test passed while the compensation's residual, estimated with MIR's own VPLs, still
/// left 15 % of the slit scene's light out (its resolution there is ~25 %):
/// `the_compensation_brings_back_what_the_chains_clamped_target_leaves_out` is the sharp check.
#[test]
fn compensated_mir_agrees_with_pt_on_the_hard_scenes() {
    for name in builtin::HARD_NAMES {
        let (s, a) = scene(builtin::by_name(name).unwrap(), 32, 24);
        let imgs: Vec<Image> = (0..8)
            .map(|b| {
                let st = OfflineSettings {
                    budget: Budget::Samples(1536),
                    seed: 70 + b,
                    max_depth: 64,
                    ..OfflineSettings::preview()
                };
                offline::render_pt(&s, &a, &st, &NoProgress).film.image()
            })
            .collect();
        let reference = Estimate::from_batches(&imgs);
        let (r, se_r, ..) = seed_spread(&reference);
        let settings = FrameSettings { interleave: (4, 4), ..FrameSettings::compensated(256) };
        let run = |kind: VplSamplerArg, kernel: KernelArg, settings: &FrameSettings| {
            let config = SamplerConfig { kernel, ..Default::default() };
            seed_runs(name, &s, &a, || kind.build_with(&config), (settings, None), 31, 8)
        };
        for (kind, kernel) in [
            (VplSamplerArg::Mtmh, KernelArg::Bidir),
            (VplSamplerArg::Mtmh, KernelArg::Pss),
            (VplSamplerArg::Mh, KernelArg::Bidir),
            (VplSamplerArg::Mh, KernelArg::Pss),
        ] {
            let e = run(kind, kernel, &settings);
            let (m, se, med, lo, hi) = seed_spread(&e);
            let z = (m - r) / (se * se + se_r * se_r).sqrt();
            eprintln!(
                "{name} {kind:?} {kernel:?}: mean/pt {:.3} ± {:.3} (median {:.3}, {:.3}–{:.3}), z = {z:.2}",
                m / r,
                se / r,
                med / r,
                lo / r,
                hi / r
            );
            assert!(z.abs() < 4.0, "{name} {kind:?} {kernel:?}: image mean {m} vs pt {r} (z = {z:.2})");
            assert_agree_blocks(&format!("{name}-compensated-{kind:?}-{kernel:?}-vs-pt"), &e, &reference, 8);
        }
    }
}

/// The options of `mirage render --mode mir` with no other flag (mtmh, 256 VPLs, 8×8
/// interleave, clamp 300 compensated, discontinuity buffer faded out), at the given image size.
fn default_render_options(w: u32, h: u32) -> mirage::options::RenderOptions {
    use clap::Parser;
    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        render: mirage::options::RenderArgs,
    }
    let (w, h) = (w.to_string(), h.to_string());
    Cli::parse_from(["mirage", "--mode", "mir", "--width", &w, "--height", &h]).render.options().unwrap()
}

/// What a user gets from the default `mirage render` (MIR, clamp 300 compensated, filter faded
/// out over the frames):
/// on every built-in diffuse scene, easy and hard, the image mean over 8 seeds agrees with
/// pt's. Checked two ways: within four standard errors of the difference (the seeds' spread
/// is what resolves a bias), and, where that resolution is finer than 1 % of the mean, within
/// 1 %. On the hard scenes also per 8×8 block, the interleave tile (the block test: no block
/// of the mean image brighter or darker than pt's beyond the two estimates' noise; the bright
/// 8×8 squares of issue 19 were such blocks). Without compensation the same renders are darker where the
/// clamp acts much (on the slit and box scenes, by more than 3 standard errors).
#[test]
fn the_default_render_agrees_with_pt_on_every_diffuse_scene() {
    let (w, h) = (32, 24);
    let options = default_render_options(w, h);
    assert!(options.frame.compensate && options.frame.clamp == 300.0 && options.frame.filter.is_some());
    assert_eq!(options.filter_fade, Some(64));
    let mut unresolved = Vec::new();
    for name in builtin::NAMES.into_iter().filter(|n| *n != "glass-sphere") {
        let (s, a) = scene(builtin::by_name(name).unwrap(), w, h);
        let hard = builtin::HARD_NAMES.contains(&name);
        let imgs: Vec<Image> = (0..8)
            .map(|b| {
                let spp = if hard { 1536 } else { 512 };
                let st = OfflineSettings { budget: Budget::Samples(spp), seed: 90 + b, ..options.offline };
                offline::render_pt(&s, &a, &st, &NoProgress).film.image()
            })
            .collect();
        let reference = Estimate::from_batches(&imgs);
        let (r, se_r, ..) = seed_spread(&reference);
        let sampler = || options.vpl_sampler.build_with(&options.sampler);
        let default = seed_runs(name, &s, &a, sampler, (&options.frame, options.filter_fade), 7, 8);
        let (m, se, med, lo, hi) = seed_spread(&default);
        // On the hard scenes, no 8×8 block (the interleave tile, the squares' size) brighter or
        // darker than pt's beyond the noise of the two estimates. Not on sunlit-room at this
        // size: there the discontinuity buffer (weight 0.8 after 16 frames) blurs the sun's
        // sharp patches over its 8×8 window, a quarter of a 32×24 image, and moves up to 25 % of
        // a block's light to its neighbour (measured over 8 seeds: blocks −16 % and +20 %
        // beside the patch on the far wall; with --no-filter every block within 3 %). That is
        // the filter's known blur where light changes within a few pixels, which the fade
        // removes as frames accumulate, not the estimator's.
        if hard {
            assert_agree_blocks(&format!("{name}-default-render-vs-pt"), &default, &reference, 8);
        }
        let sd = (se * se + se_r * se_r).sqrt();
        let z = (m - r) / sd;
        eprintln!(
            "{name}: default render mean/pt {:.4} ± {:.4} (median {:.3}, {:.3}–{:.3}; pt ± {:.4}), z = {z:.2}",
            m / r,
            se / r,
            med / r,
            lo / r,
            hi / r,
            se_r / r
        );
        assert!(z.abs() < 4.0, "{name}: default render mean {m} vs pt {r} (z = {z:.2})");
        if 4.0 * sd < 0.01 * r {
            assert!((m - r).abs() < 0.01 * r, "{name}: default render mean {m} more than 1 % from pt {r}");
        } else {
            unresolved.push(format!("{name} (4 s.e. = {:.1} %)", 400.0 * sd / r));
        }
        // The loss without compensation is resolved on the slit scene only. On light-box-thick
        // the uncompensated mean's standard error at this budget (8–9 % over 16 seeds, a heavy
        // tail of runs lit by a few strong VPLs) is the size of the loss (13 %, the chains'
        // clamped target): measured z 3.9, 2.6 (8 seeds) and 1.3 (16 seeds) with three sets of
        // streams, so the check there had no power and passed by the draw.
        if name == "ajar-door-thick" {
            // 16 seeds: at 8 a 24 % loss gave z 7.4; more seeds keep the margin.
            let sampler = || options.vpl_sampler.build_with(&options.sampler);
            let bare = FrameSettings { compensate: false, ..options.frame };
            let (m, se, ..) = seed_spread(&seed_runs(name, &s, &a, sampler, (&bare, options.filter_fade), 7, 16));
            let z = (r - m) / (se * se + se_r * se_r).sqrt();
            eprintln!("{name}: uncompensated mean/pt {:.4} ± {:.4}, z = {z:.2}", m / r, se / r);
            assert!(z > 3.0, "{name}: without compensation the default render should be darker (z = {z:.2})");
        }
    }
    eprintln!("1 % not resolvable at this budget on: {}", unresolved.join(", "));
}

/// MIR's VPLs bring, by their normalisation, the chain target's clamped camera power P_c; the
/// clamp compensation must add the rest. On the slit scene, where the clamped target leaves
/// out 30 % of pt's light, P̂_c plus the light the compensation recovered, averaged over
/// 32 seeds × 16 frames, equals pt's image luminance within four standard errors (one is
/// ~2.5 % here, nearly all of it P̂_c's). The residual estimated with MIR's own VPLs
/// (Kollig & Keller's recursion) recovered 0.157 of the 0.30 (sum 0.857, z ≈ −5 at this
/// resolution); the path-traced residual recovers 0.287.
#[test]
fn the_compensation_brings_back_what_the_chains_clamped_target_leaves_out() {
    let (s, a) = scene(builtin::by_name("ajar-door-thick").unwrap(), 32, 24);
    let npix = s.camera.pixel_count() as f64;
    let refs: Vec<f64> = (0..8).map(|b| pt(&s, &a, 1024, 120 + b, None).mean_luminance()).collect();
    let (r, se_r) = mean_se(&refs);
    let settings = FrameSettings { interleave: (4, 4), ..FrameSettings::compensated(256) };
    let (mut pcs, mut totals) = (vec![], vec![]);
    for seed in 0..32u64 {
        let mut mir = Mir::new(Bidirectional::default(), MirSettings::mtmh());
        let (mut pc, mut total) = (0.0, 0.0);
        for f in 0..16 {
            let fr = frame::render_frame(&s, &a, &s.camera, &mut mir, &settings, 1000 * seed + f);
            pc += mir.last.pc / npix / 16.0;
            total += (mir.last.pc + fr.stats.energy.recovered) / npix / 16.0;
        }
        pcs.push(pc);
        totals.push(total);
    }
    let (pc, _) = mean_se(&pcs);
    let (m, se) = mean_se(&totals);
    let z = (m - r) / (se * se + se_r * se_r).sqrt();
    eprintln!("P_c/pt {:.3}, (P_c + recovered)/pt {:.4} ± {:.4}, z = {z:.2}", pc / r, m / r, se / r);
    assert!(pc < 0.8 * r, "not vacuous: the clamped target leaves much out (P_c/pt = {:.3})", pc / r);
    assert!(z.abs() < 4.0, "P_c + recovered = {m} vs pt {r} (z = {z:.2})");
}

fn mean_se(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    (m, (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0) / n).sqrt())
}

/// The bound on how unevenly the default render's VPLs light the image (issue 19's 8×8
/// squares): in the median frame, the strongest VPL brings at most 64 times the median VPL's
/// light (the interleave tile's pixel count: one VPL worth a whole tile of its peers). Measured
/// at 256×192 over 16 frames: 3.9 cornell, 7.3 deep-shaft, 20.5 ajar-door-thick, 30.7
/// light-box-thick (without splitting strong VPLs 8.5, 10.4, 31.4, 40.6; SIR 4.1, 49.8, 39.3,
/// 23.3, its worst frames 7–4734). The median frame is what a viewer sees most; the worst
/// frame is printed by `render`. On light-box-thick what remains is VPLs seen through the
/// holes, which light a few pixels each and whose screen regions are too large to gather
/// whole.
#[test]
fn the_default_renders_vpls_bring_comparable_light() {
    let (w, h) = (256, 192);
    let options = default_render_options(w, h);
    assert!(options.frame.vpl_power && options.frame.split_strong > 0.0);
    for name in ["cornell", "ajar-door-thick", "light-box-thick", "deep-shaft"] {
        let (s, a) = scene(builtin::by_name(name).unwrap(), w, h);
        let mut sampler = options.vpl_sampler.build_with(&options.sampler);
        let acc = Accumulation { budget: Budget::Samples(16), seed: 3, aovs: false, filter_fade: options.filter_fade };
        let (out, stats) = frame::render_progressive(&s, &a, sampler.as_mut(), &options.frame, acc, &NoProgress);
        assert_eq!(out.film.image().non_finite_count(), 0, "{name}");
        let mut r = stats.power_ratios.clone();
        assert_eq!(r.len(), 16, "{name}: a ratio per frame");
        r.sort_by(f32::total_cmp);
        let median = r[r.len() / 2];
        eprintln!("{name}: strongest / median VPL {median:.1} (median frame), {:.1} (worst)", r[r.len() - 1]);
        assert!(median <= 64.0, "{name}: the strongest VPL brings {median:.1}× the median one's light");
    }
}
