//! Emitters: emissive triangles, point and spot lights, the sun and the sky (lights at infinity,
//! [`super::sky`]); the power distribution used to choose among them; and the sampling routines
//! every estimator shares (next-event estimation, emission sampling for light paths, and their
//! densities for MIS).
//!
//! Lights at infinity follow pbrt (Pharr, Jakob & Humphreys, *Physically Based Rendering*, 3rd
//! ed., §12.5 and §16.3.1): a light path leaving one starts on a disk of the scene's bounding
//! sphere radius R facing the chosen direction (area density 1/(πR²)), so its power is
//! πR²·∫L dω (the sun: πR²·E); next-event estimation picks a direction; a path that leaves the
//! scene meets every non-delta one at once ([`Scene::escaped`], density [`Scene::pdf_li_escaped`]).
//! A light vertex at infinity is stored at a point beyond the bounding sphere in its direction
//! (`Scene::far_point`), so shadow rays test the whole scene.
//!
//! Radiometry (docs/design.md §2): an emissive triangle has radiance `Le` on its front face (both faces
//! when double-sided), power `Φ = π·Le·area` per emitting face; a point light of radiant
//! intensity `I` has `Φ = 4π I`; a spot light `Φ = 2π I ((1 − cos_inner) + (cos_inner − cos_outer)/3)`
//! with glTF's smooth (quadratic in cosine) falloff between the cones.

use std::f32::consts::PI;

use glam::{Vec2, Vec3};

use super::Scene;
use super::mesh::NO_LIGHT;
use super::sky::{Environment, Sun};
use crate::bsdf::Frame;
use crate::color::luminance;
use crate::sampling::Distribution1D;
use crate::sampling::warp::{
    cosine_hemisphere_pdf_w, sample_cosine_hemisphere, sample_uniform_cone, sample_uniform_sphere,
    sample_uniform_triangle, uniform_cone_pdf_w, uniform_sphere_pdf_w,
};

/// One light source.
#[derive(Clone, Debug)]
pub enum Light {
    /// An emissive triangle.
    Area {
        /// Triangle index in the mesh.
        tri: u32,
        /// Emits from both faces.
        two_sided: bool,
        /// Triangle area.
        area: f32,
    },
    /// An isotropic point light.
    Point {
        /// Position.
        position: Vec3,
        /// Radiant intensity W/sr.
        intensity: Vec3,
    },
    /// A spot light.
    Spot {
        /// Position.
        position: Vec3,
        /// Frame whose normal is the spot axis.
        frame: Frame,
        /// On-axis radiant intensity W/sr.
        intensity: Vec3,
        /// Cosine of the inner cone angle.
        cos_inner: f32,
        /// Cosine of the outer cone angle.
        cos_outer: f32,
    },
    /// The sun: a distant light (delta direction or a small cone).
    Sun(Sun),
    /// The sky: an environment light at infinity.
    Sky(Environment),
}

impl Light {
    /// True for lights at infinity (sun, sky).
    #[inline]
    pub fn at_infinity(&self) -> bool {
        matches!(self, Light::Sun(_) | Light::Sky(_))
    }

    /// True for lights no ray can hit: point and spot lights, and a sun without extent.
    #[inline]
    pub fn is_delta(&self) -> bool {
        match self {
            Light::Point { .. } | Light::Spot { .. } => true,
            Light::Sun(sun) => sun.is_delta(),
            Light::Area { .. } | Light::Sky(_) => false,
        }
    }
}

/// The scene's lights and the distribution that chooses them ∝ power.
#[derive(Clone, Debug)]
pub struct Lights {
    /// All lights.
    pub list: Vec<Light>,
    /// Power (luminance) of each light.
    pub power: Vec<Vec3>,
    /// Chooses a light ∝ the luminance of its power.
    pub distribution: Distribution1D,
    /// The lights at infinity that a ray leaving the scene can meet (sky, soft sun).
    pub escaped: Vec<u32>,
}

impl Lights {
    /// Total emitted power (RGB, W).
    pub fn total_power(&self) -> Vec3 {
        self.power.iter().copied().sum()
    }
}

