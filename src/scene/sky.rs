//! Lights at infinity: the sun (a distant light: a delta direction, or a small cone of uniform
//! radiance for a soft sun) and the sky (an environment light: a constant radiance, or an
//! equirectangular map importance-sampled by its luminance).
//!
//! Directions here are `wi`: unit vectors from the scene towards the light. Radiometry: the sun's
//! `irradiance` E is what it gives a surface facing it; a soft sun of angular radius θ has the
//! uniform radiance L = E / (π sin²θ) inside its cone (∫ L cos dω over the cone = E). The sky's
//! radiance arrives from every direction; a constant sky of radiance L gives an unoccluded
//! upward-facing surface the irradiance π L.
//!
//! Equirectangular maps (the layout of `.hdr` and latitude–longitude `.exr` environments): +y is
//! up; row 0 is the zenith, the last row the nadir (polar angle θ = π·v); the longitude
//! φ = 2π (u − ½) + rotation runs from −x through +z, so u = ½ (the centre column) looks along
//! +x. The map is sampled ∝ luminance × sin θ (pbrt-v4's image infinite light): density
//! p(ω) = p(u, v) / (2π² sin θ).

use std::f32::consts::PI;

use glam::{Vec2, Vec3};

use crate::bsdf::Frame;
use crate::color::luminance;
use crate::sampling::Distribution2D;
use crate::sampling::warp::{sample_uniform_sphere, uniform_sphere_pdf_w};

/// The sun: a distant light.
///
/// The real sun's cone is 0.27° wide: its 1 − cos θ is 1.1·10⁻⁵, which f32 cosines near 1
/// resolve to about 1 %, so membership uses sin²θ = |n × ω|² (no cancellation) and sampling
/// draws 1 − cos θ directly.
#[derive(Clone, Debug)]
pub struct Sun {
    /// Frame whose normal points from the scene towards the sun.
    pub frame: Frame,
    /// Irradiance on a surface facing the sun (W/m² per channel).
    pub irradiance: Vec3,
    /// Angular radius (radians); 0 for a delta direction.
    pub half_angle: f32,
    /// 1 − cos of the angular radius, computed as 2 sin²(θ/2).
    one_minus_cos: f32,
    /// sin² of the angular radius.
    sin2_max: f32,
}

impl Sun {
    /// A sun in direction `wi` (towards it) of irradiance `irradiance`, angular diameter
    /// `diameter` radians (0: a delta direction).
    pub fn new(wi: Vec3, irradiance: Vec3, diameter: f32) -> Sun {
        let half = (0.5 * diameter).clamp(0.0, 0.25 * PI);
        let s = (0.5 * half).sin();
        Sun {
            frame: Frame::from_normal(wi.normalize()),
            irradiance,
            half_angle: half,
            one_minus_cos: 2.0 * s * s,
            sin2_max: half.sin() * half.sin(),
        }
    }

    /// A delta direction (no ray can hit it).
    #[inline]
    pub fn is_delta(&self) -> bool {
        self.one_minus_cos <= 0.0
    }

    /// Direction towards the sun's centre.
    #[inline]
    pub fn wi(&self) -> Vec3 {
        self.frame.n
    }

    /// Whether `wi` points into the sun's disk.
    #[inline]
    fn inside(&self, wi: Vec3) -> bool {
        self.frame.n.dot(wi) > 0.0 && self.frame.n.cross(wi).length_squared() <= self.sin2_max
    }

    /// Radiance inside the cone (soft sun); for a delta sun, the irradiance.
    pub fn radiance(&self) -> Vec3 {
        if self.is_delta() { self.irradiance } else { self.irradiance / (PI * self.sin2_max.max(1e-30)) }
    }

    /// Radiance arriving from `wi` (zero outside the cone, always zero for a delta sun).
    pub fn radiance_from(&self, wi: Vec3) -> Vec3 {
        if !self.is_delta() && self.inside(wi) { self.radiance() } else { Vec3::ZERO }
    }

