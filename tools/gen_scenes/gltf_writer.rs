//! [`SceneDesc`] → a self-contained glTF 2.0 `.gltf` (JSON with the geometry in one base64
//! `data:` buffer).
//!
//! The JSON is built from `#[derive(Serialize)]` structs, so keys come out in declaration
//! order and floats in serde_json's shortest round-trip form: the same scene gives the same
//! bytes on every run. The big buffer is the last key, so the head of the file stays readable.
//!
//! Conventions (the glTF loader in `src/load/gltf.rs` applies the inverse; scenes/README.md):
//! * one mesh with one indexed triangle primitive (u32 indices) and one root node without a
//!   transform per `MeshDesc` (positions are already in world space);
//! * materials: Diffuse → metallic 0, roughness 1; Mirror → metallic 1, roughness 0;
//!   Dielectric → KHR_materials_transmission (factor 1) + KHR_materials_ior, metallic 0,
//!   roughness 0; Glossy → metallic 0, roughness (2 / (n + 2))^¼ (approximate);
//!   `base_color` → baseColorFactor (alpha 1); emission `e` with `s = max(e)` →
//!   emissiveFactor `e / s` and KHR_materials_emissive_strength `s` when `s > 1`, else
//!   emissiveFactor `e`; `double_sided` → doubleSided;
//! * camera: a perspective camera on its own node, translation = eye, rotation taking the local
//!   axes (+X right, +Y up, −Z forward) to the look-at frame (see [`camera_rotation`]);
//! * the resolution goes in the scene's `extras.mirage` (`width`, `height`);
//! * a distant light (the sun) becomes a `KHR_lights_punctual` directional light on its own node
//!   (rotation taking −Z to the direction it travels; intensity the largest channel of the
//!   illuminance, colour the rest), its angular diameter `extras.mirage.sun_angular_diameter`
//!   (radians; glTF's are parallel); a constant sky `extras.mirage.sky` ([R, G, B]: glTF has
//!   no environment light).

use glam::{Mat3, Quat, Vec2, Vec3, Vec4};
use mirage::load::{CameraDesc, EnvironmentDesc, MaterialDesc, MeshDesc, Origin, PunctualDesc, ScatterDesc, SceneDesc};
use serde::Serialize;

use super::base64;

/// glTF component type of `u32` indices.
const UNSIGNED_INT: u32 = 5125;
/// glTF component type of `f32` attributes.
const FLOAT: u32 = 5126;
/// Buffer-view target of vertex attributes.
const ARRAY_BUFFER: u32 = 34962;
/// Buffer-view target of indices.
const ELEMENT_ARRAY_BUFFER: u32 = 34963;

/// Near plane of the written cameras (glTF requires one; mirage's cameras have none).
pub const ZNEAR: f32 = 0.01;

/// glTF extension names.
pub const KHR_TRANSMISSION: &str = "KHR_materials_transmission";
/// See [`KHR_TRANSMISSION`].
pub const KHR_IOR: &str = "KHR_materials_ior";
/// See [`KHR_TRANSMISSION`].
pub const KHR_EMISSIVE_STRENGTH: &str = "KHR_materials_emissive_strength";

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
struct Root {
    asset: Asset,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    extensions_used: Vec<&'static str>,
    #[serde(skip_serializing_if = "Option::is_none")]
    extensions: Option<RootExtensions>,
    scene: usize,
    scenes: Vec<Scene>,
    nodes: Vec<Node>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    cameras: Vec<Camera>,
    meshes: Vec<Mesh>,
    materials: Vec<Material>,
    accessors: Vec<Accessor>,
    buffer_views: Vec<BufferView>,
    buffers: Vec<Buffer>,
}

#[derive(Serialize)]
struct Asset {
    version: &'static str,
    generator: &'static str,
}

#[derive(Serialize)]
struct Scene {
    nodes: Vec<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    extras: Option<SceneExtras>,
}

#[derive(Serialize)]
struct SceneExtras {
    mirage: MirageExtras,
}

#[derive(Serialize, Default)]
struct MirageExtras {
    #[serde(skip_serializing_if = "Option::is_none")]
    width: Option<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    height: Option<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    sky: Option<[f32; 3]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    sun_angular_diameter: Option<f32>,
}

#[derive(Serialize)]
struct RootExtensions {
    #[serde(rename = "KHR_lights_punctual")]
    lights: LightList,
}

#[derive(Serialize)]
struct LightList {
    lights: Vec<Light>,
}

