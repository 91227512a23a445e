//! Image files out (and back in, for `mirage diff`): EXR (float32 linear RGB, optional
//! albedo / normal / depth / clamp-compensation layers) through `exr`, and tone-mapped 8-bit
//! PNG through `image`.

use std::fmt;
use std::path::{Path, PathBuf};

use exr::prelude::{AnyChannel, AnyChannels, Encoding, FlatSamples, Layer, LayerAttributes, SmallVec, WritableImage};
use glam::Vec3;

use crate::film::{Image, Tonemap, to_srgb8};

/// A failure writing or reading an image file, naming it.
#[derive(Debug)]
pub struct SaveError {
    /// The file.
    pub path: PathBuf,
    /// What went wrong.
    pub message: String,
}

impl fmt::Display for SaveError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.path.display(), self.message)
    }
}

impl std::error::Error for SaveError {}

fn err(path: &Path, message: impl fmt::Display) -> SaveError {
    SaveError { path: path.to_path_buf(), message: message.to_string() }
}

/// Optional extra layers of an EXR file.
#[derive(Clone, Copy, Debug, Default)]
pub struct Aovs<'a> {
    /// Albedo (written as albedo.R/G/B).
    pub albedo: Option<&'a Image>,
    /// Shading normal (N.X/Y/Z).
    pub normal: Option<&'a Image>,
    /// Depth (Z, from the first channel).
    pub depth: Option<&'a Image>,
    /// The clamp compensation's term (compensation.R/G/B).
    pub compensation: Option<&'a Image>,
}

fn channel(name: &str, img: &Image, c: usize) -> AnyChannel<FlatSamples> {
    AnyChannel::new(name, FlatSamples::F32(img.data.iter().map(|p| p[c]).collect()))
}

/// Writes `img` (and any AOVs) as a float32 EXR.
pub fn write_exr(path: &Path, img: &Image, aovs: Aovs<'_>) -> Result<(), SaveError> {
    let mut channels: Vec<AnyChannel<FlatSamples>> =
        vec![channel("R", img, 0), channel("G", img, 1), channel("B", img, 2)];
    if let Some(a) = aovs.albedo {
        channels.extend([channel("albedo.R", a, 0), channel("albedo.G", a, 1), channel("albedo.B", a, 2)]);
    }
    if let Some(n) = aovs.normal {
        channels.extend([channel("N.X", n, 0), channel("N.Y", n, 1), channel("N.Z", n, 2)]);
    }
    if let Some(d) = aovs.depth {
        channels.push(channel("Z", d, 0));
    }
    if let Some(c) = aovs.compensation {
        channels.extend([
            channel("compensation.R", c, 0),
            channel("compensation.G", c, 1),
            channel("compensation.B", c, 2),
        ]);
    }
    let size = (img.width as usize, img.height as usize);
    let layer = Layer::new(
        size,
        LayerAttributes::named("mirage"),
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(SmallVec::from_vec(channels)),
    );
    exr::prelude::Image::from_layer(layer)
        .write()
        .to_file(path)
        .map_err(|e| err(path, format!("cannot write EXR: {e}")))
}

/// Reads the RGB channels of an EXR file written by mirage or any other renderer.
pub fn read_exr(path: &Path) -> Result<Image, SaveError> {
    if !path.exists() {
        return Err(err(path, "file not found"));
    }
    let read = exr::prelude::read_first_rgba_layer_from_file(
        path,
        |res, _| Image::new(res.width() as u32, res.height() as u32),
        |img: &mut Image, pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            let w = img.width as usize;
            img.data[pos.y() * w + pos.x()] = Vec3::new(r, g, b);
        },
    )
    .map_err(|e| err(path, format!("cannot read EXR: {e}")))?;
    Ok(read.layer_data.channel_data.pixels)
}

/// Reads the three channels `{prefix}.R/G/B` of the first layer of an EXR file (for example
/// the `compensation` layer that `render --aov` writes in VPL modes).
pub fn read_exr_layer(path: &Path, prefix: &str) -> Result<Image, SaveError> {
    if !path.exists() {
        return Err(err(path, "file not found"));
    }
    let read =
        exr::prelude::read_first_flat_layer_from_file(path).map_err(|e| err(path, format!("cannot read EXR: {e}")))?;
    let layer = &read.layer_data;
    let mut img = Image::new(layer.size.width() as u32, layer.size.height() as u32);
    for (c, suffix) in ["R", "G", "B"].into_iter().enumerate() {
        let name = format!("{prefix}.{suffix}");
        let ch = layer
            .channel_data
            .list
            .iter()
            .find(|ch| ch.name.to_string() == name)
            .ok_or_else(|| err(path, format!("no channel {name}")))?;
        for (p, v) in img.data.iter_mut().zip(ch.sample_data.values_as_f32()) {
            p[c] = v;
        }
    }
    Ok(img)
}

/// Writes a tone-mapped 8-bit sRGB PNG.
pub fn write_png(path: &Path, img: &Image, tonemap: Tonemap) -> Result<(), SaveError> {
    let bytes = to_srgb8(img, tonemap);
    image::save_buffer(path, &bytes, img.width, img.height, image::ColorType::Rgb8)
        .map_err(|e| err(path, format!("cannot write PNG: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exr_round_trips_float_values() {
        let dir = std::env::temp_dir().join(format!("mirage-output-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut img = Image::new(3, 2);
        for (i, p) in img.data.iter_mut().enumerate() {
            *p = Vec3::new(i as f32 * 0.5, 1e-3, 1e4);
        }
        let path = dir.join("a.exr");
        write_exr(&path, &img, Aovs { albedo: Some(&img), normal: None, depth: Some(&img), compensation: Some(&img) })
            .unwrap();
        assert_eq!(read_exr(&path).unwrap(), img);
        assert_eq!(read_exr_layer(&path, "compensation").unwrap(), img);
        assert!(read_exr_layer(&path, "N").unwrap_err().to_string().contains("no channel N.R"));
        write_png(&dir.join("a.png"), &img, Tonemap::Reinhard).unwrap();
        assert!(read_exr(&dir.join("missing.exr")).unwrap_err().to_string().contains("missing.exr: file not found"));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
