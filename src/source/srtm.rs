//! SRTM elevation tiles: `.hgt`, `.hgt.zip` and `.hgt.gz` files (what the free SRTM mirrors
//! serve), 1 and 3 arc-seconds.
//!
//! A file named after its south-west corner (`N43E007.hgt`) holds a square of big-endian `i16`
//! samples, 1201² (3″) or 3601² (1″), row 0 on the north edge, column 0 on the west edge.
//! Neighbouring files share their edge rows and columns. A void is −32768; voids are filled from
//! their neighbours when a file is read (inverse-distance blend of the nearest valid samples
//! along the eight compass directions), so nothing downstream ever sees one.
//!
//! [`SrtmDirectory`] indexes a directory once, checks every file's size at start, and decodes a
//! file the first time a tile needs it (kept in a bounded in-memory cache).

use std::collections::BTreeMap;
use std::fs;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::voids::{IMPLAUSIBLE_SHARE, PLAUSIBLE_M};
use crate::terrain::cell::{CellId, SrtmTile};

/// The value SRTM uses for a sample without data.
pub const VOID: i16 = -32768;

/// Samples per side of a 3-arc-second file.
pub const SAMPLES_3_ARCSEC: usize = 1201;
/// Samples per side of a 1-arc-second file.
pub const SAMPLES_1_ARCSEC: usize = 3601;

/// The most bytes an SRTM file may have: a 1″ tile stored in a zip without compression, with
/// room for the archive's headers.
pub const LARGEST_FILE_BYTES: u64 = (SAMPLES_1_ARCSEC * SAMPLES_1_ARCSEC * 2) as u64 + (1 << 20);

/// Decoded files kept in memory at once (a 3″ file takes 5.8 MB as `f32`).
const DECODED_FILES_CACHED: u64 = 64;