#[derive(Serialize)]
struct Light {
    #[serde(rename = "type")]
    kind: &'static str,
    color: [f32; 3],
    intensity: f32,
}

#[derive(Serialize)]
struct NodeExtensions {
    #[serde(rename = "KHR_lights_punctual")]
    light: NodeLight,
}

#[derive(Serialize)]
struct NodeLight {
    light: usize,
}

#[derive(Serialize)]
struct Node {
    name: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    mesh: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    camera: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    translation: Option<[f32; 3]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    rotation: Option<[f32; 4]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    extensions: Option<NodeExtensions>,
}

#[derive(Serialize)]
struct Camera {
    name: &'static str,
    #[serde(rename = "type")]
    kind: &'static str,
    perspective: Perspective,
}

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
struct Perspective {
    #[serde(skip_serializing_if = "Option::is_none")]
    aspect_ratio: Option<f32>,
    yfov: f32,
    znear: f32,
}

#[derive(Serialize)]
struct Mesh {
    name: String,
    primitives: [Primitive; 1],
}

#[derive(Serialize)]
struct Primitive {
    attributes: Attributes,
    indices: usize,
    material: usize,
}

#[derive(Serialize)]
struct Attributes {
    #[serde(rename = "POSITION")]
    position: usize,
    #[serde(rename = "NORMAL", skip_serializing_if = "Option::is_none")]
    normal: Option<usize>,
    #[serde(rename = "TEXCOORD_0", skip_serializing_if = "Option::is_none")]
    texcoord_0: Option<usize>,
}

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
struct Material {
    name: String,
    pbr_metallic_roughness: Pbr,
    #[serde(skip_serializing_if = "Option::is_none")]
    emissive_factor: Option<[f32; 3]>,
    double_sided: bool,
    #[serde(skip_serializing_if = "MaterialExtensions::is_empty")]
    extensions: MaterialExtensions,
}

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
struct Pbr {
    base_color_factor: [f32; 4],
    metallic_factor: f32,
    roughness_factor: f32,
}

#[derive(Default, Serialize)]
struct MaterialExtensions {
    #[serde(rename = "KHR_materials_transmission", skip_serializing_if = "Option::is_none")]
    transmission: Option<Transmission>,
    #[serde(rename = "KHR_materials_ior", skip_serializing_if = "Option::is_none")]
    ior: Option<Ior>,
    #[serde(rename = "KHR_materials_emissive_strength", skip_serializing_if = "Option::is_none")]
    emissive_strength: Option<EmissiveStrength>,
}

impl MaterialExtensions {
    fn is_empty(&self) -> bool {
        self.transmission.is_none() && self.ior.is_none() && self.emissive_strength.is_none()
    }
}

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
struct Transmission {
    transmission_factor: f32,
}

#[derive(Serialize)]
struct Ior {
    ior: f32,
}

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
struct EmissiveStrength {
    emissive_strength: f32,
}

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
struct Accessor {
    buffer_view: usize,
    component_type: u32,
    count: usize,
    #[serde(rename = "type")]
    kind: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    min: Option<[f32; 3]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    max: Option<[f32; 3]>,
}

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
struct BufferView {
    buffer: usize,
    byte_offset: usize,
    byte_length: usize,
    target: u32,
}

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
struct Buffer {
    byte_length: usize,
    uri: String,
}

/// The one binary buffer, with a buffer view and an accessor per array pushed into it.
#[derive(Default)]
struct BufferBuilder {
    data: Vec<u8>,
    views: Vec<BufferView>,
    accessors: Vec<Accessor>,
}

impl BufferBuilder {
    /// Appends little-endian `f32`/`u32` words as a new view and accessor; returns its index.
    fn push(&mut self, words: impl Iterator<Item = [u8; 4]>, accessor: Accessor, target: u32) -> usize {
        let byte_offset = self.data.len();
        words.for_each(|w| self.data.extend(w));
        // Every element is 4 bytes, so every view stays 4-byte aligned as glTF requires.
        self.views.push(BufferView { buffer: 0, byte_offset, byte_length: self.data.len() - byte_offset, target });
        self.accessors.push(Accessor { buffer_view: self.views.len() - 1, ..accessor });
        self.accessors.len() - 1
    }

    fn indices(&mut self, indices: &[u32]) -> usize {
        let accessor = Accessor {
            buffer_view: 0,
            component_type: UNSIGNED_INT,
            count: indices.len(),
            kind: "SCALAR",
            min: None,
            max: None,
        };
        self.push(indices.iter().map(|i| i.to_le_bytes()), accessor, ELEMENT_ARRAY_BUFFER)
    }

