//! Bidirectional path tracing (`--mode bdpt`, Veach 1997 ch. 10; papers/000 §3.3): for every
//! pixel sample one camera sub-path and one light sub-path are built and every strategy (s, t)
//! is evaluated and combined with the power heuristic. Strategies with t = 1 (light tracing)
//! land on arbitrary pixels and are splatted (papers/001 Appendix A); the camera's importance is
//! normalised so splats and pixel samples share one scale.

use std::cell::RefCell;

use glam::{Vec2, Vec3};

use crate::accel::Accel;
use crate::film::{AovSample, FilmTile};
use crate::path::{Vertex, camera_subpath, connect, light_subpath};
use crate::sampling::Sampler;
use crate::scene::Scene;
use crate::stats::RayStats;

/// Restricts a render to some strategies, for diagnosing MIS (`--debug-strategy s,t`) and
/// for tests (all t = 1 strategies: light tracing).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StrategyFilter {
    /// Only this number of light vertices, when set.
    pub s: Option<usize>,
    /// Only this number of camera vertices, when set.
    pub t: Option<usize>,
    /// Multiply by the MIS weight (weighted) or not (unweighted).
    pub weighted: bool,
}

impl StrategyFilter {
    fn admits(&self, s: usize, t: usize) -> bool {
        self.s.is_none_or(|x| x == s) && self.t.is_none_or(|x| x == t)
    }
}

/// Which strategies and path lengths contribute.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BdptOptions {
    /// Maximum number of scattering events (s + t − 2 ≤ max_depth).
    pub max_depth: u32,
    /// Only this strategy, when set.
    pub only: Option<StrategyFilter>,
    /// Only paths with this many edges (s + t − 1), when set.
    pub path_edges: Option<usize>,
}

thread_local! {
    static PATHS: RefCell<(Vec<Vertex>, Vec<Vertex>)> = const { RefCell::new((Vec::new(), Vec::new())) };
}

/// One BDPT sample for the camera ray through `raster`: returns the radiance of all strategies
/// with t ≥ 2 and pushes the t = 1 splats into `tile`.
pub fn sample(
    scene: &Scene,
    accel: &Accel,
    raster: Vec2,
    sampler: &mut impl Sampler,
    opts: &BdptOptions,
    tile: &mut FilmTile,
    stats: &mut RayStats,
) -> (Vec3, AovSample) {
    PATHS.with(|paths| {
        let (camera, light) = &mut *paths.borrow_mut();
        let max_depth = opts.max_depth as usize;
        camera_subpath(scene, accel, raster, sampler, max_depth + 2, camera, stats);
        light_subpath(scene, accel, sampler, max_depth + 1, light, stats);
        let aov = match camera.get(1).and_then(|v| v.bsdf.map(|b| (v, b))) {
            Some((v, b)) => AovSample {
                albedo: b.albedo(),
                normal: b.frame.n,
                depth: (v.p - camera[0].p).length(),
                ..Default::default()
            },
            None => AovSample::default(),
        };
        let mut l = Vec3::ZERO;
        for t in 1..=camera.len() {
            for s in 0..=light.len() {
                let depth = s as i64 + t as i64 - 2;
                if depth < 0 || depth > max_depth as i64 || (s == 1 && t == 1) {
                    continue;
                }
                if let Some(edges) = opts.path_edges
                    && s + t - 1 != edges
                {
                    continue;
                }
                if let Some(f) = opts.only
                    && !f.admits(s, t)
                {
                    continue;
                }
                let c = connect(scene, accel, light, camera, s, t, sampler, stats);
                let value = match opts.only {
                    Some(StrategyFilter { weighted: false, .. }) => c.unweighted,
                    _ => c.weighted(),
                };
                if value == Vec3::ZERO || !value.is_finite() {
                    continue;
                }
                match c.raster {
                    Some(r) => tile.splats.push((r, value)),
                    None => l += value,
                }
            }
        }
        (l, aov)
    })
}
