//! Elevation in GeoTIFF files — Copernicus GLO-30 and GLO-90 (`Copernicus_DSM_COG_10_N43_00_
//! E007_00_DEM.tif`, which covers beyond SRTM's 60°N), or any one-band GeoTIFF of a one-degree
//! cell in WGS 84 degrees — read with the `tiff` crate and put on the grid of an SRTM file of the
//! same cell: `size²` samples at whole steps of a degree over `size − 1`, both edges included.
//!
//! The raster is placed by its `ModelTiepoint` and `ModelPixelScale` tags; `GTRasterTypeGeoKey`
//! says whether the tie point is a pixel's corner (`PixelIsArea`, the default) or its centre
//! (`PixelIsPoint`, Copernicus). Copernicus tiles hold 3600 rows of pixel centres from the cell's
//! north edge down, without the south edge row (the next tile's first), and 3600 columns up to
//! 50° of latitude, fewer farther north (2400 to 60°, 1800 to 70°, …). A grid sample between
//! pixel centres is interpolated bilinearly; one past the last row or column takes the nearest
//! (the neighbouring file's first row is not read). `GDAL_NODATA`, NaN and infinities mark
//! voids. The plausibility rule of `.hgt` files holds here too: a raster with more than 1 % of
//! its samples outside −500 to 9000 m is not elevation data and is refused; the few such
//! samples of one that passes are voids.

use std::path::Path;

use tiff::decoder::{Decoder, DecodingResult};
use tiff::tags::Tag;

use crate::terrain::cell::{CellId, SrtmTile};

/// `GTRasterTypeGeoKey` and its value for a tie point at a pixel's centre.
const RASTER_TYPE_KEY: u16 = 1025;
const PIXEL_IS_POINT: u16 = 2;

/// Samples a side of the grids of SRTM's 1″ and 3″ files.
const SAMPLES_1_ARCSEC: usize = 3601;
const SAMPLES_3_ARCSEC: usize = 1201;

/// Why a GeoTIFF could not be read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GeoTiffError {
    pub path: std::path::PathBuf,
    pub report: String,
}

/// Where the raster lies: the centre of pixel (0, 0) and the step between pixels, degrees.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Placement {
    west: f64,
    north: f64,
    step_x: f64,
    step_y: f64,
}

/// The grid of `cell` from a GeoTIFF, with its count of voids (filled).
pub fn read(cell: CellId, path: &Path) -> Result<(SrtmTile, usize), GeoTiffError> {
    let bad = |report: String| GeoTiffError {
        path: path.to_path_buf(),
        report,
    };
    let file = std::fs::File::open(path).map_err(|e| bad(e.to_string()))?;
    let mut decoder =
        Decoder::new(std::io::BufReader::new(file)).map_err(|e| bad(e.to_string()))?;
    let (width, height) = decoder.dimensions().map_err(|e| bad(e.to_string()))?;
    let placement = placement(&mut decoder).map_err(bad)?;
    let nodata = nodata(&mut decoder);
    let image = decoder.read_image().map_err(|e| bad(e.to_string()))?;
    let pixels =
        as_f32(image).ok_or_else(|| bad("its samples are not one band of numbers".into()))?;
    let pixels = plausible(pixels, nodata).map_err(bad)?;
    let (width, height) = (width as usize, height as usize);
    if pixels.len() != width * height {
        return Err(bad(format!(
            "it holds {} samples for {width} × {height} pixels (one band expected)",
            pixels.len()
        )));
    }
    let raster = Raster {
        pixels,
        width,
        height,
        placement,
    };
    raster.check_covers(cell).map_err(bad)?;
    let size = match placement.step_y <= 1.5 / 3600.0 {
        true => SAMPLES_1_ARCSEC,
        false => SAMPLES_3_ARCSEC,
    };
    let samples = raster.resampled(cell, size);
    let voids = samples.iter().filter(|h| h.is_nan()).count();
    let heights = super::voids::fill_nan_voids(samples, size)
        .ok_or_else(|| bad("it holds only voids over the cell".to_string()))?;
    Ok((
        SrtmTile {
            cell,
            size,
            heights,
        },
        voids,
    ))
}