/// Spot falloff of glTF KHR_lights_punctual as a function of the cosine to the axis.
#[inline]
pub fn spot_falloff(cos: f32, cos_inner: f32, cos_outer: f32) -> f32 {
    let scale = 1.0 / (cos_inner - cos_outer).max(1e-3);
    let a = ((cos - cos_outer) * scale).clamp(0.0, 1.0);
    a * a
}

/// A point on a light chosen for next-event estimation from a reference point.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// Index of the chosen light.
    pub light: u32,
    /// Position on the light.
    pub p: Vec3,
    /// Unit normal of the emitting face at `p` (zero for point and spot lights and lights at
    /// infinity).
    pub n: Vec3,
    /// Unit direction from the reference point to `p`.
    pub wi: Vec3,
    /// Distance from the reference point to `p`.
    pub dist: f32,
    /// Radiance arriving along `-wi` (area lights, sky, soft sun), intensity / d² (point and
    /// spot lights) or irradiance (a delta sun).
    pub li: Vec3,
    /// Solid-angle density at the reference point, including the light choice; for delta
    /// lights, the choice probability alone.
    pub pdf_w: f32,
    /// True for point and spot lights and a delta sun (a delta in position or direction).
    pub delta: bool,
}

/// A light-path origin: position and direction sampled from a light's emission.
#[derive(Clone, Copy, Debug)]
pub struct EmissionSample {
    /// Index of the chosen light.
    pub light: u32,
    /// Position on the light.
    pub p: Vec3,
    /// Unit normal of the emitting face (zero for point and spot lights; for lights at infinity
    /// the emission direction: the disk faces it).
    pub n: Vec3,
    /// Unit emission direction.
    pub dir: Vec3,
    /// Emitted radiance (area, sky, soft sun), intensity (point, spot) or irradiance (a delta
    /// sun) along `dir`.
    pub le: Vec3,
    /// Area density of `p`, including the light choice (choice probability alone for delta
    /// positions; on the disk of a light at infinity, choice / (πR²)).
    pub pdf_pos: f32,
    /// Solid-angle density of `dir` (1 for a delta sun).
    pub pdf_dir: f32,
    /// True for point and spot lights.
    pub delta_pos: bool,
    /// True for lights at infinity (the path starts on their disk).
    pub at_infinity: bool,
}

impl Scene {
    /// Builds the light list from emissive triangles and punctual lights, and marks emissive
    /// triangles in the mesh.
    pub(super) fn build_lights(&mut self, punctual: Vec<Light>) -> Option<Lights> {
        let mut list = Vec::new();
        for tri in 0..self.mesh.len() as u32 {
            let m = &self.materials[self.mesh.material[tri as usize] as usize];
            if m.is_emissive() {
                self.mesh.emitter[tri as usize] = list.len() as u32;
                list.push(Light::Area { tri, two_sided: m.double_sided, area: self.mesh.area(tri) });
            } else {
                self.mesh.emitter[tri as usize] = NO_LIGHT;
            }
        }
        list.extend(punctual);
        let power: Vec<Vec3> = list.iter().map(|l| self.power_of(l)).collect();
        let weights: Vec<f64> = power.iter().map(|&p| luminance(p).max(p.max_element() * 1e-3) as f64).collect();
        let distribution = Distribution1D::new(&weights)?;
        let escaped = (0..list.len() as u32)
            .filter(|&i| list[i as usize].at_infinity() && !list[i as usize].is_delta())
            .collect();
        Some(Lights { list, power, distribution, escaped })
    }

    /// The bounding sphere lights at infinity emit from: the bounds' centre and half diagonal.
    pub fn bounding_sphere(&self) -> (Vec3, f32) {
        (self.bounds.center(), (0.5 * self.bounds.diagonal()).max(1e-6))
    }

    /// A point in direction `wi` from `p` beyond the bounding sphere: where a light at infinity
    /// is placed for a shadow ray from `p` (distance 2R + |p − c|, never inside the scene).
    pub fn far_point(&self, p: Vec3, wi: Vec3) -> Vec3 {
        let (c, r) = self.bounding_sphere();
        p + wi * (2.0 * r + (p - c).length())
    }

