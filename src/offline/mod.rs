//! Offline use: [`seed`] renders every tile of an area into the cache, [`export`] copies an
//! area's tiles out of it into an MBTiles file or a `z/x/y.glb` directory that any static file
//! server can serve. [`shared_seed`] seeds through the queue of a cluster sharing PostgreSQL,
//! with any number of workers on any number of machines.

pub mod export;
pub mod seed;
pub mod shared_seed;