#[derive(Debug, thiserror::Error)]
pub enum SrtmError {
    #[error("SRTM file {path} has {actual} bytes; a 3-arc-second tile has {} and a 1-arc-second tile {}", SAMPLES_3_ARCSEC * SAMPLES_3_ARCSEC * 2, SAMPLES_1_ARCSEC * SAMPLES_1_ARCSEC * 2)]
    BadSize { path: PathBuf, actual: u64 },
    #[error("cannot read SRTM file {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("SRTM archive {path} is not a readable zip file: {message}")]
    Zip { path: PathBuf, message: String },
    #[error("SRTM archive {path} holds no .hgt file")]
    EmptyZip { path: PathBuf },
    #[error("SRTM file {path} inflates to more than the {declared} bytes it declares")]
    TooLarge { path: PathBuf, declared: u64 },
    #[error("SRTM file {path} is not a readable gzip file: {source}")]
    Gzip {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("elevation file {path} cannot be read as a GeoTIFF DEM: {report}")]
    GeoTiff { path: PathBuf, report: String },
    #[error("SRTM file {path} holds only voids")]
    AllVoid { path: PathBuf },
    #[error("SRTM file {path} is not elevation data: {percent:.1} % of its samples lie outside {} to {} m", PLAUSIBLE_M.0, PLAUSIBLE_M.1)]
    Implausible { path: PathBuf, percent: f64 },
    #[error("SRTM directory {path} cannot be read: {source}")]
    Directory {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
}

/// Values that mark a sample without data: SRTM's void, and those other elevation files
/// converted to `.hgt` use.
const NO_DATA: [i16; 3] = [VOID, -32767, -9999];

/// Decodes the raw big-endian bytes of a `.hgt` file; `path` names the file in errors.
pub fn decode(cell: CellId, bytes: &[u8], path: &Path) -> Result<SrtmTile, SrtmError> {
    decode_counting(cell, bytes, path).map(|(tile, _)| tile)
}

/// [`decode`], with the count of voids filled.
fn decode_counting(
    cell: CellId,
    bytes: &[u8],
    path: &Path,
) -> Result<(SrtmTile, usize), SrtmError> {
    let size = side_for_len(bytes.len() as u64).ok_or_else(|| SrtmError::BadSize {
        path: path.to_path_buf(),
        actual: bytes.len() as u64,
    })?;
    let raw: Vec<i16> = bytes
        .chunks_exact(2)
        .map(|pair| i16::from_be_bytes([pair[0], pair[1]]))
        .collect();
    let outside = raw
        .iter()
        .filter(|&&h| !NO_DATA.contains(&h) && !(PLAUSIBLE_M.0..=PLAUSIBLE_M.1).contains(&h))
        .count();
    let share = outside as f64 / raw.len().max(1) as f64;
    if share > IMPLAUSIBLE_SHARE {
        return Err(SrtmError::Implausible {
            path: path.to_path_buf(),
            percent: share * 100.0,
        });
    }
    let heights = fill_voids(&raw, size).ok_or_else(|| SrtmError::AllVoid {
        path: path.to_path_buf(),
    })?;
    let voids = raw.iter().filter(|&&h| h == VOID).count();
    Ok((
        SrtmTile {
            cell,
            size,
            heights,
        },
        voids,
    ))
}

/// Reads a `.hgt`, `.hgt.zip` or `.hgt.gz` file.
pub fn read(cell: CellId, path: &Path) -> Result<SrtmTile, SrtmError> {
    read_counting(cell, path).map(|(tile, _)| tile)
}

/// Reads an SRTM file or a GeoTIFF, with the count of voids filled.
fn read_counting(cell: CellId, path: &Path) -> Result<(SrtmTile, usize), SrtmError> {
    if is_geotiff(path) {
        return super::geotiff::read(cell, path).map_err(|e| SrtmError::GeoTiff {
            path: e.path,
            report: e.report,
        });
    }
    let bytes = read_hgt_bytes(path)?;
    decode_counting(cell, &bytes, path)
}

fn is_geotiff(path: &Path) -> bool {
    let name = path
        .file_name()
        .and_then(|n| n.to_str())
        .unwrap_or_default();
    super::geotiff::cell_of_name(name).is_some()
}

fn side_for_len(len: u64) -> Option<usize> {
    [SAMPLES_3_ARCSEC, SAMPLES_1_ARCSEC]
        .into_iter()
        .find(|&side| (side * side * 2) as u64 == len)
}

fn read_hgt_bytes(path: &Path) -> Result<Vec<u8>, SrtmError> {
    let io = |source| SrtmError::Io {
        path: path.to_path_buf(),
        source,
    };
    // A file holds one tile's samples, as many bytes as it declares: a packed file that
    // inflates past them is refused, not read into memory whole.
    let declared = hgt_len(path)?;
    if side_for_len(declared).is_none() {
        return Err(SrtmError::BadSize {
            path: path.to_path_buf(),
            actual: declared,
        });
    }
    let inflated = |result: Result<Vec<u8>, crate::inflate::InflateError>| match result {
        Ok(bytes) => Ok(bytes),
        Err(crate::inflate::InflateError::TooLarge { limit }) => Err(SrtmError::TooLarge {
            path: path.to_path_buf(),
            declared: limit,
        }),
        Err(crate::inflate::InflateError::Corrupt(source)) => match packing(path) {
            Packing::Gzip => Err(SrtmError::Gzip {
                path: path.to_path_buf(),
                source,
            }),
            _ => Err(io(source)),
        },
    };
    match packing(path) {
        Packing::Plain => return fs::read(path).map_err(io),
        Packing::Gzip => {
            let file = fs::File::open(path).map_err(io)?;
            let decoder = flate2::read::GzDecoder::new(file);
            return inflated(crate::inflate::read_at_most(decoder, declared));
        }
        Packing::Zip => {}
    }
    let file = fs::File::open(path).map_err(io)?;
    let zip_error = |error: zip::result::ZipError| SrtmError::Zip {
        path: path.to_path_buf(),
        message: error.to_string(),
    };
    let mut archive = zip::ZipArchive::new(file).map_err(zip_error)?;
    let index = (0..archive.len())
        .find(|&i| {
            archive
                .name_for_index(i)
                .is_some_and(|name| name.to_ascii_lowercase().ends_with(".hgt"))
        })
        .ok_or_else(|| SrtmError::EmptyZip {
            path: path.to_path_buf(),
        })?;
    let entry = archive.by_index(index).map_err(zip_error)?;
    inflated(crate::inflate::read_at_most(entry, declared))
}

/// The uncompressed length of the `.hgt` data in a file, read without decoding the samples.
fn hgt_len(path: &Path) -> Result<u64, SrtmError> {
    let io = |source| SrtmError::Io {
        path: path.to_path_buf(),
        source,
    };
    match packing(path) {
        Packing::Plain => return Ok(fs::metadata(path).map_err(io)?.len()),
        Packing::Gzip => return gzip_len(path),
        Packing::Zip => {}
    }
    let file = fs::File::open(path).map_err(io)?;
    let zip_error = |error: zip::result::ZipError| SrtmError::Zip {
        path: path.to_path_buf(),
        message: error.to_string(),
    };
    let mut archive = zip::ZipArchive::new(file).map_err(zip_error)?;
    for i in 0..archive.len() {
        let entry = archive.by_index_raw(i).map_err(zip_error)?;
        if entry.name().to_ascii_lowercase().ends_with(".hgt") {
            return Ok(entry.size());
        }
    }
    Err(SrtmError::EmptyZip {
        path: path.to_path_buf(),
    })
}

/// How a file holds its `.hgt` data.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Packing {
    Plain,
    Zip,
    Gzip,
}

