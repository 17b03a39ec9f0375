//! Terrain: an elevation for every point, approximated from the SRTM samples (thesis ch. 3).
//!
//! [`Mosaic`] holds the SRTM files around a tile as one grid of sites, so a tile that straddles
//! two files reads both and no method sees a cut. [`Interpolation`] chooses how points between
//! sites are approximated: local quadratic least squares (the default, §3.3), natural-neighbour
//! interpolation (§3.4), or bilinear interpolation as the cheap baseline. Every method computes a
//! point's elevation from the sites around it alone, in global coordinates, so the same point
//! gets the same value whichever tile asks.

use std::cell::Cell;

pub mod cell;
pub mod least_squares;
pub mod mosaic;
pub mod natural_neighbor;

pub use least_squares::LeastSquares;
pub use mosaic::Mosaic;
pub use natural_neighbor::NaturalNeighbor;

/// How elevations between SRTM samples are approximated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Interpolation {
    /// Bilinear within the four surrounding samples.
    Bilinear,
    /// Blended local quadratic least-squares fits (thesis §3.3).
    #[default]
    LeastSquares,
    /// Sibson's natural-neighbour interpolation (thesis §3.4).
    NaturalNeighbor,
}

enum Method<'a> {
    Bilinear,
    LeastSquares(Box<LeastSquares<'a>>),
    NaturalNeighbor(NaturalNeighbor<'a>),
}

/// The terrain surface as the mesh stage sees it. Holds per-site caches, so keep one per render.
pub struct TerrainModel<'a> {
    pub mosaic: &'a Mosaic,
    pub interpolation: Interpolation,
    method: Method<'a>,
    tiles_per_axis: f64,
    /// The last `v` read (its bits) and its latitude: points come along rows, and a normal's
    /// reads east and west of a vertex share their `v`.
    last_latitude: Cell<Option<(u64, f64)>>,
}

impl<'a> TerrainModel<'a> {
    pub fn new(mosaic: &'a Mosaic, interpolation: Interpolation, zoom: u8) -> TerrainModel<'a> {
        let method = match interpolation {
            Interpolation::Bilinear => Method::Bilinear,
            Interpolation::LeastSquares => {
                Method::LeastSquares(Box::new(LeastSquares::new(mosaic)))
            }
            Interpolation::NaturalNeighbor => Method::NaturalNeighbor(NaturalNeighbor::new(mosaic)),
        };
        TerrainModel {
            mosaic,
            interpolation,
            method,
            tiles_per_axis: f64::from(1u32 << zoom),
            last_latitude: Cell::new(None),
        }
    }

    /// The elevation in metres at a point in degrees, `None` where no file covers it.
    pub fn elevation(&self, lon: f64, lat: f64) -> Option<f64> {
        match &self.method {
            Method::Bilinear => self.mosaic.bilinear(lon, lat),
            Method::LeastSquares(ls) => ls.elevation(lon, lat),
            Method::NaturalNeighbor(nn) => nn.elevation(lon, lat),
        }
    }

    /// Elevation in metres at `[u, v]`; sea level where no file covers the point (the caller
    /// checks coverage before rendering).
    pub fn elevation_uv(&self, p: [f64; 2]) -> f64 {
        self.known_elevation_uv(p).unwrap_or(0.0)
    }

    /// Elevation in metres at `[u, v]`, `None` where no file covers the point.
    pub fn known_elevation_uv(&self, p: [f64; 2]) -> Option<f64> {
        let lon = crate::tile::u_to_lon(p[0], self.tiles_per_axis);
        self.elevation(lon, self.latitude(p[1]))
    }

    /// The latitude of `v`, in degrees.
    fn latitude(&self, v: f64) -> f64 {
        match self.last_latitude.get() {
            Some((bits, lat)) if bits == v.to_bits() => lat,
            _ => {
                let lat = crate::tile::v_to_lat(v, self.tiles_per_axis);
                self.last_latitude.set(Some((v.to_bits(), lat)));
                lat
            }
        }
    }

    /// Where the raster's samples lie inside a box of tile units.
    pub fn sample_positions_uv(&self, min: [f64; 2], max: [f64; 2]) -> Vec<[f64; 2]> {
        let n = self.tiles_per_axis;
        let west = crate::tile::u_to_lon(min[0], n);
        let east = crate::tile::u_to_lon(max[0], n);
        let north = crate::tile::v_to_lat(min[1], n);
        let south = crate::tile::v_to_lat(max[1], n);
        self.mosaic
            .samples_in(west, south, east, north)
            .into_iter()
            .map(|(lon, lat, _)| {
                let (u, v) = crate::tile::lon_lat_to_uv(lon, lat, n);
                [u, v]
            })
            .collect()
    }
}

/// An elevation in metres at any point in global tile units: the approximated terrain, or the
/// ground once features have settled it.
pub trait Elevation {
    fn elevation_uv(&self, p: [f64; 2]) -> f64;

    /// The elevation at `p` where the ground there is known (`None` where no SRTM file
    /// covers it).
    fn known_elevation_uv(&self, p: [f64; 2]) -> Option<f64> {
        Some(self.elevation_uv(p))
    }
}

impl Elevation for TerrainModel<'_> {
    fn elevation_uv(&self, p: [f64; 2]) -> f64 {
        TerrainModel::elevation_uv(self, p)
    }

    fn known_elevation_uv(&self, p: [f64; 2]) -> Option<f64> {
        TerrainModel::known_elevation_uv(self, p)
    }
}
