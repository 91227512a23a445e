//! glTF 2.0 loader: `.gltf` (external files or embedded `data:` URIs) and `.glb` → [`SceneDesc`].
//!
//! The default scene (else scene 0, else every root node) is walked depth-first, composing node
//! transforms to world space. Each triangle primitive becomes one [`MeshDesc`] (positions,
//! normals by the inverse transpose, `TEXCOORD_0`); a node with a negative-determinant transform
//! has its winding reversed so that counter-clockwise still means front. The first perspective
//! camera met becomes the scene camera (eye = node origin, looking down the node's −z, up = +y,
//! `aspectRatio` kept; the image size comes from the scene's `extras.mirage.width/height` when
//! present, as scenes/README.md specifies, else it is left to the command line);
//! `KHR_lights_punctual` point and spot lights become [`PunctualDesc`]s (range ignored with a
//! warning); directional lights become distant lights (the sun: colour × intensity as the
//! illuminance in lux, taken as W/m², travelling along the node's −Z; a zero or negative
//! intensity is an error naming the node).
//!
//! # Materials
//!
//! glTF's metallic-roughness model is mapped onto mirage's four scattering models:
//!
//! | glTF material                                          | mirage                                   |
//! |--------------------------------------------------------|------------------------------------------|
//! | `KHR_materials_transmission` factor > 0                | `Dielectric { ior }` (`KHR_materials_ior`, default 1.5), tint = base colour |
//! | metallic ≥ 0.9 and roughness ≤ 0.05                    | `Mirror`, reflectance = base colour      |
//! | roughness ≥ 0.95 (includes the default 1, 1)           | `Diffuse`, albedo = base colour          |
//! | otherwise                                              | `Glossy`: n = 2/r⁴ − 2, k_s = 0.04·(1 − m) + base·m, k_d = base·(1 − m), both scaled so k_d + k_s ≤ 1 per channel |
//!
//! (r = roughness, m = metallic; the exponent follows Walter et al. 2007 §5.2's Phong/Beckmann
//! correspondence with α = r².) Scene generators write the inverse: a diffuse surface is
//! metallic 0 / roughness 1, a mirror metallic 1 / roughness 0. Emission is `emissiveFactor` ×
//! `KHR_materials_emissive_strength`; `baseColorTexture` and `emissiveTexture` are decoded from
//! sRGB to linear, only when a material that a primitive uses refers to them.
//! `metallicRoughnessTexture`, normal and occlusion maps, alpha and other unsupported features
//! are reported as warnings, one line per place.
//!
//! # Robustness
//!
//! Malformed input must give a [`LoadError`], never a panic. The `gltf` crate's accessor
//! iterators and some of its accessors (`Camera::projection`, `Image::source`) can panic or
//! overflow on inconsistent files that pass its validation, so this module reads accessors with
//! its own bounds-checked reader and reads cameras and images from the raw JSON. Buffers are
//! loaded here (rather than with `gltf::import_buffers`) so that a missing file is named and a
//! malformed relative URI cannot reach the crate's `unwrap`; `data:` URIs are still decoded by
//! `gltf::buffer::Data`. `extensionsRequired` is checked before the crate's validation (which
//! would reject unknown ones with a terse "Unsupported extension") so the message names the
//! extension. Also before validation: every primitive must have a `POSITION` accessor that
//! exists (the crate's validation indexes it unchecked); missing `POSITION` min/max, which mirage
//! never reads, are filled in with a warning; application-specific attributes (`_BATCHID`),
//! which the crate rejects without its `extras` feature, are dropped with a warning. A seeded
//! corruption test (tests/io.rs; `MIRAGE_IO_FUZZ=20000` for a deeper run) guards all this.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::{Mat3, Mat4, Vec2, Vec3};
use gltf::Document;
use gltf::accessor::{DataType, Dimensions};
use gltf::json::validation::Checked;
use gltf::mesh::{Mode, Semantic};

use super::desc::{CameraDesc, MaterialDesc, MeshDesc, Origin, PunctualDesc, ScatterDesc, SceneDesc, TextureDesc};
use super::error::{LoadError, LoadErrorKind};
mod accessors;
mod materials;

pub use materials::decode_srgb_texture;

/// Extensions this loader interprets; `extensionsRequired` may only name these.
pub const IMPLEMENTED_EXTENSIONS: [&str; 4] =
    ["KHR_lights_punctual", "KHR_materials_emissive_strength", "KHR_materials_ior", "KHR_materials_transmission"];

