//! The raw scene description a loader produces: world-space triangle meshes, materials,
//! textures, punctual lights and an optional camera, each carrying where it came from so that
//! validation errors can name it. Nothing here is validated yet; `scene::Scene::from_desc`
//! does that.

use std::path::PathBuf;

use glam::{Vec2, Vec3};

/// Where an element of a scene file came from (for error messages and warnings).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Origin {
    /// A glTF primitive reached through a node.
    Gltf {
        /// Node index.
        node: usize,
        /// Mesh index.
        mesh: usize,
        /// Primitive index within the mesh.
        primitive: usize,
    },
    /// An OBJ object/group, with the 1-based line of its first face when known.
    Obj {
        /// Model (object or group) name.
        name: String,
        /// 1-based source line, 0 when unknown.
        line: usize,
    },
    /// Built in code (the default Cornell box, generated test scenes).
    Builtin(String),
}

impl std::fmt::Display for Origin {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Origin::Gltf { node, mesh, primitive } => write!(f, "node {node}, mesh {mesh}, primitive {primitive}"),
            Origin::Obj { name, line } if *line > 0 => write!(f, "object '{name}' (line {line})"),
            Origin::Obj { name, .. } => write!(f, "object '{name}'"),
            Origin::Builtin(what) => write!(f, "built-in {what}"),
        }
    }
}

/// A texture decoded to linear RGB, row-major, top row first.
#[derive(Clone, Debug, PartialEq)]
pub struct TextureDesc {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// Linear RGB texels.
    pub texels: Vec<Vec3>,
}

/// How a surface scatters light (before validation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ScatterDesc {
    /// Lambertian: albedo = `base_color` (× texture).
    Diffuse,
    /// Modified Phong with diffuse part `base_color` (× texture), specular albedo and exponent.
    Glossy {
        /// Specular albedo.
        specular: Vec3,
        /// Phong exponent.
        exponent: f32,
    },
    /// Perfect mirror with reflectance `base_color`.
    Mirror,
    /// Smooth dielectric with this index of refraction, tinted by `base_color`.
    Dielectric {
        /// Index of refraction.
        ior: f32,
    },
}

/// A material as read from the file.
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialDesc {
    /// Name for messages.
    pub name: String,
    /// Diffuse albedo / reflectance factor (linear RGB).
    pub base_color: Vec3,
    /// Index into `SceneDesc::textures` multiplying `base_color`.
    pub base_color_texture: Option<usize>,
    /// Scattering model.
    pub scatter: ScatterDesc,
    /// Emitted radiance in W/(m²·sr) (factor × strength).
    pub emission: Vec3,
    /// Index into `SceneDesc::textures` multiplying `emission`.
    pub emission_texture: Option<usize>,
    /// Emits from both faces (glTF `doubleSided`); otherwise only the front (CCW) face.
    pub double_sided: bool,
}

impl MaterialDesc {
    /// A grey Lambertian material.
    pub fn diffuse(name: &str, albedo: Vec3) -> Self {
        MaterialDesc {
            name: name.to_string(),
            base_color: albedo,
            base_color_texture: None,
            scatter: ScatterDesc::Diffuse,
            emission: Vec3::ZERO,
            emission_texture: None,
            double_sided: false,
        }
    }
}

/// A triangle mesh in world space.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshDesc {
    /// Where it came from.
    pub origin: Origin,
    /// Vertex positions (world space).
    pub positions: Vec<Vec3>,
    /// Vertex normals (world space), empty when absent.
    pub normals: Vec<Vec3>,
    /// Texture coordinates, empty when absent.
    pub uvs: Vec<Vec2>,
    /// Triangle vertex indices, three per triangle, counter-clockwise = front.
    pub indices: Vec<u32>,
    /// Index into `SceneDesc::materials`.
    pub material: usize,
}

