//! The EGM96 geoid: how far mean sea level (what SRTM's heights are measured from) lies above
//! the WGS 84 ellipsoid (what globes and GPS measure from), by latitude and longitude.
//!
//! The grid is EGM96's 15-minute grid of undulations (721 × 1440 points, public domain, from
//! PROJ's `egm96_15.gtx`), embedded in centimetres (`src/geoid-egm96-15.bin`, written by
//! `scripts/egm96_grid.py`), read bilinearly as PROJ and CesiumJS read it. Nothing is
//! downloaded at run time.

use std::sync::OnceLock;

static GRID_BYTES: &[u8] = include_bytes!("geoid-egm96-15.bin");

/// Which surface a tile's heights are measured from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum VerticalDatum {
    /// SRTM's heights as they are, used as heights above the ellipsoid: tiles sit at sea level
    /// on a bare ellipsoid.
    #[default]
    Srtm,
    /// Heights above the ellipsoid: SRTM's plus the EGM96 undulation, so tiles sit on a terrain
    /// in ellipsoid heights (Cesium World Terrain, GPS).
    Egm96,
}

impl VerticalDatum {
    /// What to add to a height above mean sea level at a place to have it in this datum.
    pub fn offset(self, lon_deg: f64, lat_deg: f64) -> f64 {
        match self {
            VerticalDatum::Srtm => 0.0,
            VerticalDatum::Egm96 => undulation(lon_deg, lat_deg),
        }
    }
}

impl VerticalDatum {
    /// The lowest and highest offset over a box of longitudes and latitudes (degrees): the
    /// grid points of every cell the box meets bound what is read between them.
    pub fn offset_range(self, west: f64, south: f64, east: f64, north: f64) -> (f64, f64) {
        if self == VerticalDatum::Srtm {
            return (0.0, 0.0);
        }
        let grid = grid();
        let last_row = (grid.rows - 1) as f64;
        let row = |lat: f64| ((lat.clamp(-90.0, 90.0) - grid.south) / SPACING).clamp(0.0, last_row);
        let (r0, r1) = (row(south).floor() as usize, row(north).ceil() as usize);
        let c0 = ((west - grid.west) / SPACING).floor() as i64;
        let c1 = ((east - grid.west) / SPACING).ceil() as i64;
        let columns = grid.columns as i64;
        let mut range = (f64::INFINITY, f64::NEG_INFINITY);
        for r in r0..=r1 {
            for c in c0..=c1.min(c0 + columns) {
                let value = grid.values[r * grid.columns + c.rem_euclid(columns) as usize];
                let value = f64::from(value) / 100.0;
                range = (range.0.min(value), range.1.max(value));
            }
        }
        range
    }
}

struct Grid {
    rows: usize,
    columns: usize,
    south: f64,
    west: f64,
    /// Centimetres, rows from south to north.
    values: Vec<i16>,
}

/// Spacing of the grid, degrees.
const SPACING: f64 = 0.25;

fn grid() -> &'static Grid {
    static GRID: OnceLock<Grid> = OnceLock::new();
    GRID.get_or_init(|| {
        let word = |i: usize| {
            let b = &GRID_BYTES[i * 4..i * 4 + 4];
            [b[0], b[1], b[2], b[3]]
        };
        let rows = u32::from_le_bytes(word(0)) as usize;
        let columns = u32::from_le_bytes(word(1)) as usize;
        let values = GRID_BYTES[16..]
            .chunks_exact(2)
            .map(|b| i16::from_le_bytes([b[0], b[1]]))
            .collect::<Vec<_>>();
        debug_assert_eq!(values.len(), rows * columns);
        Grid {
            rows,
            columns,
            south: f64::from(i32::from_le_bytes(word(2))) / 100.0,
            west: f64::from(i32::from_le_bytes(word(3))) / 100.0,
            values,
        }
    })
}

/// The geoid's height above the WGS 84 ellipsoid at a place, metres (bilinear between the
/// grid's points; longitudes wrap, latitudes are clamped to ±90°).
pub fn undulation(lon_deg: f64, lat_deg: f64) -> f64 {
    let grid = grid();
    let row =
        ((lat_deg.clamp(-90.0, 90.0) - grid.south) / SPACING).clamp(0.0, (grid.rows - 1) as f64);
    let column = (lon_deg - grid.west).rem_euclid(360.0) / SPACING;
    let (r0, c0) = (row.floor() as usize, column.floor() as usize);
    let (r1, c1) = ((r0 + 1).min(grid.rows - 1), c0 + 1);
    let (fr, fc) = (row - r0 as f64, column - c0 as f64);
    let at =
        |r: usize, c: usize| f64::from(grid.values[r * grid.columns + c % grid.columns]) / 100.0;
    let south = at(r0, c0) * (1.0 - fc) + at(r0, c1) * fc;
    let north = at(r1, c0) * (1.0 - fc) + at(r1, c1) * fc;
    south * (1.0 - fr) + north * fr
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn undulations_match_published_values() {
        // NGA's published EGM96 check points (the 15-minute grid read bilinearly stays within
        // a few centimetres of the spherical harmonics there).
        for (lat, lon, expected) in [
            (38.628_155_6, 269.779_155_6 - 360.0, -31.628),
            (-14.621_717_2, 305.021_046_1 - 360.0, -2.969),
            (46.874_300_0, 102.448_779_6, -43.575),
            (-23.617_446_1, 133.874_712_2, 15.871),
            (38.625_473_0, 359.999_500_0 - 360.0, 50.066),
            (-0.466_1, 0.002_3, 17.329),
        ] {
            let n = undulation(lon, lat);
            assert!(
                (n - expected).abs() < 0.1,
                "{lat}, {lon}: {n} against {expected}"
            );
        }
    }

    #[test]
    fn longitudes_wrap_and_latitudes_clamp() {
        assert!((undulation(180.0, 10.0) - undulation(-180.0, 10.0)).abs() < 1e-9);
        assert!((undulation(179.9, 10.0) - undulation(-180.1, 10.0)).abs() < 1e-9);
        assert!(undulation(0.0, 95.0).is_finite());
        assert_eq!(VerticalDatum::Srtm.offset(7.42, 43.74), 0.0);
    }

    #[test]
    fn a_boxs_range_holds_every_undulation_read_inside_it() {
        let egm96 = VerticalDatum::Egm96;
        for (w, s, e, n) in [
            (7.38, 43.70, 7.50, 43.78),
            (-10.0, 35.0, 30.0, 60.0),
            (179.0, -20.0, 181.0, -10.0),
        ] {
            let (low, high) = egm96.offset_range(w, s, e, n);
            for i in 0..=40 {
                for j in 0..=40 {
                    let lon = w + (e - w) * f64::from(i) / 40.0;
                    let lat = s + (n - s) * f64::from(j) / 40.0;
                    let v = egm96.offset(lon, lat);
                    assert!(
                        low - 1e-9 <= v && v <= high + 1e-9,
                        "{lon}, {lat}: {v} not in {low}..{high}"
                    );
                }
            }
        }
        assert_eq!(
            VerticalDatum::Srtm.offset_range(0.0, 0.0, 1.0, 1.0),
            (0.0, 0.0)
        );
    }
}
