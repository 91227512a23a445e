//! ⑦ Image-space filters applied to the gathered light: the discontinuity buffer.

pub mod discontinuity;

pub use discontinuity::{DiscontinuitySettings, Masks, PlaneLayout, filter as discontinuity_filter, filter_planes};
