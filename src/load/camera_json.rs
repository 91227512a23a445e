//! `camera.json`: the camera of an OBJ scene, in a small JSON file beside the `.obj`.
//!
//! ```json
//! { "eye": [0, 1, 4], "target": [0, 1, 0], "up": [0, 1, 0], "fov_y_deg": 40, "width": 256, "height": 256 }
//! ```
//!
//! `eye`, `target` and `fov_y_deg` are required; `up` defaults to +y; `width` and `height` are
//! optional (when both are given they also set the aspect ratio). Unknown keys are reported as
//! warnings, never silently dropped. Wrong types, non-finite numbers (a literal too large for
//! `f32`), a field of view outside (0°, 179°) and `eye == target` are errors naming the file and
//! the key.

use std::path::Path;

use glam::Vec3;
use serde_json::{Map, Value};

use super::desc::CameraDesc;
use super::error::{LoadError, LoadErrorKind};

/// The file name the OBJ loader looks for beside the `.obj`.
pub const FILE_NAME: &str = "camera.json";

/// The keys `camera.json` understands.
const KNOWN_KEYS: [&str; 6] = ["eye", "target", "up", "fov_y_deg", "width", "height"];

/// A camera read from a `camera.json` file, with a warning for each key it ignored.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraFile {
    /// The camera.
    pub camera: CameraDesc,
    /// One line per ignored key, naming the file and the key.
    pub warnings: Vec<String>,
}

/// Reads and checks a `camera.json` file.
pub fn read_camera_json(path: &Path) -> Result<CameraFile, LoadError> {
    let bytes = std::fs::read(path).map_err(|e| LoadError::io(path, e))?;
    parse_camera_json(path, &bytes)
}

/// Parses the bytes of a `camera.json` file; `path` is only used in messages.
pub fn parse_camera_json(path: &Path, bytes: &[u8]) -> Result<CameraFile, LoadError> {
    let value: Value = serde_json::from_slice(bytes).map_err(|e| json_error(path, &e))?;
    let Value::Object(map) = value else {
        return Err(LoadError::new(
            path,
            LoadErrorKind::Invalid,
            "must contain a JSON object such as {\"eye\": [...]}",
        ));
    };
    let fields = Fields { path, map: &map };

    let eye = fields.vec3("eye")?.ok_or_else(|| fields.missing("eye"))?;
    let target = fields.vec3("target")?.ok_or_else(|| fields.missing("target"))?;
    let up = fields.vec3("up")?.unwrap_or(Vec3::Y);
    let fov_y_deg = fields.number("fov_y_deg")?.ok_or_else(|| fields.missing("fov_y_deg"))?;
    let width = fields.pixels("width")?;
    let height = fields.pixels("height")?;

    if !(fov_y_deg > 0.0 && fov_y_deg < 179.0) {
        return Err(
            fields.invalid("fov_y_deg", format!("must be between 0 and 179 degrees (exclusive), got {fov_y_deg}"))
        );
    }
    if eye == target {
        return Err(fields.invalid("target", "must differ from 'eye'"));
    }
    if up == Vec3::ZERO {
        return Err(fields.invalid("up", "must not be the zero vector"));
    }

    let warnings = map
        .keys()
        .filter(|k| !KNOWN_KEYS.contains(&k.as_str()))
        .map(|k| format!("{}: unknown key '{k}' ignored (known keys: {})", path.display(), KNOWN_KEYS.join(", ")))
        .collect();
    let aspect = match (width, height) {
        (Some(w), Some(h)) => Some(w as f32 / h as f32),
        _ => None,
    };
    Ok(CameraFile { camera: CameraDesc { eye, target, up, fov_y_deg, aspect, width, height }, warnings })
}

/// A serde_json error as one sentence with its line and column as the location.
fn json_error(path: &Path, e: &serde_json::Error) -> LoadError {
    let text = e.to_string();
    // serde_json appends " at line L column C"; the location carries that instead.
    let what = text.split(" at line ").next().unwrap_or(&text);
    let message = match e.classify() {
        serde_json::error::Category::Io => format!("cannot read: {what}"),
        _ => format!("is not valid JSON: {what}"),
    };
    LoadError::new(path, LoadErrorKind::Malformed, message).at(format!("line {}, column {}", e.line(), e.column()))
}

/// Typed access to the keys of the top-level object, with errors naming the key.
struct Fields<'a> {
    path: &'a Path,
    map: &'a Map<String, Value>,
}

