//! Scripted camera paths (`--camera-path`): a keyframe file or a built-in motion around the
//! scene's camera, sampled once per frame.
//!
//! **File format.** Plain text, one keyframe per line: `ex ey ez tx ty tz` (eye position, then
//! the point looked at; numbers separated by spaces, tabs or commas). `#` starts a comment;
//! blank lines are ignored. The keyframes are spread evenly over the frames of the run (the
//! first at frame 0, the last at the final frame) and eye and target are interpolated linearly
//! between them, so a file with exactly N lines gives frame i the pose of line i. One keyframe
//! is a still camera. The up vector and field of view stay those of the scene camera.
//!
//! ```text
//! # walk along the Sponza atrium
//! -12 2.5 0   0 3 0
//!   8 2.5 0  14 3 0
//! ```
//!
//! **Built-in paths** (used when the argument names no existing file), each a smooth periodic
//! motion starting and ending at the scene camera, slow enough that every per-frame step is a
//! small move (papers/002 §8: the case chain reuse is for):
//! * `orbit`: the eye swings ±20° about the vertical axis through the target;
//! * `dolly`: the eye moves towards the target by up to 30 % of their distance and back;
//! * `pan`: the view direction turns ±10° about the vertical axis through the eye.

use std::f32::consts::TAU;
use std::fmt;
use std::path::{Path, PathBuf};

use glam::{Quat, Vec3};

/// A camera pose: where the eye is and what it looks at.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    /// Eye position.
    pub eye: Vec3,
    /// Point looked at.
    pub target: Vec3,
}

impl Pose {
    /// Linear interpolation between two poses.
    pub fn lerp(self, o: Pose, t: f32) -> Pose {
        Pose { eye: self.eye.lerp(o.eye, t), target: self.target.lerp(o.target, t) }
    }
}

/// The built-in scripted motions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BuiltinPath {
    /// Eye swings ±20° about the vertical axis through the target.
    Orbit,
    /// Eye moves towards the target by up to 30 % of the distance and back.
    Dolly,
    /// View direction turns ±10° about the vertical axis through the eye.
    Pan,
}

