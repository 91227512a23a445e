//! ④ Path space: vertices with cached densities, camera and light random walks, connections
//! of sub-paths and their MIS weights. Shared by the offline bidirectional modes and by the VPL
//! samplers (a VPL is the end of a light sub-path; MIR's chain mutates complete paths built from
//! these pieces).

pub mod connect;
pub mod vertex;
pub mod walk;

pub use connect::{Connection, connect, mis_weight, unoccluded};
pub use vertex::{NO_TRI, Vertex, VertexKind, geometry, shading_correction};
pub use walk::{
    RR_START, camera_subpath, camera_subpath_exact, light_subpath, light_subpath_exact, light_subpath_with, random_walk,
};
