//! Writers of the formats tiles are served in.

pub mod glb;
pub mod quantized_mesh;
