//! Environment maps: an equirectangular radiance image (`.exr` through the `exr` crate, Radiance
//! `.hdr` through `image`) read into an [`EnvironmentDesc`]. Texels that are not finite or are
//! negative are set to 0 and counted in a warning (a documented fallback: one bad texel should
//! not refuse a sky); a map that is black everywhere is refused when the scene is built.

use std::path::Path;

use glam::Vec3;

use super::desc::EnvironmentDesc;
use super::error::{LoadError, LoadErrorKind};

/// Reads the equirectangular map at `path`, rotated by `rotation` radians about +y; returns it
/// with a warning when texels had to be repaired.
pub fn load_environment(path: &Path, rotation: f32) -> Result<(EnvironmentDesc, Option<String>), LoadError> {
    if !path.exists() {
        return Err(LoadError::io(path, std::io::Error::from(std::io::ErrorKind::NotFound)));
    }
    if !rotation.is_finite() {
        return Err(LoadError::new(path, LoadErrorKind::Invalid, "the environment rotation is not finite"));
    }
    let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase()).unwrap_or_default();
    let (width, height, mut texels) = match ext.as_str() {
        "exr" => read_exr(path)?,
        "hdr" => read_hdr(path)?,
        _ => {
            return Err(LoadError::new(
                path,
                LoadErrorKind::UnknownFormat,
                format!("unsupported environment format '.{ext}' (mirage reads equirectangular .exr and .hdr)"),
            ));
        }
    };
    if width == 0 || height == 0 {
        return Err(LoadError::new(path, LoadErrorKind::Invalid, "the environment map has no texels"));
    }
    let mut repaired = 0usize;
    for t in &mut texels {
        if !(t.is_finite() && t.min_element() >= 0.0) {
            *t = if t.is_finite() { t.max(Vec3::ZERO) } else { Vec3::ZERO };
            repaired += 1;
        }
    }
    let warning = (repaired > 0)
        .then(|| format!("{}: {repaired} environment texel(s) not finite or negative, set to 0", path.display()));
    let desc = EnvironmentDesc::Map { path: path.to_path_buf(), width, height, texels, rotation };
    Ok((desc, warning))
}

fn read_exr(path: &Path) -> Result<(u32, u32, Vec<Vec3>), LoadError> {
    let read = exr::prelude::read_first_rgba_layer_from_file(
        path,
        |res, _| (res.width(), vec![Vec3::ZERO; res.width() * res.height()]),
        |(w, data): &mut (usize, Vec<Vec3>), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            data[pos.y() * *w + pos.x()] = Vec3::new(r, g, b);
        },
    )
    .map_err(|e| LoadError::new(path, LoadErrorKind::Malformed, format!("cannot read EXR: {e}")))?;
    let (w, data) = read.layer_data.channel_data.pixels;
    let h = data.len() / w.max(1);
    Ok((w as u32, h as u32, data))
}

fn read_hdr(path: &Path) -> Result<(u32, u32, Vec<Vec3>), LoadError> {
    let img = image::open(path)
        .map_err(|e| LoadError::new(path, LoadErrorKind::Malformed, format!("cannot read HDR image: {e}")))?
        .into_rgb32f();
    let (w, h) = img.dimensions();
    let data = img.pixels().map(|p| Vec3::new(p[0], p[1], p[2])).collect();
    Ok((w, h, data))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir() -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("mirage-env-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    /// A missing file, a file that is not an image and an unknown extension are refused naming
    /// the file; non-finite and negative texels become 0 with a warning counting them.
    #[test]
    fn bad_environment_files_are_refused_and_bad_texels_repaired() {
        let d = dir();
        let missing = d.join("missing.exr");
        assert!(load_environment(&missing, 0.0).unwrap_err().to_string().contains("missing.exr"));
        let junk = d.join("junk.hdr");
        std::fs::write(&junk, b"this is not an image").unwrap();
        let e = load_environment(&junk, 0.0).unwrap_err().to_string();
        assert!(e.contains("junk.hdr") && e.contains("cannot read"), "{e}");
        let txt = d.join("sky.txt");
        std::fs::write(&txt, b"1 1 1").unwrap();
        assert!(load_environment(&txt, 0.0).unwrap_err().to_string().contains("unsupported environment format"));
        // An EXR with a NaN, an infinity and a negative texel.
        let exr_path = d.join("bad.exr");
        let texels = [Vec3::ONE, Vec3::new(f32::NAN, 1.0, 1.0), Vec3::splat(f32::INFINITY), Vec3::new(-1.0, 2.0, 3.0)];
        exr::prelude::write_rgb_file(&exr_path, 2, 2, |x, y| {
            let t = texels[y * 2 + x];
            (t.x, t.y, t.z)
        })
        .unwrap();
        let (desc, warning) = load_environment(&exr_path, 0.0).unwrap();
        assert!(warning.unwrap().contains("3 environment texel(s)"));
        let EnvironmentDesc::Map { texels: read, .. } = desc else { panic!("a map") };
        assert_eq!(read, vec![Vec3::ONE, Vec3::ZERO, Vec3::ZERO, Vec3::new(0.0, 2.0, 3.0)]);
        std::fs::remove_dir_all(&d).ok();
    }
}