    /// Radiance arriving along a ray that leaves the scene in direction `wi`: the sky and every
    /// soft sun whose disk it points into.
    pub fn escaped(&self, wi: Vec3) -> Vec3 {
        self.lights.escaped.iter().map(|&i| self.radiance_at_infinity(i, wi)).sum()
    }

    /// Radiance light `light` (at infinity) sends along `-wi`.
    pub fn radiance_at_infinity(&self, light: u32, wi: Vec3) -> Vec3 {
        match &self.lights.list[light as usize] {
            Light::Sun(sun) => sun.radiance_from(wi),
            Light::Sky(env) => env.radiance(wi),
            _ => Vec3::ZERO,
        }
    }

    /// Solid-angle density with which next-event estimation picks direction `wi` on the lights
    /// at infinity, light choice included (for MIS of rays that leave the scene).
    pub fn pdf_li_escaped(&self, wi: Vec3) -> f32 {
        self.pdf_li_escaped_with(&self.lights.distribution, wi)
    }

    /// [`pdf_li_escaped`](Self::pdf_li_escaped) with lights chosen by `dist`.
    pub fn pdf_li_escaped_with(&self, dist: &Distribution1D, wi: Vec3) -> f32 {
        self.lights
            .escaped
            .iter()
            .map(|&i| {
                dist.pmf(i as usize)
                    * match &self.lights.list[i as usize] {
                        Light::Sun(sun) => sun.pdf_w(wi),
                        Light::Sky(env) => env.pdf_w(wi),
                        _ => 0.0,
                    }
            })
            .sum()
    }

    fn power_of(&self, light: &Light) -> Vec3 {
        match *light {
            Light::Area { tri, two_sided, area } => {
                let m = &self.materials[self.mesh.material[tri as usize] as usize];
                let sides = if two_sided { 2.0 } else { 1.0 };
                m.mean_emission(&self.textures) * (PI * area * sides)
            }
            Light::Point { intensity, .. } => intensity * (4.0 * PI),
            Light::Spot { intensity, cos_inner, cos_outer, .. } => {
                intensity * (2.0 * PI * ((1.0 - cos_inner) + (cos_inner - cos_outer) / 3.0))
            }
            // What crosses the disk of the bounding sphere (module doc).
            Light::Sun(ref sun) => sun.irradiance * (PI * self.bounding_sphere().1.powi(2)),
            Light::Sky(ref env) => env.integral() * (PI * self.bounding_sphere().1.powi(2)),
        }
    }

    /// Radiance emitted by the surface point on triangle `tri` (with geometric normal `ng`
    /// from the winding and texture coordinates `uv`) in direction `w`.
    #[inline]
    pub fn emitted(&self, tri: u32, ng: Vec3, uv: Vec2, w: Vec3) -> Vec3 {
        let light = self.mesh.emitter[tri as usize];
        if light == NO_LIGHT {
            return Vec3::ZERO;
        }
        let m = &self.materials[self.mesh.material[tri as usize] as usize];
        let c = ng.dot(w);
        if c > 0.0 || (m.double_sided && c < 0.0) { m.emission_at(uv, &self.textures) } else { Vec3::ZERO }
    }

