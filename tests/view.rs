//! `mirage view` end to end: the headless frame loop renders finite, lit, reproducible frames;
//! its measures (flicker, convergence, camera jumps) behave as defined; bad camera paths and a
//! missing display fail with one clear line; and the real window, under Xvfb when it is
//! installed, shows the Cornell box.

use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use mirage::film::Image;
use mirage::output;

fn mirage(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_mirage")).args(args).output().expect("mirage runs")
}

fn tmp(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("view").join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn text(o: &Output) -> (String, String) {
    (String::from_utf8_lossy(&o.stdout).into_owned(), String::from_utf8_lossy(&o.stderr).into_owned())
}

fn success(o: &Output) -> String {
    let (out, err) = text(o);
    assert!(o.status.success(), "mirage failed:\n{out}\n{err}");
    out
}

/// The failure contract of the CLI: non-zero exit, one "mirage: error:" line naming `what`.
fn assert_clean_failure(o: &Output, what: &str) -> String {
    let (_, err) = text(o);
    assert!(!o.status.success(), "expected failure for {what}");
    assert!(!err.contains("panicked"), "panic for {what}: {err}");
    let lines: Vec<&str> = err.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "expected one error line for {what}: {err}");
    assert!(lines[0].starts_with("mirage: error:") && lines[0].contains(what), "{err}");
    lines[0].to_string()
}

/// The number after `key` in `s` (e.g. "flicker 0.61" → 0.61).
fn number_after(s: &str, key: &str) -> f64 {
    let i = s.find(key).unwrap_or_else(|| panic!("'{key}' not in {s}")) + key.len();
    let t: String = s[i..].trim_start().chars().take_while(|c| c.is_ascii_digit() || ".e-+".contains(*c)).collect();
    t.parse().unwrap_or_else(|_| panic!("no number after '{key}' in {s}"))
}

fn headless(extra: &[&str]) -> Vec<String> {
    let mut a = vec!["view", "--headless", "--width", "40", "--height", "32", "--vpl-sampler", "sir", "--vpls", "64"];
    a.extend_from_slice(extra);
    a.into_iter().map(String::from).collect()
}

fn run(args: &[String]) -> Output {
    let a: Vec<&str> = args.iter().map(String::as_str).collect();
    mirage(&a)
}

#[test]
fn headless_loop_renders_finite_lit_frames_reproducibly_with_a_summary() {
    let last = |dir: &PathBuf| output::read_exr(&dir.join("frame-00003.exr")).unwrap();
    let (a, b) = (tmp("det-a"), tmp("det-b"));
    for (dir, threads) in [(&a, "1"), (&b, "2")] {
        let o = run(&headless(&[
            "--frames",
            "4",
            "--seed",
            "5",
            "--threads",
            threads,
            "--record",
            dir.to_str().unwrap(),
            "--record-exr",
        ]));
        let out = success(&o);
        let summary = out.lines().last().unwrap();
        for s in ["4 frames 40×32", "frames/s", "ms/frame", "VPLs", "primary", "shadow", "filter", "Mrays/s"] {
            assert!(summary.contains(s), "summary lacks '{s}': {summary}");
        }
        assert!(dir.join("frame-00000.png").exists() && dir.join("frame-00003.png").exists());
    }
    let img = last(&a);
    assert_eq!((img.width, img.height), (40, 32));
    assert_eq!(img.non_finite_count(), 0);
    assert!(img.mean_luminance() > 0.05, "black frame: {}", img.mean_luminance());
    assert_eq!(img, last(&b), "same seed, different thread count: frames differ");
    // Another seed gives another (equally valid) image.
    let c = tmp("det-c");
    success(&run(&headless(&["--frames", "4", "--seed", "6", "--record", c.to_str().unwrap(), "--record-exr"])));
    assert_ne!(img, last(&c));
}

#[test]
fn every_sampler_runs_in_the_frame_loop() {
    use clap::ValueEnum;
    for s in mirage::options::VplSamplerArg::value_variants() {
        let name = s.to_possible_value().unwrap().get_name().to_string();
        let dir = tmp(&format!("sampler-{name}"));
        let out = success(&mirage(&[
            "view",
            "--headless",
            "--frames",
            "2",
            "--width",
            "24",
            "--height",
            "24",
            "--vpls",
            "32",
            "--vpl-sampler",
            &name,
            "--screenshot-on-exit",
            dir.join("s.png").to_str().unwrap(),
        ]));
        assert!(out.contains(&format!("VPLs {name}")), "{out}");
        let img = output::read_exr(&dir.join("s.exr")).unwrap();
        assert_eq!(img.non_finite_count(), 0, "{name}");
        assert!(img.mean_luminance() > 0.05, "{name}: black");
    }
}