fn packing(path: &Path) -> Packing {
    match path.extension().and_then(|e| e.to_str()) {
        Some(ext) if ext.eq_ignore_ascii_case("zip") => Packing::Zip,
        Some(ext) if ext.eq_ignore_ascii_case("gz") => Packing::Gzip,
        _ => Packing::Plain,
    }
}

fn is_packed(path: &Path) -> bool {
    packing(path) != Packing::Plain
}

/// The uncompressed length a gzip file declares (its last four bytes: the length modulo 2³²,
/// exact for any SRTM tile); reading the data checks it.
fn gzip_len(path: &Path) -> Result<u64, SrtmError> {
    use std::io::{Seek, SeekFrom};
    let gzip = |source| SrtmError::Gzip {
        path: path.to_path_buf(),
        source,
    };
    let mut file = fs::File::open(path).map_err(|source| SrtmError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let mut trailer = [0u8; 4];
    file.seek(SeekFrom::End(-4)).map_err(gzip)?;
    file.read_exact(&mut trailer).map_err(gzip)?;
    Ok(u64::from(u32::from_le_bytes(trailer)))
}

/// Fills voids: each void takes the inverse-distance blend of the nearest valid sample in each of
/// the eight compass directions (a cheap, deterministic stand-in for a full interpolation that
/// behaves well for the small holes SRTM has). Returns `None` if every sample is void.
pub fn fill_voids(raw: &[i16], size: usize) -> Option<Vec<f32>> {
    let heights = raw
        .iter()
        .map(|&h| match h {
            VOID => f32::NAN,
            h => f32::from(h),
        })
        .collect();
    super::voids::fill_nan_voids(heights, size)
}

/// A file's version as its size and modification time (nanoseconds): a file replaced by
/// another, or rewritten, gets a new one.
pub fn file_version(path: &Path) -> Result<String, SrtmError> {
    let metadata = fs::metadata(path).map_err(|source| SrtmError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let modified = metadata
        .modified()
        .ok()
        .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
        .map_or(0, |d| d.as_nanos());
    Ok(format!("{}-{modified}", metadata.len()))
}

/// A cell's file: its version (size and modification time), cheap to check for changes, and
/// the digest of its content, what tiles record as their source's version (the same file has
/// the same digest on every machine, whenever it was copied), read when first asked for.
/// The elevation files of one cell, in the order they are tried: its SRTM file, then GeoTIFFs
/// (by name). The first without voids is used, else the first (see [`SrtmDirectory::tile`]).
#[derive(Debug, Clone, PartialEq, Eq)]
struct CellFile {
    paths: Vec<PathBuf>,
    version: String,
    content: std::sync::OnceLock<String>,
}

impl CellFile {
    fn new(paths: Vec<PathBuf>) -> Result<CellFile, SrtmError> {
        let versions: Vec<String> = paths
            .iter()
            .map(|p| file_version(p))
            .collect::<Result<_, _>>()?;
        Ok(CellFile {
            paths,
            version: versions.join("+"),
            content: std::sync::OnceLock::new(),
        })
    }

    /// The digest of the files' bytes (their sizes and modification times if one cannot be
    /// read).
    fn content_version(&self) -> String {
        self.content
            .get_or_init(|| {
                use sha2::Digest;
                let mut digests = Vec::new();
                for path in &self.paths {
                    match fs::read(path) {
                        Ok(bytes) => digests.push(sha2::Sha256::digest(&bytes)),
                        Err(_) => return self.version.clone(),
                    }
                }
                let digest = match digests.as_slice() {
                    [one] => *one,
                    several => sha2::Sha256::digest(several.concat()),
                };
                digest[..16].iter().map(|b| format!("{b:02x}")).collect()
            })
            .clone()
    }

    /// The same cell with `path` as its SRTM file.
    fn with_srtm(&self, path: &Path) -> Result<CellFile, SrtmError> {
        let mut paths = vec![path.to_path_buf()];
        paths.extend(self.paths.iter().filter(|p| is_geotiff(p)).cloned());
        CellFile::new(paths)
    }
}

/// The SRTM files of one directory (and of the directory downloads go to), checked at start,
/// added to as files are downloaded, and decoded on demand.
pub struct SrtmDirectory {
    root: PathBuf,
    files: std::sync::RwLock<BTreeMap<CellId, CellFile>>,
    decoded: moka::sync::Cache<CellId, Arc<SrtmTile>>,
    /// Lowest and highest sample of each file decoded so far (kept when the decoded samples are
    /// dropped).
    ranges: std::sync::Mutex<BTreeMap<CellId, (f32, f32)>>,
}

impl std::fmt::Debug for SrtmDirectory {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SrtmDirectory")
            .field("root", &self.root)
            .field("files", &self.read().len())
            .finish()
    }
}

impl SrtmDirectory {
    /// Indexes `root` (not recursively) and checks the size of every `.hgt`, `.hgt.zip` and
    /// `.hgt.gz` in it. When several forms of a cell exist, the plain `.hgt` is used.
    pub fn open(root: &Path) -> Result<SrtmDirectory, SrtmError> {
        SrtmDirectory::open_all(root, &[])
    }

    /// Indexes `root`, then each of `more` for the cells `root` lacks (downloads).
    pub fn open_all(root: &Path, more: &[PathBuf]) -> Result<SrtmDirectory, SrtmError> {
        let mut files = index_directory(root)?;
        for extra in more.iter().filter(|d| d.is_dir()) {
            for (cell, file) in index_directory(extra)? {
                files.entry(cell).or_insert(file);
            }
        }
        Ok(SrtmDirectory {
            root: root.to_path_buf(),
            files: std::sync::RwLock::new(files),
            decoded: moka::sync::Cache::new(DECODED_FILES_CACHED),
            ranges: Default::default(),
        })
    }

    fn read(&self) -> std::sync::RwLockReadGuard<'_, BTreeMap<CellId, CellFile>> {
        self.files.read().unwrap_or_else(|p| p.into_inner())
    }

    /// Adds a file (a download) for a cell, after checking its size.
    pub fn insert(&self, cell: CellId, path: &Path) -> Result<(), SrtmError> {
        let len = hgt_len(path)?;
        if side_for_len(len).is_none() {
            return Err(SrtmError::BadSize {
                path: path.to_path_buf(),
                actual: len,
            });
        }
        let mut files = self.files.write().unwrap_or_else(|p| p.into_inner());
        let file = match files.get(&cell) {
            Some(held) => held.with_srtm(path)?,
            None => CellFile::new(vec![path.to_path_buf()])?,
        };
        files.insert(cell, file);
        drop(files);
        self.decoded.invalidate(&cell);
        self.ranges
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .remove(&cell);
        Ok(())
    }

    /// The lowest and highest sample of a cell's file (decoding it the first time), or `None`
    /// when the directory has no file for the cell.
    pub fn height_range(&self, cell: CellId) -> Result<Option<(f32, f32)>, SrtmError> {
        let known = self
            .ranges
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .get(&cell)
            .copied();
        if known.is_some() {
            return Ok(known);
        }
        let Some(tile) = self.tile(cell)? else {
            return Ok(None);
        };
        let range = tile
            .heights
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(low, high), &h| {
                (low.min(h), high.max(h))
            });
        self.ranges
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .insert(cell, range);
        Ok(Some(range))
    }
}