/// A light that is not a surface: a punctual light (KHR_lights_punctual, intensity taken as
/// radiant intensity in W/sr), a distant light (glTF `directional`, or `--sun`) or an
/// environment (`--sky`, `--environment`).
#[derive(Clone, Debug, PartialEq)]
pub enum PunctualDesc {
    /// Isotropic point light.
    Point {
        /// World position.
        position: Vec3,
        /// Radiant intensity (W/sr) per channel.
        intensity: Vec3,
    },
    /// Spot light with glTF's smooth cone falloff.
    Spot {
        /// World position.
        position: Vec3,
        /// Unit direction the spot points to.
        direction: Vec3,
        /// Radiant intensity on the axis (W/sr).
        intensity: Vec3,
        /// Inner cone angle (radians): full intensity inside.
        inner_cone: f32,
        /// Outer cone angle (radians): zero outside.
        outer_cone: f32,
    },
    /// A distant light (the sun).
    Directional {
        /// Unit direction the light travels in (glTF: the node's −Z).
        direction: Vec3,
        /// Illuminance on a surface facing the light (W/m² per channel; glTF's lux).
        illuminance: Vec3,
        /// Angular diameter (radians); 0 for parallel light.
        angular_diameter: f32,
    },
    /// An environment light at infinity.
    Environment(EnvironmentDesc),
}

/// The radiance of an environment light.
#[derive(Clone, Debug, PartialEq)]
pub enum EnvironmentDesc {
    /// The same radiance from every direction.
    Constant(Vec3),
    /// An equirectangular map (+y up, row 0 at the zenith; see `scene::sky`).
    Map {
        /// The file it was read from (for messages).
        path: PathBuf,
        /// Width in texels.
        width: u32,
        /// Height in texels.
        height: u32,
        /// Radiance per texel, row-major.
        texels: Vec<Vec3>,
        /// Rotation about +y, radians.
        rotation: f32,
    },
}

/// A camera as read from the file or the command line.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraDesc {
    /// Eye position.
    pub eye: Vec3,
    /// Point looked at.
    pub target: Vec3,
    /// Up vector.
    pub up: Vec3,
    /// Vertical field of view in degrees.
    pub fov_y_deg: f32,
    /// Aspect ratio width / height, when the file gives one.
    pub aspect: Option<f32>,
    /// Image width, when the file gives one.
    pub width: Option<u32>,
    /// Image height, when the file gives one.
    pub height: Option<u32>,
}

/// Everything a loader read from a scene file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SceneDesc {
    /// The file (for messages); empty for built-in scenes.
    pub path: PathBuf,
    /// Triangle meshes.
    pub meshes: Vec<MeshDesc>,
    /// Materials referenced by meshes.
    pub materials: Vec<MaterialDesc>,
    /// Decoded textures referenced by materials.
    pub textures: Vec<TextureDesc>,
    /// Point and spot lights.
    pub lights: Vec<PunctualDesc>,
    /// The camera, when the file has one.
    pub camera: Option<CameraDesc>,
    /// Things the loader ignored or repaired, for the user to see.
    pub warnings: Vec<String>,
}

impl SceneDesc {
    /// The same scene with all geometry, punctual lights and the camera scaled by `s` about the
    /// origin (radiance is unchanged, so the image must not change: a scale-invariance check).
    pub fn scaled(mut self, s: f32) -> Self {
        for m in &mut self.meshes {
            for p in &mut m.positions {
                *p *= s;
            }
        }
        for l in &mut self.lights {
            match l {
                // Intensity scales with s² so that irradiance at scaled distances is unchanged.
                PunctualDesc::Point { position, intensity } => {
                    *position *= s;
                    *intensity *= s * s;
                }
                PunctualDesc::Spot { position, intensity, .. } => {
                    *position *= s;
                    *intensity *= s * s;
                }
                // At infinity: the same light whatever the scale.
                PunctualDesc::Directional { .. } | PunctualDesc::Environment(_) => {}
            }
        }
        if let Some(c) = &mut self.camera {
            c.eye *= s;
            c.target *= s;
        }
        self
    }
}
