//! OBJ + MTL loader → [`SceneDesc`], with the camera from a `camera.json` beside the `.obj`.
//!
//! `tobj` does the assembly (triangulation, one index per vertex, grouping faces into models by
//! `o`/`g`/`usemtl`); each non-empty model becomes one [`MeshDesc`]. Before `tobj` runs, one
//! light pass over the text checks what `tobj` would reject without a line number (or, for
//! overflowing face indices, panic on): `v`/`vt`/`vn` need numbers, face references must be
//! non-zero and in range, and a vertex with a non-finite coordinate used by a face is an error
//! naming its `v` line. The same pass records where each model's first face is, so that a mesh's
//! [`Origin::Obj`] carries a line. MTL files are read here too (relative to the `.obj`) and
//! checked line by line before `tobj` parses them: `tobj` panics on a colour with fewer than
//! three numbers, which MTL allows (`Kd 0.5` means grey), so such lines are expanded.
//!
//! OBJ texture v = 0 is the bottom row, mirage's (glTF's) is the top: uv = (u, 1 − v).
//!
//! # Materials
//!
//! | MTL                                 | mirage                                                    |
//! |-------------------------------------|-----------------------------------------------------------|
//! | `illum 5`                           | `Mirror`, reflectance `Ks` (or `Kd` when `Ks` is zero)     |
//! | `illum 7`                           | `Dielectric { ior: Ni }` (default 1.5), tint `Tf` (default white) |
//! | `Ks` non-zero                       | `Glossy { specular: Ks, exponent: Ns }` (`Ns` default 1), `Kd` and `Ks` scaled down together where `Kd + Ks > 1` |
//! | otherwise                           | `Diffuse`, albedo `Kd` (default 0.7)                      |
//!
//! `Ke` is the emitted radiance, `map_Kd` / `map_Ke` multiply `Kd` / `Ke` (sRGB-decoded, paths
//! relative to the `.mtl`). OBJ emitters are single-sided. A missing `.mtl`, an unknown
//! `usemtl` name and faces without a material give the grey (0.7) default and a warning;
//! a missing texture is a warning too.

use std::borrow::Cow;
use std::cell::RefCell;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3};

use super::camera_json;
use super::desc::{MaterialDesc, MeshDesc, Origin, ScatterDesc, SceneDesc};
use super::error::{LoadError, LoadErrorKind};
use super::gltf::decode_srgb_texture;

/// Albedo of the default material (no `mtllib`, missing `.mtl`, unknown or no `usemtl`, no `Kd`).
const DEFAULT_ALBEDO: f32 = 0.7;