/// The elevation files of a directory, by cell: per cell one SRTM file (a plain `.hgt` before
/// a packed one) and any GeoTIFFs.
fn index_directory(root: &Path) -> Result<BTreeMap<CellId, CellFile>, SrtmError> {
    let entries = fs::read_dir(root).map_err(|source| SrtmError::Directory {
        path: root.to_path_buf(),
        source,
    })?;
    let mut srtm: BTreeMap<CellId, PathBuf> = BTreeMap::new();
    let mut tiffs: BTreeMap<CellId, Vec<PathBuf>> = BTreeMap::new();
    for entry in entries {
        let entry = entry.map_err(|source| SrtmError::Directory {
            path: root.to_path_buf(),
            source,
        })?;
        let path = entry.path();
        let Some(name) = path.file_name().and_then(|n| n.to_str()) else {
            continue;
        };
        if let Some(cell) = super::geotiff::cell_of_name(name) {
            tiffs.entry(cell).or_default().push(path);
            continue;
        }
        let lower = name.to_ascii_lowercase();
        let stem = lower
            .strip_suffix(".hgt.zip")
            .or_else(|| lower.strip_suffix(".hgt.gz"))
            .or_else(|| lower.strip_suffix(".hgt"));
        let Some(cell) = stem.and_then(CellId::from_name) else {
            continue;
        };
        let len = hgt_len(&path)?;
        if side_for_len(len).is_none() {
            return Err(SrtmError::BadSize { path, actual: len });
        }
        let plain_exists = srtm.get(&cell).is_some_and(|p| !is_packed(p));
        if !plain_exists {
            srtm.insert(cell, path);
        }
    }
    let cells: std::collections::BTreeSet<CellId> =
        srtm.keys().chain(tiffs.keys()).copied().collect();
    let mut files = BTreeMap::new();
    for cell in cells {
        let mut paths: Vec<PathBuf> = srtm.remove(&cell).into_iter().collect();
        let mut more = tiffs.remove(&cell).unwrap_or_default();
        more.sort();
        paths.extend(more);
        files.insert(cell, CellFile::new(paths)?);
    }
    Ok(files)
}

