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
//!
//! Nothing the file says is used before it is checked: the header's sections lie inside the
//! file, every entry's bytes inside its section and every run of tiles inside the zooms the
//! header names, with checked arithmetic throughout; directories, metadata and tiles inflate
//! to a bounded size at most; a run of tiles is walked, never expanded into a list.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, MutexGuard};

use super::{
    archived_tile, metadata, ArchiveStore, Contents, TileBodies, WriteError, CONTENTS_KEY,
};
use crate::cache::store::{
    Provenance, StoreError, StoredEntry, StoredTile, TileFilter, TileReader, Usage,
};
use crate::format::TileKey;
use crate::tile::{LonLatBounds, TileId};
use serde_json::Value;

const HEADER_LEN: usize = 127;
/// Leaf directories nest at most this deep (the specification allows one level; some writers
/// use more).
const MAX_DEPTH: usize = 4;
/// Leaf directories kept in memory.
const LEAVES_KEPT: usize = 256;
/// The most a directory inflates to. The writers we know keep the leaves of whole-planet
/// archives under a megabyte (go-pmtiles and planetiler grow a leaf only until the root fits
/// its 16 KiB); sixteen times that leaves room for any of them.
const MAX_DIRECTORY_BYTES: u64 = 16 << 20;
/// The most the JSON metadata inflates to. Ours lists the ground's range under each tile,
/// about 40 bytes a tile: 64 MiB holds an export of over a million tiles.
const MAX_METADATA_BYTES: u64 = 64 << 20;

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
    /// Largest tile, uncompressed, it may give.
    max_tile: u64,
}

impl PmtilesStore {
    /// Opens the file and reads its header, root directory and metadata; a file that is not a
    /// PMTiles v3 archive of glb or terrain tiles, or whose header or root directory points
    /// outside it, is an error naming it. A tile longer than `max_tile` bytes, uncompressed,
    /// is damaged.
    pub fn open(path: &Path, max_tile: u64) -> Result<PmtilesStore, StoreError> {
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
            max_tile,
        };
        let bytes = store.read_at(0, HEADER_LEN as u64)?;
        store.header = Header::parse(&bytes).map_err(|report| store.damaged(report))?;
        store.check_sections()?;
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