/// Reads an `.obj` file with its `.mtl` libraries and an optional `camera.json` beside it.
pub fn load_obj(path: &Path) -> Result<SceneDesc, LoadError> {
    let bytes = std::fs::read(path).map_err(|e| LoadError::io(path, e))?;
    let text = std::str::from_utf8(&bytes).map_err(|e| {
        let line = 1 + bytes[..e.valid_up_to()].iter().filter(|&&b| b == b'\n').count();
        at_line(path, LoadErrorKind::Malformed, line, "not valid UTF-8 text")
    })?;
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let scan = scan(path, text)?;
    let text = if scan.needs_rewrite { Cow::Owned(rewrite_for_tobj(text)) } else { Cow::Borrowed(text) };

    let libs = RefCell::new(MtlLibs::default());
    let options = tobj::LoadOptions { triangulate: true, single_index: true, ignore_points: true, ignore_lines: true };
    let result = tobj::load_obj_buf(&mut text.as_bytes(), &options, |lib| libs.borrow_mut().load(path, &dir, lib));
    let libs = libs.into_inner();
    if let Some(e) = libs.error {
        return Err(e);
    }
    let (models, materials) = result
        .map_err(|e| LoadError::new(path, LoadErrorKind::Malformed, format!("cannot parse the OBJ file: {e}")))?;
    let materials = materials.unwrap_or_default();

    let mut desc = SceneDesc { path: path.to_path_buf(), warnings: scan.warnings.clone(), ..SceneDesc::default() };
    desc.warnings.extend(libs.warnings.iter().cloned());
    if !scan.has_mtllib {
        desc.warnings.push(format!("{}: no mtllib: every face uses the grey default material", path.display()));
    }
    let mut textures = Textures::default();
    for (i, m) in materials.iter().enumerate() {
        let mtl_path = libs.file_of(i).unwrap_or(path);
        let converted = convert_material(m, mtl_path, &mut textures, &mut desc);
        desc.materials.push(converted);
    }
    let by_name: HashMap<&str, usize> = materials.iter().enumerate().map(|(i, m)| (m.name.as_str(), i)).collect();
    let mut reported = std::collections::HashSet::new();
    for (name, line) in &scan.usemtl {
        if !by_name.contains_key(name.as_str()) && scan.has_mtllib && reported.insert(name) {
            desc.warnings.push(format!(
                "{}: line {line}: usemtl '{name}' names no loaded material; the grey default is used",
                path.display()
            ));
        }
    }

    let first_lines = scan.model_lines(&by_name);
    let mut default_material = None;
    for (k, model) in models.iter().enumerate() {
        let mesh = &model.mesh;
        if mesh.indices.is_empty() {
            continue;
        }
        let origin = Origin::Obj { name: model.name.clone(), line: first_lines.get(k).copied().unwrap_or(0) };
        let positions: Vec<Vec3> = mesh.positions.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect();
        if positions.iter().any(|p| !p.is_finite()) {
            // Only a forward reference to a bad vertex gets here; the scan catches the rest.
            let line = scan.first_bad_vertex_line.unwrap_or(0);
            return Err(at_line(path, LoadErrorKind::Invalid, line, "vertex has a non-finite coordinate"));
        }
        let n = positions.len();
        let mut normals = Vec::new();
        if !mesh.normals.is_empty() {
            if mesh.normals.len() == 3 * n {
                normals = mesh.normals.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect();
            } else {
                desc.warnings
                    .push(format!("{}: {origin}: only some vertices have normals; normals ignored", path.display()));
            }
        }
        let mut uvs = Vec::new();
        if !mesh.texcoords.is_empty() {
            if mesh.texcoords.len() == 2 * n {
                uvs = mesh.texcoords.chunks_exact(2).map(|c| Vec2::new(c[0], 1.0 - c[1])).collect();
            } else {
                desc.warnings.push(format!(
                    "{}: {origin}: only some vertices have texture coordinates; they are ignored",
                    path.display()
                ));
            }
        }
        let material = match mesh.material_id.filter(|&m| m < desc.materials.len()) {
            Some(m) => m,
            None => *default_material.get_or_insert_with(|| {
                desc.materials.push(MaterialDesc::diffuse("default (no material)", Vec3::splat(DEFAULT_ALBEDO)));
                desc.materials.len() - 1
            }),
        };
        desc.meshes.push(MeshDesc { origin, positions, normals, uvs, indices: mesh.indices.clone(), material });
    }

    let camera_path = dir.join(camera_json::FILE_NAME);
    if camera_path.is_file() {
        let file = camera_json::read_camera_json(&camera_path)?;
        desc.camera = Some(file.camera);
        desc.warnings.extend(file.warnings);
    }
    Ok(desc)
}

fn at_line(path: &Path, kind: LoadErrorKind, line: usize, message: impl Into<String>) -> LoadError {
    LoadError::new(path, kind, message).at(format!("line {line}"))
}

/// What the pre-scan learned about the file.
#[derive(Default)]
struct Scan {
    /// `o`/`g`, `usemtl` and face events in order, the input to [`Scan::model_lines`].
    events: Vec<Event>,
    /// Every `usemtl` name with its line (for unknown-name warnings, one per name).
    usemtl: Vec<(String, usize)>,
    has_mtllib: bool,
    /// Vertex colours or one-number `vt` lines, which tobj mishandles, are present.
    needs_rewrite: bool,
    /// Some `v` lines carry colours (ignored).
    vertex_colors: bool,
    /// Line of the first `v` with a non-finite coordinate.
    first_bad_vertex_line: Option<usize>,
    warnings: Vec<String>,
}