/// Albedo of the material given to primitives without one.
const DEFAULT_ALBEDO: f32 = 0.8;

/// Most elements an accessor without a buffer view (all zeros) may declare.
const MAX_ZERO_ACCESSOR_COUNT: usize = 1 << 24;

/// Reads a `.gltf` or `.glb` file.
pub fn load_gltf(path: &Path) -> Result<SceneDesc, LoadError> {
    let bytes = std::fs::read(path).map_err(|e| LoadError::io(path, e))?;
    let base = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let Parsed { doc, blob, warnings } = parse(path, &bytes)?;
    let mut loader = Loader {
        path,
        base: &base,
        doc: &doc,
        buffers: Vec::new(),
        desc: SceneDesc { path: path.to_path_buf(), warnings, ..SceneDesc::default() },
        materials: HashMap::new(),
        textures: HashMap::new(),
        default_material: None,
        camera_node: None,
    };
    loader.buffers = loader.load_buffers(blob)?;
    loader.report_ignored_features();
    let scene = loader.walk()?;
    let mut desc = loader.desc;
    let extras = scene.and_then(|s| scene_extras(json_chunk(&bytes), s)).unwrap_or_default();
    if let Some(camera) = desc.camera.as_mut()
        && let Some((width, height)) = extras.resolution
    {
        camera.width = Some(width);
        camera.height = Some(height);
    }
    if let Some(d) = extras.sun_angular_diameter {
        for l in &mut desc.lights {
            if let PunctualDesc::Directional { angular_diameter, .. } = l {
                *angular_diameter = d;
            }
        }
    }
    if let Some(l) = extras.sky {
        desc.lights.push(PunctualDesc::Environment(crate::load::EnvironmentDesc::Constant(l)));
    }
    Ok(desc)
}

/// The JSON text of a `.gltf`, or the JSON chunk of a `.glb` (empty when it cannot be found).
fn json_chunk(bytes: &[u8]) -> &[u8] {
    if !bytes.starts_with(b"glTF") {
        return bytes;
    }
    let length = bytes.get(12..16).and_then(|b| b.try_into().ok()).map(u32::from_le_bytes).unwrap_or(0);
    bytes.get(20..20usize.saturating_add(length as usize)).unwrap_or_default()
}

/// What mirage's scene generator writes into a scene's extras (scenes/README.md):
/// `"extras": {"mirage": {"width": W, "height": H, "sky": [R, G, B], "sun_angular_diameter": RAD}}`,
/// each optional: the image size, a constant sky (glTF has no environment light) and the angular
/// diameter of the directional lights (glTF's are parallel).
#[derive(Clone, Copy, Debug, Default)]
struct MirageExtras {
    resolution: Option<(u32, u32)>,
    sky: Option<Vec3>,
    sun_angular_diameter: Option<f32>,
}

/// Reads [`MirageExtras`]. The gltf crate is built without its `extras` feature, so this reads
/// the JSON directly.
fn scene_extras(json: &[u8], scene: usize) -> Option<MirageExtras> {
    #[derive(serde::Deserialize)]
    struct Root {
        #[serde(default)]
        scenes: Vec<SceneExtras>,
    }
    #[derive(serde::Deserialize)]
    struct SceneExtras {
        #[serde(default)]
        extras: Option<serde_json::Value>,
    }
    let root: Root = serde_json::from_slice(json).ok()?;
    let mirage = root.scenes.get(scene)?.extras.as_ref()?.get("mirage")?;
    let pixels = |key: &str| mirage.get(key)?.as_u64().and_then(|v| u32::try_from(v).ok()).filter(|&v| v > 0);
    let number = |v: &serde_json::Value| v.as_f64().map(|x| x as f32).filter(|x| x.is_finite());
    let sky = mirage.get("sky").and_then(|v| v.as_array()).and_then(|a| match a.as_slice() {
        [r, g, b] => Some(Vec3::new(number(r)?, number(g)?, number(b)?)),
        _ => None,
    });
    Some(MirageExtras {
        resolution: pixels("width").zip(pixels("height")),
        sky,
        sun_angular_diameter: mirage.get("sun_angular_diameter").and_then(number),
    })
}

/// A parsed and validated document.
struct Parsed {
    doc: Document,
    /// The `.glb` binary chunk.
    blob: Option<Vec<u8>>,
    /// Unsupported extensions used, repaired or dropped parts.
    warnings: Vec<String>,
}

