//! Random walks that build camera and light sub-paths (Veach 1997 §10.2; papers/000 §3.3).
//!
//! Both walks record, for every vertex, the forward density of generating it and (once the
//! next vertex is sampled) the reverse density of generating it from the other end, in area
//! measure, so that MIS weights of every connection strategy can be computed later without
//! re-tracing anything. Russian roulette ends walks after [`RR_START`] bounces; its survival
//! probability enters `beta` but not the cached densities (MIS weights built from any
//! consistent set of densities still sum to one, so the estimator stays unbiased).

use glam::{Vec2, Vec3};

use super::vertex::{Vertex, VertexKind, shading_correction};
use crate::accel::{Accel, offset_origin, ray_offset};
use crate::bsdf::{Bsdf, TransportMode};
use crate::sampling::{Distribution1D, Sampler};
use crate::scene::{Ray, Scene};
use crate::stats::RayStats;

/// Bounces after which Russian roulette may end a walk.
pub const RR_START: usize = 3;

/// Builds a camera sub-path of at most `max_vertices` vertices for the camera ray through
/// `raster` (vertex 0 is the lens point).
pub fn camera_subpath(
    scene: &Scene,
    accel: &Accel,
    raster: Vec2,
    sampler: &mut impl Sampler,
    max_vertices: usize,
    path: &mut Vec<Vertex>,
    stats: &mut RayStats,
) {
    camera_walk(scene, accel, raster, sampler, max_vertices, true, path, stats);
}

/// [`camera_subpath`] without Russian roulette: the walk ends only at `max_vertices`, a miss or
/// absorption (for samplers that fix the path length, as PSSMLT's chains do: roulette would
/// only end paths they need).
pub fn camera_subpath_exact(
    scene: &Scene,
    accel: &Accel,
    raster: Vec2,
    sampler: &mut impl Sampler,
    max_vertices: usize,
    path: &mut Vec<Vertex>,
    stats: &mut RayStats,
) {
    camera_walk(scene, accel, raster, sampler, max_vertices, false, path, stats);
}

#[allow(clippy::too_many_arguments)]
fn camera_walk(
    scene: &Scene,
    accel: &Accel,
    raster: Vec2,
    sampler: &mut impl Sampler,
    max_vertices: usize,
    roulette: bool,
    path: &mut Vec<Vertex>,
    stats: &mut RayStats,
) {
    path.clear();
    if max_vertices == 0 {
        return;
    }
    let cam = &scene.camera;
    let ray = cam.generate_ray(raster, sampler.next_2d());
    let (pdf_pos, pdf_dir) = cam.pdf_we(ray.dir);
    path.push(Vertex::camera(ray.origin, cam.forward, Vec3::ONE, pdf_pos));
    let start = (ray, Vec3::ONE, pdf_dir);
    walk(scene, accel, start, sampler, max_vertices, TransportMode::Radiance, roulette, path, stats);
}

/// Builds a light sub-path of at most `max_vertices` vertices: a light chosen ∝ power, a point
/// and an emission direction on it, then a random walk.
pub fn light_subpath(
    scene: &Scene,
    accel: &Accel,
    sampler: &mut impl Sampler,
    max_vertices: usize,
    path: &mut Vec<Vertex>,
    stats: &mut RayStats,
) {
    light_subpath_with(scene, accel, &scene.lights.distribution, sampler, max_vertices, path, stats)
}

/// [`light_subpath`] with the light chosen by `dist` (a light-source CDF) instead of ∝ power;
/// the first vertex's density includes that choice.
pub fn light_subpath_with(
    scene: &Scene,
    accel: &Accel,
    dist: &Distribution1D,
    sampler: &mut impl Sampler,
    max_vertices: usize,
    path: &mut Vec<Vertex>,
    stats: &mut RayStats,
) {
    light_walk(scene, accel, dist, sampler, max_vertices, true, path, stats);
}