/// A statement that can start a new tobj model, or a run of faces.
enum Event {
    Group,
    UseMtl(String),
    /// The first face line after the previous non-face event.
    Faces(usize),
}

impl Scan {
    /// The line of the first face of each tobj model, replaying tobj's splitting rule: a model
    /// ends at `o`/`g`, or at a `usemtl` that changes the material, when it already has faces;
    /// and the last model is always emitted.
    fn model_lines(&self, materials: &HashMap<&str, usize>) -> Vec<usize> {
        let mut lines = Vec::new();
        let mut pending: Option<usize> = None;
        let mut current: Option<usize> = None;
        for event in &self.events {
            match event {
                Event::Group => lines.extend(pending.take()),
                Event::UseMtl(name) => {
                    let next = materials.get(name.as_str()).copied();
                    if next != current {
                        lines.extend(pending.take());
                    }
                    current = next;
                }
                Event::Faces(line) => {
                    pending.get_or_insert(*line);
                }
            }
        }
        lines.push(pending.unwrap_or(0));
        lines
    }
}

/// Statements of free-form geometry, which mirage does not read.
const FREE_FORM: [&str; 6] = ["vp", "cstype", "curv", "curv2", "surf", "deg"];

/// One pass over the OBJ text: validates vertex and face statements (see the module doc).
fn scan(path: &Path, text: &str) -> Result<Scan, LoadError> {
    let err = |line: usize, message: String| at_line(path, LoadErrorKind::Malformed, line, message);
    let mut s = Scan::default();
    // Counts of v, vt, vn so far; the largest positive reference of each kind with its line.
    let mut counts = [0usize; 3];
    let mut max_ref = [(0usize, 0usize); 3];
    let mut bad_vertices: HashMap<usize, usize> = HashMap::new();
    let mut ignored_elements = (0usize, 0usize);
    let mut free_form = 0usize;
    for (i, line) in text.lines().enumerate() {
        let ln = i + 1;
        let mut words = line.split_whitespace();
        let Some(keyword) = words.next() else { continue };
        match keyword {
            "v" => {
                let xyz = numbers::<3>(&mut words).ok_or_else(|| err(ln, "'v' needs three numbers x y z".into()))?;
                let mut p = Vec3::from_array(xyz);
                match (words.next(), words.next(), words.next(), words.next()) {
                    (None, ..) => {}
                    (Some(w), None, ..) => {
                        let w: f32 = w.parse().map_err(|_| err(ln, format!("'v' weight '{w}' is not a number")))?;
                        if w == 0.0 {
                            return Err(err(ln, "'v' weight w is zero".into()));
                        }
                        p /= w;
                    }
                    (Some(_), Some(_), Some(_), None) => {
                        s.needs_rewrite = true;
                        s.vertex_colors = true;
                    }
                    _ => return Err(err(ln, "'v' takes x y z, x y z w, or x y z r g b".into())),
                }
                if !p.is_finite() {
                    bad_vertices.insert(counts[0], ln);
                    s.first_bad_vertex_line.get_or_insert(ln);
                }
                counts[0] += 1;
            }
            "vt" => {
                let mut first = words.clone();
                if numbers::<2>(&mut words).is_none() {
                    numbers::<1>(&mut first).ok_or_else(|| err(ln, "'vt' needs numbers u [v]".into()))?;
                    s.needs_rewrite = true;
                }
                counts[1] += 1;
            }
            "vn" => {
                numbers::<3>(&mut words).ok_or_else(|| err(ln, "'vn' needs three numbers x y z".into()))?;
                counts[2] += 1;
            }
            "f" | "l" => {
                let mut corners = 0;
                for token in words {
                    corners += 1;
                    for (slot, part) in token.split('/').enumerate() {
                        if slot > 2 {
                            return Err(err(ln, format!("'{token}' has more than three indices")));
                        }
                        if part.is_empty() {
                            if slot == 0 {
                                return Err(err(ln, format!("'{token}' has no vertex index")));
                            }
                            continue;
                        }
                        let x: i64 =
                            part.parse().map_err(|_| err(ln, format!("'{token}' is not a vertex reference")))?;
                        let index = match x {
                            0 => return Err(err(ln, format!("'{token}' uses index 0 (OBJ indices start at 1)"))),
                            x if x > 0 => {
                                let x = x as usize;
                                if x > max_ref[slot].0 {
                                    max_ref[slot] = (x, ln);
                                }
                                x - 1
                            }
                            x => match usize::try_from(counts[slot] as i64 + x) {
                                Ok(index) => index,
                                Err(_) => {
                                    return Err(err(
                                        ln,
                                        format!("relative index in '{token}' points before the first element"),
                                    ));
                                }
                            },
                        };
                        if let (0, Some(&v_line)) = (slot, bad_vertices.get(&index)) {
                            let message = format!("vertex has a non-finite coordinate (used by the face on line {ln})");
                            return Err(at_line(path, LoadErrorKind::Invalid, v_line, message));
                        }
                    }
                }
                if keyword == "l" || corners < 3 {
                    ignored_elements.0 += 1;
                    ignored_elements.1 = if ignored_elements.1 == 0 { ln } else { ignored_elements.1 };
                }
                if !matches!(s.events.last(), Some(Event::Faces(_))) {
                    s.events.push(Event::Faces(ln));
                }
            }
            "p" => {
                ignored_elements.0 += 1;
                ignored_elements.1 = if ignored_elements.1 == 0 { ln } else { ignored_elements.1 };
            }
            "o" | "g" => s.events.push(Event::Group),
            "usemtl" => {
                // tobj takes everything after the first space as the name.
                let name = line.split_once(' ').unwrap_or_default().1.trim();
                if name.is_empty() {
                    return Err(err(ln, "'usemtl' needs a material name after a space".into()));
                }
                s.events.push(Event::UseMtl(name.to_string()));
                s.usemtl.push((name.to_string(), ln));
            }
            "mtllib" => s.has_mtllib = true,
            k if FREE_FORM.contains(&k) => free_form += 1,
            _ => {}
        }
    }
    let kinds = ["vertex", "texture coordinate", "normal"];
    for slot in 0..3 {
        let (x, ln) = max_ref[slot];
        // tobj ignores vt/vn references when the file has none of that kind.
        if x > counts[slot] && (slot == 0 || counts[slot] > 0) {
            return Err(err(ln, format!("{} index {x} is out of range (the file has {})", kinds[slot], counts[slot])));
        }
    }
    if ignored_elements.0 > 0 {
        s.warnings.push(format!(
            "{}: line {}: {} point/line element(s) ignored (only faces are rendered)",
            path.display(),
            ignored_elements.1,
            ignored_elements.0
        ));
    }
    if free_form > 0 {
        s.warnings.push(format!("{}: {free_form} free-form geometry statement(s) ignored", path.display()));
    }
    if s.vertex_colors {
        s.warnings.push(format!("{}: vertex colours ignored", path.display()));
    }
    Ok(s)
}