/// Parses and validates the document (see the module doc for what is checked or repaired first).
fn parse(path: &Path, bytes: &[u8]) -> Result<Parsed, LoadError> {
    if bytes.starts_with(b"glTF") {
        check_glb_header(path, bytes)?;
    }
    let gltf = gltf::Gltf::from_slice_without_validation(bytes).map_err(|e| translate(path, e))?;
    let gltf::Gltf { document, blob } = gltf;
    let mut root = document.into_json();
    for ext in &root.extensions_required {
        if !IMPLEMENTED_EXTENSIONS.contains(&ext.as_str()) {
            return Err(LoadError::new(
                path,
                LoadErrorKind::Unsupported,
                format!(
                    "requires unsupported extension '{ext}' (mirage implements {})",
                    IMPLEMENTED_EXTENSIONS.join(", ")
                ),
            ));
        }
    }
    let mut warnings: Vec<String> = root
        .extensions_used
        .iter()
        .filter(|e| !IMPLEMENTED_EXTENSIONS.contains(&e.as_str()))
        .map(|e| format!("{}: extension '{e}' is not supported and is ignored", path.display()))
        .collect();
    // Application-specific attributes ("_BATCHID") parse as invalid semantics without the gltf
    // crate's `extras` feature; drop them before validation instead of rejecting the file.
    for (m, mesh) in root.meshes.iter_mut().enumerate() {
        for (p, prim) in mesh.primitives.iter_mut().enumerate() {
            if prim.attributes.remove(&Checked::Invalid).is_some() {
                warnings.push(format!(
                    "{}: mesh {m}, primitive {p}: unrecognised vertex attribute(s) ignored",
                    path.display()
                ));
            }
        }
    }
    // glTF requires min/max on POSITION accessors; mirage never uses them, so files that omit
    // them (hand-written or generated) load with a warning instead of failing validation. The
    // gltf crate's validation indexes the POSITION accessor unchecked, so check it exists first.
    let mut positions = Vec::new();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            let place = format!("mesh {m}, primitive {p}");
            let Some(a) = prim.attributes.get(&Checked::Valid(Semantic::Positions)).map(|a| a.value()) else {
                return Err(LoadError::new(path, LoadErrorKind::Malformed, "has no POSITION attribute").at(place));
            };
            if a >= root.accessors.len() {
                let message = format!("POSITION refers to accessor {a}, which does not exist");
                return Err(LoadError::new(path, LoadErrorKind::Malformed, message).at(place));
            }
            positions.push(a);
        }
    }
    for a in positions {
        let Some(accessor) = root.accessors.get_mut(a) else { continue };
        let mut repaired = false;
        for bound in [&mut accessor.min, &mut accessor.max] {
            if bound.as_ref().is_none_or(|v| serde_json::from_value::<[f32; 3]>(v.clone()).is_err()) {
                *bound = Some(serde_json::json!([0.0, 0.0, 0.0]));
                repaired = true;
            }
        }
        if repaired {
            warnings.push(format!(
                "{}: accessor {a}: POSITION lacks valid min/max (required by glTF); not needed, ignored",
                path.display()
            ));
        }
    }
    let doc = Document::from_json(root).map_err(|e| translate(path, e))?;
    Ok(Parsed { doc, blob, warnings })
}

/// Checks the 12-byte `.glb` header so that a truncated file gets a clear message.
fn check_glb_header(path: &Path, bytes: &[u8]) -> Result<(), LoadError> {
    let malformed = |m: String| LoadError::new(path, LoadErrorKind::Malformed, m);
    let word = |i: usize| bytes.get(i..i + 4).and_then(|b| b.try_into().ok()).map(u32::from_le_bytes);
    let (Some(version), Some(length)) = (word(4), word(8)) else {
        return Err(malformed(format!("truncated .glb: only {} bytes, shorter than the 12-byte header", bytes.len())));
    };
    if version != 2 {
        return Err(LoadError::new(
            path,
            LoadErrorKind::Unsupported,
            format!("binary glTF version {version} (mirage reads 2)"),
        ));
    }
    if (length as usize) < 12 {
        return Err(malformed(format!("corrupt .glb header: declared length {length} is shorter than the header")));
    }
    if length as usize > bytes.len() {
        return Err(malformed(format!(
            "truncated .glb: the header declares {length} bytes but the file has {}",
            bytes.len()
        )));
    }
    Ok(())
}

