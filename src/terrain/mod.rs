//! Terrain: an elevation for every point of a tile, approximated from the SRTM samples.
//!
//! [`Mosaic`] holds the SRTM files a tile needs, so a tile that straddles two files reads both
//! and no method sees a cut. [`Interpolation`] chooses how points between samples are
//! approximated; bilinear interpolation within the four surrounding samples is the baseline.

use std::collections::BTreeMap;
use std::sync::Arc;

use crate::source::srtm::{CellId, SrtmTile};

/// How elevations between SRTM samples are approximated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Interpolation {
    /// Bilinear within the four surrounding samples.
    #[default]
    Bilinear,
}

/// The SRTM files around a tile.
#[derive(Debug, Clone, Default)]
pub struct Mosaic {
    tiles: BTreeMap<CellId, Arc<SrtmTile>>,
}

impl Mosaic {
    pub fn new(tiles: impl IntoIterator<Item = Arc<SrtmTile>>) -> Mosaic {
        Mosaic {
            tiles: tiles.into_iter().map(|t| (t.cell, t)).collect(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.tiles.is_empty()
    }

    /// The file that holds a point. A point on the edge between two files belongs to the one
    /// north/east of it; both hold the same samples along a shared edge, so the value agrees.
    fn tile_at(&self, lon: f64, lat: f64) -> Option<&SrtmTile> {
        let cell = CellId::containing(lon, lat);
        if let Some(tile) = self.tiles.get(&cell) {
            return Some(tile);
        }
        // On the north or east edge of the mosaic, the point's cell may be absent while the
        // file below/left of it still contains the point on its edge.
        let candidates = [
            CellId {
                lat: cell.lat - 1,
                ..cell
            },
            CellId {
                lon: cell.lon - 1,
                ..cell
            },
            CellId {
                lat: cell.lat - 1,
                lon: cell.lon - 1,
            },
        ];
        candidates
            .iter()
            .filter_map(|c| self.tiles.get(c))
            .find(|t| t.fractional_index(lon, lat).is_some())
            .map(|t| t.as_ref())
    }

    /// The elevation in metres at a point, or `None` where no file covers it.
    pub fn elevation(&self, interpolation: Interpolation, lon: f64, lat: f64) -> Option<f64> {
        let tile = self.tile_at(lon, lat)?;
        match interpolation {
            Interpolation::Bilinear => tile.bilinear(lon, lat),
        }
    }

    /// The SRTM samples that lie inside a box, with their positions (used for minima over areas).
    pub fn samples_in(&self, west: f64, south: f64, east: f64, north: f64) -> Vec<(f64, f64, f64)> {
        let mut out = Vec::new();
        for tile in self.tiles.values() {
            let steps = (tile.size - 1) as f64;
            let row_of = |lat: f64| (f64::from(tile.cell.lat) + 1.0 - lat) * steps;
            let column_of = |lon: f64| (lon - f64::from(tile.cell.lon)) * steps;
            let last = tile.size as f64 - 1.0;
            let r0 = row_of(north).ceil().max(0.0);
            let r1 = row_of(south).floor().min(last);
            let c0 = column_of(west).ceil().max(0.0);
            let c1 = column_of(east).floor().min(last);
            if r0 > r1 || c0 > c1 {
                continue;
            }
            for row in r0 as usize..=r1 as usize {
                for column in c0 as usize..=c1 as usize {
                    let (lon, lat) = tile.sample_position(row, column);
                    out.push((lon, lat, f64::from(tile.sample(row, column))));
                }
            }
        }
        out
    }
}

/// The terrain surface as the mesh stage sees it: elevations at points in global tile units.
#[derive(Debug, Clone, Copy)]
pub struct TerrainModel<'a> {
    pub mosaic: &'a Mosaic,
    pub interpolation: Interpolation,
    tiles_per_axis: f64,
}

impl<'a> TerrainModel<'a> {
    pub fn new(mosaic: &'a Mosaic, interpolation: Interpolation, zoom: u8) -> TerrainModel<'a> {
        TerrainModel {
            mosaic,
            interpolation,
            tiles_per_axis: f64::from(1u32 << zoom),
        }
    }

    /// Elevation in metres at `[u, v]`; sea level where no file covers the point (the caller
    /// checks coverage before rendering).
    pub fn elevation_uv(&self, p: [f64; 2]) -> f64 {
        let lon = crate::tile::u_to_lon(p[0], self.tiles_per_axis);
        let lat = crate::tile::v_to_lat(p[1], self.tiles_per_axis);
        self.mosaic
            .elevation(self.interpolation, lon, lat)
            .unwrap_or(0.0)
    }

    /// The raster samples inside a box of tile units, as `([u, v], elevation)`.
    pub fn samples_in_uv(&self, min: [f64; 2], max: [f64; 2]) -> Vec<([f64; 2], f64)> {
        let n = self.tiles_per_axis;
        let west = crate::tile::u_to_lon(min[0], n);
        let east = crate::tile::u_to_lon(max[0], n);
        let north = crate::tile::v_to_lat(min[1], n);
        let south = crate::tile::v_to_lat(max[1], n);
        self.mosaic
            .samples_in(west, south, east, north)
            .into_iter()
            .map(|(lon, lat, h)| {
                let (u, v) = crate::tile::lon_lat_to_uv(lon, lat, n);
                ([u, v], h)
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn flat(cell: CellId, height: f32) -> Arc<SrtmTile> {
        Arc::new(SrtmTile {
            cell,
            size: 3,
            heights: vec![height; 9],
        })
    }

    #[test]
    fn a_point_on_the_east_edge_of_the_mosaic_is_still_covered() {
        let mosaic = Mosaic::new([flat(CellId { lat: 48, lon: 9 }, 470.0)]);
        assert_eq!(
            mosaic.elevation(Interpolation::Bilinear, 10.0, 48.5),
            Some(470.0)
        );
        assert_eq!(mosaic.elevation(Interpolation::Bilinear, 10.2, 48.5), None);
    }

    #[test]
    fn reads_across_two_files() {
        let mosaic = Mosaic::new([
            flat(CellId { lat: 48, lon: 9 }, 470.0),
            flat(CellId { lat: 48, lon: 10 }, 480.0),
        ]);
        assert_eq!(
            mosaic.elevation(Interpolation::Bilinear, 9.9, 48.5),
            Some(470.0)
        );
        assert_eq!(
            mosaic.elevation(Interpolation::Bilinear, 10.1, 48.5),
            Some(480.0)
        );
    }
}
