//! Warps from the unit square to the domains rendering needs, as sample / pdf / invert triads
//! (docs/design.md §2). Every pdf names its measure; every `invert_*` maps a point of the
//! domain back to the square, so primary-sample-space methods and tests can round-trip.

use std::f32::consts::{FRAC_1_PI, FRAC_PI_2, FRAC_PI_4, PI};

use glam::{Vec2, Vec3, vec2, vec3};

/// Uniform point on the unit disk (Shirley–Chiu concentric map, area pdf 1/π).
#[inline]
pub fn sample_uniform_disk_concentric(u: Vec2) -> Vec2 {
    let o = 2.0 * u - Vec2::ONE;
    if o.x == 0.0 && o.y == 0.0 {
        return Vec2::ZERO;
    }
    let (r, theta) =
        if o.x.abs() > o.y.abs() { (o.x, FRAC_PI_4 * (o.y / o.x)) } else { (o.y, FRAC_PI_2 - FRAC_PI_4 * (o.x / o.y)) };
    r * vec2(theta.cos(), theta.sin())
}

/// Area density of [`sample_uniform_disk_concentric`].
#[inline]
pub fn uniform_disk_pdf_a() -> f32 {
    FRAC_1_PI
}

/// Inverse of [`sample_uniform_disk_concentric`].
pub fn invert_uniform_disk_concentric(p: Vec2) -> Vec2 {
    let r = p.length();
    if r == 0.0 {
        return vec2(0.5, 0.5);
    }
    let mut phi = p.y.atan2(p.x);
    if phi < -FRAC_PI_4 {
        phi += 2.0 * PI;
    }
    let (x, y) = if phi < FRAC_PI_4 {
        (r, r * phi / FRAC_PI_4)
    } else if phi < 3.0 * FRAC_PI_4 {
        (r * (FRAC_PI_2 - phi) / FRAC_PI_4, r)
    } else if phi < 5.0 * FRAC_PI_4 {
        (-r, -r * (phi - PI) / FRAC_PI_4)
    } else {
        (-r * (3.0 * FRAC_PI_2 - phi) / FRAC_PI_4, -r)
    };
    vec2((x + 1.0) * 0.5, (y + 1.0) * 0.5)
}

/// Cosine-weighted direction on the +z hemisphere (Malley's method).
#[inline]
pub fn sample_cosine_hemisphere(u: Vec2) -> Vec3 {
    let d = sample_uniform_disk_concentric(u);
    let z = (1.0 - d.length_squared()).max(0.0).sqrt();
    vec3(d.x, d.y, z)
}

/// Solid-angle density of [`sample_cosine_hemisphere`] for a direction with `cos_theta` to +z.
#[inline]
pub fn cosine_hemisphere_pdf_w(cos_theta: f32) -> f32 {
    cos_theta.max(0.0) * FRAC_1_PI
}

/// Inverse of [`sample_cosine_hemisphere`].
pub fn invert_cosine_hemisphere(w: Vec3) -> Vec2 {
    invert_uniform_disk_concentric(vec2(w.x, w.y))
}

/// Uniform direction on the unit sphere.
#[inline]
pub fn sample_uniform_sphere(u: Vec2) -> Vec3 {
    let z = 1.0 - 2.0 * u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    vec3(r * phi.cos(), r * phi.sin(), z)
}

/// Solid-angle density of [`sample_uniform_sphere`].
#[inline]
pub fn uniform_sphere_pdf_w() -> f32 {
    0.25 * FRAC_1_PI
}

/// Inverse of [`sample_uniform_sphere`].
pub fn invert_uniform_sphere(w: Vec3) -> Vec2 {
    let mut phi = w.y.atan2(w.x);
    if phi < 0.0 {
        phi += 2.0 * PI;
    }
    vec2((1.0 - w.z) * 0.5, phi / (2.0 * PI))
}

/// Uniform direction in the cone of half-angle acos(`cos_max`) around +z.
#[inline]
pub fn sample_uniform_cone(u: Vec2, cos_max: f32) -> Vec3 {
    let cos_theta = 1.0 - u.x * (1.0 - cos_max);
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    vec3(sin_theta * phi.cos(), sin_theta * phi.sin(), cos_theta)
}

/// Solid-angle density of [`sample_uniform_cone`].
#[inline]
pub fn uniform_cone_pdf_w(cos_max: f32) -> f32 {
    1.0 / (2.0 * PI * (1.0 - cos_max))
}

/// Inverse of [`sample_uniform_cone`].
pub fn invert_uniform_cone(w: Vec3, cos_max: f32) -> Vec2 {
    let mut phi = w.y.atan2(w.x);
    if phi < 0.0 {
        phi += 2.0 * PI;
    }
    vec2((1.0 - w.z) / (1.0 - cos_max), phi / (2.0 * PI))
}

