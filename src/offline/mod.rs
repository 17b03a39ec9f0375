//! Offline use: [`seed`] renders every tile of an area into the cache, [`export`] copies an
//! area's tiles out of it into an MBTiles file or a `z/x/y.glb` directory that any static file
//! server can serve.

pub mod export;
pub mod seed;
