//! Offline use: [`seed`] renders every tile of an area into the cache, [`export`] copies an
//! area's tiles out of it into an MBTiles file or a `z/x/y.glb` directory that any static file
//! server can serve. A seed works through its coordinator's queue: in memory for a store of its
//! own, the cluster's for a PostgreSQL store, with any number of workers on any number of
//! machines.

pub mod export;
pub mod seed;
