//! The camera: pinhole or thin lens, with the importance function W_e needed to connect light
//! sub-paths to the image (light tracing, BDPT t = 1, MIR's camera power).
//!
//! Raster coordinates: x to the right, y down, pixel (i, j) covers [i, i+1) × [j, j+1).
//! Importance is normalised so that ∫ W_e over the image plane and lens is 1; a pixel's
//! measurement is then `width·height · ∫_pixel W_e L`, i.e. the mean radiance through it, the
//! same scale as camera samples (papers/001 Appendix A; pbrt-v3 §16.1).

use glam::{Vec2, Vec3, vec2};

use crate::sampling::warp::sample_uniform_disk_concentric;
use crate::simd::{F8, Lanes};

/// A ray with origin and unit direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Origin.
    pub origin: Vec3,
    /// Unit direction.
    pub dir: Vec3,
}

/// A validated camera.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// Eye (centre of the lens).
    pub position: Vec3,
    /// Unit viewing direction.
    pub forward: Vec3,
    /// Unit right vector (raster +x).
    pub right: Vec3,
    /// Unit up vector (raster −y).
    pub up: Vec3,
    /// Vertical field of view, radians.
    pub fov_y_radians: f32,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Lens radius (0 = pinhole).
    pub lens_radius: f32,
    /// Distance along `forward` of the plane in focus.
    pub focus_distance: f32,
    tan_half_x: f32,
    tan_half_y: f32,
}

/// A camera connection from a scene point to the lens (for light tracing).
#[derive(Clone, Copy, Debug)]
pub struct CameraSample {
    /// Point on the lens.
    pub p_lens: Vec3,
    /// Unit direction from the scene point towards the lens.
    pub wi: Vec3,
    /// Distance to the lens point.
    pub dist: f32,
    /// Importance W_e carried back along the connection.
    pub we: f32,
    /// Solid-angle density (at the scene point) of choosing this lens point.
    pub pdf_w: f32,
    /// Raster position the connection lands on.
    pub raster: Vec2,
}

impl Camera {
    /// A camera at `eye` looking at `target`. Callers validate the inputs (finite, distinct,
    /// `up` not parallel to the view direction, 0 < fov < 180°).
    pub fn look_at(eye: Vec3, target: Vec3, up: Vec3, fov_y_radians: f32, width: u32, height: u32) -> Self {
        let forward = (target - eye).normalize();
        let right = forward.cross(up).normalize();
        let up = right.cross(forward);
        let tan_half_y = (0.5 * fov_y_radians).tan();
        let tan_half_x = tan_half_y * width as f32 / height as f32;
        Camera {
            position: eye,
            forward,
            right,
            up,
            fov_y_radians,
            width,
            height,
            lens_radius: 0.0,
            focus_distance: (target - eye).length(),
            tan_half_x,
            tan_half_y,
        }
    }

    /// The same camera with a thin lens of `radius` focused at `focus_distance`.
    pub fn with_lens(mut self, radius: f32, focus_distance: f32) -> Self {
        self.lens_radius = radius.max(0.0);
        self.focus_distance = focus_distance;
        self
    }

    /// The same camera rendering `width` × `height` pixels (vertical fov kept).
    pub fn with_resolution(mut self, width: u32, height: u32) -> Self {
        self.width = width;
        self.height = height;
        self.tan_half_x = self.tan_half_y * width as f32 / height as f32;
        self
    }