impl SrtmDirectory {
    pub fn root(&self) -> &Path {
        &self.root
    }

    /// The cells with a file.
    pub fn cells(&self) -> Vec<CellId> {
        self.read().keys().copied().collect()
    }

    /// The version of a cell's file (its size and modification time), if there is one.
    pub fn version(&self, cell: CellId) -> Option<String> {
        self.read().get(&cell).map(|f| f.version.clone())
    }

    /// The cells with a file whose latitude and longitude are in the ranges, with the digests
    /// of the files' content, in order.
    pub fn versions_in(
        &self,
        lats: std::ops::RangeInclusive<i32>,
        lons: std::ops::RangeInclusive<i32>,
    ) -> Vec<(CellId, String)> {
        let (first, last) = (
            CellId {
                lat: *lats.start(),
                lon: i32::MIN,
            },
            CellId {
                lat: *lats.end(),
                lon: i32::MAX,
            },
        );
        if first > last {
            return Vec::new();
        }
        self.read()
            .range(first..=last)
            .filter(|(cell, _)| lons.contains(&cell.lon))
            .map(|(cell, file)| (*cell, file.content_version()))
            .collect()
    }

    pub fn has(&self, cell: CellId) -> bool {
        self.read().contains_key(&cell)
    }

    /// The decoded file of a cell, `None` if the directory has no file for it. Of several files,
    /// the first without voids is taken (a void-free DEM over SRTM with its holes filled), else
    /// the first.
    pub fn tile(&self, cell: CellId) -> Result<Option<Arc<SrtmTile>>, SrtmError> {
        let Some(paths) = self.read().get(&cell).map(|f| f.paths.clone()) else {
            return Ok(None);
        };
        self.decoded
            .try_get_with(cell, || decode_first_whole(cell, &paths).map(Arc::new))
            .map(Some)
            .map_err(|error| match Arc::try_unwrap(error) {
                Ok(error) => error,
                Err(shared) => SrtmError::Io {
                    path: paths.first().cloned().unwrap_or_default(),
                    source: std::io::Error::other(shared.to_string()),
                },
            })
    }
}

