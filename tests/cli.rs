//! The command line as a new user meets it: the default render works, every scene file in
//! scenes/ renders, and bad input gives one clear error line naming the file, a non-zero exit
//! code and never a panic.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use mirage::film::Image;
use mirage::output;

fn mirage(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_mirage")).args(args).output().expect("mirage runs")
}

fn tmp(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("cli").join(name);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// The failure contract: exit code ≠ 0, exactly one line on stderr starting with
/// "mirage: error:", naming `what`, and no panic.
fn assert_clean_failure(o: &Output, what: &str) {
    let err = stderr(o);
    assert!(!o.status.success(), "expected failure for {what}, got success");
    assert!(!err.contains("panicked"), "panic for {what}: {err}");
    let lines: Vec<&str> = err.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "expected one error line for {what}: {err}");
    assert!(lines[0].starts_with("mirage: error:"), "{err}");
    assert!(lines[0].contains(what), "error line should name '{what}': {err}");
}

#[test]
fn default_render_writes_exr_and_png_of_the_cornell_box() {
    let dir = tmp("default");
    let out = dir.join("cornell.exr");
    let o =
        mirage(&["render", "--spp", "2", "--width", "32", "--height", "32", "--quiet", "-o", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let img = mirage::output::read_exr(&out).unwrap();
    assert_eq!((img.width, img.height), (32, 32));
    assert_eq!(img.non_finite_count(), 0);
    assert!(img.mean_luminance() > 0.01);
    assert!(out.with_extension("png").exists());
    let summary = String::from_utf8_lossy(&o.stdout);
    assert!(summary.contains("spp") && summary.contains("Mrays/s"), "{summary}");
    assert!(summary.contains("compensation recovered") && summary.contains("net bias estimate"), "{summary}");
    // With --aov the EXR carries the compensation term as its own layer, and only in a VPL
    // mode that compensated.
    let aov = dir.join("aov.exr");
    let small =
        ["render", "--spp", "2", "--width", "16", "--height", "16", "--quiet", "--aov", "-o", aov.to_str().unwrap()];
    let o = mirage(&small);
    assert!(o.status.success(), "{}", stderr(&o));
    let comp = mirage::output::read_exr_layer(&aov, "compensation").unwrap();
    assert_eq!(comp.non_finite_count(), 0);
    assert!(comp.mean_luminance() > 0.0, "the default clamp removes some light the compensation brings back");
    assert!(mirage::output::read_exr_layer(&aov, "albedo").is_ok());
    let o = mirage(&[&small[..], &["--compensate", "off"]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(mirage::output::read_exr_layer(&aov, "compensation").is_err());
    assert!(String::from_utf8_lossy(&o.stdout).contains("not compensated"));
}

#[test]
fn every_scene_file_renders_in_every_mode() {
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&scenes)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "gltf"))
        .collect();
    files.push(scenes.join("cornell-obj/cornell.obj"));
    files.sort();
    assert!(files.len() >= 8, "{files:?}");
    let dir = tmp("scenes");
    for f in &files {
        for mode in ["pt", "bdpt", "ir", "pssmlt"] {
            let out = dir.join(format!("{}-{mode}.exr", f.file_stem().unwrap().to_string_lossy()));
            let o = mirage(&[
                "render",
                f.to_str().unwrap(),
                "--mode",
                mode,
                "--spp",
                "1",
                "--width",
                "24",
                "--height",
                "16",
                "--quiet",
                "-o",
                out.to_str().unwrap(),
            ]);
            assert!(o.status.success(), "{} {mode}: {}", f.display(), stderr(&o));
            let img = mirage::output::read_exr(&out).unwrap();
            assert_eq!(img.non_finite_count(), 0, "{} {mode}", f.display());
        }
    }
}

#[test]
fn bad_inputs_fail_cleanly_naming_the_file() {
    let dir = tmp("bad");
    let run = |file: &Path| {
        mirage(&["render", file.to_str().unwrap(), "--spp", "1", "--width", "8", "--height", "8", "--quiet"])
    };

    // Missing file.
    let missing = dir.join("nope.gltf");
    assert_clean_failure(&run(&missing), "nope.gltf");

    // Unknown file extension.
    let fbx = dir.join("model.fbx");
    std::fs::write(&fbx, b"x").unwrap();
    assert_clean_failure(&run(&fbx), "model.fbx");

    // Broken JSON.
    let broken = dir.join("broken.gltf");
    std::fs::write(&broken, b"{ \"asset\": { \"version\": \"2.0\" ").unwrap();
    assert_clean_failure(&run(&broken), "broken.gltf");

    // Truncated .glb: take a valid scene, wrap it as GLB, cut it.
    let json = std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell.gltf")).unwrap();
    let mut glb = Vec::new();
    let pad = (4 - json.len() % 4) % 4;
    let chunk_len = json.len() + pad;
    glb.extend_from_slice(b"glTF");
    glb.extend_from_slice(&2u32.to_le_bytes());
    glb.extend_from_slice(&((12 + 8 + chunk_len) as u32).to_le_bytes());
    glb.extend_from_slice(&(chunk_len as u32).to_le_bytes());
    glb.extend_from_slice(b"JSON");
    glb.extend_from_slice(&json);
    glb.extend(std::iter::repeat_n(b' ', pad));
    let whole = dir.join("whole.glb");
    std::fs::write(&whole, &glb).unwrap();
    let ok = run(&whole);
    assert!(ok.status.success(), "the untruncated GLB renders: {}", stderr(&ok));
    let cut = dir.join("cut.glb");
    std::fs::write(&cut, &glb[..glb.len() / 2]).unwrap();
    assert_clean_failure(&run(&cut), "cut.glb");

    // NaN vertex (OBJ).
    let nan = dir.join("nan.obj");
    std::fs::write(&nan, "v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n").unwrap();
    assert_clean_failure(&run(&nan), "nan.obj");

    // No emitter.
    let dark = dir.join("dark.obj");
    std::fs::write(&dark, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    assert_clean_failure(&run(&dark), "dark.obj");
    // ... which `--add-light` lights (a panel over the model, a camera inside it).
    let room = dir.join("room.obj");
    std::fs::write(&room, "v 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0 1\nv 1 1 0\nv 1 1 1\nf 1 4 3 2\nf 2 3 6 5\n").unwrap();
    let lit_exr = dir.join("room.exr");
    let lit = mirage(&[
        "render",
        room.to_str().unwrap(),
        "--add-light",
        "--spp",
        "4",
        "--width",
        "16",
        "--height",
        "16",
        "--quiet",
        "-o",
        lit_exr.to_str().unwrap(),
    ]);
    assert!(lit.status.success(), "--add-light renders a geometry-only model: {}", stderr(&lit));
    let img = mirage::output::read_exr(&lit_exr).unwrap();
    assert_eq!(img.non_finite_count(), 0);
    assert!(img.mean_luminance() > 0.0, "the added panel lights the room");
    assert_clean_failure(&mirage(&["render", room.to_str().unwrap(), "--add-light", "0"]), "--add-light");

    // Unknown required glTF extension.
    let text = String::from_utf8(json).unwrap();
    let ext = dir.join("ext.gltf");
    assert!(text.contains("\"extensionsUsed\": ["));
    let edited = text.replacen(
        "\"extensionsUsed\": [",
        "\"extensionsRequired\": [\"KHR_unheard_of\"], \"extensionsUsed\": [\"KHR_unheard_of\", ",
        1,
    );
    std::fs::write(&ext, edited).unwrap();
    let o = run(&ext);
    assert_clean_failure(&o, "ext.gltf");
    assert!(stderr(&o).contains("KHR_unheard_of"));
}

#[test]
fn absurd_parameters_are_rejected_with_the_flag_named() {
    for (args, flag) in [
        (vec!["render", "--spp", "0"], "--spp"),
        (vec!["render", "--time", "-3"], "--time"),
        (vec!["render", "--width", "0"], "--width"),
        (vec!["render", "--threads", "0"], "--threads"),
        (vec!["render", "--mode", "ir", "--vpls", "0"], "--vpls"),
        (vec!["render", "--mode", "ir", "--clamp", "-1"], "--clamp"),
        (vec!["render", "--chains", "0"], "--chains"),
        (vec!["render", "--mode", "pssmlt", "--mlt-chains", "0"], "--mlt-chains"),
        (vec!["render", "--mode", "pssmlt", "--bootstrap", "0"], "--bootstrap"),
        (vec!["render", "--mode", "pssmlt", "--large-step", "0"], "--large-step"),
        (vec!["render", "--mode", "pssmlt", "--sigma", "NaN"], "--sigma"),
        (vec!["render", "--mode", "mlt", "--mutations", "lens,warp"], "--mutations"),
        (vec!["render", "--mode", "mlt", "--mutations", ","], "--mutations"),
        (vec!["render", "--mode", "mlt", "--bidir-share", "1.5"], "--bidir-share"),
        (vec!["render", "--mode", "mlt", "--bidir-share", "NaN"], "--bidir-share"),
        (vec!["render", "--fov-y", "200"], "field of view"),
        (vec!["render", "--eye", "0,0,0", "--target", "0,0,0"], "coincide"),
        (vec!["render", "--tonemap", "reinhard", "--exposure", "1"], "--exposure"),
        (vec!["render", "--exposure", "inf"], "--exposure"),
        (vec!["view", "--headless", "--tonemap", "reinhard", "--exposure", "-1"], "--exposure"),
        (vec!["view", "--headless", "--exposure", "NaN"], "--exposure"),
    ] {
        let o = mirage(&args);
        assert!(!o.status.success(), "{args:?} should fail");
        let err = stderr(&o);
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert!(err.contains(flag), "{args:?}: error should mention {flag}: {err}");
    }
}

/// `--mode mlt` renders a built-in scene and prints its chains' summary; a scene with a sun is
/// refused with a message naming the scene and the modes that handle it, not a panic.
#[test]
fn mlt_renders_and_refuses_lights_at_infinity() {
    let dir = tmp("mlt");
    let out = dir.join("glass.exr");
    let base = ["--mode", "mlt", "--spp", "2", "--bootstrap", "2000", "--width", "24", "--height", "16", "--quiet"];
    let mut args = vec!["render", "glass-sphere"];
    args.extend(base);
    args.extend(["-o", out.to_str().unwrap()]);
    let o = mirage(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("bidir") && text.contains("caustic") && text.contains("b = "), "{text}");
    assert_eq!(mirage::output::read_exr(&out).unwrap().non_finite_count(), 0);
    let mut args = vec!["render", "sunlit-room"];
    args.extend(base);
    let sun = dir.join("sun.exr");
    args.extend(["-o", sun.to_str().unwrap()]);
    let o = mirage(&args);
    assert!(!o.status.success());
    let err = stderr(&o);
    assert!(!err.contains("panicked") && err.contains("sunlit-room") && err.contains("pssmlt"), "{err}");
}

#[test]
fn info_and_diff_report_on_files() {
    let o = mirage(&["info", "cornell"]);
    assert!(o.status.success());
    let s = String::from_utf8_lossy(&o.stdout);
    assert!(s.contains("triangles  32") && s.contains("emitters"), "{s}");
    let o = mirage(&["diff", "missing-a.exr", "missing-b.exr"]);
    assert_clean_failure(&o, "missing-a.exr");
    assert_clean_failure(&mirage(&["png", "missing-c.exr"]), "missing-c.exr");

    // diff of an image against itself scaled by 2: nMSE = mean((x − 2x)²)/(2m)² over channels,
    // the --map image's mean; png writes the tone-mapped picture.
    let dir = tmp("diff-map");
    let (a, b) = (dir.join("a.exr"), dir.join("b.exr"));
    let img = Image { width: 2, height: 1, data: vec![glam::Vec3::new(1.0, 0.0, 0.0), glam::Vec3::splat(0.5)] };
    output::write_exr(&a, &img, Default::default()).unwrap();
    output::write_exr(&b, &img.scaled(2.0), Default::default()).unwrap();
    let map = dir.join("map.exr");
    let o = mirage(&["diff", a.to_str().unwrap(), b.to_str().unwrap(), "--map", map.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let m = 2.0 * img.mean_luminance();
    let expected = (1.0 + 3.0 * 0.25) / 6.0 / (m * m);
    let s = String::from_utf8_lossy(&o.stdout);
    let got: f64 = s.split("nmse ").nth(1).and_then(|t| t.split_whitespace().next()).unwrap().parse().unwrap();
    assert!((got / expected - 1.0).abs() < 1e-4, "{s}: nMSE {got} against {expected}");
    let mean_map = output::read_exr(&map).unwrap().mean_luminance();
    assert!((mean_map / expected - 1.0).abs() < 1e-4, "map mean {mean_map} against {expected}");
    let o = mirage(&["png", a.to_str().unwrap(), "--tonemap", "exposure", "--exposure", "-1"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let png = image::open(dir.join("a.png")).unwrap().to_rgb8();
    assert_eq!(png.get_pixel(0, 0).0, [188, 0, 0], "1.0 at −1 stop is 0.5 → sRGB 188");
}

/// A reader that stops early (`mirage info cornell | head -1`) closes stdout under the command:
/// it ends quietly with success, not with println!'s panic (exit 101).
#[test]
fn a_closed_stdout_ends_the_command_quietly() {
    use std::process::Stdio;
    for args in [&["info", "cornell"][..], &["render", "--help"][..]] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_mirage"))
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("mirage runs");
        drop(child.stdout.take());
        let o = child.wait_with_output().expect("mirage ends");
        let err = stderr(&o);
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert!(o.status.success(), "{args:?}: {:?} {err}", o.status);
    }
}