/// [`light_subpath`] without Russian roulette (see [`camera_subpath_exact`]).
pub fn light_subpath_exact(
    scene: &Scene,
    accel: &Accel,
    sampler: &mut impl Sampler,
    max_vertices: usize,
    path: &mut Vec<Vertex>,
    stats: &mut RayStats,
) {
    light_walk(scene, accel, &scene.lights.distribution, sampler, max_vertices, false, path, stats);
}

#[allow(clippy::too_many_arguments)]
fn light_walk(
    scene: &Scene,
    accel: &Accel,
    dist: &Distribution1D,
    sampler: &mut impl Sampler,
    max_vertices: usize,
    roulette: bool,
    path: &mut Vec<Vertex>,
    stats: &mut RayStats,
) {
    path.clear();
    if max_vertices == 0 {
        return;
    }
    let u_light = sampler.next_1d();
    let u_pos = sampler.next_2d();
    let u_dir = sampler.next_2d();
    let Some(es) = scene.sample_le_with(dist, u_light, u_pos, u_dir) else { return };
    if es.pdf_pos <= 0.0 || es.pdf_dir <= 0.0 || es.le == Vec3::ZERO {
        return;
    }
    if es.at_infinity {
        light_walk_from_infinity(scene, accel, dist, &es, sampler, max_vertices, roulette, path, stats);
        return;
    }
    let mut v = Vertex::light(scene, es.light, es.p, es.n, es.le, es.pdf_pos);
    v.delta = es.delta_pos;
    path.push(v);
    let cos = if es.n == Vec3::ZERO { 1.0 } else { es.n.dot(es.dir).abs() };
    let beta = es.le * (cos / (es.pdf_pos * es.pdf_dir));
    let origin =
        if es.n == Vec3::ZERO { es.p } else { es.p + es.n * ray_offset(es.p, &scene.mesh.corners(path[0].tri)) };
    let start = (Ray { origin, dir: es.dir }, beta, es.pdf_dir);
    walk(scene, accel, start, sampler, max_vertices, TransportMode::Importance, roulette, path, stats);
}

/// A light sub-path from a light at infinity (pbrt-v3 §16.3.2): the ray leaves the disk point
/// `es.p` along `es.dir`, carrying Le / (choice · disk density · direction density) = πR²·L /
/// (choice · p(ω)). The first vertex's density is the direction's over all the lights a ray
/// meets there (or the choice alone for a delta sun), the next one's the disk's 1/(πR²) times
/// its cosine: the measures [`Vertex::pdf_light_origin`] and [`Vertex::pdf_light`] use.
#[allow(clippy::too_many_arguments)]
fn light_walk_from_infinity(
    scene: &Scene,
    accel: &Accel,
    dist: &Distribution1D,
    es: &crate::scene::EmissionSample,
    sampler: &mut impl Sampler,
    max_vertices: usize,
    roulette: bool,
    path: &mut Vec<Vertex>,
    stats: &mut RayStats,
) {
    let wi = -es.dir;
    let delta = scene.lights.list[es.light as usize].is_delta();
    let pdf_origin = if delta { dist.pmf(es.light as usize) } else { scene.pdf_li_escaped_with(dist, wi) };
    let mut v = Vertex::at_infinity(es.light, es.p, wi, es.le, pdf_origin);
    v.delta = delta;
    path.push(v);
    let beta = es.le / (es.pdf_pos * es.pdf_dir);
    let start = (Ray { origin: es.p, dir: es.dir }, beta, es.pdf_dir);
    walk(scene, accel, start, sampler, max_vertices, TransportMode::Importance, roulette, path, stats);
    if path.len() > 1 {
        let r = scene.bounding_sphere().1;
        let v1 = &mut path[1];
        let cos = if v1.on_surface() { v1.ng.dot(wi).abs() } else { 1.0 };
        v1.pdf_fwd = cos / (std::f32::consts::PI * r * r);
    }
}