/// The first of `paths` that decodes without voids, else the first that decodes; a file
/// refused (damaged, or not elevation data) is passed over, with a warning, when another of
/// the cell is sound.
fn decode_first_whole(cell: CellId, paths: &[PathBuf]) -> Result<SrtmTile, SrtmError> {
    let mut first = None;
    let mut refused = None;
    for path in paths {
        match read_counting(cell, path) {
            Ok((tile, 0)) => return Ok(tile),
            Ok((tile, _)) => {
                first.get_or_insert(tile);
            }
            Err(error) => {
                tracing::warn!(%error, "an elevation file is refused; the cell's others are used");
                refused.get_or_insert(error);
            }
        }
    }
    match (first, refused) {
        (Some(tile), _) => Ok(tile),
        (None, Some(error)) => Err(error),
        (None, None) => Err(SrtmError::Io {
            path: PathBuf::new(),
            source: std::io::Error::other(format!("no elevation file for cell {cell:?}")),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tile_from(values: &[i16], size: usize) -> SrtmTile {
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_be_bytes()).collect();
        let heights = fill_voids(
            &bytes
                .chunks_exact(2)
                .map(|p| i16::from_be_bytes([p[0], p[1]]))
                .collect::<Vec<_>>(),
            size,
        )
        .unwrap();
        SrtmTile {
            cell: CellId { lat: 43, lon: 7 },
            size,
            heights,
        }
    }

    #[test]
    fn names_round_trip() {
        for name in ["N43E007", "S12W071", "N00E000", "S01W001"] {
            assert_eq!(CellId::from_name(name).unwrap().name(), name);
        }
        assert_eq!(
            CellId::from_name("N44W072"),
            Some(CellId { lat: 44, lon: -72 })
        );
        assert_eq!(CellId::from_name("X44W072"), None);
        assert_eq!(
            CellId::containing(-71.3, 44.27),
            CellId { lat: 44, lon: -72 }
        );
    }

    #[test]
    fn rejects_a_truncated_file_and_names_it() {
        let path = Path::new("N43E007.hgt");
        let error = decode(CellId { lat: 43, lon: 7 }, &[0u8; 1000], path)
            .unwrap_err()
            .to_string();
        assert!(
            error.contains("N43E007.hgt") && error.contains("1000"),
            "{error}"
        );
    }

    #[test]
    fn voids_take_the_values_around_them() {
        let size = 3;
        let tile = tile_from(&[10, 10, 10, 10, VOID, 10, 10, 10, 10], size);
        assert_eq!(tile.sample(1, 1), 10.0);
        let tile = tile_from(&[0, 0, 0, 0, VOID, VOID, 0, 0, 0], size);
        assert!(tile.heights.iter().all(|&h| h == 0.0));
    }

    #[test]
    fn reads_a_zipped_file_and_prefers_nothing_else_in_the_directory() {
        use std::io::Write;
        let dir = tempfile::tempdir().unwrap();
        let side = SAMPLES_3_ARCSEC;
        let mut samples = vec![0u8; side * side * 2];
        // North-west sample 100 m, one void next to it.
        samples[0..2].copy_from_slice(&100i16.to_be_bytes());
        samples[2..4].copy_from_slice(&VOID.to_be_bytes());
        let file = fs::File::create(dir.path().join("N43E007.hgt.zip")).unwrap();
        let mut zip = zip::ZipWriter::new(file);
        zip.start_file("N43E007.hgt", zip::write::SimpleFileOptions::default())
            .unwrap();
        zip.write_all(&samples).unwrap();
        zip.finish().unwrap();
        fs::write(dir.path().join("notes.txt"), "not a tile").unwrap();

        let directory = SrtmDirectory::open(dir.path()).unwrap();
        let cell = CellId { lat: 43, lon: 7 };
        assert_eq!(directory.cells(), vec![cell]);
        let tile = directory.tile(cell).unwrap().unwrap();
        assert_eq!(tile.sample(0, 0), 100.0);
        assert!(
            tile.sample(0, 1) > 0.0 && tile.sample(0, 1) < 100.0,
            "void filled"
        );
        assert_eq!(tile.bilinear(7.0, 44.0), Some(100.0));
        assert!(directory.tile(CellId { lat: 0, lon: 0 }).unwrap().is_none());
    }

    #[test]
    fn a_zipped_file_that_inflates_past_what_it_declares_is_refused() {
        use std::io::Write;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("N43E007.hgt.zip");
        let declared = SAMPLES_3_ARCSEC * SAMPLES_3_ARCSEC * 2;
        // A megabyte more than a 3″ tile, then the entry's sizes changed to a 3″ tile's.
        let actual = declared + (1 << 20);
        let mut zip = zip::ZipWriter::new(fs::File::create(&path).unwrap());
        zip.start_file("N43E007.hgt", zip::write::SimpleFileOptions::default())
            .unwrap();
        zip.write_all(&vec![0u8; actual]).unwrap();
        zip.finish().unwrap();
        let mut bytes = fs::read(&path).unwrap();
        let size = (actual as u32).to_le_bytes();
        let mut patched = 0;
        for at in 0..bytes.len() - 4 {
            let field = match &bytes[at..at + 4] {
                b"PK\x03\x04" => at + 22,
                b"PK\x01\x02" => at + 24,
                _ => continue,
            };
            assert_eq!(bytes[field..field + 4], size);
            bytes[field..field + 4].copy_from_slice(&(declared as u32).to_le_bytes());
            patched += 1;
        }
        assert_eq!(patched, 2, "the local and the central header");
        fs::write(&path, &bytes).unwrap();

        let error = read_hgt_bytes(&path).unwrap_err().to_string();
        assert!(
            error.contains("inflates to more than the 2884802 bytes it declares"),
            "{error}"
        );
    }

    #[test]
    fn reads_a_gzipped_file_as_the_mirrors_serve_it() {
        use std::io::Write;
        let dir = tempfile::tempdir().unwrap();
        let side = SAMPLES_3_ARCSEC;
        let mut samples = vec![0u8; side * side * 2];
        samples[0..2].copy_from_slice(&250i16.to_be_bytes());
        let file = fs::File::create(dir.path().join("N43E007.hgt.gz")).unwrap();
        let mut gzip = flate2::write::GzEncoder::new(file, flate2::Compression::fast());
        gzip.write_all(&samples).unwrap();
        gzip.finish().unwrap();

        let directory = SrtmDirectory::open(dir.path()).unwrap();
        let cell = CellId { lat: 43, lon: 7 };
        assert_eq!(directory.cells(), vec![cell]);
        let tile = directory.tile(cell).unwrap().unwrap();
        assert_eq!(tile.sample(0, 0), 250.0);

        // A gzip file cut short is refused by name when it is read.
        let whole = fs::read(dir.path().join("N43E007.hgt.gz")).unwrap();
        let cut = dir.path().join("N44E007.hgt.gz");
        let mut bytes = whole[..whole.len() / 2].to_vec();
        bytes.extend_from_slice(&whole[whole.len() - 8..]);
        fs::write(&cut, bytes).unwrap();
        let error = read(CellId { lat: 44, lon: 7 }, &cut).unwrap_err();
        assert!(
            matches!(error, SrtmError::Gzip { .. }) && error.to_string().contains("N44E007.hgt.gz"),
            "{error}"
        );
    }

    #[test]
    fn a_truncated_file_in_a_directory_is_rejected_at_open() {
        let dir = tempfile::tempdir().unwrap();
        fs::write(dir.path().join("N43E007.hgt"), vec![0u8; 1000]).unwrap();
        let error = SrtmDirectory::open(dir.path()).unwrap_err().to_string();
        assert!(
            error.contains("N43E007.hgt") && error.contains("1000 bytes"),
            "{error}"
        );
    }

    #[test]
    fn random_bytes_are_refused_as_not_elevation_data() {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let bytes: Vec<u8> = (0..SAMPLES_3_ARCSEC * SAMPLES_3_ARCSEC * 2)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                state as u8
            })
            .collect();
        let cell = CellId { lat: 43, lon: 7 };
        let error = decode(cell, &bytes, Path::new("random.hgt")).unwrap_err();
        assert!(matches!(error, SrtmError::Implausible { .. }), "{error}");
        assert!(error.to_string().contains("random.hgt"));
        // The bundled file is elevation data.
        let real = std::fs::read(concat!(env!("CARGO_MANIFEST_DIR"), "/data/N43E007.hgt")).unwrap();
        assert!(decode(cell, &real, Path::new("N43E007.hgt")).is_ok());
    }

    #[test]
    fn all_void_is_an_error() {
        assert!(fill_voids(&[VOID; 4], 2).is_none());
    }

    #[test]
    fn row_zero_is_north() {
        // 2×2 is not a real SRTM size, but the interpolation only needs the side length.
        let tile = SrtmTile {
            cell: CellId { lat: 43, lon: 7 },
            size: 2,
            heights: vec![100.0, 200.0, 0.0, 0.0],
        };
        assert_eq!(tile.bilinear(7.0, 44.0), Some(100.0));
        assert_eq!(tile.bilinear(8.0, 44.0), Some(200.0));
        assert_eq!(tile.bilinear(7.5, 43.0), Some(0.0));
        assert_eq!(tile.bilinear(7.5, 43.5), Some(75.0));
        assert_eq!(tile.bilinear(8.5, 43.5), None);
    }
}