    /// Number of pixels.
    pub fn pixel_count(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// Area of the image rectangle on the plane at unit distance.
    fn image_plane_area(&self) -> f32 {
        4.0 * self.tan_half_x * self.tan_half_y
    }

    fn lens_area(&self) -> f32 {
        if self.lens_radius > 0.0 { std::f32::consts::PI * self.lens_radius * self.lens_radius } else { 1.0 }
    }

    /// True for a pinhole camera (a delta in lens position).
    pub fn is_pinhole(&self) -> bool {
        self.lens_radius <= 0.0
    }

    /// Camera-space direction (not normalised, z = 1) through a raster position.
    #[inline]
    fn plane_point(&self, raster: Vec2) -> Vec3 {
        let x = (2.0 * raster.x / self.width as f32 - 1.0) * self.tan_half_x;
        let y = (1.0 - 2.0 * raster.y / self.height as f32) * self.tan_half_y;
        self.right * x + self.up * y + self.forward
    }

    /// The primary ray through `raster`, with a lens sample `u_lens` (ignored for a pinhole).
    #[inline]
    pub fn generate_ray(&self, raster: Vec2, u_lens: Vec2) -> Ray {
        let d = self.plane_point(raster);
        if self.lens_radius <= 0.0 {
            return Ray { origin: self.position, dir: d.normalize() };
        }
        let l = sample_uniform_disk_concentric(u_lens) * self.lens_radius;
        let origin = self.position + self.right * l.x + self.up * l.y;
        let focus = self.position + d * self.focus_distance;
        Ray { origin, dir: (focus - origin).normalize() }
    }

    /// A lens point for the uniform numbers `u_lens` (the eye for a pinhole), with the density
    /// [`Camera::pdf_we`] gives it.
    pub fn sample_lens(&self, u_lens: Vec2) -> Vec3 {
        if self.lens_radius <= 0.0 {
            return self.position;
        }
        let l = sample_uniform_disk_concentric(u_lens) * self.lens_radius;
        self.position + self.right * l.x + self.up * l.y
    }

    /// The ray that leaves lens point `p_lens` and lands on `raster` (through the point in
    /// focus; [`Camera::generate_ray`] with the lens sample that gives `p_lens`).
    pub fn ray_from_lens(&self, p_lens: Vec3, raster: Vec2) -> Ray {
        let d = self.plane_point(raster);
        if self.lens_radius <= 0.0 {
            return Ray { origin: self.position, dir: d.normalize() };
        }
        let focus = self.position + d * self.focus_distance;
        Ray { origin: p_lens, dir: (focus - p_lens).normalize() }
    }

    /// [`Camera::generate_ray`] for the first `n` (≤ 8) of eight raster positions and lens
    /// samples. A pinhole's directions are computed eight at a time with the scalar form's
    /// operations in the same order, so the rays are the same bits (tested); a thin lens takes
    /// the scalar form lane by lane.
    #[inline]
    pub fn generate_rays8(&self, raster: &[Vec2; 8], u_lens: &[Vec2; 8], n: usize) -> [Ray; 8] {
        let mut rays = [Ray { origin: self.position, dir: self.forward }; 8];
        if self.lens_radius > 0.0 {
            for (ray, (&r, &u)) in rays.iter_mut().zip(raster.iter().zip(u_lens)).take(n) {
                *ray = self.generate_ray(r, u);
            }
            return rays;
        }
        let (one, two) = (F8::splat(1.0), F8::splat(2.0));
        let (rx, ry) = (F8::from_fn(|i| raster[i].x), F8::from_fn(|i| raster[i].y));
        let x = (two * rx / F8::splat(self.width as f32) - one) * F8::splat(self.tan_half_x);
        let y = (one - two * ry / F8::splat(self.height as f32)) * F8::splat(self.tan_half_y);
        let (right, up, forward) = (self.right.to_array(), self.up.to_array(), self.forward.to_array());
        let d: [F8; 3] =
            std::array::from_fn(|c| F8::splat(right[c]) * x + F8::splat(up[c]) * y + F8::splat(forward[c]));
        // Vec3::normalize: v · (1 / √((x² + y²) + z²)).
        let r = one / (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        // One array per lane, so each lane's direction is read from one store.
        let lanes = F8::transpose([d[0] * r, d[1] * r, d[2] * r, one, one, one, one, one]);
        for (ray, lane) in rays.iter_mut().zip(lanes).take(n) {
            let l = lane.to_array();
            ray.dir = Vec3::new(l[0], l[1], l[2]);
        }
        rays
    }

    /// The slopes (x / forward along `right`, y / forward along `up`: low x, high x, low y,
    /// high y) bounding the rays [`Camera::generate_rays8`] gives for raster positions in
    /// `[x0, x1) × [y0, y1)`, before rounding; None for a thin-lens camera (its rays leave
    /// different points of the lens).
    pub fn raster_slopes(&self, (x0, x1): (f32, f32), (y0, y1): (f32, f32)) -> Option<[f32; 4]> {
        if self.lens_radius > 0.0 {
            return None;
        }
        let x = |r: f32| (2.0 * r / self.width as f32 - 1.0) * self.tan_half_x;
        let y = |r: f32| (1.0 - 2.0 * r / self.height as f32) * self.tan_half_y;
        Some([x(x0), x(x1), y(y1), y(y0)])
    }

    /// The raster position a ray leaving the lens at `p_lens` along `dir` maps to, or `None`
    /// when it leaves the image.
    pub fn raster_of(&self, p_lens: Vec3, dir: Vec3) -> Option<Vec2> {
        let cos = dir.dot(self.forward);
        if cos <= 0.0 {
            return None;
        }
        // Point on the focus plane (or the unit plane for a pinhole) → pinhole projection.
        let dist = if self.lens_radius > 0.0 { self.focus_distance } else { 1.0 };
        let p_focus = p_lens + dir * (dist / cos) - self.position;
        let q = p_focus / p_focus.dot(self.forward);
        let x = q.dot(self.right) / self.tan_half_x;
        let y = q.dot(self.up) / self.tan_half_y;
        let raster = vec2((x + 1.0) * 0.5 * self.width as f32, (1.0 - y) * 0.5 * self.height as f32);
        if raster.x < 0.0 || raster.y < 0.0 || raster.x >= self.width as f32 || raster.y >= self.height as f32 {
            return None;
        }
        Some(raster)
    }

    /// Importance W_e of a ray leaving the lens along `dir` (0 outside the image).
    pub fn we(&self, p_lens: Vec3, dir: Vec3) -> f32 {
        if self.raster_of(p_lens, dir).is_none() {
            return 0.0;
        }
        let cos = dir.dot(self.forward);
        let cos2 = cos * cos;
        1.0 / (self.image_plane_area() * self.lens_area() * cos2 * cos2)
    }

    /// Densities of a camera ray: (area density of the lens point, solid-angle density of
    /// the direction). The lens density is 1 for a pinhole (its delta is handled by flags).
    pub fn pdf_we(&self, dir: Vec3) -> (f32, f32) {
        let cos = dir.dot(self.forward);
        if cos <= 0.0 {
            return (0.0, 0.0);
        }
        (1.0 / self.lens_area(), 1.0 / (self.image_plane_area() * cos * cos * cos))
    }

    /// Chooses a lens point to connect the scene point `p` to (light tracing).
    pub fn sample_wi(&self, p: Vec3, u_lens: Vec2) -> Option<CameraSample> {
        let l = sample_uniform_disk_concentric(u_lens) * self.lens_radius;
        let p_lens = self.position + self.right * l.x + self.up * l.y;
        let to_lens = p_lens - p;
        let dist2 = to_lens.length_squared();
        if dist2 <= 0.0 || !dist2.is_finite() {
            return None;
        }
        let dist = dist2.sqrt();
        let wi = to_lens / dist;
        let raster = self.raster_of(p_lens, -wi)?;
        let cos_lens = (-wi).dot(self.forward);
        let pdf_w = dist2 / (cos_lens * self.lens_area());
        Some(CameraSample { p_lens, wi, dist, we: self.we(p_lens, -wi), pdf_w, raster })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Pcg32;

    fn cam() -> Camera {
        Camera::look_at(Vec3::new(1.0, 2.0, 3.0), Vec3::new(0.0, 1.0, -2.0), Vec3::Y, 0.8, 64, 48)
    }

    #[test]
    fn rays_project_back_to_their_raster_position() {
        for c in [cam(), cam().with_lens(0.1, 4.0)] {
            let mut r = Pcg32::new(4);
            for _ in 0..1000 {
                let raster = vec2(r.next_f32() * 64.0, r.next_f32() * 48.0);
                let ray = c.generate_ray(raster, vec2(r.next_f32(), r.next_f32()));
                let back = c.raster_of(ray.origin, ray.dir).unwrap();
                assert!((back - raster).length() < 1e-2, "{raster} -> {back}");
            }
        }
    }

    /// Eight rays at a time are the scalar rays, bit for bit, for a pinhole and a thin lens and
    /// for partly filled lanes (the G-buffer's packets equal its single rays through this).
    #[test]
    fn eight_rays_at_a_time_are_the_scalar_rays() {
        let mut r = Pcg32::new(11);
        for c in [cam(), cam().with_lens(0.1, 4.0)] {
            for n in (0..300).map(|k| [8, 5, 1][k % 3]) {
                let raster: [Vec2; 8] = std::array::from_fn(|_| vec2(r.next_f32() * 64.0, r.next_f32() * 48.0));
                let lens: [Vec2; 8] = std::array::from_fn(|_| vec2(r.next_f32(), r.next_f32()));
                let rays = c.generate_rays8(&raster, &lens, n);
                for i in 0..n {
                    let scalar = c.generate_ray(raster[i], lens[i]);
                    assert_eq!(rays[i].origin.to_array().map(f32::to_bits), scalar.origin.to_array().map(f32::to_bits));
                    assert_eq!(rays[i].dir.to_array().map(f32::to_bits), scalar.dir.to_array().map(f32::to_bits));
                }
            }
        }
    }

    /// ∫ W_e cos θ dω over directions through the image is 1 / lens area (pinhole: 1).
    #[test]
    fn importance_integrates_to_one_over_the_image() {
        let c = cam();
        let mut r = Pcg32::new(8);
        let n = 200_000;
        let mut sum = 0.0f64;
        for _ in 0..n {
            let w = crate::sampling::warp::sample_uniform_sphere(vec2(r.next_f32(), r.next_f32()));
            let cos = w.dot(c.forward).max(0.0);
            sum += (c.we(c.position, w) * cos) as f64 / crate::sampling::warp::uniform_sphere_pdf_w() as f64;
        }
        let v = sum / n as f64;
        assert!((v - 1.0).abs() < 0.03, "{v}");
    }
}