/// Extends `path` (whose last vertex emitted `ray` with solid-angle density `pdf_w`) by
/// tracing and sampling BSDFs until `max_vertices`, a miss, absorption or Russian roulette.
pub fn random_walk(
    scene: &Scene,
    accel: &Accel,
    ray: Ray,
    beta: Vec3,
    pdf_w: f32,
    sampler: &mut impl Sampler,
    max_vertices: usize,
    mode: TransportMode,
    path: &mut Vec<Vertex>,
    stats: &mut RayStats,
) {
    walk(scene, accel, (ray, beta, pdf_w), sampler, max_vertices, mode, true, path, stats);
}

/// [`random_walk`] from (ray, β, pdf_w), with or without Russian roulette.
#[allow(clippy::too_many_arguments)]
fn walk(
    scene: &Scene,
    accel: &Accel,
    (mut ray, mut beta, mut pdf_w): (Ray, Vec3, f32),
    sampler: &mut impl Sampler,
    max_vertices: usize,
    mode: TransportMode,
    roulette: bool,
    path: &mut Vec<Vertex>,
    stats: &mut RayStats,
) {
    let beta_start = beta.max_element().max(1e-30);
    while path.len() < max_vertices {
        stats.closest += 1;
        let Some(hit) = accel.intersect(ray.origin, ray.dir, f32::INFINITY) else {
            // A camera path that leaves the scene ends on the lights at infinity, if any.
            if mode == TransportMode::Radiance
                && let Some(&light) = scene.lights.escaped.first()
            {
                let prev = path.last().expect("walks start from a vertex");
                let p = scene.far_point(prev.p, ray.dir);
                path.push(Vertex::at_infinity(light, p, ray.dir, beta, pdf_w));
            }
            break;
        };
        let sp = scene.surface_point(hit.tri, hit.b1, hit.b2);
        let wo = -ray.dir;
        let material = scene.material_of(hit.tri);
        let bsdf = Bsdf::new(material.bsdf_kind(sp.uv, &scene.textures), sp.ns, sp.ng, wo);
        let prev = *path.last().expect("walks start from a vertex");
        let mut v = Vertex {
            kind: VertexKind::Surface,
            p: sp.p,
            ng: sp.ng,
            ns: bsdf.frame.n,
            uv: sp.uv,
            tri: hit.tri,
            light: scene.mesh.emitter[hit.tri as usize],
            wo,
            bsdf: Some(bsdf),
            beta,
            delta: false,
            pdf_fwd: 0.0,
            pdf_rev: 0.0,
            at_infinity: false,
        };
        v.pdf_fwd = prev.convert_density(pdf_w, &v);
        path.push(v);
        if path.len() >= max_vertices {
            break;
        }
        let u_lobe = sampler.next_1d();
        let u = sampler.next_2d();
        let Some(bs) = bsdf.sample(wo, u_lobe, u, mode) else { break };
        let mut pdf_rev_w = bsdf.pdf_w(bs.wi, wo);
        pdf_w = bs.pdf_w;
        if bs.delta {
            let last = path.len() - 1;
            path[last].delta = true;
            pdf_w = 0.0;
            pdf_rev_w = 0.0;
        }
        let mut scale = bs.f * (bsdf.abs_cos(bs.wi) / bs.pdf_w);
        if mode == TransportMode::Importance {
            scale *= shading_correction(&bsdf, wo, bs.wi);
        }
        beta *= scale;
        let n = path.len();
        let (head, tail) = path.split_at_mut(n - 1);
        head[n - 2].pdf_rev = tail[0].convert_density(pdf_rev_w, &head[n - 2]);
        if beta == Vec3::ZERO || !beta.is_finite() {
            break;
        }
        if roulette && n > RR_START {
            let q = (beta.max_element() / beta_start).min(0.95);
            if sampler.next_1d() >= q {
                break;
            }
            beta /= q;
        }
        let corners = scene.mesh.corners(hit.tri);
        ray = Ray { origin: offset_origin(&sp, &corners, bs.wi), dir: bs.wi };
    }
}