fn placement<R: std::io::Read + std::io::Seek>(
    decoder: &mut Decoder<R>,
) -> Result<Placement, String> {
    let numbers = |decoder: &mut Decoder<R>, tag: Tag, name: &str| -> Result<Vec<f64>, String> {
        decoder
            .find_tag(tag)
            .map_err(|e| e.to_string())?
            .ok_or_else(|| format!("it has no {name} tag: it is not a GeoTIFF"))?
            .into_f64_vec()
            .map_err(|e| e.to_string())
    };
    let scale = numbers(decoder, Tag::ModelPixelScaleTag, "ModelPixelScale")?;
    let tie = numbers(decoder, Tag::ModelTiepointTag, "ModelTiepoint")?;
    let (&[step_x, step_y, ..], &[i, j, _, x, y, ..]) = (scale.as_slice(), tie.as_slice()) else {
        return Err("its ModelPixelScale or ModelTiepoint tag is short".to_string());
    };
    if !(step_x > 0.0 && step_y > 0.0 && step_x < 1.0 && step_y < 1.0) {
        return Err(format!(
            "its pixels measure {step_x} × {step_y}: not a grid in degrees"
        ));
    }
    let keys = decoder
        .find_tag(Tag::GeoKeyDirectoryTag)
        .ok()
        .flatten()
        .and_then(|v| v.into_u16_vec().ok())
        .unwrap_or_default();
    let point = keys
        .chunks_exact(4)
        .skip(1)
        .any(|key| key[0] == RASTER_TYPE_KEY && key[3] == PIXEL_IS_POINT);
    // The tie point names raster position (i, j); a corner is half a pixel from the centre.
    let half = if point { 0.0 } else { 0.5 };
    Ok(Placement {
        west: x + (half - i) * step_x,
        north: y - (half - j) * step_y,
        step_x,
        step_y,
    })
}

fn nodata<R: std::io::Read + std::io::Seek>(decoder: &mut Decoder<R>) -> Option<f32> {
    let text = decoder
        .find_tag(Tag::GdalNodata)
        .ok()
        .flatten()?
        .into_string()
        .ok()?;
    text.trim_matches(char::from(0)).trim().parse::<f32>().ok()
}

/// The samples with every void as NaN: `nodata`, numbers that are not finite, and heights
/// outside [`super::voids::PLAUSIBLE_M`] — unless those are more than
/// [`super::voids::IMPLAUSIBLE_SHARE`] of the samples, when the raster is not elevation data.
fn plausible(mut pixels: Vec<f32>, nodata: Option<f32>) -> Result<Vec<f32>, String> {
    let (low, high) = super::voids::PLAUSIBLE_M;
    let range = f32::from(low)..=f32::from(high);
    let mut outside = 0usize;
    for value in pixels.iter_mut() {
        if Some(*value) == nodata || !value.is_finite() {
            *value = f32::NAN;
        } else if !range.contains(value) {
            outside += 1;
            *value = f32::NAN;
        }
    }
    let share = outside as f64 / pixels.len().max(1) as f64;
    match share > super::voids::IMPLAUSIBLE_SHARE {
        true => Err(format!(
            "it is not elevation data: {:.1} % of its samples lie outside {low} to {high} m",
            share * 100.0
        )),
        false => Ok(pixels),
    }
}

/// The samples as heights; `None` for a kind that is not one of numbers.
fn as_f32(image: DecodingResult) -> Option<Vec<f32>> {
    Some(match image {
        DecodingResult::F32(v) => v,
        DecodingResult::F64(v) => v.into_iter().map(|h| h as f32).collect(),
        DecodingResult::I16(v) => v.into_iter().map(f32::from).collect(),
        DecodingResult::U16(v) => v.into_iter().map(f32::from).collect(),
        DecodingResult::I32(v) => v.into_iter().map(|h| h as f32).collect(),
        DecodingResult::I8(v) => v.into_iter().map(f32::from).collect(),
        DecodingResult::U8(v) => v.into_iter().map(f32::from).collect(),
        _ => return None,
    })
}

