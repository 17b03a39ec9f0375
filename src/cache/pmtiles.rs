//! A PMTiles v3 file (as `terrastitch export -o FILE.pmtiles` writes it) as a read-only tile
//! store: `terrastitch serve --archive FILE.pmtiles`.
//!
//! The layout, from the PMTiles v3 specification: a 127-byte header; a root directory; JSON
//! metadata; leaf directories; tile data. A directory is a varint count, then four columns of
//! varints — tile ids (delta-coded, Hilbert order over all zooms), run lengths, lengths, offsets
//! (0 after the first entry: just after the previous one; otherwise offset + 1). An entry of run
//! length 0 points at a leaf directory. Directories and metadata are compressed with the
//! header's internal compression (gzip or none here).
//!
//! The `pmtiles` crate writes these files and numbers tiles along the Hilbert curve here too;
//! its reader is asynchronous over HTTP and object-store backends, while stores are read from
//! blocking threads, so the file is read here by offset (positioned reads: requests read it
//! at once). The root directory is kept in memory, and leaf directories as they are met.

use std::collections::HashMap;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, MutexGuard};

use super::archive::{archived_tile, ArchiveStore, Contents, CONTENTS_KEY};
use super::store::{Provenance, StoreError, StoredEntry, StoredTile, TileFilter, TileStore, Usage};
use crate::format::TileKey;
use crate::tile::{LonLatBounds, TileId};

const HEADER_LEN: usize = 127;
/// Leaf directories nest at most this deep (the specification allows one level; some writers
/// use more).
const MAX_DEPTH: usize = 4;
/// Leaf directories kept in memory.
const LEAVES_KEPT: usize = 256;

/// The header's numbers this reader uses.
#[derive(Debug, Clone, Copy)]
struct Header {
    root: (u64, u64),
    metadata: (u64, u64),
    leaves: (u64, u64),
    data: (u64, u64),
    internal_gzip: bool,
    tile_gzip: bool,
    min_zoom: u8,
    max_zoom: u8,
    bounds: [f64; 4],
}

/// One directory entry.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Entry {
    tile_id: u64,
    offset: u64,
    length: u32,
    run_length: u32,
}

#[derive(Debug)]
pub struct PmtilesStore {
    path: PathBuf,
    file: std::fs::File,
    /// The file's length in bytes.
    len: u64,
    header: Header,
    root: Vec<Entry>,
    leaves: Mutex<HashMap<u64, Arc<Vec<Entry>>>>,
    contents: Contents,
}

