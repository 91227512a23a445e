//! ② [`SceneDesc`] → validated, immutable [`Scene`].
//!
//! Owns the merged world-space mesh, materials, textures, lights (with their power
//! distribution) and the camera. Validation happens here once: triangles with non-finite
//! vertices or zero area are dropped and counted in a warning; a scene with no light, or whose
//! lights have zero total power, is an error naming the file; camera parameters are checked.
//! Nothing downstream re-validates.

pub mod camera;
pub mod emitter;
pub mod material;
pub mod mesh;
pub mod sky;

use std::fmt;
use std::path::PathBuf;

use glam::{Vec2, Vec3};

pub use camera::{Camera, CameraSample, Ray};
pub use emitter::{EmissionSample, Light, LightSample, Lights};
pub use material::{Material, Scatter, Texture};
pub use mesh::{Mesh, NO_LIGHT, SurfacePoint};

use crate::bsdf::Frame;
use crate::load::{CameraDesc, PunctualDesc, ScatterDesc, SceneDesc};

/// A problem that makes a scene unrenderable, naming the file.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneError {
    /// The scene file (empty for built-in scenes).
    pub path: PathBuf,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.path.as_os_str().is_empty() {
            write!(f, "built-in scene: {}", self.message)
        } else {
            write!(f, "{}: {}", self.path.display(), self.message)
        }
    }
}

impl std::error::Error for SceneError {}

/// Camera settings from the command line; each `Some` overrides the scene file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CameraSettings {
    /// Image width in pixels.
    pub width: Option<u32>,
    /// Image height in pixels.
    pub height: Option<u32>,
    /// Eye position.
    pub eye: Option<Vec3>,
    /// Point looked at.
    pub target: Option<Vec3>,
    /// Up vector.
    pub up: Option<Vec3>,
    /// Vertical field of view, degrees.
    pub fov_y_deg: Option<f32>,
    /// Thin-lens aperture radius (0 = pinhole).
    pub lens_radius: f32,
    /// Focus distance; defaults to the distance from eye to target.
    pub focus_distance: Option<f32>,
}

/// Axis-aligned bounds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    /// Minimum corner.
    pub min: Vec3,
    /// Maximum corner.
    pub max: Vec3,
}

impl Bounds {
    /// Centre point.
    pub fn center(&self) -> Vec3 {
        0.5 * (self.min + self.max)
    }

    /// Length of the diagonal.
    pub fn diagonal(&self) -> f32 {
        (self.max - self.min).length()
    }
}

/// A validated scene, immutable once built.
#[derive(Clone, Debug)]
pub struct Scene {
    /// Source file (empty for built-in scenes).
    pub path: PathBuf,
    /// All triangles.
    pub mesh: Mesh,
    /// Materials.
    pub materials: Vec<Material>,
    /// Textures.
    pub textures: Vec<Texture>,
    /// Lights and their power distribution.
    pub lights: Lights,
    /// The camera.
    pub camera: Camera,
    /// Bounds of the geometry (and punctual lights).
    pub bounds: Bounds,
    /// Warnings from loading and validation.
    pub warnings: Vec<String>,
}

/// Default image width when neither the file nor the command line sets one.
pub const DEFAULT_WIDTH: u32 = 512;

