//! Writers of the formats tiles are served in.

pub mod glb;
