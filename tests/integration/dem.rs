//! Elevation from GeoTIFF files laid out as Copernicus's (pixel centres from the cell's
//! north-west corner, the south row and east column left to the neighbours, `PixelIsPoint`,
//! deflate), written here from the bundled SRTM file: the same heights give the same tiles, and a
//! void-free file takes precedence over an SRTM file with voids in the same cell.

use crate::common;

use std::path::{Path, PathBuf};

use common::{render_in_process, repo, sample_osm};
use terrastitch::source::srtm::{SrtmDirectory, VOID};
use terrastitch::terrain::cell::CellId;
use tiff::encoder::{colortype, Compression, DeflateLevel, TiffEncoder};
use tiff::tags::Tag;

const CELL: CellId = CellId { lat: 43, lon: 7 };
/// A tile on Monaco's steep coast, far inside the cell.
const TILE: &str = "14/8529/5974";

/// The bundled cell's heights, voids filled, row 0 north.
fn srtm_heights() -> (Vec<f32>, usize) {
    let directory = SrtmDirectory::open(&repo().join("data")).unwrap();
    let tile = directory.tile(CELL).unwrap().unwrap();
    (tile.heights.clone(), tile.size)
}

/// Writes the heights as Copernicus lays out a tile: `size − 1` pixels a side, the tie point at
/// the centre of the north-west pixel on the cell's corner.
fn write_copernicus(heights: &[f32], size: usize, path: &Path) {
    let side = size - 1;
    let mut pixels = Vec::with_capacity(side * side);
    for row in 0..side {
        pixels.extend_from_slice(&heights[row * size..row * size + side]);
    }
    let file = std::fs::File::create(path).unwrap();
    let mut encoder = TiffEncoder::new(file)
        .unwrap()
        .with_compression(Compression::Deflate(DeflateLevel::Fast));
    let mut image = encoder
        .new_image::<colortype::Gray32Float>(side as u32, side as u32)
        .unwrap();
    let step = 1.0 / side as f64;
    let directory = image.encoder();
    directory
        .write_tag(Tag::ModelPixelScaleTag, &[step, step, 0.0][..])
        .unwrap();
    let tie = [
        0.0,
        0.0,
        0.0,
        f64::from(CELL.lon),
        f64::from(CELL.lat + 1),
        0.0,
    ];
    directory
        .write_tag(Tag::ModelTiepointTag, &tie[..])
        .unwrap();
    // Version 1.1.0, three keys: geographic model, pixel is point, WGS 84.
    let keys: [u16; 16] = [1, 1, 0, 3, 1024, 0, 1, 2, 1025, 0, 1, 2, 2048, 0, 1, 4326];
    directory
        .write_tag(Tag::GeoKeyDirectoryTag, &keys[..])
        .unwrap();
    directory.write_tag(Tag::GdalNodata, "-32767").unwrap();
    image.write_data(&pixels).unwrap();
}

/// The bundled cell written as Copernicus's file of it into `dir`, with its heights and size.
fn copernicus_of_the_sample(dir: &Path) -> (PathBuf, Vec<f32>, usize) {
    let (heights, size) = srtm_heights();
    let tif = dir.join("Copernicus_DSM_COG_10_N43_00_E007_00_DEM.tif");
    write_copernicus(&heights, size, &tif);
    (tif, heights, size)
}

/// A directory holding copies of `files` (from the test's temporary folder or the repository).
fn directory_of(root: &Path, name: &str, files: &[&Path]) -> PathBuf {
    let dir = root.join(name);
    std::fs::create_dir_all(&dir).unwrap();
    for file in files {
        std::fs::copy(file, dir.join(file.file_name().unwrap())).unwrap();
    }
    dir
}

fn render_from(srtm: &Path, out: &Path) -> Vec<u8> {
    let osm = sample_osm();
    let args = [
        std::ffi::OsStr::new("--osm"),
        osm.as_os_str(),
        std::ffi::OsStr::new("--srtm"),
        srtm.as_os_str(),
    ];
    std::fs::create_dir_all(out).unwrap();
    render_in_process(TILE, &args, out)
}

#[test]
fn a_copernicus_geotiff_of_the_same_heights_makes_the_same_tile() {
    let dir = tempfile::tempdir().unwrap();
    let (tif, heights, size) = copernicus_of_the_sample(dir.path());
    let only_tif = directory_of(dir.path(), "tif", &[&tif]);
    let read = SrtmDirectory::open(&only_tif).unwrap();
    assert_eq!(read.cells(), vec![CELL]);
    let grid = read.tile(CELL).unwrap().unwrap();
    assert_eq!(grid.size, size);
    // Inside the cell every sample is the same; the south row and east column, which the file
    // leaves to its neighbours, repeat its last ones.
    for row in 0..size - 1 {
        for column in 0..size - 1 {
            let i = row * size + column;
            assert_eq!(grid.heights[i], heights[i], "row {row} column {column}");
        }
    }
    let last = (size - 1) * size;
    assert_eq!(grid.heights[last + 5], heights[last - size + 5]);

    let from_srtm = render_from(&repo().join("data"), &dir.path().join("a"));
    let from_tif = render_from(&only_tif, &dir.path().join("b"));
    assert!(from_srtm == from_tif, "the tiles differ");
}

