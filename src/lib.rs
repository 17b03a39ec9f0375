//! terrastitch turns OpenStreetMap extracts and SRTM elevation tiles into seamless 3D map tiles.
//!
//! The layers, lowest first (each imports only those below it; ARCHITECTURE.md draws them):
//! [`tile`], [`geometry`], [`geodesy`], [`mod@format`], [`panics`], [`inflate`], [`budget`]
//! (value types, small mathematics, bounded decompression, memory budgets) → [`osm`] (the OSM model and its index) → [`features`] (the only reader of tags:
//! roads, water, buildings, bridges and tunnels as typed values) → [`terrain`] (SRTM rasters and
//! the approximations between samples) → [`elevation`] (the LP that settles structures and
//! roads) → [`mesh`] (the ground with features stitched in, buildings, structures) → [`output`]
//! (glb, quantized-mesh, 3D Tiles) → [`render`] (the pure core of one tile). Beside the core:
//! [`source`] reads files and downloads, [`cache`] stores keys and bytes, [`config`] is the
//! configuration, [`provider`] opens the inputs and makes a tile from them
//! ([`provider::pipeline::make`]), [`server`] and [`offline`] (`seed`, `export`) use it, and
//! [`cli`] is the command line over them all.

pub mod budget;
pub mod cache;
pub mod cli;
pub mod config;
pub mod elevation;
pub mod features;
pub mod format;
pub mod geodesy;
pub mod geoid;
pub mod geometry;
pub mod inflate;
pub mod mesh;
pub mod offline;
pub mod osm;
pub mod output;
pub mod panics;
pub mod parallel;
pub mod provider;
pub mod render;
pub mod server;
pub mod source;
pub mod terrain;
pub mod tile;

pub use render::{render as render_tile, RenderSettings, RenderedTile};
pub use tile::TileId;