/// Barycentrics (b1, b2) of a uniform point on a triangle (Heitz 2019's area-preserving map);
/// the point is `(1 - b1 - b2) p0 + b1 p1 + b2 p2`, area density 1 / area.
#[inline]
pub fn sample_uniform_triangle(u: Vec2) -> Vec2 {
    let (b0, b1);
    if u.x < u.y {
        b0 = u.x / 2.0;
        b1 = u.y - b0;
    } else {
        b1 = u.y / 2.0;
        b0 = u.x - b1;
    }
    vec2(b1, 1.0 - b0 - b1)
}

/// Inverse of [`sample_uniform_triangle`] for barycentrics (b1, b2).
pub fn invert_uniform_triangle(b: Vec2) -> Vec2 {
    let b1 = b.x;
    let b0 = 1.0 - b.x - b.y;
    if b0 > b1 {
        // u.x >= u.y branch: b1 = u.y / 2, b0 = u.x - b1.
        let uy = 2.0 * b1;
        vec2(b0 + b1, uy)
    } else {
        let ux = 2.0 * b0;
        vec2(ux, b1 + b0)
    }
}

/// Direction around +z with density ∝ cos^n α (the lobe of the modified Phong BRDF,
/// Lafortune & Willems 1994): solid-angle pdf (n + 1)/(2π) cos^n α.
#[inline]
pub fn sample_phong_lobe(u: Vec2, exponent: f32) -> Vec3 {
    let cos_a = u.x.powf(1.0 / (exponent + 1.0));
    let sin_a = (1.0 - cos_a * cos_a).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    vec3(sin_a * phi.cos(), sin_a * phi.sin(), cos_a)
}

/// Solid-angle density of [`sample_phong_lobe`] for a direction at `cos_alpha` to the lobe axis.
#[inline]
pub fn phong_lobe_pdf_w(cos_alpha: f32, exponent: f32) -> f32 {
    if cos_alpha <= 0.0 {
        return 0.0;
    }
    (exponent + 1.0) * 0.5 * FRAC_1_PI * cos_alpha.powf(exponent)
}

/// Inverse of [`sample_phong_lobe`].
pub fn invert_phong_lobe(w: Vec3, exponent: f32) -> Vec2 {
    let mut phi = w.y.atan2(w.x);
    if phi < 0.0 {
        phi += 2.0 * PI;
    }
    vec2(w.z.max(0.0).powf(exponent + 1.0), phi / (2.0 * PI))
}

/// Converts a solid-angle density at a point seen at distance² `dist2` under `cos_theta`
/// (angle between the direction and the receiving surface's normal) to an area density:
/// `pdf_a = pdf_w · |cos θ| / d²`. The one conversion between measures.
#[inline]
pub fn pdf_w_to_a(pdf_w: f32, dist2: f32, cos_theta: f32) -> f32 {
    pdf_w * cos_theta.abs() / dist2
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Pcg32;

    fn uniform2(r: &mut Pcg32) -> Vec2 {
        vec2(r.next_f32(), r.next_f32())
    }

    #[test]
    fn warps_invert_to_their_samples() {
        let mut r = Pcg32::new(11);
        for _ in 0..10_000 {
            let u = uniform2(&mut r);
            let checks = [
                invert_uniform_disk_concentric(sample_uniform_disk_concentric(u)),
                invert_cosine_hemisphere(sample_cosine_hemisphere(u)),
                invert_uniform_sphere(sample_uniform_sphere(u)),
                invert_uniform_cone(sample_uniform_cone(u, 0.3), 0.3),
                invert_uniform_triangle(sample_uniform_triangle(u)),
                invert_phong_lobe(sample_phong_lobe(u, 20.0), 20.0),
            ];
            for (i, back) in checks.iter().enumerate() {
                // Angles near the seam phi = 0 = 2π may wrap; compare on the torus.
                let d = (*back - u).abs();
                let d = vec2(d.x.min(1.0 - d.x), d.y.min(1.0 - d.y));
                assert!(d.max_element() < 2e-3, "warp {i}: {u} -> {back}");
            }
        }
    }

    /// Monte Carlo estimate of ∫ pdf dω over the sphere with uniform directions: must be 1.
    fn integrate_pdf_w(pdf: impl Fn(Vec3) -> f32) -> f64 {
        let mut r = Pcg32::new(5);
        let n = 400_000;
        let sum: f64 =
            (0..n).map(|_| pdf(sample_uniform_sphere(uniform2(&mut r))) as f64 / uniform_sphere_pdf_w() as f64).sum();
        sum / n as f64
    }

    #[test]
    fn directional_densities_integrate_to_one() {
        let cos = integrate_pdf_w(|w| cosine_hemisphere_pdf_w(w.z));
        let cone = integrate_pdf_w(|w| if w.z >= 0.5 { uniform_cone_pdf_w(0.5) } else { 0.0 });
        let phong = integrate_pdf_w(|w| phong_lobe_pdf_w(w.z, 4.0));
        for (name, v) in [("cosine", cos), ("cone", cone), ("phong", phong)] {
            assert!((v - 1.0).abs() < 0.02, "{name} integrates to {v}");
        }
    }
}