impl PmtilesStore {
    /// Opens the file and reads its header, root directory and metadata; a file that is not a
    /// PMTiles v3 archive of glb or terrain tiles is an error naming it.
    pub fn open(path: &Path) -> Result<PmtilesStore, StoreError> {
        let file = std::fs::File::open(path).map_err(|source| StoreError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let len = file
            .metadata()
            .map(|m| m.len())
            .map_err(|source| StoreError::Io {
                path: path.to_path_buf(),
                source,
            })?;
        let mut store = PmtilesStore {
            path: path.to_path_buf(),
            file,
            len,
            header: Header::empty(),
            root: Vec::new(),
            leaves: Mutex::new(HashMap::new()),
            contents: Contents::read(crate::format::Format::GLB, None, (0, 0), None),
        };
        let bytes = store.read_at(0, HEADER_LEN as u64)?;
        store.header = Header::parse(&bytes).map_err(|report| store.damaged(report))?;
        let (offset, length) = store.header.root;
        store.root = store.directory(offset, length)?;
        store.contents = store.read_contents()?;
        Ok(store)
    }

    fn damaged(&self, report: impl Into<String>) -> StoreError {
        StoreError::Damaged {
            path: self.path.clone(),
            report: report.into(),
        }
    }

    fn read_at(&self, offset: u64, length: u64) -> Result<Vec<u8>, StoreError> {
        let io = |source| StoreError::Io {
            path: self.path.clone(),
            source,
        };
        // A damaged header must not make us allocate what the file cannot hold.
        let end = offset.checked_add(length);
        if end.is_none_or(|end| end > self.len) {
            return Err(self.damaged(format!(
                "it points at bytes {offset} to {} of its {}",
                offset.saturating_add(length),
                self.len
            )));
        }
        let length = usize::try_from(length).map_err(|_| self.damaged("a length overflows"))?;
        let mut bytes = vec![0u8; length];
        read_exact_at(&self.file, &mut bytes, offset).map_err(|e| match e.kind() {
            std::io::ErrorKind::UnexpectedEof => self.damaged(format!(
                "it ends before byte {} that it points at",
                offset + length as u64
            )),
            _ => io(e),
        })?;
        Ok(bytes)
    }

    /// The bytes of a directory or the metadata, uncompressed.
    fn internal(&self, offset: u64, length: u64) -> Result<Vec<u8>, StoreError> {
        let bytes = self.read_at(offset, length)?;
        if !self.header.internal_gzip {
            return Ok(bytes);
        }
        gunzip(&bytes).map_err(|e| self.damaged(format!("a directory does not inflate: {e}")))
    }

    fn directory(&self, offset: u64, length: u64) -> Result<Vec<Entry>, StoreError> {
        let bytes = self.internal(offset, length)?;
        parse_directory(&bytes).map_err(|report| self.damaged(report))
    }

    fn leaf(&self, offset: u64, length: u64) -> Result<Arc<Vec<Entry>>, StoreError> {
        if let Some(leaf) = self.leaves().get(&offset) {
            return Ok(leaf.clone());
        }
        let (base, _) = self.header.leaves;
        let leaf = Arc::new(self.directory(base + offset, length)?);
        let mut leaves = self.leaves();
        if leaves.len() >= LEAVES_KEPT {
            leaves.clear();
        }
        leaves.insert(offset, leaf.clone());
        Ok(leaf)
    }

    fn leaves(&self) -> MutexGuard<'_, HashMap<u64, Arc<Vec<Entry>>>> {
        self.leaves
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    fn read_contents(&self) -> Result<Contents, StoreError> {
        let (offset, length) = self.header.metadata;
        let metadata: serde_json::Value = if length == 0 {
            serde_json::Value::Null
        } else {
            let bytes = self.internal(offset, length)?;
            serde_json::from_slice(&bytes)
                .map_err(|e| self.damaged(format!("its metadata is not JSON: {e}")))?
        };
        let entry = metadata.get(CONTENTS_KEY);
        let named = entry
            .and_then(|e| e["format"].as_str())
            .or(metadata["format"].as_str());
        let format = named
            .and_then(super::archive::format_named)
            .ok_or_else(|| {
                self.damaged(format!(
                    "its format is {named:?}, not a glb variant or terrain"
                ))
            })?;
        let [west, south, east, north] = self.header.bounds;
        let bounds = (west < east && south < north).then_some(LonLatBounds {
            west,
            south,
            east,
            north,
        });
        let zooms = (self.header.min_zoom, self.header.max_zoom);
        Ok(Contents::read(format, bounds, zooms, entry))
    }

    /// The entry addressing `tile`, following leaf directories.
    fn find(&self, tile: TileId) -> Result<Option<Entry>, StoreError> {
        let Some(id) = hilbert_id(tile) else {
            return Ok(None);
        };
        let mut found = find_entry(&self.root, id);
        for _ in 0..MAX_DEPTH {
            match found {
                Some(entry) if entry.run_length == 0 => {
                    let leaf = self.leaf(entry.offset, u64::from(entry.length))?;
                    found = find_entry(&leaf, id);
                }
                other => return Ok(other),
            }
        }
        Err(self.damaged("its leaf directories nest too deep"))
    }

    /// Every tile entry, leaves followed.
    fn entries(&self) -> Result<Vec<Entry>, StoreError> {
        let mut tiles = Vec::new();
        let mut pending: Vec<(Vec<Entry>, usize)> = vec![(self.root.clone(), 0)];
        while let Some((directory, depth)) = pending.pop() {
            for entry in directory {
                if entry.run_length > 0 {
                    tiles.push(entry);
                } else if depth < MAX_DEPTH {
                    let leaf = self.leaf(entry.offset, u64::from(entry.length))?;
                    pending.push((leaf.as_ref().clone(), depth + 1));
                } else {
                    return Err(self.damaged("its leaf directories nest too deep"));
                }
            }
        }
        Ok(tiles)
    }

    fn provenance(&self) -> Provenance {
        Provenance {
            pipeline: "pmtiles".to_string(),
            sources: self.path.display().to_string(),
        }
    }

    fn read_only(&self) -> StoreError {
        StoreError::ReadOnly {
            path: self.path.clone(),
        }
    }
}

impl Header {
    fn empty() -> Header {
        Header {
            root: (0, 0),
            metadata: (0, 0),
            leaves: (0, 0),
            data: (0, 0),
            internal_gzip: false,
            tile_gzip: false,
            min_zoom: 0,
            max_zoom: 0,
            bounds: [0.0; 4],
        }
    }