    /// Chooses a light ∝ power and a point on it, for next-event estimation at `p_ref`.
    pub fn sample_li(&self, p_ref: Vec3, u_light: f32, u: Vec2) -> Option<LightSample> {
        let choice = self.lights.distribution.sample(u_light);
        let light = choice.index as u32;
        match self.lights.list[choice.index] {
            Light::Area { tri, two_sided, area } => {
                let b = sample_uniform_triangle(u);
                let sp = self.mesh.surface_point(tri, b.x, b.y);
                let to = sp.p - p_ref;
                let dist2 = to.length_squared();
                if dist2 <= 0.0 || !dist2.is_finite() {
                    return None;
                }
                let dist = dist2.sqrt();
                let wi = to / dist;
                let cos_l = sp.ng.dot(-wi);
                if cos_l == 0.0 || (!two_sided && cos_l < 0.0) {
                    return None;
                }
                let n = if cos_l > 0.0 { sp.ng } else { -sp.ng };
                let m = &self.materials[self.mesh.material[tri as usize] as usize];
                let li = m.emission_at(sp.uv, &self.textures);
                let pdf_w = choice.pmf / area * dist2 / cos_l.abs();
                Some(LightSample { light, p: sp.p, n, wi, dist, li, pdf_w, delta: false })
            }
            Light::Point { position, intensity } => {
                let to = position - p_ref;
                let dist2 = to.length_squared();
                if dist2 <= 0.0 || !dist2.is_finite() {
                    return None;
                }
                let dist = dist2.sqrt();
                Some(LightSample {
                    light,
                    p: position,
                    n: Vec3::ZERO,
                    wi: to / dist,
                    dist,
                    li: intensity / dist2,
                    pdf_w: choice.pmf,
                    delta: true,
                })
            }
            Light::Spot { position, frame, intensity, cos_inner, cos_outer } => {
                let to = position - p_ref;
                let dist2 = to.length_squared();
                if dist2 <= 0.0 || !dist2.is_finite() {
                    return None;
                }
                let dist = dist2.sqrt();
                let wi = to / dist;
                let falloff = spot_falloff(frame.n.dot(-wi), cos_inner, cos_outer);
                if falloff <= 0.0 {
                    return None;
                }
                Some(LightSample {
                    light,
                    p: position,
                    n: Vec3::ZERO,
                    wi,
                    dist,
                    li: intensity * falloff / dist2,
                    pdf_w: choice.pmf,
                    delta: true,
                })
            }
            // Lights at infinity that rays can meet are one emitter for next-event estimation:
            // a direction from the chosen one, then the radiance of all of them along it over
            // the mixture's density (the light choice included), which is what a ray leaving
            // the scene in that direction sees and what MIS weighs it by.
            Light::Sun(ref sun) if sun.is_delta() => {
                let wi = sun.wi();
                let p = self.far_point(p_ref, wi);
                let (li, pdf_w, dist) = (sun.irradiance, choice.pmf, (p - p_ref).length());
                Some(LightSample { light, p, n: Vec3::ZERO, wi, dist, li, pdf_w, delta: true })
            }
            Light::Sun(ref sun) => {
                let (wi, ..) = sun.sample_wi(u);
                self.sample_at_infinity(light, p_ref, wi)
            }
            Light::Sky(ref env) => {
                let (wi, ..) = env.sample_wi(u)?;
                self.sample_at_infinity(light, p_ref, wi)
            }
        }
    }

    /// The next-event sample of direction `wi` on the non-delta lights at infinity.
    fn sample_at_infinity(&self, light: u32, p_ref: Vec3, wi: Vec3) -> Option<LightSample> {
        let pdf_w = self.pdf_li_escaped(wi);
        if !(pdf_w > 0.0) {
            return None;
        }
        let p = self.far_point(p_ref, wi);
        let li = self.escaped(wi);
        Some(LightSample { light, p, n: Vec3::ZERO, wi, dist: (p - p_ref).length(), li, pdf_w, delta: false })
    }

    /// Solid-angle density at `p_ref` with which [`sample_li`](Self::sample_li) picks the point
    /// `p_light` with geometric normal `ng` on emissive triangle `tri` (for MIS).
    pub fn pdf_li(&self, p_ref: Vec3, tri: u32, p_light: Vec3, ng: Vec3) -> f32 {
        let light = self.mesh.emitter[tri as usize];
        if light == NO_LIGHT {
            return 0.0;
        }
        let Light::Area { area, .. } = self.lights.list[light as usize] else {
            return 0.0;
        };
        let to = p_light - p_ref;
        let dist2 = to.length_squared();
        let cos_l = ng.dot(to).abs() / dist2.sqrt();
        if cos_l <= 0.0 {
            return 0.0;
        }
        self.lights.distribution.pmf(light as usize) / area * dist2 / cos_l
    }