/// `N` numbers from the iterator, or `None` when there are fewer or one does not parse.
fn numbers<const N: usize>(words: &mut std::str::SplitWhitespace) -> Option<[f32; N]> {
    let mut out = [0.0; N];
    for x in &mut out {
        *x = words.next()?.parse().ok()?;
    }
    Some(out)
}

/// The OBJ text with vertex colours dropped and one-number `vt` lines completed, two things
/// tobj rejects or mishandles (mixed coloured and plain vertices fail its colour lookup).
fn rewrite_for_tobj(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for line in text.lines() {
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["v", x, y, z, _, _, _] => out.push_str(&format!("v {x} {y} {z}")),
            ["vt", u] => out.push_str(&format!("vt {u} 0")),
            _ => out.push_str(line),
        }
        out.push('\n');
    }
    out
}

/// The `.mtl` libraries tobj asked for, in load order, with problems found while reading them.
#[derive(Default)]
struct MtlLibs {
    /// Each successfully parsed file with its material count (tobj appends them in this order).
    files: Vec<(PathBuf, usize)>,
    warnings: Vec<String>,
    /// The first malformed `.mtl`: aborts the load.
    error: Option<LoadError>,
}

impl MtlLibs {
    fn load(&mut self, obj: &Path, dir: &Path, lib: &Path) -> tobj::MTLLoadResult {
        let file = dir.join(lib);
        let bytes = match std::fs::read(&file) {
            Ok(b) => b,
            Err(e) => {
                let reason =
                    if e.kind() == std::io::ErrorKind::NotFound { "not found".to_string() } else { e.to_string() };
                self.warnings.push(format!(
                    "{}: mtllib '{}' {reason}; its materials are replaced by the grey default",
                    obj.display(),
                    file.display()
                ));
                return Err(tobj::LoadError::OpenFileFailed);
            }
        };
        let text = String::from_utf8_lossy(&bytes);
        let checked = match check_mtl(&file, &text) {
            Ok(t) => t,
            Err(e) => {
                self.error.get_or_insert(e);
                return Err(tobj::LoadError::MaterialParseError);
            }
        };
        match tobj::load_mtl_buf(&mut checked.as_bytes()) {
            Ok((materials, names)) => {
                self.files.push((file, materials.len()));
                Ok((materials, names))
            }
            Err(e) => {
                let message = format!("cannot parse the material library: {e}");
                self.error.get_or_insert(LoadError::new(&file, LoadErrorKind::Malformed, message));
                Err(e)
            }
        }
    }