    fn parse(bytes: &[u8]) -> Result<Header, String> {
        if bytes.len() < HEADER_LEN || &bytes[..7] != b"PMTiles" {
            return Err("it does not begin with a PMTiles header".to_string());
        }
        if bytes[7] != 3 {
            return Err(format!("it is PMTiles version {}, not 3", bytes[7]));
        }
        let u64_at = |at: usize| {
            let mut word = [0u8; 8];
            word.copy_from_slice(&bytes[at..at + 8]);
            u64::from_le_bytes(word)
        };
        let degrees_at = |at: usize| {
            let mut word = [0u8; 4];
            word.copy_from_slice(&bytes[at..at + 4]);
            f64::from(i32::from_le_bytes(word)) / 1e7
        };
        let gzip = |code: u8, what: &str| match code {
            1 => Ok(false),
            2 => Ok(true),
            other => Err(format!(
                "its {what} compression is {other}; this reader knows none (1) and gzip (2)"
            )),
        };
        Ok(Header {
            root: (u64_at(8), u64_at(16)),
            metadata: (u64_at(24), u64_at(32)),
            leaves: (u64_at(40), u64_at(48)),
            data: (u64_at(56), u64_at(64)),
            internal_gzip: gzip(bytes[97], "internal")?,
            tile_gzip: gzip(bytes[98], "tile")?,
            min_zoom: bytes[100],
            max_zoom: bytes[101],
            bounds: [
                degrees_at(102),
                degrees_at(106),
                degrees_at(110),
                degrees_at(114),
            ],
        })
    }
}

/// Reads `buffer.len()` bytes at `offset` without moving a shared cursor, so requests read
/// the file at once.
#[cfg(unix)]
fn read_exact_at(file: &std::fs::File, buffer: &mut [u8], offset: u64) -> std::io::Result<()> {
    std::os::unix::fs::FileExt::read_exact_at(file, buffer, offset)
}

#[cfg(windows)]
fn read_exact_at(file: &std::fs::File, buffer: &mut [u8], offset: u64) -> std::io::Result<()> {
    let mut done = 0;
    while done < buffer.len() {
        let offset = offset + done as u64;
        match std::os::windows::fs::FileExt::seek_read(file, &mut buffer[done..], offset)? {
            0 => return Err(std::io::ErrorKind::UnexpectedEof.into()),
            read => done += read,
        }
    }
    Ok(())
}

fn gunzip(bytes: &[u8]) -> std::io::Result<Vec<u8>> {
    let mut out = Vec::new();
    flate2::read::GzDecoder::new(bytes).read_to_end(&mut out)?;
    Ok(out)
}

/// The tile's position along the PMTiles Hilbert numbering.
fn hilbert_id(tile: TileId) -> Option<u64> {
    let coord = pmtiles::TileCoord::new(tile.z, tile.x, tile.y).ok()?;
    Some(pmtiles::TileId::from(coord).value())
}

/// The tile a Hilbert number names.
fn tile_of(id: u64) -> Option<TileId> {
    let coord = pmtiles::TileCoord::from(pmtiles::TileId::new(id).ok()?);
    Some(TileId {
        z: coord.z(),
        x: coord.x(),
        y: coord.y(),
    })
}

fn varint(bytes: &mut &[u8]) -> Result<u64, String> {
    let mut value = 0u64;
    for shift in (0..64).step_by(7) {
        let (&byte, rest) = bytes
            .split_first()
            .ok_or("a directory ends inside a number")?;
        *bytes = rest;
        value |= u64::from(byte & 0x7f) << shift;
        if byte & 0x80 == 0 {
            return Ok(value);
        }
    }
    Err("a directory holds a number longer than 64 bits".to_string())
}

fn parse_directory(mut bytes: &[u8]) -> Result<Vec<Entry>, String> {
    let count = varint(&mut bytes)?;
    // Each entry takes at least four bytes.
    if count > bytes.len() as u64 / 4 + 1 {
        return Err(format!(
            "a directory claims {count} entries in {} bytes",
            bytes.len()
        ));
    }
    let count = count as usize;
    let mut entries = vec![
        Entry {
            tile_id: 0,
            offset: 0,
            length: 0,
            run_length: 0
        };
        count
    ];
    let mut last = 0u64;
    for entry in entries.iter_mut() {
        last = last
            .checked_add(varint(&mut bytes)?)
            .ok_or("a tile id overflows")?;
        entry.tile_id = last;
    }
    let small = |v: u64| u32::try_from(v).map_err(|_| "a length overflows".to_string());
    for entry in entries.iter_mut() {
        entry.run_length = small(varint(&mut bytes)?)?;
    }
    for entry in entries.iter_mut() {
        entry.length = small(varint(&mut bytes)?)?;
    }
    for i in 0..count {
        let coded = varint(&mut bytes)?;
        entries[i].offset = match (coded, i) {
            (0, i) if i > 0 => entries[i - 1].offset + u64::from(entries[i - 1].length),
            (coded, _) => coded.checked_sub(1).ok_or("the first offset is coded 0")?,
        };
    }
    Ok(entries)
}

/// The entry whose run holds `id`, or the leaf directory before it.
fn find_entry(entries: &[Entry], id: u64) -> Option<Entry> {
    let at = entries.partition_point(|e| e.tile_id <= id);
    let entry = *entries.get(at.checked_sub(1)?)?;
    let inside = entry.run_length == 0 || id - entry.tile_id < u64::from(entry.run_length);
    inside.then_some(entry)
}

impl ArchiveStore for PmtilesStore {
    fn contents(&self) -> &Contents {
        &self.contents
    }