    /// Area density with which a light path starts at a point of emissive triangle `tri`
    /// (choice of the light ∝ power times uniform area density).
    pub fn pdf_light_position(&self, light: u32) -> f32 {
        self.pdf_light_position_with(&self.lights.distribution, light)
    }

    /// [`pdf_light_position`](Self::pdf_light_position) when lights are chosen by `dist`.
    pub fn pdf_light_position_with(&self, dist: &Distribution1D, light: u32) -> f32 {
        let pmf = dist.pmf(light as usize);
        match self.lights.list[light as usize] {
            Light::Area { area, .. } => pmf / area,
            Light::Sun(_) | Light::Sky(_) => pmf / (PI * self.bounding_sphere().1.powi(2)),
            _ => pmf,
        }
    }

    /// Solid-angle density of emitting along `dir` from a point with emitting-face normal `n`
    /// of `light` (cosine-weighted; half for two-sided emitters; for lights at infinity the
    /// density of picking the direction −`dir` towards them, 1 for a delta sun).
    pub fn pdf_light_direction(&self, light: u32, n: Vec3, dir: Vec3) -> f32 {
        match self.lights.list[light as usize] {
            Light::Sun(ref sun) => {
                if sun.is_delta() {
                    1.0
                } else {
                    sun.pdf_w(-dir)
                }
            }
            Light::Sky(ref env) => env.pdf_w(-dir),
            Light::Area { two_sided, .. } => {
                let c = n.dot(dir);
                if two_sided { 0.5 * cosine_hemisphere_pdf_w(c.abs()) } else { cosine_hemisphere_pdf_w(c) }
            }
            Light::Point { .. } => uniform_sphere_pdf_w(),
            Light::Spot { frame, cos_outer, .. } => {
                if frame.n.dot(dir) >= cos_outer {
                    uniform_cone_pdf_w(cos_outer)
                } else {
                    0.0
                }
            }
        }
    }

    /// Samples an emission direction from a point of `light` whose emitting-face normal is `n`
    /// (cosine-weighted about `n`, uniform on the sphere or in the spot cone): the direction,
    /// its solid-angle density (as [`pdf_light_direction`](Self::pdf_light_direction)) and the
    /// directional factor of the emission (1, or the spot falloff).
    pub fn sample_light_direction(&self, light: u32, n: Vec3, u: Vec2) -> Option<(Vec3, f32, f32)> {
        match self.lights.list[light as usize] {
            Light::Area { two_sided, .. } => {
                let (n, u) = if two_sided {
                    if u.x < 0.5 { (n, Vec2::new(u.x * 2.0, u.y)) } else { (-n, Vec2::new(u.x * 2.0 - 1.0, u.y)) }
                } else {
                    (n, u)
                };
                let local = sample_cosine_hemisphere(u);
                if local.z <= 0.0 {
                    return None;
                }
                let dir = Frame::from_normal(n).to_world(local);
                Some((dir, self.pdf_light_direction(light, n, dir), 1.0))
            }
            Light::Point { .. } => Some((sample_uniform_sphere(u), uniform_sphere_pdf_w(), 1.0)),
            Light::Spot { frame, cos_inner, cos_outer, .. } => {
                let local = sample_uniform_cone(u, cos_outer);
                Some((
                    frame.to_world(local),
                    uniform_cone_pdf_w(cos_outer),
                    spot_falloff(local.z, cos_inner, cos_outer),
                ))
            }
            // The direction of a light at infinity is chosen with its disk point
            // ([`Scene::sample_le`]); from a given point it is the one it arrives along.
            Light::Sun(_) | Light::Sky(_) => None,
        }
    }

    /// Starts a light path: a light ∝ power, a point on it, and an emission direction.
    pub fn sample_le(&self, u_light: f32, u_pos: Vec2, u_dir: Vec2) -> Option<EmissionSample> {
        self.sample_le_with(&self.lights.distribution, u_light, u_pos, u_dir)
    }

