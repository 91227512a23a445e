//! # mirage
//!
//! A physically based CPU renderer built around Metropolis Instant Radiosity (MIR,
//! Segovia, Iehl & Péroche 2007, papers/002).
//!
//! ```text
//! scene file ──load──► SceneDesc ──scene──► Scene ──accel──► BVH (single rays, 4/8-wide packets)
//!        ──path──► path vertices ──vpl──► VPL set ──gather──► image ──filter──► film ──► window / EXR
//!                                  └──offline──► pt | bdpt | pssmlt | mlt ─────────────► film
//! ```
//!
//! Modules (docs/design.md §1), each importing only those listed before it: the leaves
//! [`color`], [`sampling`], [`simd`], [`stats`], [`progress`], [`bsdf`], [`film`] (accumulation, pixel
//! filters, metrics, tone mapping) and [`filter`] (the discontinuity buffer, an image
//! operation); then the pipeline [`load`] (files → [`load::SceneDesc`]), [`scene`] (validated
//! immutable [`scene::Scene`]), [`accel`] (the BVH and ray queries; the only user of obvhs),
//! [`path`] (vertices, walks, connections), [`offline`] (pt, bdpt, pssmlt, mlt), [`vpl`] (VPL samplers
//! and the VPL-to-receiver kernels), [`gather`], [`frame`] (one VPL frame), [`output`] (EXR,
//! PNG); then the command line's [`options`], [`render`], [`report`] and the window, [`view`].
#![deny(missing_docs)]

// Leaves.
pub mod color;

pub mod sampling;

pub mod simd;

pub mod stats;

pub mod progress;

pub mod bsdf;

pub mod film;

pub mod filter;

// The pipeline.
pub mod load;

pub mod scene;

pub mod accel;

pub mod path;

pub mod offline;

pub mod vpl;

pub mod gather;

pub mod frame;

pub mod output;

// The command line and the window.
pub mod options;

pub mod render;

pub mod report;

pub mod view;