    fn vec3s(&mut self, v: &[Vec3], with_bounds: bool) -> usize {
        let (lo, hi) = v.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| (lo.min(p), hi.max(p)));
        let accessor = Accessor {
            buffer_view: 0,
            component_type: FLOAT,
            count: v.len(),
            kind: "VEC3",
            min: with_bounds.then_some(lo.to_array()),
            max: with_bounds.then_some(hi.to_array()),
        };
        self.push(v.iter().flat_map(|p| p.to_array()).map(f32::to_le_bytes), accessor, ARRAY_BUFFER)
    }

    fn vec2s(&mut self, v: &[Vec2]) -> usize {
        let accessor =
            Accessor { buffer_view: 0, component_type: FLOAT, count: v.len(), kind: "VEC2", min: None, max: None };
        self.push(v.iter().flat_map(|p| p.to_array()).map(f32::to_le_bytes), accessor, ARRAY_BUFFER)
    }
}

/// The name written for a mesh and its node: the builder's part name for built-in meshes
/// ("cornell red wall"), the origin's display text otherwise.
pub fn mesh_name(mesh: &MeshDesc) -> String {
    match &mesh.origin {
        Origin::Builtin(what) => what.clone(),
        other => other.to_string(),
    }
}

/// Roughness standing in for a Phong exponent `n`: r = (2 / (n + 2))^¼ inverts the usual
/// Beckmann ↔ Phong correspondence n = 2 / α² − 2 with α = r² (only approximate: the shapes of
/// the lobes differ and the specular albedo is dropped).
pub fn roughness_from_phong_exponent(n: f32) -> f32 {
    (2.0 / (n + 2.0)).powf(0.25)
}

/// The rotation of a glTF camera node at `cam.eye` looking at `cam.target`: glTF cameras look
/// down their local −Z with +Y up and +X right, so the rotation's columns are (right, up,
/// −forward) with forward = normalize(target − eye), right = normalize(forward × up) and the
/// true up = right × forward (the component of `cam.up` orthogonal to forward). This is
/// `Mat3::look_to_rh(forward, up)` transposed and matches `scene::Camera::look_at`. The
/// quaternion is returned with w ≥ 0.
pub fn camera_rotation(cam: &CameraDesc) -> Result<Quat, String> {
    let forward = (cam.target - cam.eye).normalize_or_zero();
    let right = forward.cross(cam.up).normalize_or_zero();
    if forward == Vec3::ZERO || right == Vec3::ZERO {
        return Err(format!(
            "degenerate camera: eye {} target {} up {} (eye = target or up parallel to the view direction)",
            cam.eye, cam.target, cam.up
        ));
    }
    let up = right.cross(forward);
    let q = Quat::from_mat3(&Mat3::from_cols(right, up, -forward)).normalize();
    Ok(if q.w < 0.0 { -q } else { q })
}

/// Everything gen_scenes cannot express, or that would make an invalid file, as a message.
fn check_writable(desc: &SceneDesc) -> Result<(), String> {
    if !desc.textures.is_empty() {
        return Err("textures are not supported by gen_scenes".into());
    }
    let mut sky = 0;
    for l in &desc.lights {
        match l {
            PunctualDesc::Directional { direction, illuminance, angular_diameter } => {
                if !(direction.is_finite() && illuminance.is_finite() && illuminance.max_element() > 0.0) {
                    return Err("directional light: non-finite direction or illuminance".into());
                }
                if desc.lights.iter().any(
                    |o| matches!(o, PunctualDesc::Directional { angular_diameter: d, .. } if d != angular_diameter),
                ) {
                    return Err(
                        "directional lights of different angular diameters are not supported by gen_scenes".into()
                    );
                }
            }
            PunctualDesc::Environment(EnvironmentDesc::Constant(_)) => sky += 1,
            _ => return Err("point, spot and image-based lights are not supported by gen_scenes".into()),
        }
    }
    if sky > 1 {
        return Err("more than one sky is not supported by gen_scenes".into());
    }
    let finite3 = |v: Vec3| v.is_finite();
    for m in &desc.materials {
        if m.base_color_texture.is_some() || m.emission_texture.is_some() {
            return Err(format!("material '{}': textures are not supported by gen_scenes", m.name));
        }
        if !finite3(m.base_color) || !finite3(m.emission) || m.emission.min_element() < 0.0 {
            return Err(format!("material '{}': non-finite colour or negative emission", m.name));
        }
    }
    for m in &desc.meshes {
        let name = mesh_name(m);
        let n = m.positions.len();
        if m.indices.is_empty() || m.indices.len() % 3 != 0 {
            return Err(format!("mesh '{name}': {} indices is not a positive multiple of 3", m.indices.len()));
        }
        if let Some(i) = m.indices.iter().find(|&&i| i as usize >= n) {
            return Err(format!("mesh '{name}': index {i} out of range ({n} vertices)"));
        }
        if (!m.normals.is_empty() && m.normals.len() != n) || (!m.uvs.is_empty() && m.uvs.len() != n) {
            return Err(format!("mesh '{name}': normal or uv count differs from the {n} positions"));
        }
        if !m.positions.iter().chain(&m.normals).all(|&p| finite3(p)) || !m.uvs.iter().all(|t| t.is_finite()) {
            return Err(format!("mesh '{name}': non-finite vertex data"));
        }
        if m.material >= desc.materials.len() {
            return Err(format!("mesh '{name}': material {} out of range", m.material));
        }
    }
    Ok(())
}