/// The gltf crate's error as one readable sentence.
fn translate(path: &Path, err: gltf::Error) -> LoadError {
    let malformed = |m: String| LoadError::new(path, LoadErrorKind::Malformed, m);
    match err {
        gltf::Error::Io(e) => LoadError::io(path, e),
        gltf::Error::Binary(e) => malformed(format!("corrupt .glb: {e}")),
        gltf::Error::Deserialize(e) => {
            let text = e.to_string();
            let what = text.split(" at line ").next().unwrap_or(&text);
            let message = match e.classify() {
                serde_json::error::Category::Data => format!("not a valid glTF document: {what}"),
                _ => format!("broken JSON: {what}"),
            };
            malformed(message).at(format!("line {}, column {}", e.line(), e.column()))
        }
        gltf::Error::Validation(errors) => {
            let unsupported = errors.iter().any(|(_, e)| *e == gltf::json::validation::Error::Unsupported);
            let described: Vec<String> = errors
                .iter()
                .take(3)
                .map(|(p, e)| format!("{}: {}", p.as_str(), e.to_string().to_lowercase()))
                .collect();
            let more = if errors.len() > 3 { format!(" (and {} more)", errors.len() - 3) } else { String::new() };
            let kind = if unsupported { LoadErrorKind::Unsupported } else { LoadErrorKind::Malformed };
            LoadError::new(path, kind, format!("invalid glTF: {}{more}", described.join("; ")))
        }
        other => malformed(other.to_string()),
    }
}

/// `err` located inside `outer`: "node 1, mesh 0, primitive 0, accessor 3".
fn within(err: LoadError, outer: &str) -> LoadError {
    let location = match &err.location {
        Some(inner) => format!("{outer}, {inner}"),
        None => outer.to_string(),
    };
    err.at(location)
}