struct Raster {
    pixels: Vec<f32>,
    width: usize,
    height: usize,
    placement: Placement,
}

impl Raster {
    /// The raster must span the cell, to within a pixel at each edge (its last row or column
    /// may stop a pixel short: the next file holds that edge).
    fn check_covers(&self, cell: CellId) -> Result<(), String> {
        let p = self.placement;
        let east = p.west + (self.width - 1) as f64 * p.step_x;
        let south = p.north - (self.height - 1) as f64 * p.step_y;
        let (west_edge, south_edge) = (f64::from(cell.lon), f64::from(cell.lat));
        let spans = p.west <= west_edge + p.step_x * 0.5
            && east >= west_edge + 1.0 - p.step_x * 1.5
            && p.north >= south_edge + 1.0 - p.step_y * 0.5
            && south <= south_edge + p.step_y * 1.5;
        match spans {
            true => Ok(()),
            false => Err(format!(
                "its pixel centres run from {:.4}°E to {east:.4}°E and {south:.4}°N to {:.4}°N, \
                 not over the cell {}°N {}°E its name gives",
                p.west, p.north, cell.lat, cell.lon
            )),
        }
    }

    /// The pixel at (`column`, `row`), NaN for a void.
    fn pixel(&self, column: usize, row: usize) -> f32 {
        self.pixels[row * self.width + column]
    }

    /// The grid of `cell` with `size` samples a side, row 0 north; NaN where a void reaches.
    fn resampled(&self, cell: CellId, size: usize) -> Vec<f32> {
        let p = self.placement;
        let steps = (size - 1) as f64;
        let (last_x, last_y) = ((self.width - 1) as f64, (self.height - 1) as f64);
        let mut samples = Vec::with_capacity(size * size);
        for row in 0..size {
            let lat = f64::from(cell.lat) + 1.0 - row as f64 / steps;
            let y = ((p.north - lat) / p.step_y).clamp(0.0, last_y);
            for column in 0..size {
                let lon = f64::from(cell.lon) + column as f64 / steps;
                let x = ((lon - p.west) / p.step_x).clamp(0.0, last_x);
                samples.push(self.bilinear(x, y));
            }
        }
        samples
    }

    fn bilinear(&self, x: f64, y: f64) -> f32 {
        // Positions within a millionth of a pixel of a centre take it as it is.
        let snap = |t: f64| match (t - t.round()).abs() < 1e-6 {
            true => t.round(),
            false => t,
        };
        let (x, y) = (snap(x), snap(y));
        let (x0, y0) = (x.floor() as usize, y.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(self.width - 1), (y0 + 1).min(self.height - 1));
        let (fx, fy) = (x - x0 as f64, y - y0 as f64);
        let corner = |c: usize, r: usize, weight: f64| -> f64 {
            match weight == 0.0 {
                true => 0.0,
                false => weight * f64::from(self.pixel(c, r)),
            }
        };
        let value = corner(x0, y0, (1.0 - fx) * (1.0 - fy))
            + corner(x1, y0, fx * (1.0 - fy))
            + corner(x0, y1, (1.0 - fx) * fy)
            + corner(x1, y1, fx * fy);
        value as f32
    }
}

