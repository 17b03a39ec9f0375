//! Writers of the formats tiles are served in.

pub mod debug;
pub mod enu;
pub mod glb;
pub mod layer;
pub mod png;
pub mod quantized_mesh;
pub mod tileset;
