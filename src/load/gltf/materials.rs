//! glTF materials and textures: metallic-roughness to mirage's scatter models, base-colour and
//! emission textures decoded once each.

use glam::Vec3;

use super::*;
use crate::color::srgb_to_linear;

/// Decodes a PNG or JPEG image and converts its sRGB-encoded texels to linear RGB.
pub fn decode_srgb_texture(bytes: &[u8]) -> Result<TextureDesc, String> {
    let img = image::load_from_memory(bytes).map_err(|e| e.to_string())?;
    let (width, height) = (img.width(), img.height());
    let texels: Vec<Vec3> = if img.color().bytes_per_pixel() / img.color().channel_count().max(1) == 1 {
        let lut: Vec<f32> = (0..=255).map(|v| srgb_to_linear(v as f32 / 255.0)).collect();
        img.to_rgb8().pixels().map(|p| Vec3::new(lut[p[0] as usize], lut[p[1] as usize], lut[p[2] as usize])).collect()
    } else {
        img.to_rgb32f()
            .pixels()
            .map(|p| Vec3::new(srgb_to_linear(p[0]), srgb_to_linear(p[1]), srgb_to_linear(p[2])))
            .collect()
    };
    if texels.is_empty() || texels.len() as u64 != width as u64 * height as u64 {
        return Err(format!("image has no texels ({width}×{height})"));
    }
    Ok(TextureDesc { width, height, texels })
}

/// The scatter model and diffuse colour for a glTF metallic-roughness material (module doc).
pub(super) fn scatter_from_metallic_roughness(base: Vec3, metallic: f32, roughness: f32) -> (Vec3, ScatterDesc) {
    let m = if metallic.is_finite() { metallic.clamp(0.0, 1.0) } else { 0.0 };
    let r = if roughness.is_finite() { roughness.clamp(0.0, 1.0) } else { 1.0 };
    if m >= 0.9 && r <= 0.05 {
        return (base, ScatterDesc::Mirror);
    }
    if r >= 0.95 {
        return (base, ScatterDesc::Diffuse);
    }
    // α = r²; Phong n = 2/α² − 2 (clamped where r → 0 makes it unbounded).
    let exponent = if r > 0.0 { (2.0 / r.powi(4) - 2.0).min(1e5) } else { 1e5 };
    let mut kd = base * (1.0 - m);
    let mut ks = Vec3::splat(0.04 * (1.0 - m)) + base * m;
    let sum = kd + ks;
    let scale = Vec3::select(sum.cmpgt(Vec3::ONE), Vec3::ONE / sum, Vec3::ONE);
    kd *= scale;
    ks *= scale;
    (kd, ScatterDesc::Glossy { specular: ks, exponent })
}

impl Loader<'_> {
    pub(super) fn default_material(&mut self) -> usize {
        *self.default_material.get_or_insert_with(|| {
            self.desc.materials.push(MaterialDesc::diffuse("default (no material)", Vec3::splat(DEFAULT_ALBEDO)));
            self.desc.materials.len() - 1
        })
    }

    /// Converts glTF material `index` (once) and returns its index in `desc.materials`.
    pub(super) fn material(&mut self, index: usize) -> Result<usize, LoadError> {
        if let Some(&m) = self.materials.get(&index) {
            return Ok(m);
        }
        let doc = self.doc;
        let Some(mat) = doc.materials().nth(index) else {
            return Err(self.error(LoadErrorKind::Malformed, format!("material {index} does not exist")));
        };
        let name = mat.name().map(str::to_string).unwrap_or_else(|| format!("material {index}"));
        let place = match mat.name() {
            Some(n) => format!("material {index} '{n}'"),
            None => format!("material {index}"),
        };
        let pbr = mat.pbr_metallic_roughness();
        let factor = pbr.base_color_factor();
        let base = Vec3::new(factor[0], factor[1], factor[2]);
        let transmission = mat.transmission().map_or(0.0, |t| t.transmission_factor());
        let (base_color, scatter) = if transmission > 0.0 {
            (base, ScatterDesc::Dielectric { ior: mat.ior().unwrap_or(1.5) })
        } else {
            scatter_from_metallic_roughness(base, pbr.metallic_factor(), pbr.roughness_factor())
        };
        let emission = Vec3::from_array(mat.emissive_factor()) * mat.emissive_strength().unwrap_or(1.0);

        let mut ignored = Vec::new();
        if pbr.metallic_roughness_texture().is_some() {
            ignored.push("metallicRoughnessTexture");
        }
        if mat.normal_texture().is_some() {
            ignored.push("normalTexture");
        }
        if mat.occlusion_texture().is_some() {
            ignored.push("occlusionTexture");
        }
        if mat.transmission().is_some_and(|t| t.transmission_texture().is_some()) {
            ignored.push("transmissionTexture");
        }
        if mat.alpha_mode() != gltf::material::AlphaMode::Opaque {
            ignored.push("alphaMode (rendered opaque)");
        }
        if !ignored.is_empty() {
            self.warn(&place, format!("{} ignored", ignored.join(", ")));
        }

        let base_color_texture = match pbr.base_color_texture() {
            Some(info) => Some(self.texture(&place, &info)?),
            None => None,
        };
        let emission_texture = match mat.emissive_texture() {
            Some(info) => Some(self.texture(&place, &info)?),
            None => None,
        };
        self.desc.materials.push(MaterialDesc {
            name,
            base_color,
            base_color_texture,
            scatter,
            emission,
            emission_texture,
            double_sided: mat.double_sided(),
        });
        let m = self.desc.materials.len() - 1;
        self.materials.insert(index, m);
        Ok(m)
    }

    /// Decodes the image of a texture reference (once per image) and returns its index.
    pub(super) fn texture(&mut self, place: &str, info: &gltf::texture::Info) -> Result<usize, LoadError> {
        if info.tex_coord() != 0 {
            self.warn(place, format!("texture uses TEXCOORD_{}; mirage reads TEXCOORD_0", info.tex_coord()));
        }
        let image = info.texture().source().index();
        if let Some(&t) = self.textures.get(&image) {
            return Ok(t);
        }
        let image_place = format!("{place}, image {image}");
        let Some(json) = self.doc.as_json().images.get(image) else {
            return Err(self.error(LoadErrorKind::Malformed, "image does not exist").at(image_place));
        };
        let bytes = match (&json.buffer_view, &json.uri) {
            (Some(view), _) => {
                let view = view.value();
                self.view_bytes(view).map_err(|e| within(e, &image_place))?.to_vec()
            }
            (None, Some(uri)) => self.read_uri(uri).map_err(|e| e.at(image_place.clone()))?,
            (None, None) => {
                return Err(self.error(LoadErrorKind::Malformed, "has neither a uri nor a bufferView").at(image_place));
            }
        };
        let texture = decode_srgb_texture(&bytes).map_err(|e| {
            self.error(LoadErrorKind::Malformed, format!("cannot decode the image: {e}")).at(image_place.clone())
        })?;
        self.desc.textures.push(texture);
        let t = self.desc.textures.len() - 1;
        self.textures.insert(image, t);
        Ok(t)
    }
}