/// `%XX`-decodes a relative URI; `None` when the result is not UTF-8 or an escape is broken.
fn percent_decode(uri: &str) -> Option<String> {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while let Some(&b) = bytes.get(i) {
        if b == b'%' {
            let hex = std::str::from_utf8(bytes.get(i + 1..i + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(b);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

/// Loader state while walking one document.
struct Loader<'a> {
    path: &'a Path,
    base: &'a Path,
    doc: &'a Document,
    buffers: Vec<Vec<u8>>,
    desc: SceneDesc,
    /// glTF material index → index in `desc.materials`.
    materials: HashMap<usize, usize>,
    /// glTF image index → index in `desc.textures`.
    textures: HashMap<usize, usize>,
    default_material: Option<usize>,
    /// The node whose camera was taken.
    camera_node: Option<usize>,
}

impl Loader<'_> {
    fn error(&self, kind: LoadErrorKind, message: impl Into<String>) -> LoadError {
        LoadError::new(self.path, kind, message)
    }

    fn warn(&mut self, place: &str, what: impl std::fmt::Display) {
        self.desc.warnings.push(format!("{}: {place}: {what}", self.path.display()));
    }

    /// Reads the bytes a URI refers to: a `data:` URI or a file relative to the glTF.
    fn read_uri(&self, uri: &str) -> Result<Vec<u8>, LoadError> {
        if uri.starts_with("data:") {
            return gltf::buffer::Data::from_source(gltf::buffer::Source::Uri(uri), None).map(|d| d.0).map_err(|e| {
                self.error(
                    LoadErrorKind::Malformed,
                    format!("data URI cannot be decoded ({})", translate(self.path, e).message),
                )
            });
        }
        let file = if let Some(rest) = uri.strip_prefix("file://").or_else(|| uri.strip_prefix("file:")) {
            PathBuf::from(percent_decode(rest).unwrap_or_else(|| rest.to_string()))
        } else if uri.contains(':') {
            let scheme = uri.split(':').next().unwrap_or_default();
            return Err(self.error(
                LoadErrorKind::Unsupported,
                format!("URI scheme '{scheme}:' is not supported (use a relative file or a data: URI)"),
            ));
        } else {
            let Some(relative) = percent_decode(uri) else {
                return Err(self.error(LoadErrorKind::Malformed, format!("URI '{uri}' has a broken %-escape")));
            };
            self.base.join(relative)
        };
        std::fs::read(&file).map_err(|e| {
            let reason =
                if e.kind() == std::io::ErrorKind::NotFound { "file not found".to_string() } else { e.to_string() };
            let message = format!("cannot read '{}': {reason}", file.display());
            LoadError { path: self.path.to_path_buf(), location: None, kind: LoadErrorKind::Io(e), message }
        })
    }

    fn load_buffers(&self, mut blob: Option<Vec<u8>>) -> Result<Vec<Vec<u8>>, LoadError> {
        let mut buffers = Vec::new();
        for buffer in self.doc.buffers() {
            let place = format!("buffer {}", buffer.index());
            let data = match buffer.source() {
                gltf::buffer::Source::Bin => blob.take().ok_or_else(|| {
                    self.error(LoadErrorKind::Malformed, "refers to the .glb binary chunk, but there is none")
                        .at(place.clone())
                })?,
                gltf::buffer::Source::Uri(uri) => self.read_uri(uri).map_err(|e| e.at(place.clone()))?,
            };
            if data.len() < buffer.length() {
                return Err(self
                    .error(
                        LoadErrorKind::Malformed,
                        format!("has {} bytes but declares byteLength {}", data.len(), buffer.length()),
                    )
                    .at(place));
            }
            buffers.push(data);
        }
        Ok(buffers)
    }

    fn report_ignored_features(&mut self) {
        let animations = self.doc.animations().count();
        if animations > 0 {
            self.warn("animations", format!("{animations} animation(s) ignored (the scene is static)"));
        }
    }

    /// Walks the default scene's node hierarchy depth-first (iteratively: chains may be deep);
    /// returns the index of the scene walked, `None` when there is none (all root nodes).
    fn walk(&mut self) -> Result<Option<usize>, LoadError> {
        let doc = self.doc;
        let nodes: Vec<gltf::Node> = doc.nodes().collect();
        let scene = doc.default_scene().or_else(|| doc.scenes().next());
        let roots: Vec<usize> = match &scene {
            Some(scene) => scene.nodes().map(|n| n.index()).collect(),
            None => {
                let mut is_child = vec![false; nodes.len()];
                for child in nodes.iter().flat_map(|n| n.children()) {
                    if let Some(c) = is_child.get_mut(child.index()) {
                        *c = true;
                    }
                }
                (0..nodes.len()).filter(|&i| !is_child[i]).collect()
            }
        };
        let mut visited = vec![false; nodes.len()];
        let mut stack: Vec<(usize, Mat4)> = roots.iter().rev().map(|&i| (i, Mat4::IDENTITY)).collect();
        while let Some((index, parent)) = stack.pop() {
            let Some(node) = nodes.get(index) else { continue };
            match visited.get_mut(index) {
                Some(true) => {
                    self.warn(
                        &format!("node {index}"),
                        "has more than one parent or is part of a cycle; visited once only",
                    );
                    continue;
                }
                Some(v) => *v = true,
                None => continue,
            }
            let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
            self.visit(node, &world)?;
            let children: Vec<usize> = node.children().map(|c| c.index()).collect();
            stack.extend(children.into_iter().rev().map(|c| (c, world)));
        }
        Ok(scene.map(|s| s.index()))
    }

    fn visit(&mut self, node: &gltf::Node, world: &Mat4) -> Result<(), LoadError> {
        let place = format!("node {}", node.index());
        if node.skin().is_some() {
            self.warn(&place, "skin ignored (the mesh is used in its bind pose)");
        }
        if let Some(camera) = node.camera() {
            self.camera(node.index(), camera.index(), world);
        }
        if let Some(light) = node.light() {
            self.light(&place, &light, world)?;
        }
        if let Some(mesh) = node.mesh() {
            for (p, prim) in mesh.primitives().enumerate() {
                let origin = Origin::Gltf { node: node.index(), mesh: mesh.index(), primitive: p };
                self.primitive(origin, &prim, world)?;
            }
        }
        Ok(())
    }

    /// Takes the first perspective camera; reports the others.
    fn camera(&mut self, node: usize, index: usize, world: &Mat4) {
        let place = format!("node {node}, camera {index}");
        let Some(json) = self.doc.as_json().cameras.get(index) else { return };
        let perspective = match (&json.type_, json.perspective.as_ref()) {
            (Checked::Valid(gltf::json::camera::Type::Perspective), Some(p)) => p,
            (Checked::Valid(gltf::json::camera::Type::Perspective), None) => {
                return self.warn(&place, "perspective camera without parameters ignored");
            }
            _ => return self.warn(&place, "orthographic camera ignored (mirage renders perspective cameras only)"),
        };
        if let Some(first) = self.camera_node {
            return self.warn(&place, format!("ignored: the first camera (node {first}) is used"));
        }
        let eye = world.w_axis.truncate();
        let forward = (-world.z_axis.truncate()).normalize_or_zero();
        let up = world.y_axis.truncate().normalize_or_zero();
        if !eye.is_finite() || forward == Vec3::ZERO || up == Vec3::ZERO {
            return self.warn(&place, "camera node transform is degenerate; camera ignored");
        }
        self.camera_node = Some(node);
        self.desc.camera = Some(CameraDesc {
            eye,
            target: eye + forward,
            up,
            fov_y_deg: perspective.yfov.to_degrees(),
            aspect: perspective.aspect_ratio,
            width: None,
            height: None,
        });
    }

    fn light(&mut self, place: &str, light: &gltf::khr_lights_punctual::Light, world: &Mat4) -> Result<(), LoadError> {
        let place = format!("{place}, light {}", light.index());
        if light.range().is_some() {
            self.warn(&place, "range ignored (lights fall off with the inverse square law)");
        }
        let position = world.w_axis.truncate();
        let intensity = Vec3::from_array(light.color()) * light.intensity();
        match light.kind() {
            gltf::khr_lights_punctual::Kind::Directional => {
                if !(light.intensity() > 0.0 && intensity.is_finite() && intensity.min_element() >= 0.0) {
                    return Err(self
                        .error(
                            LoadErrorKind::Invalid,
                            format!(
                                "directional light intensity {} × colour {:?} must be positive and finite",
                                light.intensity(),
                                light.color()
                            ),
                        )
                        .at(place));
                }
                let direction = (-world.z_axis.truncate()).normalize_or_zero();
                if direction == Vec3::ZERO || !direction.is_finite() {
                    return Err(self
                        .error(LoadErrorKind::Invalid, "directional light node transform is degenerate")
                        .at(place));
                }
                self.desc.lights.push(PunctualDesc::Directional {
                    direction,
                    illuminance: intensity,
                    angular_diameter: 0.0,
                })
            }
            gltf::khr_lights_punctual::Kind::Point => {
                self.desc.lights.push(PunctualDesc::Point { position, intensity })
            }
            gltf::khr_lights_punctual::Kind::Spot { inner_cone_angle, outer_cone_angle } => {
                self.desc.lights.push(PunctualDesc::Spot {
                    position,
                    direction: (-world.z_axis.truncate()).normalize_or_zero(),
                    intensity,
                    inner_cone: inner_cone_angle,
                    outer_cone: outer_cone_angle,
                })
            }
        }
        Ok(())
    }

    fn primitive(&mut self, origin: Origin, prim: &gltf::Primitive, world: &Mat4) -> Result<(), LoadError> {
        let place = origin.to_string();
        let at = |e: LoadError| within(e, &place);
        if prim.mode() != Mode::Triangles {
            self.warn(&place, format!("mode {:?} skipped (only triangles are rendered)", prim.mode()));
            return Ok(());
        }
        if prim.morph_targets().next().is_some() {
            self.warn(&place, "morph targets ignored");
        }
        let Some(pos_accessor) = prim.get(&Semantic::Positions) else {
            return Err(at(self.error(LoadErrorKind::Malformed, "has no POSITION attribute")));
        };
        let local = self.read_vec3(&pos_accessor).map_err(at)?;
        if let Some(k) = local.iter().position(|p| !p.is_finite()) {
            return Err(at(self.error(LoadErrorKind::Invalid, format!("vertex {k} has a non-finite position"))));
        }
        let positions: Vec<Vec3> = local.iter().map(|&p| world.transform_point3(p)).collect();
        let n = positions.len();
        let Ok(n32) = u32::try_from(n) else {
            return Err(at(
                self.error(LoadErrorKind::Unsupported, format!("{n} vertices exceed the 32-bit index range"))
            ));
        };

        let mut normals = Vec::new();
        if let Some(acc) = prim.get(&Semantic::Normals) {
            let local = self.read_vec3(&acc).map_err(at)?;
            let linear = Mat3::from_mat4(*world);
            let det = linear.determinant();
            if local.len() != n {
                self.warn(&place, format!("{} normals for {n} positions; normals ignored", local.len()));
            } else if det != 0.0 && det.is_finite() {
                let normal_from_local = linear.inverse().transpose();
                normals = local.iter().map(|&v| (normal_from_local * v).normalize_or_zero()).collect();
            }
        }
        let mut uvs = Vec::new();
        if let Some(acc) = prim.get(&Semantic::TexCoords(0)) {
            let read = self.read_floats(&acc, Dimensions::Vec2).map_err(at)?;
            if read.len() != 2 * n {
                self.warn(&place, format!("{} texture coordinates for {n} positions; ignored", read.len() / 2));
            } else {
                uvs = read.chunks_exact(2).map(|c| Vec2::new(c[0], c[1])).collect();
            }
        }

        let mut indices = match prim.indices() {
            Some(acc) => {
                let indices = self.read_indices(&acc).map_err(at)?;
                if let Some((k, &i)) = indices.iter().enumerate().find(|&(_, &i)| i >= n32) {
                    let message =
                        format!("index {k} (accessor {}) is {i}, but there are only {n} vertices", acc.index());
                    return Err(at(self.error(LoadErrorKind::Invalid, message)));
                }
                indices
            }
            None => (0..n32).collect(),
        };
        if indices.len() % 3 != 0 {
            self.warn(
                &place,
                format!("{} indices is not a multiple of 3; the last {} dropped", indices.len(), indices.len() % 3),
            );
            indices.truncate(indices.len() - indices.len() % 3);
        }
        if world.determinant() < 0.0 {
            // A mirroring transform turns counter-clockwise into clockwise; swap to keep the front.
            for t in indices.chunks_exact_mut(3) {
                t.swap(1, 2);
            }
        }
        let material = match prim.material().index() {
            Some(m) => self.material(m)?,
            None => self.default_material(),
        };
        self.desc.meshes.push(MeshDesc { origin, positions, normals, uvs, indices, material });
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::materials::scatter_from_metallic_roughness;
    use super::*;

    #[test]
    fn default_and_extreme_metallic_roughness_map_to_diffuse_and_mirror() {
        let base = Vec3::new(0.5, 0.4, 0.3);
        assert_eq!(scatter_from_metallic_roughness(base, 1.0, 1.0), (base, ScatterDesc::Diffuse));
        assert_eq!(scatter_from_metallic_roughness(base, 0.0, 1.0), (base, ScatterDesc::Diffuse));
        assert_eq!(scatter_from_metallic_roughness(base, 1.0, 0.0), (base, ScatterDesc::Mirror));
    }

    #[test]
    fn glossy_mapping_uses_walter_exponent_and_conserves_energy() {
        let (kd, scatter) = scatter_from_metallic_roughness(Vec3::new(0.9, 0.5, 0.1), 0.0, 0.5);
        let ScatterDesc::Glossy { specular, exponent } = scatter else { panic!("{scatter:?}") };
        assert!((exponent - 30.0).abs() < 1e-3, "{exponent}");
        assert!((specular - Vec3::splat(0.04)).abs().max_element() < 1e-6);
        assert!((kd - Vec3::new(0.9, 0.5, 0.1)).abs().max_element() < 1e-6);
        let (kd, scatter) = scatter_from_metallic_roughness(Vec3::ONE, 0.5, 0.3);
        let ScatterDesc::Glossy { specular, .. } = scatter else { panic!("{scatter:?}") };
        assert!((kd + specular).max_element() <= 1.0 + 1e-6);
    }

    #[test]
    fn percent_decoding_accepts_utf8_and_rejects_broken_escapes() {
        assert_eq!(percent_decode("my%20scene.bin").as_deref(), Some("my scene.bin"));
        assert_eq!(percent_decode("caf%C3%A9.png").as_deref(), Some("café.png"));
        assert_eq!(percent_decode("bad%FF.bin"), None);
        assert_eq!(percent_decode("bad%2"), None);
    }

    #[test]
    fn glb_headers_that_are_short_or_lie_about_length_are_rejected() {
        let p = Path::new("x.glb");
        assert!(check_glb_header(p, b"glTF\x02\0\0").unwrap_err().message.contains("truncated"));
        let mut h = b"glTF".to_vec();
        h.extend(2u32.to_le_bytes());
        h.extend(100u32.to_le_bytes());
        assert!(check_glb_header(p, &h).unwrap_err().message.contains("declares 100 bytes"));
        h[8..12].copy_from_slice(&4u32.to_le_bytes());
        assert!(check_glb_header(p, &h).unwrap_err().message.contains("corrupt"));
    }
}