    /// A direction towards the sun, its solid-angle density (1 for a delta sun) and the radiance
    /// along it (the irradiance for a delta sun).
    pub fn sample_wi(&self, u: Vec2) -> (Vec3, f32, Vec3) {
        if self.is_delta() {
            return (self.frame.n, 1.0, self.irradiance);
        }
        // Uniform in solid angle: 1 − cos θ uniform on [0, 1 − cos θ_max], sin θ from it
        // without cancellation, capped so the direction passes the test it is judged by.
        let h = u.x * self.one_minus_cos;
        let sin_t = (h * (2.0 - h)).max(0.0).sqrt().min(0.999_999 * self.sin2_max.sqrt());
        let phi = 2.0 * PI * u.y;
        let wi = self.frame.to_world(Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), 1.0 - h)).normalize();
        (wi, self.cone_pdf(), self.radiance_from(wi))
    }

    fn cone_pdf(&self) -> f32 {
        1.0 / (2.0 * PI * self.one_minus_cos)
    }

    /// Solid-angle density of [`Sun::sample_wi`] at `wi` (0 for a delta sun).
    pub fn pdf_w(&self, wi: Vec3) -> f32 {
        if !self.is_delta() && self.inside(wi) { self.cone_pdf() } else { 0.0 }
    }
}

/// An equirectangular environment map (module doc), with its sampling distribution.
#[derive(Clone, Debug)]
pub struct EnvMap {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// Radiance per texel, row-major, row 0 at the zenith.
    pub texels: Vec<Vec3>,
    /// Rotation about +y (radians).
    pub rotation: f32,
    dist: Distribution2D,
    /// ∫ L dω over the sphere (per channel).
    integral: Vec3,
}

impl EnvMap {
    /// A map of `texels` (non-negative, finite) rotated by `rotation` radians about +y; `None`
    /// when it is black.
    pub fn new(width: u32, height: u32, texels: Vec<Vec3>, rotation: f32) -> Option<EnvMap> {
        let (w, h) = (width as usize, height as usize);
        if w == 0 || h == 0 || texels.len() != w * h {
            return None;
        }
        let mut weights = Vec::with_capacity(w * h);
        let mut integral = Vec3::ZERO;
        for y in 0..h {
            let sin_theta = (PI * (y as f32 + 0.5) / h as f32).sin();
            // Solid angle of a texel: (2π / w)(cos θ₀ − cos θ₁) over its row's polar band.
            let (t0, t1) = (PI * y as f32 / h as f32, PI * (y + 1) as f32 / h as f32);
            let d_omega = 2.0 * PI / w as f32 * (t0.cos() - t1.cos());
            for x in 0..w {
                let l = texels[y * w + x];
                integral += l * d_omega;
                weights.push((luminance(l).max(l.max_element() * 1e-3) * sin_theta) as f64);
            }
        }
        let dist = Distribution2D::new(&weights, w, h)?;
        Some(EnvMap { width, height, texels, rotation, dist, integral })
    }

    fn uv_of(&self, wi: Vec3) -> (Vec2, f32) {
        let cos_theta = wi.y.clamp(-1.0, 1.0);
        let theta = cos_theta.acos();
        let phi = wi.z.atan2(wi.x) - self.rotation;
        let u = (phi / (2.0 * PI) + 0.5).rem_euclid(1.0);
        (Vec2::new(u, theta / PI), (1.0 - cos_theta * cos_theta).max(0.0).sqrt())
    }

    fn wi_of(&self, uv: Vec2) -> (Vec3, f32) {
        let theta = PI * uv.y;
        let phi = 2.0 * PI * (uv.x - 0.5) + self.rotation;
        let (sin_t, cos_t) = theta.sin_cos();
        (Vec3::new(sin_t * phi.cos(), cos_t, sin_t * phi.sin()), sin_t)
    }

    fn texel(&self, uv: Vec2) -> Vec3 {
        let x = ((uv.x * self.width as f32) as u32).min(self.width - 1);
        let y = ((uv.y * self.height as f32) as u32).min(self.height - 1);
        self.texels[(y * self.width + x) as usize]
    }
}

/// The sky: radiance arriving from every direction.
#[derive(Clone, Debug)]
pub enum Environment {
    /// The same radiance from every direction (sampled uniformly over the sphere).
    Constant(Vec3),
    /// An equirectangular map.
    Map(Box<EnvMap>),
}

impl Environment {
    /// Radiance arriving from `wi`.
    pub fn radiance(&self, wi: Vec3) -> Vec3 {
        match self {
            Environment::Constant(l) => *l,
            Environment::Map(m) => m.texel(m.uv_of(wi).0),
        }
    }