#[test]
fn a_void_free_geotiff_takes_precedence_over_an_srtm_file_with_voids() {
    let dir = tempfile::tempdir().unwrap();
    let (tif, heights, size) = copernicus_of_the_sample(dir.path());
    // The SRTM file with a hole punched where the tile is (Monaco's hills).
    let mut bytes = std::fs::read(repo().join("data/N43E007.hgt")).unwrap();
    let (lon, lat) = (7.416, 43.731);
    let row = ((f64::from(CELL.lat + 1) - lat) * (size - 1) as f64) as usize;
    let column = ((lon - f64::from(CELL.lon)) * (size - 1) as f64) as usize;
    for r in row - 6..row + 6 {
        for c in column - 6..column + 6 {
            let at = 2 * (r * size + c);
            bytes[at..at + 2].copy_from_slice(&VOID.to_be_bytes());
        }
    }
    let holed = dir.path().join("N43E007.hgt");
    std::fs::write(&holed, &bytes).unwrap();

    let both = directory_of(dir.path(), "both", &[&holed, &tif]);
    let chosen = SrtmDirectory::open(&both)
        .unwrap()
        .tile(CELL)
        .unwrap()
        .unwrap();
    assert_eq!(
        chosen.heights[row * size + column],
        heights[row * size + column]
    );
    let only_holed = directory_of(dir.path(), "holed", &[&holed]);
    let filled = SrtmDirectory::open(&only_holed)
        .unwrap()
        .tile(CELL)
        .unwrap()
        .unwrap();
    assert_ne!(
        filled.heights[row * size + column],
        heights[row * size + column],
        "the hole changes the heights when nothing better is there"
    );
    // The tile follows the void-free file; from the holed file alone it differs.
    let from_srtm = render_from(&repo().join("data"), &dir.path().join("a"));
    let from_both = render_from(&both, &dir.path().join("b"));
    assert!(from_srtm == from_both, "the void-free file was not used");
    let from_holed = render_from(&only_holed, &dir.path().join("c"));
    assert!(from_srtm != from_holed, "the hole does not reach the tile");
}

#[test]
fn a_geotiff_that_is_not_a_dem_is_a_named_error() {
    let dir = tempfile::tempdir().unwrap();
    let tif = dir.path().join("N43E007.tif");
    std::fs::write(&tif, b"II*\0 not really a tiff").unwrap();
    let read = SrtmDirectory::open(dir.path()).unwrap();
    let error = read.tile(CELL).unwrap_err().to_string();
    assert!(error.contains("N43E007.tif"), "{error}");
    assert!(error.contains("GeoTIFF"), "{error}");
}

#[test]
fn a_geotiff_of_heights_no_land_has_is_refused_and_the_srtm_file_used() {
    let dir = tempfile::tempdir().unwrap();
    let (heights, size) = srtm_heights();
    for (name, bad) in [("infinite", f32::INFINITY), ("high", 1e30), ("deep", -1e6)] {
        let tif = dir.path().join(format!("{name}.tif"));
        write_copernicus(&vec![bad; heights.len()], size, &tif);
        let alone = directory_of(dir.path(), &format!("{name}-alone"), &[]);
        std::fs::copy(&tif, alone.join("N43E007.tif")).unwrap();
        let error = SrtmDirectory::open(&alone)
            .unwrap()
            .tile(CELL)
            .unwrap_err()
            .to_string();
        assert!(error.contains("N43E007.tif"), "{name}: {error}");
        assert!(
            error.contains("not elevation data") || error.contains("only voids"),
            "{name}: {error}"
        );
        // Beside the SRTM file, the SRTM file is used though it has voids and this has none.
        let both = directory_of(dir.path(), &format!("{name}-both"), &[]);
        std::fs::copy(&tif, both.join("N43E007.tif")).unwrap();
        std::fs::copy(repo().join("data/N43E007.hgt"), both.join("N43E007.hgt")).unwrap();
        let used = SrtmDirectory::open(&both)
            .unwrap()
            .tile(CELL)
            .unwrap()
            .unwrap();
        assert_eq!(used.heights, heights, "{name}");
    }
}