    /// The `.mtl` file that defined tobj material `index`.
    fn file_of(&self, index: usize) -> Option<&Path> {
        let mut start = 0;
        for (file, count) in &self.files {
            if index < start + count {
                return Some(file);
            }
            start += count;
        }
        None
    }
}

/// Checks an `.mtl` file line by line for what tobj would reject (or panic on), returning the
/// text with one-number colours (`Kd 0.5`) expanded to three.
fn check_mtl<'t>(path: &Path, text: &'t str) -> Result<Cow<'t, str>, LoadError> {
    let err = |line: usize, message: String| at_line(path, LoadErrorKind::Malformed, line, message);
    let mut expanded: Vec<(usize, String)> = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let ln = i + 1;
        let mut words = line.split_whitespace();
        let Some(keyword) = words.next() else { continue };
        let rest: Vec<&str> = words.collect();
        match keyword {
            "Ka" | "Kd" | "Ks" | "Ke" => {
                if matches!(rest.first(), Some(&"spectral") | Some(&"xyz")) {
                    return Err(at_line(
                        path,
                        LoadErrorKind::Unsupported,
                        ln,
                        format!("'{keyword} {}' colours are not supported (use r g b)", rest[0]),
                    ));
                }
                let parsed: Option<Vec<f32>> = rest.iter().take(3).map(|w| w.parse().ok()).collect();
                match (parsed.as_deref(), rest.len()) {
                    (Some([r]), 1) => expanded.push((i, format!("{keyword} {r} {r} {r}"))),
                    (Some([_, _, _]), _) => {}
                    _ => return Err(err(ln, format!("'{keyword}' needs three numbers r g b (or one for grey)"))),
                }
            }
            "Ns" | "Ni" | "d" if rest.first().and_then(|w| w.parse::<f32>().ok()).is_none() => {
                return Err(err(ln, format!("'{keyword}' needs a number")));
            }
            "illum" if rest.first().and_then(|w| w.parse::<u8>().ok()).is_none() => {
                return Err(err(ln, "'illum' needs an illumination model number 0–255".into()));
            }
            "newmtl" | "map_Ka" | "map_Kd" | "map_Ks" | "map_Bump" | "map_bump" | "map_Ns" | "map_ns" | "map_NS"
            | "bump" | "map_d"
                if rest.is_empty() =>
            {
                return Err(err(ln, format!("'{keyword}' needs a name")));
            }
            _ => {}
        }
    }
    if expanded.is_empty() {
        return Ok(Cow::Borrowed(text));
    }
    let mut out = String::with_capacity(text.len() + 16 * expanded.len());
    let mut next = expanded.iter().peekable();
    for (i, line) in text.lines().enumerate() {
        match next.peek() {
            Some((j, replacement)) if *j == i => {
                out.push_str(replacement);
                next.next();
            }
            _ => out.push_str(line),
        }
        out.push('\n');
    }
    Ok(Cow::Owned(out))
}

