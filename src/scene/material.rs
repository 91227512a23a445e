//! Materials and textures of a validated scene.

use glam::{Vec2, Vec3};

use crate::bsdf::BsdfKind;

/// A linear-RGB texture with bilinear filtering and repeat wrapping.
#[derive(Clone, Debug)]
pub struct Texture {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// Row-major texels, top row first.
    pub texels: Vec<Vec3>,
    /// Mean texel value (for light power).
    pub mean: Vec3,
}

impl Texture {
    /// Wraps decoded texels.
    pub fn new(width: u32, height: u32, texels: Vec<Vec3>) -> Self {
        let mean = texels.iter().copied().sum::<Vec3>() / texels.len().max(1) as f32;
        Texture { width, height, texels, mean }
    }

    /// Bilinearly filtered value at `uv` (glTF convention: v = 0 is the top row).
    pub fn lookup(&self, uv: Vec2) -> Vec3 {
        let (w, h) = (self.width as i64, self.height as i64);
        let x = uv.x * self.width as f32 - 0.5;
        let y = uv.y * self.height as f32 - 0.5;
        if !x.is_finite() || !y.is_finite() {
            return self.mean;
        }
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let texel = |i: i64, j: i64| self.texels[(j.rem_euclid(h) * w + i.rem_euclid(w)) as usize];
        let (i, j) = (x0 as i64, y0 as i64);
        let top = texel(i, j) * (1.0 - fx) + texel(i + 1, j) * fx;
        let bottom = texel(i, j + 1) * (1.0 - fx) + texel(i + 1, j + 1) * fx;
        top * (1.0 - fy) + bottom * fy
    }
}

/// How a material scatters light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Scatter {
    /// Lambertian.
    Diffuse,
    /// Modified Phong with this specular albedo and exponent; the diffuse part is the base colour.
    Glossy {
        /// Specular albedo.
        specular: Vec3,
        /// Phong exponent.
        exponent: f32,
    },
    /// Perfect mirror.
    Mirror,
    /// Smooth dielectric.
    Dielectric {
        /// Index of refraction.
        ior: f32,
    },
}

/// A validated material.
#[derive(Clone, Debug)]
pub struct Material {
    /// Name for messages.
    pub name: String,
    /// Diffuse albedo / reflectance factor.
    pub base_color: Vec3,
    /// Texture multiplying `base_color`.
    pub base_color_texture: Option<u32>,
    /// Scattering model.
    pub scatter: Scatter,
    /// Emitted radiance W/(m²·sr).
    pub emission: Vec3,
    /// Texture multiplying `emission`.
    pub emission_texture: Option<u32>,
    /// Emits from both faces.
    pub double_sided: bool,
}

impl Material {
    /// True when the material emits light.
    pub fn is_emissive(&self) -> bool {
        self.emission.max_element() > 0.0
    }

    /// The BSDF model at texture coordinates `uv`.
    pub fn bsdf_kind(&self, uv: Vec2, textures: &[Texture]) -> BsdfKind {
        let base = match self.base_color_texture {
            Some(t) => self.base_color * textures[t as usize].lookup(uv),
            None => self.base_color,
        };
        match self.scatter {
            Scatter::Diffuse => BsdfKind::Lambert { albedo: base },
            Scatter::Glossy { specular, exponent } => BsdfKind::Phong { kd: base, ks: specular, exponent },
            Scatter::Mirror => BsdfKind::Mirror { reflectance: base },
            Scatter::Dielectric { ior } => BsdfKind::Dielectric { eta: ior, tint: base },
        }
    }

    /// Emitted radiance at `uv` (before sidedness is applied).
    pub fn emission_at(&self, uv: Vec2, textures: &[Texture]) -> Vec3 {
        match self.emission_texture {
            Some(t) => self.emission * textures[t as usize].lookup(uv),
            None => self.emission,
        }
    }

    /// Mean emitted radiance over the surface (for light power).
    pub fn mean_emission(&self, textures: &[Texture]) -> Vec3 {
        match self.emission_texture {
            Some(t) => self.emission * textures[t as usize].mean,
            None => self.emission,
        }
    }
}
