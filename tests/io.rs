//! The input boundary end to end: scene files written by the tests (glTF with embedded buffers
//! and PNG textures, `.glb`, OBJ + MTL + camera.json) load into the expected `SceneDesc`, and
//! bad files give errors that name the file and the problem.

use std::f32::consts::FRAC_1_SQRT_2;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use glam::{Vec2, Vec3};
use mirage::bsdf::BsdfKind;
use mirage::color::srgb_to_linear;
use mirage::load::{self, LoadError, LoadErrorKind, Origin, PunctualDesc, ScatterDesc, SceneDesc};
use mirage::scene::{CameraSettings, Scene};

// ---------------------------------------------------------------------------------------------
// Helpers: temporary directories, base64, PNG and glTF / GLB writers.

/// A fresh directory for one test, under cargo's temporary directory for integration tests
/// (inside `target/`, replaced on the next run: nothing is left in the system's temp dir).
fn temp_dir(test: &str) -> PathBuf {
    static COUNTER: AtomicUsize = AtomicUsize::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("io").join(format!("{test}-{n}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn write(dir: &Path, name: &str, contents: impl AsRef<[u8]>) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, contents).unwrap();
    path
}

fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for chunk in bytes.chunks(3) {
        let b = [chunk[0], *chunk.get(1).unwrap_or(&0), *chunk.get(2).unwrap_or(&0)];
        let n = (b[0] as u32) << 16 | (b[1] as u32) << 8 | b[2] as u32;
        for i in 0..4 {
            if i <= chunk.len() {
                out.push(ALPHABET[(n >> (18 - 6 * i) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// A PNG of `width × height` sRGB texels, row-major from the top.
fn png(width: u32, height: u32, texels: &[[u8; 3]]) -> Vec<u8> {
    let img = image::RgbImage::from_fn(width, height, |x, y| image::Rgb(texels[(y * width + x) as usize]));
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).unwrap();
    out.into_inner()
}

/// One glTF buffer being filled, with its buffer views and accessors as JSON.
#[derive(Default)]
struct Buffer {
    bytes: Vec<u8>,
    views: Vec<String>,
    accessors: Vec<String>,
    /// Leave out the min/max bounds glTF requires on POSITION accessors.
    omit_bounds: bool,
}

impl Buffer {
    fn view(&mut self, data: &[u8]) -> usize {
        while !self.bytes.len().is_multiple_of(4) {
            self.bytes.push(0);
        }
        self.views.push(format!(
            r#"{{"buffer": 0, "byteOffset": {}, "byteLength": {}}}"#,
            self.bytes.len(),
            data.len()
        ));
        self.bytes.extend_from_slice(data);
        self.views.len() - 1
    }

    /// A float accessor of `ty` ("VEC2", "VEC3") over `values`.
    fn floats(&mut self, ty: &str, values: &[f32]) -> usize {
        let comps = if ty == "VEC2" { 2 } else { 3 };
        let data: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        let view = self.view(&data);
        let mut bounds = String::new();
        if comps == 3 && !self.omit_bounds {
            let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
            for p in values.chunks_exact(3) {
                lo = lo.min(Vec3::from_slice(p));
                hi = hi.max(Vec3::from_slice(p));
            }
            bounds = format!(r#", "min": [{}, {}, {}], "max": [{}, {}, {}]"#, lo.x, lo.y, lo.z, hi.x, hi.y, hi.z);
        }
        self.accessors.push(format!(
            r#"{{"bufferView": {view}, "componentType": 5126, "count": {}, "type": "{ty}"{bounds}}}"#,
            values.len() / comps
        ));
        self.accessors.len() - 1
    }

    fn indices(&mut self, indices: &[u16]) -> usize {
        let data: Vec<u8> = indices.iter().flat_map(|v| v.to_le_bytes()).collect();
        let view = self.view(&data);
        self.accessors.push(format!(
            r#"{{"bufferView": {view}, "componentType": 5123, "count": {}, "type": "SCALAR"}}"#,
            indices.len()
        ));
        self.accessors.len() - 1
    }

    /// The complete document: `rest` holds the scene-specific top-level members; the buffer is
    /// embedded as a data URI, or left to the GLB binary chunk when `embed` is false.
    fn document(&self, rest: &str, embed: bool) -> String {
        let uri = if embed {
            format!(r#", "uri": "data:application/octet-stream;base64,{}""#, base64(&self.bytes))
        } else {
            String::new()
        };
        format!(
            r#"{{"asset": {{"version": "2.0"}}, "buffers": [{{"byteLength": {}{uri}}}],
                "bufferViews": [{}], "accessors": [{}], {rest}}}"#,
            self.bytes.len(),
            self.views.join(", "),
            self.accessors.join(", ")
        )
    }
}

/// A binary glTF with `json` and `bin` chunks.
fn glb(json: &str, bin: &[u8]) -> Vec<u8> {
    let mut json = json.as_bytes().to_vec();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let mut bin = bin.to_vec();
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = b"glTF".to_vec();
    out.extend(2u32.to_le_bytes());
    out.extend((total as u32).to_le_bytes());
    out.extend((json.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(json);
    out.extend((bin.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(bin);
    out
}

/// One triangle (with a point light so that it validates into a `Scene`), as buffer + JSON.
fn triangle_gltf(positions: &[f32]) -> (Buffer, String) {
    let mut buf = Buffer::default();
    let pos = buf.floats("VEC3", positions);
    let rest = format!(
        r#""extensionsUsed": ["KHR_lights_punctual"],
           "extensions": {{"KHR_lights_punctual": {{"lights": [{{"type": "point", "intensity": 5}}]}}}},
           "meshes": [{{"primitives": [{{"attributes": {{"POSITION": {pos}}}}}]}}],
           "nodes": [{{"mesh": 0}}, {{"translation": [0, 0, 2], "extensions": {{"KHR_lights_punctual": {{"light": 0}}}}}}],
           "scenes": [{{"nodes": [0, 1]}}], "scene": 0"#
    );
    (buf, rest)
}

fn assert_close(a: Vec3, b: Vec3, what: &str) {
    assert!((a - b).abs().max_element() < 1e-5, "{what}: {a} != {b}");
}

/// The error's text names the file and contains every key word.
fn assert_names(e: &LoadError, file: &str, words: &[&str]) {
    let s = e.to_string();
    assert!(s.contains(file), "'{s}' does not name {file}");
    for w in words {
        assert!(s.contains(w), "'{s}' does not mention '{w}'");
    }
}

fn validate(desc: SceneDesc) -> Scene {
    Scene::from_desc(desc, &CameraSettings::default()).unwrap()
}

// ---------------------------------------------------------------------------------------------
// Bad inputs.

#[test]
fn missing_file_is_an_io_error_naming_the_file() {
    let dir = temp_dir("missing");
    for name in ["nowhere.gltf", "nowhere.obj"] {
        let e = load::load(&dir.join(name)).unwrap_err();
        assert_names(&e, name, &["not found"]);
        assert!(matches!(e.kind, LoadErrorKind::Io(_)));
    }
    let e = load::gltf::load_gltf(&dir.join("direct.glb")).unwrap_err();
    assert_names(&e, "direct.glb", &["not found"]);
}

#[test]
fn truncated_glb_is_malformed_and_names_the_file() {
    let dir = temp_dir("truncated");
    let (buf, rest) = triangle_gltf(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
    let bytes = glb(&buf.document(&rest, false), &buf.bytes);
    let whole = write(&dir, "whole.glb", &bytes);
    let desc = load::load(&whole).unwrap();
    assert_eq!(desc.meshes.len(), 1);
    assert_eq!(desc.meshes[0].positions[1], Vec3::X);

    let cut = write(&dir, "cut.glb", &bytes[..bytes.len() / 2]);
    let e = load::load(&cut).unwrap_err();
    assert_names(&e, "cut.glb", &["truncated"]);
    assert!(matches!(e.kind, LoadErrorKind::Malformed));
    let stub = write(&dir, "stub.glb", &bytes[..7]);
    assert_names(&load::load(&stub).unwrap_err(), "stub.glb", &["truncated"]);
}

#[test]
fn position_accessor_without_bounds_loads_with_a_warning() {
    let dir = temp_dir("no-bounds");
    let mut buf = Buffer { omit_bounds: true, ..Buffer::default() };
    let pos = buf.floats("VEC3", &[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
    let rest =
        format!(r#""meshes": [{{"primitives": [{{"attributes": {{"POSITION": {pos}}}}}]}}], "nodes": [{{"mesh": 0}}]"#);
    let path = write(&dir, "unbounded.gltf", buf.document(&rest, true));
    let desc = load::load(&path).unwrap();
    assert_eq!(desc.meshes.len(), 1);
    assert!(desc.warnings.iter().any(|w| w.contains("accessor 0") && w.contains("min/max")), "{:?}", desc.warnings);
}

#[test]
fn broken_json_is_malformed_with_its_line() {
    let dir = temp_dir("broken-json");
    let path = write(&dir, "broken.gltf", "{\"asset\": {\"version\": \"2.0\"},\n \"nodes\": [ }");
    let e = load::load(&path).unwrap_err();
    assert_names(&e, "broken.gltf", &["broken JSON", "line 2"]);
    assert!(matches!(e.kind, LoadErrorKind::Malformed));
}

#[test]
fn nan_position_in_gltf_is_invalid_naming_node_mesh_primitive_and_vertex() {
    let dir = temp_dir("nan-gltf");
    let (buf, rest) = triangle_gltf(&[0.0, 0.0, 0.0, 1.0, f32::NAN, 0.0, 0.0, 1.0, 0.0]);
    let path = write(&dir, "nan.gltf", buf.document(&rest, true));
    let e = load::load(&path).unwrap_err();
    assert_names(&e, "nan.gltf", &["node 0, mesh 0, primitive 0", "vertex 1 has a non-finite position"]);
    assert!(matches!(e.kind, LoadErrorKind::Invalid));
}

#[test]
fn nan_vertex_in_obj_names_the_line_of_its_v_statement() {
    let dir = temp_dir("nan-obj");
    let path = write(&dir, "nan.obj", "# a triangle\nv 0 0 0\nv nan 0 0\nv 0 1 0\n\nf 1 2 3\n");
    let e = load::load(&path).unwrap_err();
    assert_names(&e, "nan.obj", &["line 3", "non-finite", "line 6"]);
    assert!(matches!(e.kind, LoadErrorKind::Invalid));
    // An unused bad vertex is harmless.
    let unused = write(&dir, "unused.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv inf 0 0\nf 1 2 3\n");
    assert_eq!(load::load(&unused).unwrap().meshes.len(), 1);
}

#[test]
fn unknown_required_extension_is_unsupported_and_named() {
    let dir = temp_dir("required-ext");
    let (buf, rest) = triangle_gltf(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
    let rest = rest.replace(
        r#""extensionsUsed": ["KHR_lights_punctual"],"#,
        r#""extensionsUsed": ["KHR_lights_punctual", "KHR_draco_mesh_compression", "EXT_fancy"],
           "extensionsRequired": ["KHR_draco_mesh_compression"],"#,
    );
    let path = write(&dir, "draco.gltf", buf.document(&rest, true));
    let e = load::load(&path).unwrap_err();
    assert_names(&e, "draco.gltf", &["requires unsupported extension 'KHR_draco_mesh_compression'"]);
    assert!(matches!(e.kind, LoadErrorKind::Unsupported));

    // Merely used (not required) unknown extensions are warnings.
    let rest = rest.replace(r#""extensionsRequired": ["KHR_draco_mesh_compression"],"#, "");
    let path = write(&dir, "used.gltf", buf.document(&rest, true));
    let desc = load::load(&path).unwrap();
    assert!(desc.warnings.iter().any(|w| w.contains("'EXT_fancy'")), "{:?}", desc.warnings);
}

#[test]
fn unsupported_file_extension_is_an_unknown_format_error() {
    let dir = temp_dir("fbx");
    let path = write(&dir, "model.fbx", "Kaydara FBX Binary");
    let e = load::load(&path).unwrap_err();
    assert_names(&e, "model.fbx", &["'.fbx'"]);
    assert!(matches!(e.kind, LoadErrorKind::UnknownFormat));
}

#[test]
fn missing_buffer_file_and_short_buffer_are_named() {
    let dir = temp_dir("buffers");
    let (buf, rest) = triangle_gltf(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
    let doc =
        buf.document(&rest, false).replace(r#""byteLength": 36}"#, r#""byteLength": 36, "uri": "missing%20data.bin"}"#);
    let path = write(&dir, "external.gltf", &doc);
    let e = load::load(&path).unwrap_err();
    assert_names(&e, "external.gltf", &["buffer 0", "missing data.bin", "not found"]);
    assert!(matches!(e.kind, LoadErrorKind::Io(_)));

    // The accessor claims 4 vertices but the view holds 3.
    write(&dir, "missing data.bin", &buf.bytes);
    assert_eq!(load::load(&path).unwrap().meshes[0].positions.len(), 3);
    let short = doc.replace(r#""count": 3"#, r#""count": 4"#);
    let path = write(&dir, "short.gltf", &short);
    let e = load::load(&path).unwrap_err();
    assert_names(&e, "short.gltf", &["accessor 0", "buffer too short"]);
    assert!(matches!(e.kind, LoadErrorKind::Malformed));
}

#[test]
fn camera_json_with_a_bad_field_fails_the_obj_load_naming_the_key() {
    let dir = temp_dir("bad-camera");
    let obj = write(&dir, "tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    write(&dir, "camera.json", r#"{"eye": [0, 0, 3], "target": [0, 0, 0], "fov_y_deg": 200}"#);
    let e = load::load(&obj).unwrap_err();
    assert_names(&e, "camera.json", &["'fov_y_deg'", "179"]);
    assert!(matches!(e.kind, LoadErrorKind::Invalid));
    write(&dir, "camera.json", r#"{"eye": "here", "target": [0, 0, 0], "fov_y_deg": 40}"#);
    assert_names(&load::load(&obj).unwrap_err(), "camera.json", &["'eye'", "array of three numbers"]);
}

// ---------------------------------------------------------------------------------------------
// Well-formed scenes.

/// sRGB texels of the 2×2 test texture: red, green / blue, mid grey.
const TEXELS: [[u8; 3]; 4] = [[255, 0, 0], [0, 255, 0], [0, 0, 255], [128, 128, 128]];

#[test]
fn gltf_hierarchy_texture_and_camera_load_in_world_space() {
    let dir = temp_dir("hierarchy");
    let mut buf = Buffer::default();
    let pos = buf.floats("VEC3", &[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
    let nrm = buf.floats("VEC3", &[0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0]);
    let uv = buf.floats("VEC2", &[0.25, 0.25, 0.75, 0.25, 0.25, 0.75]);
    let idx = buf.indices(&[0, 1, 2]);
    let image = format!("data:image/png;base64,{}", base64(&png(2, 2, &TEXELS)));
    let (s, c) = (std::f32::consts::FRAC_PI_4.sin(), std::f32::consts::FRAC_PI_4.cos());
    // Parent: T (1, 2, 3) · R (90° about z) · S (2); child: x scaled by 3 after moving to z = −1.
    let rest = format!(
        r#""extensionsUsed": ["KHR_lights_punctual"],
           "extensions": {{"KHR_lights_punctual": {{"lights": [{{"type": "point", "intensity": 1}}]}}}},
           "images": [{{"uri": "{image}"}}], "textures": [{{"source": 0}}],
           "materials": [{{"name": "tex", "pbrMetallicRoughness": {{"baseColorFactor": [0.5, 1, 1, 1],
                            "baseColorTexture": {{"index": 0}}, "metallicFactor": 0, "roughnessFactor": 1}}}}],
           "meshes": [{{"primitives": [{{"attributes": {{"POSITION": {pos}, "NORMAL": {nrm}, "TEXCOORD_0": {uv}}},
                                        "indices": {idx}, "material": 0}}]}}],
           "cameras": [{{"type": "perspective", "perspective": {{"yfov": 0.7, "aspectRatio": 1.5, "znear": 0.1}}}}],
           "nodes": [
             {{"translation": [1, 2, 3], "rotation": [0, 0, {s}, {c}], "scale": [2, 2, 2], "children": [1, 2]}},
             {{"matrix": [3, 0, 0, 0,  0, 1, 0, 0,  0, 0, 1, 0,  0, 0, -1, 1], "mesh": 0}},
             {{"translation": [0, 0, 5], "camera": 0, "extensions": {{"KHR_lights_punctual": {{"light": 0}}}}}}
           ],
           "scenes": [{{"nodes": [0]}}]"#
    );
    let path = write(&dir, "hierarchy.gltf", buf.document(&rest, true));
    let desc = load::load(&path).unwrap();
    assert_eq!(desc.path, path);
    assert_eq!(desc.meshes.len(), 1);
    let mesh = &desc.meshes[0];
    assert_eq!(mesh.origin, Origin::Gltf { node: 1, mesh: 0, primitive: 0 });
    // p_world = T + R(S(M p)) with R: (x, y, z) → (−y, x, z).
    assert_close(mesh.positions[0], Vec3::new(1.0, 2.0, 1.0), "vertex 0");
    assert_close(mesh.positions[1], Vec3::new(1.0, 8.0, 1.0), "vertex 1");
    assert_close(mesh.positions[2], Vec3::new(-1.0, 2.0, 1.0), "vertex 2");
    assert_close(mesh.normals[0], Vec3::Z, "normal");
    assert_eq!(mesh.uvs[1], Vec2::new(0.75, 0.25));
    assert_eq!(mesh.indices, vec![0, 1, 2]);

    let cam = desc.camera.clone().unwrap();
    assert_close(cam.eye, Vec3::new(1.0, 2.0, 13.0), "eye");
    assert_close((cam.target - cam.eye).normalize(), -Vec3::Z, "forward");
    assert_close(cam.up, -Vec3::X, "up");
    assert!((cam.fov_y_deg - 0.7f32.to_degrees()).abs() < 1e-4);
    assert_eq!(cam.aspect, Some(1.5));
    let PunctualDesc::Point { position, .. } = desc.lights[0] else { panic!("{:?}", desc.lights) };
    assert_close(position, cam.eye, "light on the camera node");

    assert_eq!(desc.textures.len(), 1);
    let tex = &desc.textures[0];
    assert_eq!((tex.width, tex.height), (2, 2));
    let grey = srgb_to_linear(128.0 / 255.0);
    assert_close(tex.texels[0], Vec3::X, "top-left texel");
    assert_close(tex.texels[3], Vec3::splat(grey), "bottom-right texel");
    assert_eq!(desc.materials[mesh.material].base_color_texture, Some(0));

    let scene = validate(desc);
    let material = scene.material_of(0);
    let albedo = |uv: Vec2| match material.bsdf_kind(uv, &scene.textures) {
        BsdfKind::Lambert { albedo } => albedo,
        other => panic!("{other:?}"),
    };
    // Texel centres: factor (0.5, 1, 1) × texel.
    assert_close(albedo(Vec2::new(0.25, 0.25)), Vec3::new(0.5, 0.0, 0.0), "top-left");
    assert_close(albedo(Vec2::new(0.25, 0.75)), Vec3::new(0.0, 0.0, 1.0), "bottom-left");
    assert_close(albedo(Vec2::new(0.75, 0.75)), Vec3::new(0.5 * grey, grey, grey), "bottom-right");
    assert_close(scene.surface_point(0, 1.0, 0.0).uv.extend(0.0), Vec3::new(0.75, 0.25, 0.0), "uv at vertex 1");
}

#[test]
fn emissive_double_sided_material_and_punctual_lights_load() {
    let dir = temp_dir("emissive");
    let mut buf = Buffer::default();
    let pos = buf.floats("VEC3", &[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
    let rest = format!(
        r#""extensionsUsed": ["KHR_lights_punctual", "KHR_materials_emissive_strength"],
           "extensions": {{"KHR_lights_punctual": {{"lights": [
               {{"type": "point", "color": [1, 0.5, 0.5], "intensity": 10, "range": 100}},
               {{"type": "spot", "intensity": 2, "spot": {{"innerConeAngle": 0.2, "outerConeAngle": 0.5}}}},
               {{"type": "directional", "intensity": 3}}]}}}},
           "materials": [{{"name": "lamp", "doubleSided": true, "emissiveFactor": [1, 0.5, 0.25],
                           "extensions": {{"KHR_materials_emissive_strength": {{"emissiveStrength": 4}}}}}}],
           "meshes": [{{"primitives": [{{"attributes": {{"POSITION": {pos}}}, "material": 0}}]}}],
           "nodes": [{{"mesh": 0}},
                     {{"translation": [0, 3, 0], "extensions": {{"KHR_lights_punctual": {{"light": 0}}}}}},
                     {{"translation": [1, 2, 3], "rotation": [{}, 0, 0, {}],
                       "extensions": {{"KHR_lights_punctual": {{"light": 1}}}}}},
                     {{"extensions": {{"KHR_lights_punctual": {{"light": 2}}}}}}]"#,
        -FRAC_1_SQRT_2, FRAC_1_SQRT_2
    );
    // No "scenes": every root node is walked.
    let path = write(&dir, "lamp.gltf", buf.document(&rest, true));
    let desc = load::load(&path).unwrap();
    let lamp = &desc.materials[desc.meshes[0].material];
    assert_eq!(lamp.name, "lamp");
    assert_close(lamp.emission, Vec3::new(4.0, 2.0, 1.0), "emission = factor × strength");
    assert!(lamp.double_sided);
    // The glTF default (metallic 1, roughness 1) is diffuse.
    assert_eq!(lamp.scatter, ScatterDesc::Diffuse);

    assert_eq!(desc.lights.len(), 3, "{:?}", desc.lights);
    let PunctualDesc::Point { position, intensity } = desc.lights[0] else { panic!("{:?}", desc.lights[0]) };
    assert_close(position, Vec3::new(0.0, 3.0, 0.0), "point position");
    assert_close(intensity, Vec3::new(10.0, 5.0, 5.0), "point intensity = colour × intensity");
    let PunctualDesc::Spot { position, direction, intensity, inner_cone, outer_cone } = desc.lights[1] else {
        panic!("{:?}", desc.lights[1])
    };
    assert_close(position, Vec3::new(1.0, 2.0, 3.0), "spot position");
    assert_close(direction, -Vec3::Y, "spot direction: −z rotated −90° about x");
    assert_close(intensity, Vec3::splat(2.0), "spot intensity");
    assert_eq!((inner_cone, outer_cone), (0.2, 0.5));
    // Directional: illuminance = colour × intensity (lux as W/m²), travelling along the node's −Z.
    let PunctualDesc::Directional { direction, illuminance, angular_diameter } = desc.lights[2] else {
        panic!("{:?}", desc.lights[2])
    };
    assert_close(direction, -Vec3::Z, "directional light travels along −z");
    assert_close(illuminance, Vec3::splat(3.0), "directional illuminance");
    assert_eq!(angular_diameter, 0.0);
    assert!(desc.warnings.iter().any(|w| w.contains("range ignored")), "{:?}", desc.warnings);
    assert!(desc.camera.is_none());
    validate(desc);
}

/// A scene lit only by a glTF sun (as Blender exports a sun lamp) loads and renders; a sun
/// with zero or negative intensity is refused naming the file, node and light.
#[test]
fn a_gltf_sun_alone_lights_a_scene_and_a_dark_sun_is_refused() {
    let dir = temp_dir("sun");
    let mut buf = Buffer::default();
    let pos = buf.floats("VEC3", &[-1.0, 0.0, 1.0, 1.0, 0.0, 1.0, 1.0, 0.0, -1.0]);
    let doc = |intensity: &str| {
        format!(
            r#""extensionsUsed": ["KHR_lights_punctual"],
               "extensions": {{"KHR_lights_punctual": {{"lights": [{{"type": "directional", "intensity": {intensity}}}]}}}},
               "meshes": [{{"primitives": [{{"attributes": {{"POSITION": {pos}}}}}]}}],
               "nodes": [{{"mesh": 0}},
                         {{"rotation": [{}, 0, 0, {}], "extensions": {{"KHR_lights_punctual": {{"light": 0}}}}}}]"#,
            -FRAC_1_SQRT_2, FRAC_1_SQRT_2
        )
    };
    let path = write(&dir, "sunlit.gltf", buf.document(&doc("5"), true));
    let desc = load::load(&path).unwrap();
    let scene = Scene::from_desc(desc, &CameraSettings::default()).expect("a sun is a light");
    assert!(scene.lights.list.iter().any(|l| matches!(l, mirage::scene::Light::Sun(_))));
    for bad in ["0", "-2"] {
        let path = write(&dir, "dark.gltf", buf.document(&doc(bad), true));
        let e = load::load(&path).unwrap_err().to_string();
        assert!(e.contains("dark.gltf") && e.contains("node 1, light 0") && e.contains("directional"), "{e}");
    }
}

#[test]
fn mirrored_node_keeps_the_front_face_of_its_mirror_image() {
    let dir = temp_dir("mirror");
    let mut buf = Buffer::default();
    // Front normal (−1, 0, 1)/√2 by the counter-clockwise winding.
    let pos = buf.floats("VEC3", &[0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.0]);
    let rest = format!(
        r#""materials": [{{"emissiveFactor": [1, 1, 1]}}],
           "meshes": [{{"primitives": [{{"attributes": {{"POSITION": {pos}}}, "material": 0}}]}}],
           "nodes": [{{"mesh": 0}}, {{"mesh": 0, "translation": [5, 0, 0], "scale": [-1, 1, 1]}}],
           "scenes": [{{"nodes": [0, 1]}}]"#
    );
    let path = write(&dir, "mirror.gltf", buf.document(&rest, true));
    let desc = load::load(&path).unwrap();
    assert!(!desc.materials[0].double_sided);
    let scene = validate(desc);
    let ng_original = scene.surface_point(0, 1.0 / 3.0, 1.0 / 3.0).ng;
    let ng_mirrored = scene.surface_point(1, 1.0 / 3.0, 1.0 / 3.0).ng;
    assert_close(ng_original, Vec3::new(-1.0, 0.0, 1.0).normalize(), "original front");
    // The mirror image of the front normal, not its negation.
    assert_close(ng_mirrored, ng_original * Vec3::new(-1.0, 1.0, 1.0), "mirrored front");
}

#[test]
fn obj_mtl_materials_map_to_scatter_models_and_camera_json_is_used() {
    let dir = temp_dir("obj");
    write(
        &dir,
        "room.mtl",
        "newmtl light\nKd 0 0 0\nKe 10 8 6\n\n\
         newmtl gloss\nKd 0.6 0.5 0.4\nKs 0.6 0.6 0.6\nNs 50\n\n\
         newmtl mirror\nKd 0.1 0.1 0.1\nKs 0.9 0.8 0.7\nillum 5\n\n\
         newmtl glass\nKd 0.2 0.2 0.2\nNi 1.33\nillum 7\n\n\
         newmtl textured\nKd 1 1 1\nmap_Kd tex.png\n",
    );
    write(&dir, "tex.png", png(2, 2, &TEXELS));
    let obj = "mtllib room.mtl\n\
               v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n\
               vt 0 0\nvt 1 0\nvt 0 1\n\
               o plain\nf 1 2 3\n\
               o lamp\nusemtl light\nf 1 2 3\n\
               o shiny\nusemtl gloss\nf 1 2 3\nusemtl mirror\nf 2 4 3\n\
               o window\nusemtl glass\nf 1 2 3\n\
               o picture\nusemtl textured\nf 1/1 2/2 3/3\n";
    let path = write(&dir, "room.obj", obj);
    write(
        &dir,
        "camera.json",
        r#"{"eye": [0.5, 0.5, 3], "target": [0.5, 0.5, 0], "fov_y_deg": 35, "width": 64, "height": 48}"#,
    );
    let desc = load::load(&path).unwrap();

    let names: Vec<(String, usize)> = desc
        .meshes
        .iter()
        .map(|m| match &m.origin {
            Origin::Obj { name, line } => (name.clone(), *line),
            other => panic!("{other:?}"),
        })
        .collect();
    let expected = [("plain", 10), ("lamp", 13), ("shiny", 16), ("shiny", 18), ("window", 21), ("picture", 24)];
    assert_eq!(names, expected.map(|(n, l)| (n.to_string(), l)).to_vec());

    let material = |mesh: usize| &desc.materials[desc.meshes[mesh].material];
    assert_eq!(material(0).scatter, ScatterDesc::Diffuse);
    assert_close(material(0).base_color, Vec3::splat(0.7), "grey default");

    assert_close(material(1).emission, Vec3::new(10.0, 8.0, 6.0), "Ke");
    assert!(!material(1).double_sided);

    let ScatterDesc::Glossy { specular, exponent } = material(2).scatter else { panic!("{:?}", material(2)) };
    assert_eq!(exponent, 50.0);
    // Kd + Ks = (1.2, 1.1, 1.0): red and green scaled down to sum to 1.
    assert_close(material(2).base_color, Vec3::new(0.5, 0.5 / 1.1, 0.4), "glossy kd");
    assert_close(specular, Vec3::new(0.5, 0.6 / 1.1, 0.6), "glossy ks");
    assert!(desc.warnings.iter().any(|w| w.contains("'gloss'") && w.contains("scaled")), "{:?}", desc.warnings);

    assert_eq!(material(3).scatter, ScatterDesc::Mirror);
    assert_close(material(3).base_color, Vec3::new(0.9, 0.8, 0.7), "mirror reflectance = Ks");
    assert_eq!(material(4).scatter, ScatterDesc::Dielectric { ior: 1.33 });

    let picture = &desc.meshes[5];
    assert_eq!(picture.uvs[0], Vec2::new(0.0, 1.0), "OBJ v = 0 is the bottom row");
    let tex = material(5).base_color_texture.unwrap();
    assert_close(desc.textures[tex].texels[2], Vec3::Z, "bottom-left texel");

    let cam = desc.camera.clone().unwrap();
    assert_eq!(cam.eye, Vec3::new(0.5, 0.5, 3.0));
    assert_eq!((cam.width, cam.height, cam.fov_y_deg), (Some(64), Some(48), 35.0));

    let scene = validate(desc);
    assert_eq!((scene.camera.width, scene.camera.height), (64, 48));
    // OBJ uv (0.25, 0.25), near the bottom-left corner, is the centre of the blue texel.
    let last = scene.mesh.len() as u32 - 1;
    let sp = scene.surface_point(last, 0.25, 0.25);
    assert_eq!(sp.uv, Vec2::new(0.25, 0.75));
    match scene.material_of(last).bsdf_kind(sp.uv, &scene.textures) {
        BsdfKind::Lambert { albedo } => assert_close(albedo, Vec3::Z, "blue texel"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn obj_without_mtl_or_with_missing_mtl_uses_grey_and_warns() {
    let dir = temp_dir("obj-plain");
    let plain = write(&dir, "plain.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    let desc = load::load(&plain).unwrap();
    assert_eq!(desc.materials.len(), 1);
    assert_close(desc.materials[0].base_color, Vec3::splat(0.7), "grey");
    assert_eq!(desc.warnings.len(), 1, "{:?}", desc.warnings);
    assert!(desc.camera.is_none());

    let missing = write(&dir, "missing.obj", "mtllib gone.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\n");
    let desc = load::load(&missing).unwrap();
    assert_eq!(desc.meshes.len(), 1);
    assert_eq!(desc.materials[desc.meshes[0].material].scatter, ScatterDesc::Diffuse);
    assert!(desc.warnings.iter().any(|w| w.contains("gone.mtl") && w.contains("not found")), "{:?}", desc.warnings);
}

/// The scene files in `scenes/` (exports of the built-in scenes) load back into the built-in
/// descriptions: same triangles, materials and camera.
#[test]
fn committed_scene_files_load_back_into_the_builtin_scenes() {
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut files: Vec<(PathBuf, SceneDesc)> = load::builtin::NAMES
        .iter()
        .map(|name| (scenes.join(format!("{name}.gltf")), load::builtin::by_name(name).unwrap()))
        .collect();
    files.push((scenes.join("cornell-obj/cornell.obj"), load::builtin::cornell()));
    for (path, builtin) in files {
        if !path.exists() {
            continue; // not generated in this checkout
        }
        let desc = load::load(&path).unwrap_or_else(|e| panic!("{e}"));
        let file = path.display();
        assert!(desc.warnings.is_empty(), "{file}: {:?}", desc.warnings);
        assert_eq!(desc.meshes.len(), builtin.meshes.len(), "{file}");
        for (m, b) in desc.meshes.iter().zip(&builtin.meshes) {
            assert_eq!(m.indices.len(), b.indices.len(), "{file}: {}", m.origin);
            for (i, j) in m.indices.iter().zip(&b.indices) {
                assert_close(m.positions[*i as usize], b.positions[*j as usize], &format!("{file}: {}", m.origin));
            }
            let (mm, bm) = (&desc.materials[m.material], &builtin.materials[b.material]);
            assert_eq!(mm.scatter, bm.scatter, "{file}: {}", bm.name);
            assert_close(mm.base_color, bm.base_color, &format!("{file}: {} base colour", bm.name));
            let scale = bm.emission.max_element().max(1.0);
            assert_close(mm.emission / scale, bm.emission / scale, &format!("{file}: {} emission", bm.name));
            let obj_emitter = path.extension().is_some_and(|e| e == "obj") && bm.emission != Vec3::ZERO;
            if !obj_emitter {
                assert_eq!(mm.double_sided, bm.double_sided, "{file}: {}", bm.name);
            }
        }
        // Lights that are not surfaces (the sunlit room's sun and sky) come back too.
        assert_eq!(desc.lights.len(), builtin.lights.len(), "{file}: lights");
        for (l, b) in desc.lights.iter().zip(&builtin.lights) {
            match (l, b) {
                (
                    PunctualDesc::Directional { direction, illuminance, angular_diameter },
                    PunctualDesc::Directional { direction: bd, illuminance: bi, angular_diameter: ba },
                ) => {
                    assert_close(*direction, *bd, &format!("{file}: sun direction"));
                    assert_close(*illuminance, *bi, &format!("{file}: sun illuminance"));
                    assert!((angular_diameter - ba).abs() < 1e-6, "{file}: sun diameter");
                }
                (PunctualDesc::Environment(a), PunctualDesc::Environment(b)) => assert_eq!(a, b, "{file}: sky"),
                _ => panic!("{file}: light {l:?} read back for {b:?}"),
            }
        }
        let (c, b) = (desc.camera.unwrap(), builtin.camera.unwrap());
        assert_close(c.eye, b.eye, &format!("{file}: eye"));
        assert_close((c.target - c.eye).normalize(), (b.target - b.eye).normalize(), &format!("{file}: forward"));
        assert!((c.fov_y_deg - b.fov_y_deg).abs() < 1e-3, "{file}: fov {} vs {}", c.fov_y_deg, b.fov_y_deg);
        assert_eq!((c.width, c.height), (b.width, b.height), "{file}: resolution");
    }
}

/// The real models beside the repository (`../shared/models`, absent in a plain clone) load
/// with the triangle counts their README gives.
#[test]
fn shared_real_models_load_with_their_triangle_counts_when_present() {
    let models = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/models");
    for (file, triangles) in [("sponza.obj", 66_454), ("igea.obj", 268_686)] {
        let path = models.join(file);
        if !path.exists() {
            continue;
        }
        let desc = load::load(&path).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(desc.meshes.iter().map(|m| m.indices.len() / 3).sum::<usize>(), triangles, "{file}");
        assert_eq!(desc.warnings.len(), 1, "{file}: only the no-mtllib note: {:?}", desc.warnings);
    }
}

// ---------------------------------------------------------------------------------------------
// Robustness: seeded corruptions of valid files must give `Ok` or `Err`, never a panic.

/// xorshift64*: a tiny deterministic generator for the corruptions.
struct Rng(u64);

impl Rng {
    fn below(&mut self, n: usize) -> usize {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 33) as usize % n.max(1)
    }
}

/// Corruptions per file kind; `MIRAGE_IO_FUZZ=20000` searches deeper.
fn fuzz_iterations() -> usize {
    std::env::var("MIRAGE_IO_FUZZ").ok().and_then(|v| v.parse().ok()).unwrap_or(200)
}

#[test]
fn corrupted_gltf_glb_and_obj_files_give_errors_never_panics() {
    let dir = temp_dir("corrupt");
    let iterations = fuzz_iterations();
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);

    // glTF JSON: replace numbers by extreme or negative ones.
    let mut buf = Buffer::default();
    let pos = buf.floats("VEC3", &[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
    let uv = buf.floats("VEC2", &[0.0, 0.0, 1.0, 0.0, 0.0, 1.0]);
    let idx = buf.indices(&[0, 1, 2]);
    let image = format!("data:image/png;base64,{}", base64(&png(2, 2, &TEXELS)));
    let rest = format!(
        r#""images": [{{"uri": "{image}"}}], "textures": [{{"source": 0}}],
           "materials": [{{"pbrMetallicRoughness": {{"baseColorTexture": {{"index": 0}}}}}}],
           "meshes": [{{"primitives": [{{"attributes": {{"POSITION": {pos}, "TEXCOORD_0": {uv}}},
                                        "indices": {idx}, "material": 0}}]}}],
           "cameras": [{{"type": "perspective", "perspective": {{"yfov": 0.7, "znear": 0.1}}}}],
           "nodes": [{{"mesh": 0, "children": [1]}}, {{"camera": 0}}], "scenes": [{{"nodes": [0]}}]"#
    );
    let text = buf.document(&rest, true).replace(r#""uri": "data:application"#, r#""uri":"data:application"#);
    let digits: Vec<usize> = text.char_indices().filter(|(_, c)| c.is_ascii_digit()).map(|(i, _)| i).collect();
    let replacements = ["0", "1", "2", "3", "7", "255", "65535", "4294967295", "99999999999", "-1", "1e38", "0.5"];
    let path = dir.join("c.gltf");
    for _ in 0..iterations {
        let at = digits[rng.below(digits.len())];
        let mut t = text.clone();
        t.replace_range(at..at + 1, replacements[rng.below(replacements.len())]);
        std::fs::write(&path, &t).unwrap();
        let _ = load::load(&path);
    }
    // A structural edit the JSON schema allows: a perspective-typed camera without parameters.
    std::fs::write(
        &path,
        text.replace(
            r#""perspective": {"yfov""#,
            r#""orthographic": {"xmag": 1, "ymag": 1, "zfar": 9, "znear": 0.1}, "x": {"yfov""#,
        ),
    )
    .unwrap();
    let _ = load::load(&path);

    // GLB: flip and truncate bytes.
    let bytes = glb(&buf.document(&rest, false), &buf.bytes);
    let path = dir.join("c.glb");
    for _ in 0..iterations {
        let mut b = bytes.clone();
        for _ in 0..1 + rng.below(3) {
            let i = rng.below(b.len());
            b[i] = rng.below(256) as u8;
        }
        if rng.below(4) == 0 {
            b.truncate(rng.below(b.len()));
        }
        std::fs::write(&path, &b).unwrap();
        let _ = load::load(&path);
    }

    // OBJ + MTL: replace lines by plausible but broken statements.
    let obj_lines = [
        "f 1 2 3",
        "f 0 1 2",
        "f -9 1 2",
        "f 1/99 2 3",
        "f 1//99 2 3",
        "f 1/1/1/1 2 3",
        "f 1 2",
        "f 99999999999999999999 1 2",
        "f -9223372036854775808 1 2",
        "v nan 1 2",
        "v 1 2 3 0",
        "v 1 2 3 4 5 6",
        "v 1 2 3 4 5",
        "v 1e38 1 1 1e-38",
        "vt 1",
        "vt",
        "vn 1 2",
        "usemtl",
        "usemtl m",
        "usemtl nothing",
        "o",
        "g x",
        "l 1 2",
        "p 1",
        "mtllib c.mtl",
        "mtllib none.mtl",
        "s off",
        "curv 0 1 1 2",
        "f 1/1 2/1 3/1",
    ];
    let mtl_lines = [
        "newmtl m",
        "newmtl",
        "Kd 1",
        "Kd 1 2",
        "Kd a b c",
        "Ks 0.5 0.5 0.5",
        "Ns x",
        "Ns 20",
        "illum 300",
        "illum 5",
        "illum 7",
        "Ni",
        "map_Kd",
        "map_Kd tex.png",
        "map_Kd -s 1 1 1 missing.png",
        "Ke 1 1 1",
        "Kd xyz 1 1 1",
        "d 0.5",
    ];
    write(&dir, "tex.png", png(2, 2, &TEXELS));
    let obj_path = dir.join("c.obj");
    for _ in 0..iterations {
        let obj: Vec<&str> = (0..8).map(|_| obj_lines[rng.below(obj_lines.len())]).collect();
        let obj = format!("mtllib c.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n{}\nf 1 2 3\n", obj.join("\n"));
        let mtl: Vec<&str> = (0..6).map(|_| mtl_lines[rng.below(mtl_lines.len())]).collect();
        std::fs::write(&obj_path, obj).unwrap();
        std::fs::write(dir.join("c.mtl"), format!("newmtl m\n{}\n", mtl.join("\n"))).unwrap();
        let _ = load::load(&obj_path);
    }
}