fn material(m: &MaterialDesc, extensions_used: &mut Vec<&'static str>) -> Material {
    let mut use_ext = |name: &'static str| {
        if !extensions_used.contains(&name) {
            extensions_used.push(name);
        }
    };
    let mut extensions = MaterialExtensions::default();
    let (metallic_factor, roughness_factor) = match m.scatter {
        ScatterDesc::Diffuse => (0.0, 1.0),
        ScatterDesc::Glossy { exponent, .. } => (0.0, roughness_from_phong_exponent(exponent)),
        ScatterDesc::Mirror => (1.0, 0.0),
        ScatterDesc::Dielectric { ior } => {
            extensions.transmission = Some(Transmission { transmission_factor: 1.0 });
            extensions.ior = Some(Ior { ior });
            use_ext(KHR_TRANSMISSION);
            use_ext(KHR_IOR);
            (0.0, 0.0)
        }
    };
    let s = m.emission.max_element();
    let emissive_factor = if s > 1.0 {
        extensions.emissive_strength = Some(EmissiveStrength { emissive_strength: s });
        use_ext(KHR_EMISSIVE_STRENGTH);
        Some((m.emission / s).to_array())
    } else {
        (s > 0.0).then_some(m.emission.to_array())
    };
    Material {
        name: m.name.clone(),
        pbr_metallic_roughness: Pbr {
            base_color_factor: m.base_color.extend(1.0).to_array(),
            metallic_factor,
            roughness_factor,
        },
        emissive_factor,
        double_sided: m.double_sided,
        extensions,
    }
}