    /// Each section the header names lies inside the file.
    fn check_sections(&self) -> Result<(), StoreError> {
        let header = &self.header;
        for (name, (offset, length)) in [
            ("root directory", header.root),
            ("metadata", header.metadata),
            ("leaf directories", header.leaves),
            ("tile data", header.data),
        ] {
            if offset.checked_add(length).is_none_or(|end| end > self.len) {
                return Err(self.damaged(format!(
                    "its {name} points at bytes {offset} to {} of its {}",
                    u128::from(offset) + u128::from(length),
                    self.len
                )));
            }
        }
        Ok(())
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

    /// The bytes of a directory or the metadata (`what`), uncompressed: at most `limit`.
    fn internal(
        &self,
        offset: u64,
        length: u64,
        limit: u64,
        what: &str,
    ) -> Result<Vec<u8>, StoreError> {
        self.inflated(
            self.read_at(offset, length)?,
            self.header.internal_gzip,
            limit,
        )
        .map_err(|e| self.damaged(format!("{what}: {e}")))
    }

    /// `bytes` inflated when `gzip`, and at most `limit` bytes either way.
    fn inflated(
        &self,
        bytes: Vec<u8>,
        gzip: bool,
        limit: u64,
    ) -> Result<Vec<u8>, crate::inflate::InflateError> {
        match gzip {
            true => crate::inflate::gunzip(&bytes, limit),
            false if bytes.len() as u64 > limit => {
                Err(crate::inflate::InflateError::TooLarge { limit })
            }
            false => Ok(bytes),
        }
    }

    fn directory(&self, offset: u64, length: u64) -> Result<Vec<Entry>, StoreError> {
        let bytes = self.internal(offset, length, MAX_DIRECTORY_BYTES, "a directory")?;
        let entries = parse_directory(&bytes).map_err(|report| self.damaged(report))?;
        self.check_entries(&entries)?;
        Ok(entries)
    }

    /// Each entry's bytes lie inside its section (a tile's in the tile data, a leaf's among
    /// the leaf directories) and each run of tiles inside the zooms the header names.
    fn check_entries(&self, entries: &[Entry]) -> Result<(), StoreError> {
        let ids = ids_to_zoom(self.header.max_zoom);
        for entry in entries {
            let end = entry.offset.checked_add(u64::from(entry.length));
            let (section, size) = match entry.run_length {
                0 => ("leaf directories", self.header.leaves.1),
                _ => ("tile data", self.header.data.1),
            };
            if end.is_none_or(|end| end > size) {
                return Err(self.damaged(format!(
                    "an entry points at bytes {} to {} of its {section}, which hold {size}",
                    entry.offset,
                    u128::from(entry.offset) + u128::from(entry.length)
                )));
            }
            let last = entry.tile_id.checked_add(u64::from(entry.run_length));
            if last.is_none_or(|last| last > ids) {
                return Err(self.damaged(format!(
                    "an entry's run of {} tiles from tile number {} passes zoom {}, its \
                     finest",
                    entry.run_length, entry.tile_id, self.header.max_zoom
                )));
            }
        }
        Ok(())
    }

    fn leaf(&self, offset: u64, length: u64) -> Result<Arc<Vec<Entry>>, StoreError> {
        if let Some(leaf) = self.leaves().get(&offset) {
            return Ok(leaf.clone());
        }
        let (base, _) = self.header.leaves;
        let at = base
            .checked_add(offset)
            .ok_or_else(|| self.damaged("a leaf directory's offset overflows"))?;
        let leaf = Arc::new(self.directory(at, length)?);
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
            let bytes = self.internal(offset, length, MAX_METADATA_BYTES, "its metadata")?;
            serde_json::from_slice(&bytes)
                .map_err(|e| self.damaged(format!("its metadata is not JSON: {e}")))?
        };
        let entry = metadata.get(CONTENTS_KEY);
        let named = entry
            .and_then(|e| e["format"].as_str())
            .or(metadata["format"].as_str());
        let format = named.and_then(super::format_named).ok_or_else(|| {
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

    fn stored_entry(&self, tile: TileId, entry: &Entry) -> StoredEntry {
        StoredEntry {
            key: TileKey {
                tile,
                format: self.contents.format,
            },
            made_by: self.provenance(),
            size: u64::from(entry.length),
            accessed_at: 0,
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
        let (min_zoom, max_zoom) = (bytes[100], bytes[101]);
        if max_zoom > crate::tile::MAX_ZOOM || min_zoom > max_zoom {
            return Err(format!(
                "its zooms run from {min_zoom} to {max_zoom}; tiles go from 0 to {}",
                crate::tile::MAX_ZOOM
            ));
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
            min_zoom,
            max_zoom,
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

/// How many tile numbers the zooms from 0 to `zoom` take: (4^(zoom+1) − 1) / 3.
fn ids_to_zoom(zoom: u8) -> u64 {
    let zoom = u32::from(zoom.min(crate::tile::MAX_ZOOM));
    ((1u64 << (2 * (zoom + 1))) - 1) / 3
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
            (0, i) if i > 0 => entries[i - 1]
                .offset
                .checked_add(u64::from(entries[i - 1].length))
                .ok_or("an offset overflows")?,
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

impl TileReader for PmtilesStore {
    fn get(&self, key: &TileKey) -> Result<Option<StoredTile>, StoreError> {
        if key.format != self.contents.format {
            return Ok(None);
        }
        let Some(entry) = self.find(key.tile)? else {
            return Ok(None);
        };
        // The entry lies inside the tile data, and the tile data inside the file: checked when
        // the directory was read.
        let (base, _) = self.header.data;
        let at = base
            .checked_add(entry.offset)
            .ok_or_else(|| self.damaged(format!("tile {}'s offset overflows", key.tile)))?;
        let bytes = self.read_at(at, u64::from(entry.length))?;
        let data = self
            .inflated(bytes, self.header.tile_gzip, self.max_tile)
            .map_err(|e| self.damaged(format!("tile {}: {e}", key.tile)))?;
        archived_tile(data, self.provenance()).map(Some)
    }

    fn list(&self, filter: &TileFilter) -> Result<Vec<StoredEntry>, StoreError> {
        let mut listed = Vec::new();
        self.each(filter, &mut |entry| listed.push(entry))?;
        Ok(listed)
    }

    /// Walks the runs of tiles, never listing one whole: named tiles are looked up, and a
    /// range longer than a run is walked over the range instead.
    fn each(
        &self,
        filter: &TileFilter,
        visit: &mut dyn FnMut(StoredEntry),
    ) -> Result<(), StoreError> {
        if let TileFilter::Tiles(tiles) = filter {
            for &tile in tiles {
                if let Some(entry) = self.find(tile)? {
                    visit(self.stored_entry(tile, &entry));
                }
            }
            return Ok(());
        }
        for entry in self.entries()? {
            // Runs end inside the header's zooms: checked when their directory was read.
            let run = entry.tile_id..entry.tile_id.saturating_add(u64::from(entry.run_length));
            match filter {
                TileFilter::Range(range) if range.len() < u64::from(entry.run_length) => {
                    for tile in range.tiles() {
                        if hilbert_id(tile).is_some_and(|id| run.contains(&id)) {
                            visit(self.stored_entry(tile, &entry));
                        }
                    }
                }
                _ => {
                    for tile in run.filter_map(tile_of) {
                        if filter.matches(tile) {
                            visit(self.stored_entry(tile, &entry));
                        }
                    }
                }
            }
        }
        Ok(())
    }

    fn usage(&self) -> Result<Usage, StoreError> {
        let mut usage = Usage::default();
        for entry in self.entries()? {
            let run = u64::from(entry.run_length);
            usage.tiles = usage.tiles.saturating_add(run);
            usage.bytes = usage
                .bytes
                .saturating_add(run.saturating_mul(u64::from(entry.length)));
        }
        Ok(usage)
    }
}

/// Writes a PMTiles v3 file of `keys` into `into` (named `path` in errors), with the
/// `pmtiles` crate, tiles in Hilbert order (a clustered archive), each tile's bytes asked of
/// `body` in turn.
pub fn write<E: From<WriteError>>(
    (into, path): (&Path, &Path),
    contents: &Contents,
    keys: &[TileKey],
    body: &mut TileBodies<'_, E>,
) -> Result<(), E> {
    let failed = |source| WriteError::Pmtiles {
        path: path.to_path_buf(),
        source,
    };
    let mut ordered: Vec<(pmtiles::TileCoord, &TileKey)> = Vec::with_capacity(keys.len());
    for key in keys {
        let (z, x, y) = (key.tile.z, key.tile.x, key.tile.y);
        ordered.push((pmtiles::TileCoord::new(z, x, y).map_err(failed)?, key));
    }
    ordered.sort_by_key(|(coord, _)| pmtiles::TileId::from(*coord).value());
    let mut document = serde_json::Map::new();
    for (name, value) in metadata(contents) {
        let value = match name {
            CONTENTS_KEY => serde_json::from_str(&value).unwrap_or(Value::Null),
            _ => Value::String(value),
        };
        document.insert(name.to_string(), value);
    }
    let zoom = contents.max_zoom();
    let mut writer = pmtiles::PmTilesWriter::new(pmtiles::TileType::Unknown)
        .min_zoom(contents.zooms.first().copied().unwrap_or(zoom))
        .max_zoom(zoom)
        .center_zoom(zoom)
        .metadata(Value::Object(document).to_string());
    if let Some(b) = contents.bounds {
        writer = writer
            .bounds(b.west, b.south, b.east, b.north)
            .center((b.west + b.east) / 2.0, (b.south + b.north) / 2.0);
    }
    let file = std::fs::File::create(into).map_err(|source| WriteError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let mut writer = writer
        .create(std::io::BufWriter::new(file))
        .map_err(failed)?;
    for (coord, key) in ordered {
        let data = body(key)?;
        writer.add_tile(coord, &data).map_err(failed)?;
    }
    writer.finalize().map_err(failed)?;
    Ok(())
}

#[cfg(test)]
mod tests;