#[test]
fn flicker_without_vpl_reuse_is_the_same_for_a_stateless_sampler_and_lower_with_it() {
    let flicker = |extra: &[&str]| {
        let mut a = vec!["--frames", "48", "--flicker", "--camera-path", "orbit"];
        a.extend_from_slice(extra);
        let out = success(&run(&headless(&a)));
        let line = out.lines().find(|l| l.starts_with("flicker")).unwrap().to_string();
        (number_after(&line, "flicker"), line)
    };
    let (chain_only, line) = flicker(&["--vpl-reuse", "1"]);
    let (fresh, fresh_line) = flicker(&["--fresh-chains"]);
    let (reuse, reuse_line) = flicker(&["--vpl-reuse", "4"]);
    assert!(line.contains("chain reuse") && fresh_line.contains("fresh chains"), "{line}\n{fresh_line}");
    assert!(reuse_line.contains("VPL reuse ×4"), "{reuse_line}");
    assert!(chain_only > 0.0 && chain_only.is_finite(), "{line}");
    assert_eq!(chain_only, fresh, "sir has no chain: without VPL reuse both modes must agree");
    // Consecutive frames sharing 3/4 of their VPLs differ less than independent ones.
    assert!(reuse < 0.9 * fresh, "VPL reuse does not lower flicker: {reuse} vs {fresh}");
}

/// Frames with reused VPLs are still unbiased for a stateless sampler: the mean brightness over
/// a camera path matches fresh frames within the statistical error (frames with reuse factor K
/// are correlated over about K frames, which the bound accounts for).
#[test]
fn vpl_reuse_keeps_the_mean_brightness_of_the_frames() {
    use glam::Vec3;
    use mirage::accel::Accel;
    use mirage::load::builtin;
    use mirage::options::VplSamplerArg;
    use mirage::scene::{CameraSettings, Scene};
    use mirage::view::fly::FlyCamera;
    use mirage::view::path::{BuiltinPath, CameraPath};
    use mirage::view::session::{Session, SessionSettings};

    let frame_means = |fresh: bool, k: u32, seed: u64| {
        let scene = Scene::from_desc(builtin::cornell(), &CameraSettings::default()).unwrap();
        let accel = Accel::build(&scene.mesh);
        let mut fly = FlyCamera::from_camera(&scene.camera, Vec3::Y, scene.bounds.diagonal());
        let home = fly.pose();
        let frame = mirage::frame::FrameSettings { vpls: 64, ..mirage::frame::FrameSettings::interactive() };
        let settings = SessionSettings {
            sampler: VplSamplerArg::Sir,
            max_depth: 64,
            frame,
            seed,
            fresh_chains: fresh,
            reuse_frames: k,
            ..Default::default()
        };
        let mut s = Session::new(scene, accel, fly.camera(32, 32), settings);
        let path = CameraPath::Builtin(BuiltinPath::Orbit);
        (0..400u64)
            .map(|i| {
                fly.set_pose(path.pose(home, Vec3::Y, i % 100, 100));
                s.set_camera(fly.camera(32, 32));
                let img = s.step().image;
                img.iter().map(|p| mirage::color::luminance(*p) as f64).sum::<f64>() / img.len() as f64
            })
            .collect::<Vec<f64>>()
    };
    let stats = |v: &[f64]| {
        let n = v.len() as f64;
        let m = v.iter().sum::<f64>() / n;
        (m, v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (n - 1.0) / n)
    };
    let (mf, vf) = stats(&frame_means(true, 1, 1));
    let (mr, vr) = stats(&frame_means(false, 4, 2));
    let sigma = (vf + 4.0 * vr).sqrt();
    assert!((mr - mf).abs() < 4.0 * sigma, "reuse {mr} vs fresh {mf} (σ {sigma})");
}

