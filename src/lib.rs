//! # mirage
//!
//! A physically based CPU renderer built around Metropolis Instant Radiosity (MIR,
//! Segovia, Iehl & Péroche 2007, papers/002).
//!
//! ```text
//! scene file ──load──► SceneDesc ──scene──► Scene ──accel──► BVH (single rays, 4/8-wide packets)
//!        ──path──► path vertices ──vpl──► VPL set ──gather──► image ──filter──► film ──► window / EXR
//!                                  └──offline──► pt | bdpt | pssmlt ───────────────────► film
//! ```
//!
//! Modules in flow order: [`load`] (files → [`load::SceneDesc`]), [`scene`] (validated
//! immutable [`scene::Scene`]), [`accel`] (the only user of obvhs), [`offline`] (reference
//! estimators), [`film`] (accumulation, pixel filters, metrics, tone mapping) and [`output`]
//! (EXR and PNG). Leaves: [`sampling`], [`bsdf`], [`color`].
#![deny(missing_docs)]

pub mod accel;
pub mod bsdf;
pub mod color;
pub mod film;
pub mod filter;
pub mod frame;
pub mod gather;
pub mod offline;
pub mod options;
pub mod output;
pub mod path;
pub mod render;
pub mod report;

pub mod load;

pub mod sampling;
pub mod scene;
pub mod simd;
pub mod stats;
pub mod view;
pub mod vpl;
