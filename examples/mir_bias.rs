//! Where MIR's light goes: image mean over seeds against pt, with the normalisation's own
//! accounting (P_c, dropped power, compensation, VPL radiance spread) per configuration.
//!
//! ```sh
//! cargo run --release --example mir_bias -- deep-shaft 64 48 8 8 1024
//! ```
//! Arguments: scene, width, height, frames per seed, seeds, pt samples per pixel.

use mirage::accel::Accel;
use mirage::frame::{FrameSettings, render_frame};
use mirage::load::builtin;
use mirage::offline::{self, Budget, OfflineSettings};
use mirage::progress::NoProgress;
use mirage::scene::{CameraSettings, Scene};
use mirage::stats::RayStats;
use mirage::vpl::metropolis::{Chain, Mir, MirSettings, estimate_pc};
use mirage::vpl::mutation::{Bidirectional, Context, MutationKernel, PrimarySample};

fn stats(v: &[f64]) -> (f64, f64, f64) {
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    (mean, (var / n).sqrt(), s[s.len() / 2])
}

fn run<K: MutationKernel + Clone>(
    name: &str,
    s: &Scene,
    a: &Accel,
    kernel: K,
    settings: MirSettings,
    fs: FrameSettings,
    frames: u32,
    seeds: u64,
    reference: f64,
) {
    let npix = s.camera.pixel_count() as f64;
    let (mut means, mut pcs, mut dropped, mut worst, mut kept_power) = (vec![], vec![], vec![], 0.0f64, vec![]);
    let mut truncated = 0;
    let mut recovered = 0.0;
    for seed in 0..seeds {
        let mut mir = Mir::new(kernel.clone(), settings.clone());
        let mut sum = 0.0;
        for f in 0..frames {
            let frame = render_frame(s, a, &s.camera, &mut mir, &fs, 1000 * seed + f as u64);
            recovered += frame.stats.energy.recovered / npix;
            let lum: f64 = frame.image.iter().map(|c| mirage::color::luminance(*c) as f64).sum::<f64>() / npix;
            sum += lum;
            let r = &mir.last;
            pcs.push(r.pc / npix);
            dropped.push(r.dropped_share);
            kept_power.push(r.power_by_light.iter().sum::<f64>() / npix);
            worst = worst.max(r.max_over_median);
            truncated += r.truncated as u32;
        }
        means.push(sum / frames as f64 / reference);
    }
    let (m, se, med) = stats(&means);
    let lo = means.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = means.iter().copied().fold(0.0, f64::max);
    println!(
        "{name:<28} image/pt {m:.4} ± {se:.4} (median {med:.4}, {lo:.3}–{hi:.3})  P_c/pt {:.4}  kept P/pt {:.4}  dropped {:.4}  max/median {worst:.3e}  truncated {truncated}  recovered/pt {:.4}",
        stats(&pcs).0 / reference,
        stats(&kept_power).0 / reference,
        stats(&dropped).0,
        recovered / (frames as f64 * seeds as f64) / reference,
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let arg = |i: usize, d: &str| args.get(i).cloned().unwrap_or_else(|| d.to_string());
    let name = arg(1, "deep-shaft");
    let (w, h): (u32, u32) = (arg(2, "64").parse().unwrap(), arg(3, "48").parse().unwrap());
    let frames: u32 = arg(4, "8").parse().unwrap();
    let seeds: u64 = arg(5, "8").parse().unwrap();
    let spp: u32 = arg(6, "1024").parse().unwrap();
    let only = arg(7, "all");
    let desc = builtin::by_name(&name).expect("a built-in scene");
    let s = Scene::from_desc(desc, &CameraSettings { width: Some(w), height: Some(h), ..Default::default() }).unwrap();
    let a = Accel::build(&s.mesh);
    let mut refs = vec![];
    for b in 0..4 {
        let st = OfflineSettings { budget: Budget::Samples(spp / 4), seed: 77 + b, ..OfflineSettings::preview() };
        refs.push(offline::render_pt(&s, &a, &st, &NoProgress).film.image().mean_luminance());
    }
    let (reference, se, _) = stats(&refs);
    println!("{name} {w}x{h}: pt mean luminance {reference:.5} ± {se:.5} ({spp} spp)");
    if only == "pc" {
        // P_c against pt and bdpt on P_c's domain (paths of 2..=max_light + 1 edges).
        let n: usize = arg(8, "1000000").parse().unwrap();
        let dist = s.lights.distribution.clone();
        let ctx = Context { scene: &s, accel: &a, camera: &s.camera, light_choice: &dist, max_light: 16, screen: None };
        let npix = s.camera.pixel_count() as f64;
        let mut rays = RayStats::default();
        for (label, pss) in [("bidir", false), ("pss", true)] {
            let v: Vec<f64> = (0..8)
                .map(|k| {
                    let pc = if pss {
                        estimate_pc(&PrimarySample::default(), &ctx, n, 500 + k, &mut rays).0
                    } else {
                        estimate_pc(&Bidirectional::default(), &ctx, n, 500 + k, &mut rays).0
                    };
                    pc / npix
                })
                .collect();
            let (m, se, med) = stats(&v);
            println!("P_c {label} ({n} × 8): {m:.5} ± {se:.5} (median {med:.5}) = {:.4} × pt", m / reference);
        }
        let pts: Vec<f64> = (0..4)
            .map(|b| {
                let st =
                    OfflineSettings { budget: Budget::Samples(spp / 4), seed: 91 + b, ..OfflineSettings::preview() };
                offline::render_pt_of_length(&s, &a, &st, Some((2, 17)), &NoProgress).film.image().mean_luminance()
            })
            .collect();
        let (m, se, _) = stats(&pts);
        println!("pt on 2..=17 edges: {m:.5} ± {se:.5}");
        let bd: Vec<f64> = (0..4)
            .map(|b| {
                let st =
                    OfflineSettings { budget: Budget::Samples(spp / 16), seed: 191 + b, ..OfflineSettings::preview() };
                offline::render_bdpt(
                    &s,
                    &a,
                    &st,
                    &mirage::offline::bdpt::BdptOptions { max_depth: 128, only: None, path_edges: None },
                    &NoProgress,
                )
                .film
                .image()
                .mean_luminance()
            })
            .collect();
        let (m, se, _) = stats(&bd);
        println!("bdpt (all paths, {} spp): {m:.5} ± {se:.5}", spp / 4);
        return;
    }
    let base = MirSettings::mtmh();
    let (u, c) = (FrameSettings::unbiased(256), FrameSettings::compensated(256));
    let mut configs: Vec<(&str, MirSettings, FrameSettings, bool)> = vec![
        ("mtmh bidir unclamped", base.clone(), u, false),
        ("mtmh bidir comp", base.clone(), c, false),
        ("mh bidir comp", MirSettings { chain: Chain::Mh, ..base.clone() }, c, false),
        ("mtmh pss comp", base.clone(), c, true),
    ];
    if only != "all" {
        configs.retain(|c| c.0 == only);
    }
    for (label, st, fs, pss) in configs {
        if pss {
            run(label, &s, &a, PrimarySample::default(), st, fs, frames, seeds, reference);
        } else {
            run(label, &s, &a, Bidirectional::default(), st, fs, frames, seeds, reference);
        }
    }
}