/// The cell a GeoTIFF's name gives: `N43E007.tif`, or Copernicus's
/// `Copernicus_DSM_COG_10_N43_00_E007_00_DEM.tif`.
pub fn cell_of_name(name: &str) -> Option<CellId> {
    let lower = name.to_ascii_lowercase();
    let stem = lower
        .strip_suffix(".tif")
        .or_else(|| lower.strip_suffix(".tiff"))?;
    let compact = stem.replace("_00", "").replace('_', "");
    let bytes = compact.as_bytes();
    (0..bytes.len()).find_map(|at| {
        let part = compact.get(at..at + 7)?;
        matches!(bytes[at], b'n' | b's')
            .then(|| CellId::from_name(part))
            .flatten()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn copernicus_and_plain_names_give_their_cell() {
        let cell = CellId { lat: 43, lon: 7 };
        assert_eq!(
            cell_of_name("Copernicus_DSM_COG_10_N43_00_E007_00_DEM.tif"),
            Some(cell)
        );
        assert_eq!(cell_of_name("N43E007.tif"), Some(cell));
        assert_eq!(
            cell_of_name("Copernicus_DSM_COG_30_S01_00_W072_00_DEM.tif"),
            Some(CellId { lat: -1, lon: -72 })
        );
        assert_eq!(cell_of_name("N43E007.hgt"), None);
        assert_eq!(cell_of_name("landcover.tif"), None);
    }

    fn raster(pixels: Vec<f32>, width: usize, placement: Placement) -> Raster {
        let height = pixels.len() / width;
        Raster {
            pixels: plausible(pixels, Some(-32767.0)).unwrap(),
            width,
            height,
            placement,
        }
    }

    #[test]
    fn pixel_centres_on_the_grid_are_taken_as_they_are_and_the_missing_edge_repeats() {
        // A cell of 2 × 2 pixels, centres at the cell's north-west corner and half way.
        let cell = CellId { lat: 0, lon: 0 };
        let placement = Placement {
            west: 0.0,
            north: 1.0,
            step_x: 0.5,
            step_y: 0.5,
        };
        let r = raster(vec![1.0, 2.0, 3.0, 4.0], 2, placement);
        assert!(r.check_covers(cell).is_ok());
        let grid = r.resampled(cell, 3);
        assert_eq!(grid, vec![1.0, 2.0, 2.0, 3.0, 4.0, 4.0, 3.0, 4.0, 4.0]);
        // Between centres, the blend; a void spreads to the samples it weighs in.
        let r = raster(vec![0.0, 10.0, -32767.0, 10.0], 2, placement);
        let grid = r.resampled(cell, 5);
        assert_eq!(grid[1], 5.0);
        assert!(grid[5].is_nan() && grid[6].is_nan());
        assert_eq!(grid[4], 10.0);
    }

    #[test]
    fn a_raster_elsewhere_than_its_name_says_is_refused() {
        let placement = Placement {
            west: 5.0,
            north: 44.0,
            step_x: 0.5,
            step_y: 0.5,
        };
        let r = raster(vec![1.0; 4], 2, placement);
        let error = r.check_covers(CellId { lat: 43, lon: 7 }).unwrap_err();
        assert!(error.contains("43°N 7°E"), "{error}");
    }

    #[test]
    fn numbers_that_are_not_heights_are_voids_and_many_refuse_the_raster() {
        // A few: voids among heights.
        let mut pixels = vec![100.0f32; 1000];
        pixels[1] = f32::INFINITY;
        pixels[2] = f32::NAN;
        pixels[3] = 1e30;
        pixels[4] = -1e6;
        let settled = plausible(pixels, None).unwrap();
        assert!(settled[1..5].iter().all(|h| h.is_nan()));
        assert_eq!(settled[0], 100.0);
        // More than 1 %: not elevation data.
        for bad in [1e30f32, -1e6] {
            let mut pixels = vec![100.0f32; 1000];
            pixels[..11].fill(bad);
            let error = plausible(pixels, None).unwrap_err();
            assert!(
                error.contains("1.1 % of its samples lie outside -500 to 9000 m"),
                "{error}"
            );
        }
        // Infinities are voids, however many: a raster of nothing else holds only voids.
        let settled = plausible(vec![f32::INFINITY; 100], None).unwrap();
        assert!(settled.iter().all(|h| h.is_nan()));
    }
}