/// Decoded textures by file, so that materials sharing an image share the texture.
#[derive(Default)]
struct Textures {
    by_file: HashMap<PathBuf, Option<usize>>,
}

impl Textures {
    /// The texture a `map_*` statement names (relative to the `.mtl`), decoded once; a missing or
    /// undecodable image is a warning and `None`.
    fn get(&mut self, spec: &str, mtl: &Path, place: &str, desc: &mut SceneDesc) -> Option<usize> {
        let spec = spec.trim();
        let name = if spec.starts_with('-') {
            desc.warnings.push(format!("{place}: texture options in '{spec}' ignored"));
            spec.split_whitespace().last().unwrap_or(spec)
        } else {
            spec
        };
        let dir = mtl.parent().unwrap_or(Path::new(""));
        let mut file = dir.join(name);
        if !file.is_file() && name.contains('\\') {
            file = dir.join(name.replace('\\', "/"));
        }
        if let Some(&t) = self.by_file.get(&file) {
            return t;
        }
        let decoded = std::fs::read(&file)
            .map_err(|e| {
                if e.kind() == std::io::ErrorKind::NotFound { "file not found".to_string() } else { e.to_string() }
            })
            .and_then(|b| decode_srgb_texture(&b));
        let t = match decoded {
            Ok(texture) => {
                desc.textures.push(texture);
                Some(desc.textures.len() - 1)
            }
            Err(e) => {
                desc.warnings.push(format!("{place}: texture '{}' ignored: {e}", file.display()));
                None
            }
        };
        self.by_file.insert(file, t);
        t
    }
}

/// Three numbers (or one, for grey) from an unknown MTL parameter such as `Tf`.
fn color_param(value: &str) -> Option<Vec3> {
    let parsed: Option<Vec<f32>> = value.split_whitespace().map(|w| w.parse().ok()).collect();
    match parsed?.as_slice() {
        [g] => Some(Vec3::splat(*g)),
        [r, g, b, ..] => Some(Vec3::new(*r, *g, *b)),
        _ => None,
    }
}