#[test]
fn a_still_camera_converges_towards_a_long_run() {
    let dir = tmp("converge");
    // The view leaves the light out (a narrower field of view): at 48×48 the light's edge pixels,
    // where one jittered position that sees the emitter outweighs the rest, dominate the relMSE
    // and make it rise between 4 and 16 frames for most seeds even when every frame is traced
    // (--gbuffer-frames 1: 6 of seeds 0–9 failed). Without it, seeds 0–9 all pass.
    let view = |extra: &[&str]| {
        let mut a =
            vec!["view", "--headless", "--width", "48", "--height", "48", "--fov-y", "25", "--vpl-sampler", "sir"];
        a.extend_from_slice(extra);
        mirage(&a)
    };
    // The reference: 128 accumulated frames of an independent seed.
    let reference = dir.join("ref.png");
    success(&view(&["--frames", "128", "--seed", "99", "--screenshot-on-exit", reference.to_str().unwrap()]));
    let out = success(&view(&["--frames", "16", "--reference", dir.join("ref.exr").to_str().unwrap()]));
    let rel = |n: u32| {
        let line = out.lines().find(|l| l.trim_start().starts_with(&format!("{n} frames:"))).unwrap();
        number_after(line, "relMSE")
    };
    let (r1, r4, r16) = (rel(1), rel(4), rel(16));
    // The variance part falls as 1/N down to the reference's own (1/128): r16 / r1 ≈ 0.07 for
    // Gaussian noise; VPL noise is heavy-tailed, hence the loose bounds.
    assert!(r16 < 0.5 * r1 && r16 < r4, "relMSE does not fall: {r1} {r4} {r16}\n{out}");
    // A reference of another size is refused, naming the file.
    let small = dir.join("small.exr");
    output::write_exr(&small, &Image::new(8, 8), output::Aovs::default()).unwrap();
    let e = assert_clean_failure(&view(&["--reference", small.to_str().unwrap()]), "small.exr");
    assert!(e.contains("8×8"), "{e}");
}

#[test]
fn camera_jumps_are_detected_on_cuts_but_not_on_smooth_paths() {
    let dir = tmp("paths");
    let cut = dir.join("cut.txt");
    // Four frames: two poses of one view, then a cut across the box.
    std::fs::write(
        &cut,
        "2.78 2.73 -8 2.78 2.73 0\n2.78 2.73 -7.9 2.78 2.73 0\n# cut\n1 4 -3 2.78 2.73 0\n1 4 -3 2.78 2.73 0\n",
    )
    .unwrap();
    let out = success(&run(&headless(&["--frames", "4", "--camera-path", cut.to_str().unwrap()])));
    assert!(out.contains("1 camera jumps"), "{out}");
    let out = success(&run(&headless(&["--frames", "24", "--camera-path", "dolly"])));
    assert!(!out.contains("camera jumps"), "{out}");
}

/// Frames `0..n` of a recording.
fn recorded(dir: &std::path::Path, n: usize) -> Vec<Image> {
    (0..n).map(|i| output::read_exr(&dir.join(format!("frame-{i:05}.exr"))).unwrap()).collect()
}

#[test]
fn vpls_sampled_during_the_previous_gather_are_the_vpls_the_frame_would_sample() {
    // A still camera: from the third frame on, each frame's VPLs are sampled during the
    // previous frame's gather, with the same seed and sampler state, so the same pixels as
    // sampling them when the frame starts, for the stateful chain too.
    for sampler in ["mtmh", "sir"] {
        let (a, b) = (tmp(&format!("ahead-{sampler}")), tmp(&format!("serial-{sampler}")));
        let frames = |dir: &PathBuf, extra: &[&str]| {
            let mut args =
                vec!["view", "--headless", "--width", "40", "--height", "32", "--vpls", "64", "--frames", "6"];
            args.extend_from_slice(&["--vpl-sampler", sampler, "--record", dir.to_str().unwrap(), "--record-exr"]);
            args.extend_from_slice(extra);
            let out = success(&mirage(&args));
            (out.lines().last().unwrap().to_string(), recorded(dir, 6))
        };
        let (ahead, with) = frames(&a, &["--vpls-ahead", "always"]);
        let (serial, without) = frames(&b, &["--vpls-ahead", "never"]);
        assert!(ahead.contains("VPLs of 4 frames sampled during the previous gather"), "{ahead}");
        assert!(!serial.contains("previous gather"), "{serial}");
        assert!(with == without, "{sampler}: frames differ with VPLs sampled ahead");
    }
    // By default only a sampler that takes a millisecond or more is sampled ahead: SIR's 64
    // VPLs take microseconds.
    let dir = tmp("ahead-auto-sir");
    let out = success(&run(&headless(&["--frames", "6", "--record", dir.to_str().unwrap()])));
    assert!(!out.lines().last().unwrap().contains("previous gather"), "{out}");
    // The camera moves after three still frames: the VPLs sampled ahead for the old view are
    // dropped and the frame samples its own. sir-cdf chooses lights by their share of the
    // image, so its VPLs depend on the view; it keeps no state between frames, so dropping
    // them leaves every frame as without sampling ahead.
    let dir = tmp("ahead-move");
    let path = dir.join("still-then-move.txt");
    std::fs::write(&path, "0 1.5 0.4 0 0.9 6\n".repeat(3) + &"0.3 1.5 0.6 0 0.9 6\n".repeat(3)).unwrap();
    let frames = |name: &str, extra: &[&str]| {
        let rec = dir.join(name);
        let p = path.to_str().unwrap();
        let mut args = vec!["view", "left-right", "--headless", "--width", "40", "--height", "32", "--vpls", "64"];
        args.extend_from_slice(&["--frames", "6", "--vpl-sampler", "sir-cdf", "--camera-path", p, "--vpl-reuse", "1"]);
        args.extend_from_slice(&["--record", rec.to_str().unwrap(), "--record-exr"]);
        args.extend_from_slice(extra);
        let out = success(&mirage(&args));
        (out.lines().last().unwrap().to_string(), recorded(&rec, 6))
    };
    let (ahead, with) = frames("ahead", &["--vpls-ahead", "always"]);
    let (_, without) = frames("serial", &["--vpls-ahead", "never"]);
    // Frame 2 takes VPLs sampled during frame 1; those sampled during frame 2 are dropped at
    // the move, and frame 4 (still again) samples ahead for frame 5.
    assert!(ahead.contains("VPLs of 2 frames sampled during the previous gather"), "{ahead}");
    assert!(with == without, "frames differ after a move dropped the VPLs sampled ahead");
}