impl Scene {
    /// Validates `desc` into a scene, applying command-line camera `settings`.
    pub fn from_desc(desc: SceneDesc, settings: &CameraSettings) -> Result<Scene, SceneError> {
        let path = desc.path.clone();
        let err = |message: String| SceneError { path: path.clone(), message };
        let mut warnings = desc.warnings.clone();

        let materials: Vec<Material> = desc
            .materials
            .iter()
            .map(|m| Material {
                name: m.name.clone(),
                base_color: sanitize_color(m.base_color),
                base_color_texture: m.base_color_texture.map(|t| t as u32),
                scatter: match m.scatter {
                    ScatterDesc::Diffuse => Scatter::Diffuse,
                    ScatterDesc::Glossy { specular, exponent } => {
                        Scatter::Glossy { specular: sanitize_color(specular), exponent: exponent.clamp(0.0, 1e5) }
                    }
                    ScatterDesc::Mirror => Scatter::Mirror,
                    ScatterDesc::Dielectric { ior } => {
                        Scatter::Dielectric { ior: if ior.is_finite() && ior > 0.0 { ior } else { 1.5 } }
                    }
                },
                emission: sanitize_color(m.emission),
                emission_texture: m.emission_texture.map(|t| t as u32),
                double_sided: m.double_sided,
            })
            .collect();
        for (i, m) in materials.iter().enumerate() {
            for t in [m.base_color_texture, m.emission_texture].into_iter().flatten() {
                if t as usize >= desc.textures.len() {
                    return Err(err(format!("material {i} ('{}') refers to missing texture {t}", m.name)));
                }
            }
        }
        let textures: Vec<Texture> =
            desc.textures.into_iter().map(|t| Texture::new(t.width, t.height, t.texels)).collect();

        let mut mesh = Mesh::default();
        let mut dropped = 0usize;
        // Vertex normals and texture coordinates only when some mesh has them (memory follows
        // what the scene contains); meshes without them then get zeros (flat shading, uv 0).
        let any_normals = desc.meshes.iter().any(|m| !m.normals.is_empty());
        let any_uvs = desc.meshes.iter().any(|m| !m.uvs.is_empty());
        for (mi, m) in desc.meshes.iter().enumerate() {
            if m.material >= materials.len() {
                return Err(err(format!("{}: refers to missing material {}", m.origin, m.material)));
            }
            if m.indices.len() % 3 != 0 {
                return Err(err(format!("{}: index count {} is not a multiple of 3", m.origin, m.indices.len())));
            }
            let base = mesh.positions.len() as u32;
            let nv = m.positions.len();
            if (!m.normals.is_empty() && m.normals.len() != nv) || (!m.uvs.is_empty() && m.uvs.len() != nv) {
                return Err(err(format!("{}: attribute counts differ from the {nv} positions", m.origin)));
            }
            mesh.positions.extend_from_slice(&m.positions);
            if any_normals && m.normals.is_empty() {
                mesh.normals.extend(std::iter::repeat_n(Vec3::ZERO, nv));
            } else if any_normals {
                mesh.normals.extend(m.normals.iter().map(|n| n.try_normalize().unwrap_or(Vec3::ZERO)));
            }
            if any_uvs && m.uvs.is_empty() {
                mesh.uvs.extend(std::iter::repeat_n(Vec2::ZERO, nv));
            } else if any_uvs {
                mesh.uvs.extend(m.uvs.iter().map(|uv| if uv.is_finite() { *uv } else { Vec2::ZERO }));
            }
            for t in m.indices.chunks_exact(3) {
                if t.iter().any(|&i| i as usize >= nv) {
                    return Err(err(format!("{} (mesh {mi}): vertex index out of range ({} vertices)", m.origin, nv)));
                }
                let [a, b, c] = [m.positions[t[0] as usize], m.positions[t[1] as usize], m.positions[t[2] as usize]];
                let area2 = (b - a).cross(c - a).length();
                if !(a.is_finite() && b.is_finite() && c.is_finite() && area2 > 0.0 && area2.is_finite()) {
                    dropped += 1;
                    continue;
                }
                mesh.triangles.push([base + t[0], base + t[1], base + t[2]]);
                mesh.material.push(m.material as u32);
            }
        }
        if dropped > 0 {
            warnings.push(format!("dropped {dropped} degenerate triangle(s) (zero area or non-finite vertices)"));
        }
        mesh.emitter = vec![NO_LIGHT; mesh.triangles.len()];

        let mut punctual = Vec::new();
        for (i, l) in desc.lights.iter().enumerate() {
            let light = match *l {
                PunctualDesc::Point { position, intensity } => {
                    Light::Point { position, intensity: sanitize_color(intensity) }
                }
                PunctualDesc::Spot { position, direction, intensity, inner_cone, outer_cone } => {
                    let Some(axis) = direction.try_normalize() else {
                        return Err(err(format!("light {i}: spot direction is zero or not finite")));
                    };
                    let outer = outer_cone.clamp(1e-3, std::f32::consts::FRAC_PI_2);
                    let inner = inner_cone.clamp(0.0, outer);
                    Light::Spot {
                        position,
                        frame: Frame::from_normal(axis),
                        intensity: sanitize_color(intensity),
                        cos_inner: inner.cos(),
                        cos_outer: outer.cos(),
                    }
                }
                PunctualDesc::Directional { direction, illuminance, angular_diameter } => {
                    let Some(travel) = direction.try_normalize() else {
                        return Err(err(format!("light {i}: directional light direction is zero or not finite")));
                    };
                    if !(illuminance.is_finite() && illuminance.min_element() >= 0.0 && illuminance.max_element() > 0.0)
                    {
                        return Err(err(format!(
                            "light {i}: directional light illuminance {illuminance} must be finite, non-negative and not zero"
                        )));
                    }
                    if !(angular_diameter.is_finite()
                        && (0.0..=std::f32::consts::FRAC_PI_2).contains(&angular_diameter))
                    {
                        return Err(err(format!(
                            "light {i}: sun angular diameter {:.3}° is outside 0…90°",
                            angular_diameter.to_degrees()
                        )));
                    }
                    Light::Sun(sky::Sun::new(-travel, illuminance, angular_diameter))
                }
                PunctualDesc::Environment(ref env) => match env {
                    crate::load::EnvironmentDesc::Constant(l) => {
                        if !(l.is_finite() && l.min_element() >= 0.0 && l.max_element() > 0.0) {
                            return Err(err(format!(
                                "light {i}: sky radiance {l} must be finite, non-negative and not zero"
                            )));
                        }
                        Light::Sky(sky::Environment::Constant(*l))
                    }
                    crate::load::EnvironmentDesc::Map { path, width, height, texels, rotation } => {
                        let map = sky::EnvMap::new(*width, *height, texels.clone(), *rotation).ok_or_else(|| {
                            err(format!("{}: the environment map is black (no direction sends light)", path.display()))
                        })?;
                        Light::Sky(sky::Environment::Map(Box::new(map)))
                    }
                },
            };
            let pos = match &light {
                Light::Point { position, .. } | Light::Spot { position, .. } => *position,
                Light::Sun(_) | Light::Sky(_) => Vec3::ZERO,
                Light::Area { .. } => unreachable!(),
            };
            if !pos.is_finite() {
                return Err(err(format!("light {i}: position is not finite")));
            }
            punctual.push(light);
        }

        if mesh.triangles.is_empty() {
            return Err(err("the scene has no valid triangles".into()));
        }
        let mut min = Vec3::splat(f32::INFINITY);
        let mut max = Vec3::splat(f32::NEG_INFINITY);
        for t in &mesh.triangles {
            for &i in t {
                min = min.min(mesh.positions[i as usize]);
                max = max.max(mesh.positions[i as usize]);
            }
        }
        let bounds = Bounds { min, max };
        let camera = build_camera(desc.camera.as_ref(), settings, &bounds).map_err(err)?;

        let mut scene = Scene {
            path: path.clone(),
            mesh,
            materials,
            textures,
            lights: Lights {
                list: Vec::new(),
                power: Vec::new(),
                distribution: crate::sampling::Distribution1D::new(&[1.0]).unwrap(),
                escaped: Vec::new(),
            },
            camera,
            bounds,
            warnings,
        };
        let has_any = punctual.len() + scene.materials.iter().filter(|m| m.is_emissive()).count() > 0;
        match scene.build_lights(punctual) {
            Some(lights) => scene.lights = lights,
            None if has_any => return Err(err("the scene's lights have zero total power".into())),
            None => {
                return Err(err(
                    "the scene has no light: add an emissive material or a KHR_lights_punctual light".into()
                ));
            }
        }
        Ok(scene)
    }

