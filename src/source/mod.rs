//! Getting data: OSM extracts read into the OSM model ([`osm_pbf`]), SRTM files decoded into
//! rasters ([`srtm`]), and either downloaded from configured URLs ([`fetch`]). Files and the
//! network are all it knows: what the data is for is decided above it.

pub mod external_sort;
pub mod fetch;
pub mod geotiff;
pub mod node_locations;
pub mod osc;
pub mod osm_pbf;
pub mod replication;
pub mod srtm;
pub mod store;
pub mod voids;