    fn path(&self) -> &Path {
        &self.path
    }
}

impl TileStore for PmtilesStore {
    fn get(&self, key: &TileKey) -> Result<Option<StoredTile>, StoreError> {
        if key.format != self.contents.format {
            return Ok(None);
        }
        let Some(entry) = self.find(key.tile)? else {
            return Ok(None);
        };
        let (base, size) = self.header.data;
        if entry.offset + u64::from(entry.length) > size {
            return Err(self.damaged(format!("tile {} lies beyond its data", key.tile)));
        }
        let bytes = self.read_at(base + entry.offset, u64::from(entry.length))?;
        let data = match self.header.tile_gzip {
            true => gunzip(&bytes)
                .map_err(|e| self.damaged(format!("tile {} does not inflate: {e}", key.tile)))?,
            false => bytes,
        };
        archived_tile(data, self.provenance()).map(Some)
    }

    fn put(&self, _key: &TileKey, _tile: &StoredTile) -> Result<(), StoreError> {
        Err(self.read_only())
    }

    fn touch(&self, _keys: &[TileKey], _at: i64) -> Result<(), StoreError> {
        Ok(())
    }

    fn remove(&self, _filter: &TileFilter) -> Result<Vec<TileKey>, StoreError> {
        Err(self.read_only())
    }

    fn list(&self, filter: &TileFilter) -> Result<Vec<StoredEntry>, StoreError> {
        let mut listed = Vec::new();
        for entry in self.entries()? {
            for id in entry.tile_id..entry.tile_id + u64::from(entry.run_length) {
                let Some(tile) = tile_of(id) else { continue };
                if filter.matches(tile) {
                    listed.push(StoredEntry {
                        key: TileKey {
                            tile,
                            format: self.contents.format,
                        },
                        made_by: self.provenance(),
                        size: u64::from(entry.length),
                        accessed_at: 0,
                    });
                }
            }
        }
        Ok(listed)
    }

