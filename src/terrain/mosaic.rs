//! The SRTM files around a tile, read together so that no method sees a cut where two files
//! meet, and addressed as one grid of sites.

use std::collections::BTreeMap;
use std::sync::Arc;

use super::cell::{CellId, SrtmTile};

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

    /// Bilinear interpolation at a point, or `None` where no file covers it.
    pub fn bilinear(&self, lon: f64, lat: f64) -> Option<f64> {
        self.tile_at(lon, lat)?.bilinear(lon, lat)
    }

    /// Intervals per degree of the file that holds a point (1200 or 3600).
    pub fn steps_at(&self, lon: f64, lat: f64) -> Option<i64> {
        self.tile_at(lon, lat).map(|t| (t.size - 1) as i64)
    }

    /// The sample at the grid site `(lat_step, lon_step) / steps` degrees, from whichever file
    /// holds it (files share their edge samples). A file of another resolution answers with a
    /// bilinear value at the site's position.
    pub fn site(&self, steps: i64, lat_step: i64, lon_step: i64) -> Option<f64> {
        let lat_cell = lat_step.div_euclid(steps) as i32;
        let lon_cell = lon_step.div_euclid(steps) as i32;
        let candidates = [
            (lat_cell, lon_cell),
            (lat_cell - 1, lon_cell),
            (lat_cell, lon_cell - 1),
            (lat_cell - 1, lon_cell - 1),
        ];
        for (lat, lon) in candidates {
            let Some(tile) = self.tiles.get(&CellId { lat, lon }) else {
                continue;
            };
            let tile_steps = (tile.size - 1) as i64;
            if tile_steps == steps {
                let row = (i64::from(lat) + 1) * steps - lat_step;
                let column = lon_step - i64::from(lon) * steps;
                if (0..=steps).contains(&row) && (0..=steps).contains(&column) {
                    return Some(f64::from(tile.sample(row as usize, column as usize)));
                }
            } else {
                let (lon_deg, lat_deg) = (
                    lon_step as f64 / steps as f64,
                    lat_step as f64 / steps as f64,
                );
                if let Some(value) = tile.bilinear(lon_deg, lat_deg) {
                    return Some(value);
                }
            }
        }
        None
    }

    /// The lowest and highest SRTM samples inside a box, reading at most about `budget`
    /// samples over all the files it spans (every k-th row and column of a large box: its
    /// extremes may then be missed by the height of the ground between read samples); `None`
    /// where no file covers the box.
    pub fn height_range(
        &self,
        west: f64,
        south: f64,
        east: f64,
        north: f64,
        budget: usize,
    ) -> Option<(f64, f64)> {
        // The rows and columns of each file inside the box.
        let windows: Vec<(&SrtmTile, [usize; 4])> = self
            .tiles
            .values()
            .filter_map(|tile| {
                let steps = (tile.size - 1) as f64;
                let last = tile.size as f64 - 1.0;
                let r0 = ((f64::from(tile.cell.lat) + 1.0 - north) * steps)
                    .floor()
                    .max(0.0);
                let r1 = ((f64::from(tile.cell.lat) + 1.0 - south) * steps)
                    .ceil()
                    .min(last);
                let c0 = ((west - f64::from(tile.cell.lon)) * steps).floor().max(0.0);
                let c1 = ((east - f64::from(tile.cell.lon)) * steps).ceil().min(last);
                (r0 <= r1 && c0 <= c1).then_some((&**tile, [r0, r1, c0, c1].map(|v| v as usize)))
            })
            .collect();
        let total: usize = windows
            .iter()
            .map(|(_, [r0, r1, c0, c1])| (r1 - r0 + 1) * (c1 - c0 + 1))
            .sum();
        let stride = (total as f64 / budget.max(1) as f64).sqrt().ceil().max(1.0) as usize;
        let mut range: Option<(f64, f64)> = None;
        for (tile, [r0, r1, c0, c1]) in windows {
            for row in (r0..=r1).step_by(stride) {
                for column in (c0..=c1).step_by(stride) {
                    let h = f64::from(tile.sample(row, column));
                    range = Some(match range {
                        Some((low, high)) => (low.min(h), high.max(h)),
                        None => (h, h),
                    });
                }
            }
        }
        range
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

/// A 3″ file for N43E007 whose samples follow `f(row, column)`, for tests.
#[cfg(test)]
pub(crate) fn synthetic(f: impl Fn(f64, f64) -> f64) -> Mosaic {
    let size = 1201;
    let mut heights = Vec::with_capacity(size * size);
    for row in 0..size {
        for column in 0..size {
            heights.push(f(row as f64, column as f64) as f32);
        }
    }
    Mosaic::new([Arc::new(SrtmTile {
        cell: CellId { lat: 43, lon: 7 },
        size,
        heights,
    })])
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
        assert_eq!(mosaic.bilinear(10.0, 48.5), Some(470.0));
        assert_eq!(mosaic.bilinear(10.2, 48.5), None);
    }

    #[test]
    fn reads_across_two_files() {
        let mosaic = Mosaic::new([
            flat(CellId { lat: 48, lon: 9 }, 470.0),
            flat(CellId { lat: 48, lon: 10 }, 480.0),
        ]);
        assert_eq!(mosaic.bilinear(9.9, 48.5), Some(470.0));
        assert_eq!(mosaic.bilinear(10.1, 48.5), Some(480.0));
    }
}
