//! The default pictures: `mirage render`'s PNG of the built-in Cornell box, and a frame that
//! `mirage view --headless --record` writes, keep the linear image's hues (the red wall stays
//! red, not orange), clip no channel of the walls, show the light as the brightest region, and
//! are neither dark nor washed out. The linear EXR written beside the PNG tells which pixels
//! are the red wall, the walls and the light.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use glam::Vec3;
use mirage::color::{luminance, srgb_to_linear};
use mirage::film::Image;
use mirage::output;

fn mirage(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_mirage")).args(args).output().expect("mirage runs")
}

fn tmp(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("pictures").join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn success(o: &Output) {
    assert!(
        o.status.success(),
        "mirage failed:\n{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
}

/// The PNG's pixels as 8-bit RGB.
fn read_png(path: &Path) -> (u32, u32, Vec<[u8; 3]>) {
    let img = image::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display())).to_rgb8();
    let (w, h) = img.dimensions();
    (w, h, img.pixels().map(|p| p.0).collect())
}

/// Hue angle (degrees) of linear sRGB in Oklab (Ottosson 2020): a perceptual hue.
fn oklab_hue(c: Vec3) -> f64 {
    let (r, g, b) = (c.x as f64, c.y as f64, c.z as f64);
    let l = (0.412_221_470_8 * r + 0.536_332_536_3 * g + 0.051_445_992_9 * b).cbrt();
    let m = (0.211_903_498_2 * r + 0.680_699_545_1 * g + 0.107_396_956_6 * b).cbrt();
    let s = (0.088_302_461_9 * r + 0.281_718_837_6 * g + 0.629_978_700_5 * b).cbrt();
    let a = 1.977_998_495_1 * l - 2.428_592_205 * m + 0.450_593_709_9 * s;
    let bb = 0.025_904_037_1 * l + 0.782_771_766_2 * m - 0.808_675_766 * s;
    bb.atan2(a).to_degrees()
}

/// The properties of a default picture `png` of the Cornell box whose linear image is `linear`.
fn assert_looks_right(what: &str, linear: &Image, (w, h, png): (u32, u32, Vec<[u8; 3]>)) {
    assert_eq!((w, h), (linear.width, linear.height), "{what}: PNG and EXR sizes");
    let lum: Vec<f32> = linear.data.iter().map(|&p| luminance(p)).collect();
    let max = lum.iter().cloned().fold(0.0f32, f32::max);
    // The light is the pixels within a factor 2 of the brightest; walls are the rest, less the
    // pixels next to the light (partly on it: their pixel filter reaches over its edge).
    let light: Vec<usize> = (0..lum.len()).filter(|&i| lum[i] >= 0.5 * max).collect();
    let near_light = |i: usize| {
        let (x, y) = ((i as u32 % w) as i64, (i as u32 / w) as i64);
        (-2..=2).any(|dy| {
            (-2..=2).any(|dx| {
                let (u, v) = (x + dx, y + dy);
                (0..w as i64).contains(&u)
                    && (0..h as i64).contains(&v)
                    && lum[(v * w as i64 + u) as usize] >= 0.5 * max
            })
        })
    };
    let is_wall: Vec<bool> = (0..lum.len()).map(|i| !near_light(i)).collect();
    let walls: Vec<usize> = (0..lum.len()).filter(|&i| is_wall[i]).collect();
    assert!(
        light.len() >= 10 && walls.len() > lum.len() / 2,
        "{what}: {} light, {} wall pixels",
        light.len(),
        walls.len()
    );
    let decoded = |i: usize| Vec3::from_array(png[i].map(|v| srgb_to_linear(v as f32 / 255.0)));

    // The red wall: strongly red linear pixels. Its hue in the PNG, decoded to linear, within
    // 10° (Oklab) of the linear image's.
    let red: Vec<usize> = walls
        .iter()
        .copied()
        .filter(|&i| {
            let p = linear.data[i];
            p.x > 4.0 * p.y && p.x > 4.0 * p.z && p.x > 0.0
        })
        .collect();
    assert!(red.len() > lum.len() / 20, "{what}: only {} red-wall pixels", red.len());
    let mean = |ix: &[usize], f: &dyn Fn(usize) -> Vec3| ix.iter().map(|&i| f(i)).sum::<Vec3>() / ix.len() as f32;
    let (h_lin, h_png) = (oklab_hue(mean(&red, &|i| linear.data[i])), oklab_hue(mean(&red, &decoded)));
    let apart = |a: f64, b: f64| ((a - b + 540.0) % 360.0 - 180.0).abs();
    let dh = apart(h_png, h_lin);
    assert!(dh < 10.0, "{what}: red wall hue {h_png:.1}° in the PNG against {h_lin:.1}° linear ({dh:.1}° apart)");
    // And pixel by pixel (the 95th percentile: 8-bit rounding moves the darkest pixels' hue).
    let mut per_pixel: Vec<f64> =
        red.iter().map(|&i| apart(oklab_hue(decoded(i)), oklab_hue(linear.data[i]))).collect();
    per_pixel.sort_by(f64::total_cmp);
    let p95 = per_pixel[per_pixel.len() * 95 / 100];
    assert!(p95 < 10.0, "{what}: 5 % of the red wall's pixels change hue by {p95:.1}° or more");

    // No channel of a wall pixel at 255.
    let clipped = walls.iter().filter(|&&i| png[i].contains(&255)).count();
    assert_eq!(clipped, 0, "{what}: {clipped} wall pixels have a clipped channel");

    // The light is the brightest region: its mean PNG luma above every 8×8 block of walls.
    let luma = |i: usize| luminance(Vec3::from_array(png[i].map(|v| v as f32)));
    let light_mean = light.iter().map(|&i| luma(i)).sum::<f32>() / light.len() as f32;
    for by in 0..h / 8 {
        for bx in 0..w / 8 {
            let ix: Vec<usize> =
                (0..64).map(|k| ((by * 8 + k / 8) * w + bx * 8 + k % 8) as usize).filter(|&i| is_wall[i]).collect();
            if ix.len() == 64 {
                let block = ix.iter().map(|&i| luma(i)).sum::<f32>() / 64.0;
                assert!(
                    block < light_mean,
                    "{what}: wall block ({bx}, {by}) luma {block:.1} ≥ the light's {light_mean:.1}"
                );
            }
        }
    }

    // Neither dark nor washed out.
    let m = png.iter().flat_map(|p| p.iter().map(|&v| v as f64 / 255.0)).sum::<f64>() / (3 * png.len()) as f64;
    assert!((0.25..=0.6).contains(&m), "{what}: mean PNG value {m:.3}");
}

#[test]
fn the_default_cornell_png_keeps_hues_and_highlights() {
    let dir = tmp("render");
    let exr = dir.join("cornell.exr");
    let e = exr.to_str().unwrap();
    success(&mirage(&["render", "--width", "128", "--height", "96", "--spp", "16", "--seed", "3", "-o", e]));
    let linear = output::read_exr(&exr).unwrap();
    assert_looks_right("render", &linear, read_png(&exr.with_extension("png")));
}

#[test]
fn a_recorded_viewer_frame_keeps_hues_and_highlights() {
    let dir = tmp("record");
    let d = dir.to_str().unwrap();
    success(&mirage(&[
        "view",
        "--headless",
        "--width",
        "128",
        "--height",
        "96",
        "--frames",
        "6",
        "--record",
        d,
        "--record-exr",
    ]));
    let last = dir.join("frame-00005.png");
    let linear = output::read_exr(&last.with_extension("exr")).unwrap();
    assert_looks_right("view --record", &linear, read_png(&last));
}