    fn usage(&self) -> Result<Usage, StoreError> {
        let entries = self.entries()?;
        Ok(Usage {
            tiles: entries.iter().map(|e| u64::from(e.run_length)).sum(),
            bytes: entries
                .iter()
                .map(|e| u64::from(e.run_length) * u64::from(e.length))
                .sum(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(tile_id: u64, offset: u64, length: u32, run_length: u32) -> Entry {
        Entry {
            tile_id,
            offset,
            length,
            run_length,
        }
    }

    #[test]
    fn a_directory_decodes_its_delta_coded_columns() {
        // Three entries: ids 5, 6 and 10; runs 1, 2, 1; lengths 100, 50, 7; offsets 0, then
        // "just after", then 500.
        let bytes = [3, 5, 1, 4, 1, 2, 1, 100, 50, 7, 1, 0, 245, 3];
        let entries = parse_directory(&bytes).unwrap();
        assert_eq!(
            entries,
            vec![
                entry(5, 0, 100, 1),
                entry(6, 100, 50, 2),
                entry(10, 500, 7, 1)
            ]
        );
        assert_eq!(find_entry(&entries, 7), Some(entries[1]));
        assert_eq!(find_entry(&entries, 8), None);
        assert_eq!(find_entry(&entries, 4), None);
        assert!(parse_directory(&bytes[..9]).is_err());
        assert!(parse_directory(&[200, 1]).is_err());
    }

    #[test]
    fn a_leaf_entry_holds_every_id_after_it() {
        let entries = vec![entry(0, 0, 10, 1), entry(100, 0, 60, 0)];
        assert_eq!(find_entry(&entries, 5000), Some(entries[1]));
    }

    #[test]
    fn tile_numbers_follow_the_hilbert_curve_and_come_back() {
        let root = TileId { z: 0, x: 0, y: 0 };
        assert_eq!(hilbert_id(root), Some(0));
        assert_eq!(hilbert_id(TileId { z: 1, x: 0, y: 0 }), Some(1));
        let tile = TileId::new(14, 8528, 5974).unwrap();
        assert_eq!(hilbert_id(tile).and_then(tile_of), Some(tile));
    }

    #[test]
    fn an_archive_with_leaf_directories_reads_back_every_tile() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("many.pmtiles");
        let file = std::fs::File::create(&path).unwrap();
        let mut writer = pmtiles::PmTilesWriter::new(pmtiles::TileType::Unknown)
            .metadata(r#"{"format": "glb"}"#)
            .create(std::io::BufWriter::new(file))
            .unwrap();
        let side = 250u32;
        let tiles: Vec<TileId> = (0..side)
            .flat_map(|y| {
                (0..side).map(move |x| TileId {
                    z: 14,
                    x: 8000 + x,
                    y: 5000 + y,
                })
            })
            .collect();
        let mut ordered: Vec<(u64, TileId)> =
            tiles.iter().map(|&t| (hilbert_id(t).unwrap(), t)).collect();
        ordered.sort();
        let body = |t: TileId| format!("tile {}/{}", t.x, t.y).into_bytes();
        for &(_, t) in &ordered {
            let coord = pmtiles::TileCoord::new(t.z, t.x, t.y).unwrap();
            writer.add_tile(coord, &body(t)).unwrap();
        }
        writer.finalize().unwrap();

        let store = PmtilesStore::open(&path).unwrap();
        assert!(store.header.leaves.1 > 0, "the writer split the directory");
        for &t in tiles.iter().step_by(97) {
            let key = TileKey {
                tile: t,
                format: crate::format::Format::GLB,
            };
            let tile = store.get(&key).unwrap().unwrap();
            assert_eq!(tile.bodies.identity.to_vec(), body(t), "{t}");
        }
        let beside = TileId {
            z: 14,
            x: 7999,
            y: 5000,
        };
        let key = TileKey {
            tile: beside,
            format: crate::format::Format::GLB,
        };
        assert!(store.get(&key).unwrap().is_none());
        assert_eq!(store.usage().unwrap().tiles, tiles.len() as u64);
        assert_eq!(store.list(&TileFilter::All).unwrap().len(), tiles.len());
    }

    #[test]
    fn a_truncated_file_is_a_named_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("cut.pmtiles");
        let mut header = vec![0u8; HEADER_LEN];
        header[..7].copy_from_slice(b"PMTiles");
        header[7] = 3;
        header[8] = 127; // the root directory just after the header…
        header[16] = 40; // …40 bytes long, past the end.
        header[97] = 1;
        header[98] = 1;
        std::fs::write(&path, &header).unwrap();
        let error = PmtilesStore::open(&path).err().unwrap().to_string();
        assert!(
            error.contains("cut.pmtiles")
                && error.contains("points at bytes 127 to 167 of its 127"),
            "{error}"
        );
        // A length no file holds is refused before anything is read.
        header[23] = 0x40;
        std::fs::write(&path, &header).unwrap();
        let error = PmtilesStore::open(&path).err().unwrap().to_string();
        assert!(error.contains("points at bytes"), "{error}");
        header[7] = 2;
        std::fs::write(&path, &header).unwrap();
        let error = PmtilesStore::open(&path).err().unwrap().to_string();
        assert!(error.contains("version 2"), "{error}");
    }
}
