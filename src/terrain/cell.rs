//! One SRTM cell as a raster: the integer-degree cell a file covers and its decoded samples.
//! The raster knows nothing of files; `source::srtm` reads them into it.

/// The integer degree cell a file covers, named by its south-west corner.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct CellId {
    pub lat: i32,
    pub lon: i32,
}

impl CellId {
    /// The cell that contains a point (a point on a cell edge belongs to the cell north/east of it).
    pub fn containing(lon: f64, lat: f64) -> CellId {
        CellId {
            lat: lat.floor() as i32,
            lon: lon.floor() as i32,
        }
    }

    /// Parses a file stem such as `N43E007` or `S12W071`.
    pub fn from_name(stem: &str) -> Option<CellId> {
        let bytes = stem.as_bytes();
        if bytes.len() != 7 {
            return None;
        }
        let lat_sign = match bytes[0].to_ascii_uppercase() {
            b'N' => 1,
            b'S' => -1,
            _ => return None,
        };
        let lon_sign = match bytes[3].to_ascii_uppercase() {
            b'E' => 1,
            b'W' => -1,
            _ => return None,
        };
        let lat: i32 = stem.get(1..3)?.parse().ok()?;
        let lon: i32 = stem.get(4..7)?.parse().ok()?;
        if lat > 90 || lon > 180 {
            return None;
        }
        Some(CellId {
            lat: lat_sign * lat,
            lon: lon_sign * lon,
        })
    }

    /// The conventional file stem, e.g. `N43E007`.
    pub fn name(self) -> String {
        format!(
            "{}{:02}{}{:03}",
            if self.lat >= 0 { 'N' } else { 'S' },
            self.lat.abs(),
            if self.lon >= 0 { 'E' } else { 'W' },
            self.lon.abs()
        )
    }
}

/// One decoded SRTM file, voids filled.
#[derive(Debug, Clone)]
pub struct SrtmTile {
    pub cell: CellId,
    /// Samples per side (1201 or 3601).
    pub size: usize,
    /// Row-major, row 0 north, in metres.
    pub heights: Vec<f32>,
}

impl SrtmTile {
    /// The sample at `row`, `column` (row 0 north).
    pub fn sample(&self, row: usize, column: usize) -> f32 {
        self.heights[row * self.size + column]
    }

    /// Bilinear interpolation at a point inside the cell; `None` outside it.
    pub fn bilinear(&self, lon: f64, lat: f64) -> Option<f64> {
        let (row, column) = self.fractional_index(lon, lat)?;
        let last = self.size - 1;
        let r0 = (row.floor() as usize).min(last - 1);
        let c0 = (column.floor() as usize).min(last - 1);
        let fr = row - r0 as f64;
        let fc = column - c0 as f64;
        let h = |r: usize, c: usize| f64::from(self.sample(r, c));
        let north = h(r0, c0) * (1.0 - fc) + h(r0, c0 + 1) * fc;
        let south = h(r0 + 1, c0) * (1.0 - fc) + h(r0 + 1, c0 + 1) * fc;
        Some(north * (1.0 - fr) + south * fr)
    }

    /// Fractional (row, column) of a point, `None` if it lies outside the cell.
    pub fn fractional_index(&self, lon: f64, lat: f64) -> Option<(f64, f64)> {
        let steps = (self.size - 1) as f64;
        let row = (f64::from(self.cell.lat) + 1.0 - lat) * steps;
        let column = (lon - f64::from(self.cell.lon)) * steps;
        let range = -1e-9..=steps + 1e-9;
        (range.contains(&row) && range.contains(&column))
            .then(|| (row.clamp(0.0, steps), column.clamp(0.0, steps)))
    }

    /// Longitude and latitude of a sample.
    pub fn sample_position(&self, row: usize, column: usize) -> (f64, f64) {
        let steps = (self.size - 1) as f64;
        (
            f64::from(self.cell.lon) + column as f64 / steps,
            f64::from(self.cell.lat) + 1.0 - row as f64 / steps,
        )
    }
}