    /// [`sample_le`](Self::sample_le) with lights chosen by `dist` instead of ∝ power (the
    /// light-source CDF of Wald et al. 2003).
    pub fn sample_le_with(
        &self,
        dist: &Distribution1D,
        u_light: f32,
        u_pos: Vec2,
        u_dir: Vec2,
    ) -> Option<EmissionSample> {
        let choice = dist.sample(u_light);
        let light = choice.index as u32;
        match self.lights.list[choice.index] {
            Light::Area { tri, two_sided, area } => {
                let b = sample_uniform_triangle(u_pos);
                let sp = self.mesh.surface_point(tri, b.x, b.y);
                let (n, u_dir, side_pdf) = if two_sided {
                    // The first sample coordinate picks the face, then is re-expanded.
                    if u_dir.x < 0.5 {
                        (sp.ng, Vec2::new(u_dir.x * 2.0, u_dir.y), 0.5)
                    } else {
                        (-sp.ng, Vec2::new(u_dir.x * 2.0 - 1.0, u_dir.y), 0.5)
                    }
                } else {
                    (sp.ng, u_dir, 1.0)
                };
                let local = sample_cosine_hemisphere(u_dir);
                if local.z <= 0.0 {
                    return None;
                }
                let dir = Frame::from_normal(n).to_world(local);
                let m = &self.materials[self.mesh.material[tri as usize] as usize];
                Some(EmissionSample {
                    light,
                    p: sp.p,
                    n,
                    dir,
                    le: m.emission_at(sp.uv, &self.textures),
                    pdf_pos: choice.pmf / area,
                    pdf_dir: side_pdf * cosine_hemisphere_pdf_w(local.z),
                    delta_pos: false,
                    at_infinity: false,
                })
            }
            Light::Point { position, intensity } => Some(EmissionSample {
                light,
                p: position,
                n: Vec3::ZERO,
                dir: sample_uniform_sphere(u_dir),
                le: intensity,
                pdf_pos: choice.pmf,
                pdf_dir: uniform_sphere_pdf_w(),
                delta_pos: true,
                at_infinity: false,
            }),
            Light::Spot { position, frame, intensity, cos_inner, cos_outer } => {
                let local = sample_uniform_cone(u_dir, cos_outer);
                let falloff = spot_falloff(local.z, cos_inner, cos_outer);
                Some(EmissionSample {
                    light,
                    p: position,
                    n: Vec3::ZERO,
                    dir: frame.to_world(local),
                    le: intensity * falloff,
                    pdf_pos: choice.pmf,
                    pdf_dir: uniform_cone_pdf_w(cos_outer),
                    delta_pos: true,
                    at_infinity: false,
                })
            }
            Light::Sun(ref sun) => {
                let (wi, pdf_dir, le) = sun.sample_wi(u_dir);
                Some(self.emission_at_infinity(light, choice.pmf, wi, pdf_dir, le, u_pos))
            }
            Light::Sky(ref env) => {
                let (wi, pdf_dir, le) = env.sample_wi(u_dir)?;
                Some(self.emission_at_infinity(light, choice.pmf, wi, pdf_dir, le, u_pos))
            }
        }
    }

    /// A light path from a light at infinity arriving along −`wi`: its start on the disk of the
    /// bounding sphere's radius that faces `wi`, one radius out from the centre towards the light
    /// (pbrt-v3 §12.5).
    fn emission_at_infinity(
        &self,
        light: u32,
        pmf: f32,
        wi: Vec3,
        pdf_dir: f32,
        le: Vec3,
        u_pos: Vec2,
    ) -> EmissionSample {
        let (c, r) = self.bounding_sphere();
        let frame = Frame::from_normal(wi);
        let d = crate::sampling::warp::sample_uniform_disk_concentric(u_pos) * r;
        let p = c + wi * r + frame.to_world(Vec3::new(d.x, d.y, 0.0));
        EmissionSample {
            light,
            p,
            n: -wi,
            dir: -wi,
            le,
            pdf_pos: pmf / (PI * r * r),
            pdf_dir,
            delta_pos: false,
            at_infinity: true,
        }
    }
}