/// One MTL material as a [`MaterialDesc`] (mapping in the module doc).
fn convert_material(m: &tobj::Material, mtl: &Path, textures: &mut Textures, desc: &mut SceneDesc) -> MaterialDesc {
    let place = format!("{}: material '{}'", mtl.display(), m.name);
    let kd = m.diffuse.map(Vec3::from_array).unwrap_or(Vec3::splat(DEFAULT_ALBEDO));
    let ks = m.specular.map(Vec3::from_array).unwrap_or(Vec3::ZERO);
    let emission = m
        .emissive
        .map(Vec3::from_array)
        .or_else(|| m.unknown_param.get("Ke").and_then(|v| color_param(v)))
        .unwrap_or(Vec3::ZERO);
    let (base_color, scatter) = match m.illumination_model {
        Some(5) => (if ks.max_element() > 0.0 { ks } else { kd }, ScatterDesc::Mirror),
        Some(7) => {
            let tint = m.unknown_param.get("Tf").and_then(|v| color_param(v)).unwrap_or(Vec3::ONE);
            (tint, ScatterDesc::Dielectric { ior: m.optical_density.unwrap_or(1.5) })
        }
        _ if ks.max_element() > 0.0 => {
            let sum = kd + ks;
            let scale = Vec3::select(sum.cmpgt(Vec3::ONE), Vec3::ONE / sum, Vec3::ONE);
            if scale != Vec3::ONE {
                desc.warnings.push(format!("{place}: Kd + Ks exceeds 1; both scaled down to conserve energy"));
            }
            (kd * scale, ScatterDesc::Glossy { specular: ks * scale, exponent: m.shininess.unwrap_or(1.0) })
        }
        _ => (kd, ScatterDesc::Diffuse),
    };

    let mut ignored: Vec<String> = Vec::new();
    for (key, present) in [
        ("map_Ka", m.ambient_texture.is_some()),
        ("map_Ks", m.specular_texture.is_some()),
        ("bump map", m.normal_texture.is_some()),
        ("map_Ns", m.shininess_texture.is_some()),
        ("map_d", m.dissolve_texture.is_some()),
        ("d < 1 (rendered opaque)", m.dissolve.is_some_and(|d| d < 1.0)),
        (
            "Tr > 0 (rendered opaque)",
            m.unknown_param.get("Tr").and_then(|t| t.trim().parse::<f32>().ok()).is_some_and(|t| t > 0.0),
        ),
    ] {
        if present {
            ignored.push(key.to_string());
        }
    }
    let mut unknown: Vec<&String> =
        m.unknown_param.keys().filter(|k| !["Ke", "map_Ke", "Tf", "Tr"].contains(&k.as_str())).collect();
    unknown.sort();
    ignored.extend(unknown.into_iter().cloned());
    if !ignored.is_empty() {
        desc.warnings.push(format!("{place}: {} ignored", ignored.join(", ")));
    }

    let base_color_texture = m.diffuse_texture.as_deref().and_then(|t| textures.get(t, mtl, &place, desc));
    let emission_texture = m.unknown_param.get("map_Ke").and_then(|t| textures.get(t, mtl, &place, desc));
    MaterialDesc {
        name: m.name.clone(),
        base_color,
        base_color_texture,
        scatter,
        emission,
        emission_texture,
        double_sided: false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scan_text(text: &str) -> Result<Scan, LoadError> {
        scan(Path::new("m.obj"), text)
    }

    #[test]
    fn face_references_out_of_range_or_zero_are_errors_with_lines() {
        let e = scan_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n").err().unwrap();
        assert!(e.to_string().starts_with("m.obj: line 4: vertex index 4 is out of range"), "{e}");
        let e = scan_text("v 0 0 0\nf 0 1 1\n").err().unwrap();
        assert!(e.to_string().contains("line 2") && e.to_string().contains("index 0"), "{e}");
        let e = scan_text("v 0 0 0\nf -2 1 1\n").err().unwrap();
        assert!(e.to_string().contains("line 2"), "{e}");
        let e = scan_text("v 0 0 0\nf 1/99999999999999999999 1 1\n").err().unwrap();
        assert!(e.to_string().contains("line 2"), "{e}");
    }

    #[test]
    fn model_lines_follow_tobj_splitting() {
        let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\no a\nusemtl x\nf 1 2 3\nusemtl y\nf 1 2 3\no b\nf 1 2 3\n";
        let s = scan_text(text).unwrap();
        let materials: HashMap<&str, usize> = [("x", 0), ("y", 1)].into_iter().collect();
        assert_eq!(s.model_lines(&materials), vec![6, 8, 10]);
        // Unknown materials do not split (both resolve to "none").
        assert_eq!(s.model_lines(&HashMap::new()), vec![6, 10]);
    }

    #[test]
    fn one_number_colours_are_expanded_and_bad_colours_rejected() {
        let p = Path::new("m.mtl");
        let t = check_mtl(p, "newmtl a\nKd 0.5\nKs 0 0 0\n").unwrap();
        assert_eq!(t, "newmtl a\nKd 0.5 0.5 0.5\nKs 0 0 0\n");
        let e = check_mtl(p, "newmtl a\nKd 0.5 0.2\n").unwrap_err();
        assert!(e.to_string().starts_with("m.mtl: line 2: 'Kd' needs three numbers"), "{e}");
    }

    #[test]
    fn vertex_colours_and_short_texcoords_are_rewritten_for_tobj() {
        assert_eq!(rewrite_for_tobj("v 1 2 3 0.1 0.2 0.3\nvt 0.5\nf 1 1 1"), "v 1 2 3\nvt 0.5 0\nf 1 1 1\n");
    }
}