impl Fields<'_> {
    fn invalid(&self, key: &str, message: impl Into<String>) -> LoadError {
        LoadError::new(self.path, LoadErrorKind::Invalid, message).at(format!("key '{key}'"))
    }

    fn missing(&self, key: &str) -> LoadError {
        self.invalid(key, "is required but missing")
    }

    /// A finite number (as `f32`), if the key is present.
    fn number(&self, key: &str) -> Result<Option<f32>, LoadError> {
        self.map.get(key).map(|v| self.finite(key, v)).transpose()
    }

    fn finite(&self, key: &str, v: &Value) -> Result<f32, LoadError> {
        let Some(x) = v.as_f64() else {
            return Err(self.invalid(key, format!("must be a number, got {}", type_name(v))));
        };
        let x = x as f32;
        if !x.is_finite() {
            return Err(self.invalid(key, "must be a finite number (it overflows f32)"));
        }
        Ok(x)
    }

    /// An array of three finite numbers, if the key is present.
    fn vec3(&self, key: &str) -> Result<Option<Vec3>, LoadError> {
        let Some(v) = self.map.get(key) else { return Ok(None) };
        let shape_error =
            || self.invalid(key, format!("must be an array of three numbers [x, y, z], got {}", type_name(v)));
        let Some(items) = v.as_array() else { return Err(shape_error()) };
        if items.len() != 3 {
            return Err(self.invalid(key, format!("must have three components [x, y, z], got {}", items.len())));
        }
        let mut xyz = [0.0f32; 3];
        for (out, item) in xyz.iter_mut().zip(items) {
            if !item.is_number() {
                return Err(shape_error());
            }
            *out = self.finite(key, item)?;
        }
        Ok(Some(Vec3::from_array(xyz)))
    }

    /// A positive integer pixel count, if the key is present.
    fn pixels(&self, key: &str) -> Result<Option<u32>, LoadError> {
        let Some(v) = self.map.get(key) else { return Ok(None) };
        match v.as_u64().and_then(|n| u32::try_from(n).ok()) {
            Some(n) if n > 0 => Ok(Some(n)),
            _ => Err(self.invalid(key, format!("must be a positive whole number of pixels, got {v}"))),
        }
    }
}

fn type_name(v: &Value) -> &'static str {
    match v {
        Value::Null => "null",
        Value::Bool(_) => "a boolean",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "an array",
        Value::Object(_) => "an object",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<CameraFile, LoadError> {
        parse_camera_json(Path::new("dir/camera.json"), text.as_bytes())
    }

    #[test]
    fn full_camera_json_is_read_with_aspect_from_width_and_height() {
        let f = parse(
            r#"{"eye": [0, 1, 4], "target": [0, 1, 0], "up": [0, 0, 1], "fov_y_deg": 40,
                         "width": 200, "height": 100}"#,
        )
        .unwrap();
        assert_eq!(f.camera.eye, Vec3::new(0.0, 1.0, 4.0));
        assert_eq!(f.camera.up, Vec3::Z);
        assert_eq!(f.camera.fov_y_deg, 40.0);
        assert_eq!((f.camera.width, f.camera.height, f.camera.aspect), (Some(200), Some(100), Some(2.0)));
        assert!(f.warnings.is_empty());
    }

    #[test]
    fn up_defaults_to_y_and_unknown_keys_warn() {
        let f = parse(r#"{"eye": [0, 0, 1], "target": [0, 0, 0], "fov_y_deg": 30, "fov": 1}"#).unwrap();
        assert_eq!(f.camera.up, Vec3::Y);
        assert_eq!(f.camera.width, None);
        assert_eq!(f.warnings.len(), 1);
        assert!(f.warnings[0].contains("'fov'") && f.warnings[0].contains("camera.json"), "{:?}", f.warnings);
    }

    #[test]
    fn bad_fields_are_errors_naming_file_and_key() {
        let cases = [
            (r#"{"target": [0, 0, 0], "fov_y_deg": 30}"#, "'eye'"),
            (r#"{"eye": [0, 0, 1], "target": [0, 0], "fov_y_deg": 30}"#, "'target'"),
            (r#"{"eye": [0, 0, 1], "target": [0, 0, 0], "fov_y_deg": "wide"}"#, "'fov_y_deg'"),
            (r#"{"eye": [0, 0, 1], "target": [0, 0, 0], "fov_y_deg": 179}"#, "'fov_y_deg'"),
            (r#"{"eye": [0, 0, 1], "target": [0, 0, 0], "fov_y_deg": 0}"#, "'fov_y_deg'"),
            (r#"{"eye": [1e39, 0, 1], "target": [0, 0, 0], "fov_y_deg": 30}"#, "'eye'"),
            (r#"{"eye": [0, 0, 1], "target": [0, 0, 0], "fov_y_deg": 30, "width": -3}"#, "'width'"),
            (r#"{"eye": [0, 0, 1], "target": [0, 0, 1], "fov_y_deg": 30}"#, "'target'"),
        ];
        for (text, key) in cases {
            let e = parse(text).unwrap_err();
            let s = e.to_string();
            assert!(s.starts_with("dir/camera.json: key ") && s.contains(key), "{text}: {s}");
            assert!(matches!(e.kind, LoadErrorKind::Invalid));
        }
    }

    #[test]
    fn broken_json_names_line_and_column() {
        let e = parse("{\"eye\": [0, 0, 1],\n \"target\" [0, 0, 0]}").unwrap_err();
        assert!(matches!(e.kind, LoadErrorKind::Malformed));
        assert!(e.to_string().starts_with("dir/camera.json: line 2, column"), "{e}");
    }
}
