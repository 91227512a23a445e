//! The walkthrough camera: a first-person "fly" camera driven by keys (move), mouse drags
//! (look) and the wheel (speed). It keeps the scene camera's field of view and lens and turns
//! about a fixed world up vector, so the horizon stays level.

use glam::{Quat, Vec3};

use super::path::Pose;
use crate::scene::Camera;

/// Initial speed, in scene diagonals per second.
pub const DEFAULT_SPEED_DIAGONALS: f32 = 0.15;
/// Look sensitivity: degrees of rotation per pixel of mouse drag.
pub const LOOK_DEGREES_PER_PIXEL: f32 = 0.25;
/// Speed factor of one wheel notch.
pub const WHEEL_FACTOR: f32 = 1.25;
/// Largest pitch above or below the horizon, degrees (keeps `forward` away from `world_up`).
const MAX_PITCH_DEG: f32 = 89.0;

/// Which way the movement keys push, each component in [-1, 1].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MoveInput {
    /// W (+1) / S (−1).
    pub forward: f32,
    /// D (+1) / A (−1).
    pub right: f32,
    /// E (+1) / Q (−1), along the world up vector.
    pub up: f32,
}

impl MoveInput {
    /// True when no movement key is held.
    pub fn is_zero(&self) -> bool {
        *self == MoveInput::default()
    }
}

/// A first-person camera.
#[derive(Clone, Debug, PartialEq)]
pub struct FlyCamera {
    /// Eye position.
    pub eye: Vec3,
    /// Unit view direction.
    pub forward: Vec3,
    /// Unit vertical axis of yaw.
    pub world_up: Vec3,
    /// Vertical field of view.
    pub fov_y_radians: f32,
    /// Thin-lens radius (0: pinhole).
    pub lens_radius: f32,
    /// Distance of the plane in focus.
    pub focus_distance: f32,
    /// Movement speed, scene units per second.
    pub speed: f32,
}

impl FlyCamera {
    /// Starts at `camera`, turning about `world_up` (the camera's own up if `world_up` is
    /// parallel to the view direction), moving at [`DEFAULT_SPEED_DIAGONALS`] per second.
    pub fn from_camera(camera: &Camera, world_up: Vec3, scene_diagonal: f32) -> Self {
        let up = world_up.try_normalize().filter(|u| u.cross(camera.forward).length() > 1e-3).unwrap_or(camera.up);
        FlyCamera {
            eye: camera.position,
            forward: camera.forward,
            world_up: up,
            fov_y_radians: camera.fov_y_radians,
            lens_radius: camera.lens_radius,
            focus_distance: camera.focus_distance,
            speed: DEFAULT_SPEED_DIAGONALS * scene_diagonal.max(1e-6),
        }
    }

    /// The camera rendering `width` × `height` pixels.
    pub fn camera(&self, width: u32, height: u32) -> Camera {
        Camera::look_at(self.eye, self.eye + self.forward, self.world_up, self.fov_y_radians, width, height)
            .with_lens(self.lens_radius, self.focus_distance)
    }

    /// The current pose (target at the focus distance).
    pub fn pose(&self) -> Pose {
        Pose { eye: self.eye, target: self.eye + self.forward * self.focus_distance.max(1e-6) }
    }

    /// Moves the camera to `pose` (scripted paths).
    pub fn set_pose(&mut self, pose: Pose) {
        if let Some(f) = (pose.target - pose.eye).try_normalize()
            && f.cross(self.world_up).length() > 1e-4
        {
            self.forward = f;
        }
        self.eye = pose.eye;
    }

    /// Moves for `dt` seconds under `input`.
    pub fn advance(&mut self, input: MoveInput, dt: f32) {
        if input.is_zero() || !(dt > 0.0) {
            return;
        }
        let right = self.forward.cross(self.world_up).normalize();
        let d = self.forward * input.forward + right * input.right + self.world_up * input.up;
        self.eye += d * (self.speed * dt.min(0.5));
    }

    /// Turns by a mouse drag of (`dx`, `dy`) pixels: right turns right, down looks down.
    pub fn look(&mut self, dx: f32, dy: f32) {
        if dx == 0.0 && dy == 0.0 {
            return;
        }
        let k = LOOK_DEGREES_PER_PIXEL.to_radians();
        let yawed = Quat::from_axis_angle(self.world_up, -dx * k) * self.forward;
        let pitch = yawed.dot(self.world_up).clamp(-1.0, 1.0).asin();
        let max = MAX_PITCH_DEG.to_radians();
        let new_pitch = (pitch - dy * k).clamp(-max, max);
        let right = yawed.cross(self.world_up).normalize();
        self.forward = (Quat::from_axis_angle(right, new_pitch - pitch) * yawed).normalize();
    }

    /// Scales the speed by [`WHEEL_FACTOR`] per notch (negative notches slow down).
    pub fn scale_speed(&mut self, notches: f32) {
        self.speed = (self.speed * WHEEL_FACTOR.powf(notches)).clamp(1e-9, 1e12);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fly() -> FlyCamera {
        let cam = Camera::look_at(Vec3::ZERO, Vec3::new(0.0, 0.0, -1.0), Vec3::Y, 1.0, 64, 64);
        FlyCamera::from_camera(&cam, Vec3::Y, 10.0)
    }

    #[test]
    fn keys_move_along_the_view_and_the_horizon() {
        let mut f = fly();
        // Speed: 0.15 diagonals per second = 1.5 units/s.
        f.advance(MoveInput { forward: 1.0, ..Default::default() }, 0.4);
        assert!((f.eye - Vec3::new(0.0, 0.0, -0.6)).length() < 1e-5, "{}", f.eye);
        f.advance(MoveInput { right: 1.0, up: 1.0, ..Default::default() }, 0.4);
        assert!((f.eye - Vec3::new(0.6, 0.6, -0.6)).length() < 1e-5, "{}", f.eye);
        // A long stall (a slow frame) moves at most half a second's worth.
        f.advance(MoveInput { forward: -1.0, ..Default::default() }, 10.0);
        assert!((f.eye - Vec3::new(0.6, 0.6, 0.15)).length() < 1e-5, "{}", f.eye);
    }

    #[test]
    fn looking_keeps_the_horizon_level_and_the_pitch_bounded() {
        let mut f = fly();
        f.look(360.0, 0.0); // 90° to the right
        assert!((f.forward - Vec3::X).length() < 1e-4, "{}", f.forward);
        f.look(0.0, -10_000.0); // far up: stops below the zenith
        assert!(f.forward.dot(Vec3::Y) < 1.0 && f.forward.dot(Vec3::Y) > 0.99);
        let cam = f.camera(32, 16);
        assert!(cam.right.dot(Vec3::Y).abs() < 1e-4, "roll crept in");
        assert!(cam.forward.is_finite() && cam.up.is_finite());
    }
}