#[test]
fn bad_camera_paths_fail_with_one_line_naming_the_file() {
    let dir = tmp("bad-paths");
    let missing = dir.join("missing-path.txt");
    assert_clean_failure(&run(&headless(&["--camera-path", missing.to_str().unwrap()])), "missing-path.txt");
    let bad = dir.join("bad-path.txt");
    std::fs::write(&bad, "0 0 0 0 0 -1\n1 2 three 4 5 6\n").unwrap();
    let e = assert_clean_failure(&run(&headless(&["--camera-path", bad.to_str().unwrap()])), "bad-path.txt");
    assert!(e.contains("line 2"), "{e}");
    let empty = dir.join("empty-path.txt");
    std::fs::write(&empty, "# nothing\n").unwrap();
    assert_clean_failure(&run(&headless(&["--camera-path", empty.to_str().unwrap()])), "empty-path.txt");
}

#[test]
fn without_a_display_the_window_fails_with_one_line_pointing_to_render_and_headless() {
    let o = Command::new(env!("CARGO_BIN_EXE_mirage"))
        .args(["view", "--frames", "1"])
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .env_remove("WAYLAND_SOCKET")
        .output()
        .unwrap();
    let e = assert_clean_failure(&o, "mirage render");
    assert!(e.contains("--headless"), "{e}");
}

/// An X server on a display it chose itself (`-displayfd`), killed when dropped.
struct Xvfb(std::process::Child, String);

impl Xvfb {
    fn start() -> Option<Xvfb> {
        let found = Command::new("sh").args(["-c", "command -v Xvfb"]).output().ok()?;
        if !found.status.success() {
            return None;
        }
        let mut child = Command::new("Xvfb")
            .args(["-displayfd", "1", "-screen", "0", "320x240x24", "-nolisten", "tcp"])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .ok()?;
        let mut line = String::new();
        BufReader::new(child.stdout.take()?).read_line(&mut line).ok()?;
        let display = format!(":{}", line.trim());
        if line.trim().is_empty() {
            let _ = child.kill();
            return None;
        }
        Some(Xvfb(child, display))
    }
}

impl Drop for Xvfb {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[test]
fn the_window_under_xvfb_shows_the_cornell_box() {
    let Some(x) = Xvfb::start() else {
        eprintln!("note: Xvfb is not installed; the window test is skipped (apt-get install -y xvfb)");
        return;
    };
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("test-output");
    std::fs::create_dir_all(&dir).unwrap();
    let png = dir.join("view-window.png");
    let _ = std::fs::remove_file(&png);
    let start = Instant::now();
    let o = Command::new(env!("CARGO_BIN_EXE_mirage"))
        .args(["view", "--frames", "5", "--width", "96", "--height", "96", "--vpl-sampler", "sir"])
        .args(["--screenshot-on-exit", png.to_str().unwrap()])
        .env("DISPLAY", &x.1)
        .env_remove("WAYLAND_DISPLAY")
        .env_remove("WAYLAND_SOCKET")
        .output()
        .unwrap();
    let out = success(&o);
    assert!(start.elapsed() < Duration::from_secs(120));
    assert!(out.contains("(window): 5 frames 96×96"), "{out}");
    let shot = image::open(&png).expect("the screenshot PNG is readable").to_rgb8();
    assert_eq!(shot.dimensions(), (96, 96));
    let mean = shot.as_raw().iter().map(|&v| v as f64).sum::<f64>() / shot.as_raw().len() as f64;
    assert!(mean > 30.0, "screenshot is (nearly) black: mean {mean}");
    let exr = output::read_exr(&png.with_extension("exr")).unwrap();
    assert_eq!(exr.non_finite_count(), 0);
    assert!(exr.mean_luminance() > 0.05);
}