/// The `.gltf` file (pretty-printed JSON, ending in a newline) for `desc`.
pub fn write_gltf(desc: &SceneDesc) -> Result<Vec<u8>, String> {
    check_writable(desc)?;
    let mut buffer = BufferBuilder::default();
    let mut nodes = Vec::new();
    let mut meshes = Vec::new();
    for (i, m) in desc.meshes.iter().enumerate() {
        let indices = buffer.indices(&m.indices);
        let position = buffer.vec3s(&m.positions, true);
        let normal = (!m.normals.is_empty()).then(|| buffer.vec3s(&m.normals, false));
        let texcoord_0 = (!m.uvs.is_empty()).then(|| buffer.vec2s(&m.uvs));
        let name = mesh_name(m);
        meshes.push(Mesh {
            name: name.clone(),
            primitives: [Primitive {
                attributes: Attributes { position, normal, texcoord_0 },
                indices,
                material: m.material,
            }],
        });
        nodes.push(Node { name, mesh: Some(i), camera: None, translation: None, rotation: None, extensions: None });
    }
    let mut extensions_used = Vec::new();
    let materials = desc.materials.iter().map(|m| material(m, &mut extensions_used)).collect();
    let mut cameras = Vec::new();
    let mut mirage = MirageExtras::default();
    let mut lights = Vec::new();
    for l in &desc.lights {
        match *l {
            PunctualDesc::Directional { direction, illuminance, angular_diameter } => {
                let intensity = illuminance.max_element();
                let q = Quat::from_rotation_arc(-Vec3::Z, direction.normalize());
                nodes.push(Node {
                    name: format!("sun {}", lights.len()),
                    mesh: None,
                    camera: None,
                    translation: None,
                    rotation: Some((Vec4::from(if q.w < 0.0 { -q } else { q }) + 0.0).to_array()),
                    extensions: Some(NodeExtensions { light: NodeLight { light: lights.len() } }),
                });
                lights.push(Light { kind: "directional", color: (illuminance / intensity).to_array(), intensity });
                if angular_diameter > 0.0 {
                    mirage.sun_angular_diameter = Some(angular_diameter);
                }
            }
            PunctualDesc::Environment(EnvironmentDesc::Constant(l)) => mirage.sky = Some(l.to_array()),
            _ => unreachable!("check_writable refuses the others"),
        }
    }
    if !lights.is_empty() {
        extensions_used.push("KHR_lights_punctual");
    }
    if let Some(cam) = &desc.camera {
        let resolution = cam.width.zip(cam.height);
        let aspect_ratio = resolution.map(|(w, h)| w as f32 / h as f32).or(cam.aspect);
        cameras.push(Camera {
            name: "camera",
            kind: "perspective",
            perspective: Perspective { aspect_ratio, yfov: cam.fov_y_deg.to_radians(), znear: ZNEAR },
        });
        nodes.push(Node {
            name: "camera".into(),
            mesh: None,
            camera: Some(0),
            // `+ 0.0` turns −0.0 into 0.0 for tidier output.
            translation: Some((cam.eye + 0.0).to_array()),
            rotation: Some((Vec4::from(camera_rotation(cam)?) + 0.0).to_array()),
            extensions: None,
        });
        if let Some((width, height)) = resolution {
            (mirage.width, mirage.height) = (Some(width), Some(height));
        }
    }
    let any_extras = mirage.width.is_some() || mirage.sky.is_some() || mirage.sun_angular_diameter.is_some();
    let extras = any_extras.then_some(SceneExtras { mirage });
    let root = Root {
        asset: Asset { version: "2.0", generator: "mirage gen_scenes" },
        extensions_used,
        extensions: (!lights.is_empty()).then_some(RootExtensions { lights: LightList { lights } }),
        scene: 0,
        scenes: vec![Scene { nodes: (0..nodes.len()).collect(), extras }],
        nodes,
        cameras,
        meshes,
        materials,
        accessors: buffer.accessors,
        buffer_views: buffer.views,
        buffers: vec![Buffer {
            byte_length: buffer.data.len(),
            uri: format!("data:application/octet-stream;base64,{}", base64::encode(&buffer.data)),
        }],
    };
    let json = serde_json::to_string_pretty(&root).map_err(|e| format!("serialising glTF JSON: {e}"))?;
    Ok((compact_number_arrays(&json) + "\n").into_bytes())
}

/// Puts arrays of plain numbers on one line (`[0.73, 0.73, 0.73, 1.0]`), which serde_json's
/// pretty printer spreads one number per line. Text inside strings is left alone.
pub fn compact_number_arrays(json: &str) -> String {
    let is_number_text =
        |c: char| c.is_ascii_digit() || matches!(c, '-' | '+' | '.' | 'e' | 'E' | ',') || c.is_whitespace();
    let mut out = String::with_capacity(json.len());
    let (mut in_string, mut escaped) = (false, false);
    let mut rest = json;
    while let Some(c) = rest.chars().next() {
        if in_string {
            (in_string, escaped) = (escaped || c != '"', !escaped && c == '\\');
        } else if c == '"' {
            in_string = true;
        } else if c == '['
            && let Some(end) = rest.find(']').filter(|&end| rest[1..end].chars().all(is_number_text))
        {
            let items: Vec<&str> = rest[1..end].split(',').map(str::trim).collect();
            out.push('[');
            out.push_str(&items.join(", "));
            out.push(']');
            rest = &rest[end + 1..];
            continue;
        }
        out.push(c);
        rest = &rest[c.len_utf8()..];
    }
    out
}

#[cfg(test)]
mod tests {
    use super::compact_number_arrays;

    #[test]
    fn number_arrays_go_on_one_line_and_strings_are_untouched() {
        let pretty = "{\n  \"a\": [\n    1.0,\n    -2e-7\n  ],\n  \"b\": \"[1,  2] \\\" [3,\\n 4]\",\n  \"c\": [\n    {}\n  ],\n  \"d\": []\n}";
        let compact =
            "{\n  \"a\": [1.0, -2e-7],\n  \"b\": \"[1,  2] \\\" [3,\\n 4]\",\n  \"c\": [\n    {}\n  ],\n  \"d\": []\n}";
        assert_eq!(compact_number_arrays(pretty), compact);
    }
}