    /// A direction, its solid-angle density and the radiance from it; `None` at a pole where
    /// the density is not defined.
    pub fn sample_wi(&self, u: Vec2) -> Option<(Vec3, f32, Vec3)> {
        match self {
            Environment::Constant(l) => Some((sample_uniform_sphere(u), uniform_sphere_pdf_w(), *l)),
            Environment::Map(m) => {
                let s = m.dist.sample(u);
                let (wi, sin_t) = m.wi_of(s.uv);
                if sin_t <= 0.0 || s.pdf <= 0.0 {
                    return None;
                }
                // Density and radiance looked up from the direction, as a ray leaving the scene
                // along it would (a sample on a texel's edge can round into its neighbour).
                let pdf = self.pdf_w(wi);
                (pdf > 0.0).then(|| (wi, pdf, self.radiance(wi)))
            }
        }
    }

    /// Solid-angle density of [`Environment::sample_wi`] at `wi`.
    pub fn pdf_w(&self, wi: Vec3) -> f32 {
        match self {
            Environment::Constant(_) => uniform_sphere_pdf_w(),
            Environment::Map(m) => {
                let (uv, sin_t) = m.uv_of(wi);
                if sin_t <= 0.0 { 0.0 } else { m.dist.pdf(uv) / (2.0 * PI * PI * sin_t) }
            }
        }
    }

    /// ∫ L dω over the sphere.
    pub fn integral(&self) -> Vec3 {
        match self {
            Environment::Constant(l) => *l * (4.0 * PI),
            Environment::Map(m) => m.integral,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Pcg32;

    fn map() -> Environment {
        let (w, h) = (16u32, 8u32);
        let texels = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                if y < 3 { Vec3::new(1.0 + x as f32, 2.0, 0.5) } else { Vec3::splat(0.05 * (y as f32)) }
            })
            .collect();
        Environment::Map(Box::new(EnvMap::new(w, h, texels, 0.7).unwrap()))
    }

    /// The map's sampled directions carry its radiance, their density is `pdf_w`, and the
    /// density integrates to one over the sphere; so Σ L/p over samples estimates ∫ L dω.
    #[test]
    fn environment_sampling_density_integrates_to_one_and_estimates_the_integral() {
        for env in [Environment::Constant(Vec3::new(0.3, 0.6, 0.9)), map()] {
            let mut r = Pcg32::new(5);
            let n = 200_000;
            let (mut est, mut uniform_int) = (Vec3::ZERO, 0.0f64);
            for _ in 0..n {
                let u = Vec2::new(r.next_f32(), r.next_f32());
                if let Some((wi, pdf, l)) = env.sample_wi(u) {
                    assert!((pdf - env.pdf_w(wi)).abs() <= 2e-3 * pdf, "{pdf} vs {}", env.pdf_w(wi));
                    assert!((l - env.radiance(wi)).abs().max_element() < 1e-5);
                    est += l / pdf;
                }
                // ∫ p dω by uniform directions.
                let w = sample_uniform_sphere(Vec2::new(r.next_f32(), r.next_f32()));
                uniform_int += (env.pdf_w(w) / uniform_sphere_pdf_w()) as f64;
            }
            let est = est / n as f32;
            let int = env.integral();
            assert!(((est - int) / int).abs().max_element() < 0.01, "{est} vs {int}");
            let p = uniform_int / n as f64;
            assert!((p - 1.0).abs() < 0.02, "∫ p dω = {p}");
        }
    }

    /// A soft sun gives a facing surface its irradiance: ∫ L cos dω over the cone = E.
    #[test]
    fn soft_sun_radiance_integrates_to_its_irradiance() {
        let e = Vec3::new(1000.0, 900.0, 800.0);
        let sun = Sun::new(Vec3::new(0.3, 1.0, -0.2), e, 0.53f32.to_radians());
        let mut r = Pcg32::new(9);
        let n = 100_000;
        let mut est = Vec3::ZERO;
        for _ in 0..n {
            let (wi, pdf, l) = sun.sample_wi(Vec2::new(r.next_f32(), r.next_f32()));
            assert_eq!(sun.radiance_from(wi), l);
            est += l * wi.dot(sun.wi()) / pdf;
        }
        let est = est / n as f32;
        assert!(((est - e) / e).abs().max_element() < 1e-3, "{est}");
        let delta = Sun::new(Vec3::Y, e, 0.0);
        assert!(delta.is_delta() && delta.radiance_from(Vec3::Y) == Vec3::ZERO && delta.sample_wi(Vec2::ZERO).1 == 1.0);
    }
}