    /// The surface point of a ray hit on triangle `tri` at barycentrics (b1, b2).
    #[inline]
    pub fn surface_point(&self, tri: u32, b1: f32, b2: f32) -> SurfacePoint {
        self.mesh.surface_point(tri, b1, b2)
    }

    /// The material of triangle `tri`.
    #[inline]
    pub fn material_of(&self, tri: u32) -> &Material {
        &self.materials[self.mesh.material[tri as usize] as usize]
    }
}

/// Replaces non-finite and negative components by zero.
fn sanitize_color(c: Vec3) -> Vec3 {
    Vec3::new(sanitize(c.x), sanitize(c.y), sanitize(c.z))
}

fn sanitize(v: f32) -> f32 {
    if v.is_finite() && v > 0.0 { v } else { 0.0 }
}

fn build_camera(desc: Option<&CameraDesc>, s: &CameraSettings, bounds: &Bounds) -> Result<Camera, String> {
    // A default camera frames the scene's bounds from +z, looking down -z.
    let fov_default = 45.0f32;
    let default_eye = || {
        let r = 0.5 * bounds.diagonal();
        bounds.center() + Vec3::Z * (r / (0.5 * fov_default.to_radians()).tan() + r)
    };
    let eye = s.eye.or(desc.map(|d| d.eye)).unwrap_or_else(default_eye);
    let target = s.target.or(desc.map(|d| d.target)).unwrap_or_else(|| bounds.center());
    let up = s.up.or(desc.map(|d| d.up)).unwrap_or(Vec3::Y);
    let fov = s.fov_y_deg.or(desc.map(|d| d.fov_y_deg)).unwrap_or(fov_default);
    if !(eye.is_finite() && target.is_finite() && up.is_finite()) {
        return Err("camera eye, target and up must be finite".into());
    }
    let forward = target - eye;
    if !(forward.length_squared() > 0.0) {
        return Err("camera eye and target coincide".into());
    }
    if forward.normalize().cross(up).length() < 1e-6 {
        return Err("camera up vector is parallel to the viewing direction".into());
    }
    if !(fov > 0.0 && fov < 179.0) {
        return Err(format!("camera vertical field of view {fov}° is outside (0°, 179°)"));
    }
    let aspect = desc.and_then(|d| d.aspect).filter(|a| a.is_finite() && *a > 0.0);
    let (width, height) = match (s.width.or(desc.and_then(|d| d.width)), s.height.or(desc.and_then(|d| d.height))) {
        (Some(w), Some(h)) => (w, h),
        (Some(w), None) => (w, ((w as f32 / aspect.unwrap_or(1.0)).round() as u32).max(1)),
        (None, Some(h)) => (((h as f32 * aspect.unwrap_or(1.0)).round() as u32).max(1), h),
        (None, None) => (DEFAULT_WIDTH, ((DEFAULT_WIDTH as f32 / aspect.unwrap_or(1.0)).round() as u32).max(1)),
    };
    if width == 0 || height == 0 || width > 16384 || height > 16384 {
        return Err(format!("image size {width}×{height} is outside 1…16384 pixels per side"));
    }
    if !(s.lens_radius >= 0.0 && s.lens_radius.is_finite()) {
        return Err(format!("lens radius {} must be finite and ≥ 0", s.lens_radius));
    }
    let focus = s.focus_distance.unwrap_or(forward.length());
    if !(focus > 0.0 && focus.is_finite()) {
        return Err(format!("focus distance {focus} must be finite and > 0"));
    }
    Ok(Camera::look_at(eye, target, up, fov.to_radians(), width, height).with_lens(s.lens_radius, focus))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::load::builtin;

    #[test]
    fn builtin_scenes_validate_with_lights_and_cameras() {
        for name in builtin::NAMES {
            let s = Scene::from_desc(builtin::by_name(name).unwrap(), &CameraSettings::default()).unwrap();
            assert!(s.lights.total_power().max_element() > 0.0, "{name}");
            assert!(s.warnings.is_empty(), "{name}: {:?}", s.warnings);
        }
    }

    #[test]
    fn cornell_light_power_is_pi_le_area() {
        let s = Scene::from_desc(builtin::cornell(), &CameraSettings::default()).unwrap();
        let area = 1.30 * 1.05; // 130 mm × 105 mm at 0.01 units per mm
        let expected = Vec3::new(17.0, 12.0, 4.0) * std::f32::consts::PI * area;
        assert!((s.lights.total_power() - expected).abs().max_element() < 1e-3 * expected.max_element());
    }

    #[test]
    fn a_scene_without_light_is_rejected_with_its_path() {
        let mut d = builtin::cornell();
        d.path = "box.gltf".into();
        for m in &mut d.materials {
            m.emission = Vec3::ZERO;
        }
        let e = Scene::from_desc(d, &CameraSettings::default()).unwrap_err();
        assert!(e.to_string().starts_with("box.gltf: the scene has no light"), "{e}");
    }

    #[test]
    fn degenerate_and_non_finite_triangles_are_dropped_with_a_warning() {
        let mut d = builtin::cornell();
        let m = &mut d.meshes[0];
        m.positions.push(Vec3::new(f32::NAN, 0.0, 0.0));
        let n = m.positions.len() as u32;
        m.indices.extend([n - 1, 0, 1, 0, 0, 1]);
        let s = Scene::from_desc(d, &CameraSettings::default()).unwrap();
        assert!(s.warnings.iter().any(|w| w.contains("dropped 2 degenerate")), "{:?}", s.warnings);
    }

    #[test]
    fn furnace_walls_face_inwards() {
        let s = Scene::from_desc(builtin::furnace(), &CameraSettings::default()).unwrap();
        for t in 0..s.mesh.len() as u32 {
            let sp = s.surface_point(t, 1.0 / 3.0, 1.0 / 3.0);
            assert!(sp.ng.dot(sp.p) < 0.0);
        }
    }
}
