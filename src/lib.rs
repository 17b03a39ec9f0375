//! terrastitch turns OpenStreetMap extracts and SRTM elevation tiles into seamless 3D map tiles.
//!
//! The data flows through the modules in this order: [`source`] (extracts and rasters) →
//! [`osm`] (the OSM model and its spatial index) → [`features`] (roads, water, buildings…) →
//! [`terrain`] (elevation between samples) → [`mesh`] (the ground triangulation with features
//! stitched in, extruded buildings) → [`output`] (glb) → [`cache`] → [`server`] and
//! [`offline`] (`seed`, `export`). [`render::render`] is the pure core from one tile's inputs
//! to its bytes; [`pipeline::make`] feeds it from the opened sources.

pub mod cache;
pub mod config;
pub mod elevation;
pub mod features;
pub mod format;
pub mod geodesy;
pub mod geometry;
pub mod mesh;
pub mod offline;
pub mod osm;
pub mod output;
pub mod panics;
pub mod provider;
pub mod render;
pub mod server;
pub mod source;
pub mod terrain;
pub mod tile;

pub use render::{render as render_tile, RenderSettings, RenderedTile};
pub use tile::TileId;