impl BuiltinPath {
    /// Names accepted by `--camera-path`.
    pub const NAMES: [&'static str; 3] = ["orbit", "dolly", "pan"];

    fn by_name(name: &str) -> Option<Self> {
        match name {
            "orbit" => Some(BuiltinPath::Orbit),
            "dolly" => Some(BuiltinPath::Dolly),
            "pan" => Some(BuiltinPath::Pan),
            _ => None,
        }
    }

    /// The pose at phase `t` ∈ [0, 1] of a motion starting at `start`, with `up` vertical.
    fn pose(self, start: Pose, up: Vec3, t: f32) -> Pose {
        let s = (TAU * t).sin();
        match self {
            BuiltinPath::Orbit => {
                let q = Quat::from_axis_angle(up, 20f32.to_radians() * s);
                Pose { eye: start.target + q * (start.eye - start.target), target: start.target }
            }
            BuiltinPath::Dolly => {
                let k = 0.3 * 0.5 * (1.0 - (TAU * t).cos());
                Pose { eye: start.eye.lerp(start.target, k), target: start.target }
            }
            BuiltinPath::Pan => {
                let q = Quat::from_axis_angle(up, 10f32.to_radians() * s);
                Pose { eye: start.eye, target: start.eye + q * (start.target - start.eye) }
            }
        }
    }
}

/// A camera path: keyframes from a file, or a built-in motion.
#[derive(Clone, Debug, PartialEq)]
pub enum CameraPath {
    /// Keyframes read from a file.
    Keyframes {
        /// The file (for messages).
        source: PathBuf,
        /// At least one pose.
        keys: Vec<Pose>,
    },
    /// A built-in motion around the scene camera.
    Builtin(BuiltinPath),
}

/// A camera path file that cannot be used, naming the file (and the line when there is one).
#[derive(Clone, Debug, PartialEq)]
pub struct CameraPathError {
    /// The file.
    pub path: PathBuf,
    /// 1-based line number.
    pub line: Option<usize>,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for CameraPathError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.path.display())?;
        if let Some(l) = self.line {
            write!(f, ": line {l}")?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for CameraPathError {}

impl CameraPath {
    /// Interprets `--camera-path`: a built-in name (when no file of that name exists) or a file.
    pub fn from_arg(arg: &str) -> Result<CameraPath, CameraPathError> {
        match BuiltinPath::by_name(arg) {
            Some(b) if !Path::new(arg).exists() => Ok(CameraPath::Builtin(b)),
            _ => CameraPath::read(Path::new(arg)),
        }
    }

    /// Reads a keyframe file.
    pub fn read(path: &Path) -> Result<CameraPath, CameraPathError> {
        let text = std::fs::read_to_string(path).map_err(|e| CameraPathError {
            path: path.to_path_buf(),
            line: None,
            message: match e.kind() {
                std::io::ErrorKind::NotFound => {
                    format!("camera path file not found (built-in paths: {})", BuiltinPath::NAMES.join(", "))
                }
                _ => format!("cannot read camera path: {e}"),
            },
        })?;
        CameraPath::parse(path, &text)
    }

    /// Parses the text of a keyframe file (`path` only names it in errors).
    pub fn parse(path: &Path, text: &str) -> Result<CameraPath, CameraPathError> {
        let err = |line: Option<usize>, message: String| CameraPathError { path: path.to_path_buf(), line, message };
        let mut keys = Vec::new();
        for (i, raw) in text.lines().enumerate() {
            let line = raw.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let fields: Vec<&str> =
                line.split(|c: char| c.is_whitespace() || c == ',').filter(|f| !f.is_empty()).collect();
            let numbers: Vec<f32> = fields
                .iter()
                .map(|f| f.parse::<f32>().map_err(|_| err(Some(i + 1), format!("'{f}' is not a number"))))
                .collect::<Result<_, _>>()?;
            let [ex, ey, ez, tx, ty, tz] = numbers[..] else {
                return Err(err(
                    Some(i + 1),
                    format!("expected 6 numbers 'ex ey ez tx ty tz', found {}", numbers.len()),
                ));
            };
            let pose = Pose { eye: Vec3::new(ex, ey, ez), target: Vec3::new(tx, ty, tz) };
            if !(pose.eye.is_finite() && pose.target.is_finite()) {
                return Err(err(Some(i + 1), "eye and target must be finite".into()));
            }
            if pose.eye.distance_squared(pose.target) <= 0.0 {
                return Err(err(Some(i + 1), "eye and target coincide".into()));
            }
            keys.push(pose);
        }
        if keys.is_empty() {
            return Err(err(None, "no keyframes (expected lines 'ex ey ez tx ty tz')".into()));
        }
        Ok(CameraPath::Keyframes { source: path.to_path_buf(), keys })
    }

    /// The pose of frame `frame` of `frames`, for a scene camera at `start` with vertical `up`.
    pub fn pose(&self, start: Pose, up: Vec3, frame: u64, frames: u64) -> Pose {
        let t = if frames > 1 { (frame.min(frames - 1)) as f32 / (frames - 1) as f32 } else { 0.0 };
        match self {
            CameraPath::Builtin(b) => b.pose(start, up, t),
            CameraPath::Keyframes { keys, .. } => {
                let x = t * (keys.len() - 1) as f32;
                let i = (x.floor() as usize).min(keys.len() - 1);
                let j = (i + 1).min(keys.len() - 1);
                keys[i].lerp(keys[j], x - i as f32)
            }
        }
    }

    /// A short description for summaries.
    pub fn describe(&self) -> String {
        match self {
            CameraPath::Builtin(b) => format!("{b:?}").to_lowercase(),
            CameraPath::Keyframes { source, keys } => format!("{} ({} keyframes)", source.display(), keys.len()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn start() -> Pose {
        Pose { eye: Vec3::new(0.0, 1.0, 5.0), target: Vec3::new(0.0, 1.0, 0.0) }
    }

    #[test]
    fn keyframes_are_spread_over_the_frames_and_interpolated() {
        let p = CameraPath::parse(Path::new("p.txt"), "# c\n0 0 0  0 0 -1\n\n10,0,0, 10,0,-1 # end\n").unwrap();
        let at = |i| p.pose(start(), Vec3::Y, i, 11).eye.x;
        assert_eq!(at(0), 0.0);
        assert!((at(5) - 5.0).abs() < 1e-5);
        assert_eq!(at(10), 10.0);
        assert_eq!(at(99), 10.0);
    }

    #[test]
    fn bad_lines_name_the_file_and_line() {
        let e = CameraPath::parse(Path::new("walk.txt"), "0 0 0 0 0 -1\n1 2 3\n").unwrap_err();
        assert_eq!(e.to_string(), "walk.txt: line 2: expected 6 numbers 'ex ey ez tx ty tz', found 3");
        let e = CameraPath::parse(Path::new("walk.txt"), "0 0 x 0 0 -1\n").unwrap_err();
        assert!(e.to_string().starts_with("walk.txt: line 1: 'x' is not a number"), "{e}");
        let e = CameraPath::parse(Path::new("walk.txt"), "1 1 1 1 1 1\n").unwrap_err();
        assert!(e.to_string().contains("coincide"), "{e}");
        let e = CameraPath::parse(Path::new("walk.txt"), "# nothing\n").unwrap_err();
        assert!(e.to_string().starts_with("walk.txt: no keyframes"), "{e}");
    }

    #[test]
    fn builtin_paths_start_and_end_at_the_scene_camera_with_small_steps() {
        for name in BuiltinPath::NAMES {
            let p = CameraPath::from_arg(name).unwrap();
            let n = 100;
            assert!(p.pose(start(), Vec3::Y, 0, n).eye.distance(start().eye) < 1e-5, "{name}");
            assert!(p.pose(start(), Vec3::Y, n - 1, n).eye.distance(start().eye) < 1e-4, "{name}");
            let mut moved = 0.0f32;
            for i in 1..n {
                let (a, b) = (p.pose(start(), Vec3::Y, i - 1, n), p.pose(start(), Vec3::Y, i, n));
                let step = a.eye.distance(b.eye) + a.target.distance(b.target);
                assert!(step < 0.2, "{name}: step {step} at frame {i}");
                moved += step;
            }
            assert!(moved > 0.5, "{name} does not move");
        }
    }
}
