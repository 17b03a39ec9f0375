//! Node locations on disk while an extract is imported: every node's id and position, written
//! as the extract gives them and read back when its ways are resolved, in bounded memory
//! whatever the extract's size (the role of osm2pgsql's flat nodes and planetiler's node
//! location store).
//!
//! Records of 16 bytes (id, longitude and latitude in 10⁻⁷ degrees) are appended to one file in
//! *runs* of ascending ids; an extract sorted by type then id (as Geofabrik's and osmium's are)
//! is one run, and another run starts where an id is not above the last. Nodes are taken
//! [`CHUNK`] at a time and sorted before they are written, so an unsorted extract makes one run
//! a chunk, and runs beyond [`MERGED_ABOVE`] are merged into one when writing ends. Memory
//! holds the first id of every block of [`BLOCK_RECORDS`] records (1/256 of the file) and a
//! fixed number of blocks read lately. A lookup tries the runs in the order they were written,
//! so where several extracts hold a node, the first one's position is the one found.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};

/// Records per block: one 4 KiB read.
pub const BLOCK_RECORDS: usize = 256;
const RECORD: usize = 16;
const BLOCK: usize = BLOCK_RECORDS * RECORD;
/// Blocks kept in memory (64 MiB).
pub const CACHED_BLOCKS: usize = 16_384;
/// Nodes held and sorted before they are written (64 MiB).
pub const CHUNK: usize = 1 << 22;
/// More runs than this are merged into one: a lookup tries each.
pub const MERGED_ABOVE: usize = 16;

#[derive(Debug, thiserror::Error)]
pub enum NodeStoreError {
    #[error("node locations file {path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error(
        "node {id} lies at {nano_lon}, {nano_lat} nanodegrees, finer than the 100 nanodegrees \
         kept; extracts written with a coarser or the standard granularity are supported"
    )]
    Granularity {
        id: i64,
        nano_lon: i64,
        nano_lat: i64,
    },
    #[error(
        "node {id} lies at longitude {lon}, latitude {lat}: outside the world (longitudes run \
         from -180 to 180, latitudes from -90 to 90)"
    )]
    OutsideTheWorld { id: i64, lon: f64, lat: f64 },
}

/// Whether a position lies on the Earth: longitude −180…180, latitude −90…90, degrees.
pub fn on_the_earth(lon: f64, lat: f64) -> bool {
    (-180.0..=180.0).contains(&lon) && (-90.0..=90.0).contains(&lat)
}

/// A position as kept: 10⁻⁷ degrees.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Decimicro {
    pub lon: i32,
    pub lat: i32,
}

impl Decimicro {
    /// From nanodegrees, as a PBF block gives them; an error when they are not whole steps
    /// of 100.
    pub fn from_nano(id: i64, nano_lon: i64, nano_lat: i64) -> Result<Decimicro, NodeStoreError> {
        let fits = |nano: i64| nano % 100 == 0 && i32::try_from(nano / 100).is_ok();
        if !fits(nano_lon) || !fits(nano_lat) {
            return Err(NodeStoreError::Granularity {
                id,
                nano_lon,
                nano_lat,
            });
        }
        let at = Decimicro {
            lon: (nano_lon / 100) as i32,
            lat: (nano_lat / 100) as i32,
        };
        let (lon, lat) = at.lon_lat();
        match on_the_earth(lon, lat) {
            true => Ok(at),
            false => Err(NodeStoreError::OutsideTheWorld { id, lon, lat }),
        }
    }

    /// Degrees, exactly as a PBF reader computes them from nanodegrees.
    pub fn lon_lat(self) -> (f64, f64) {
        let degrees = |d: i32| 1e-9 * (i64::from(d) * 100) as f64;
        (degrees(self.lon), degrees(self.lat))
    }
}

#[derive(Debug, Clone, PartialEq)]
struct Run {
    /// Index of its first record in the file.
    start: u64,
    len: u64,
    /// First id of each of its blocks.
    firsts: Vec<i64>,
    last: i64,
}

/// Writes node locations; [`NodeWriter::finish`] turns it into a [`NodeLocations`].
#[derive(Debug)]
pub struct NodeWriter {
    path: PathBuf,
    out: BufWriter<File>,
    runs: Vec<Run>,
    written: u64,
    /// Nodes not written yet, in the order given.
    pending: Vec<(i64, Decimicro)>,
    /// How many are held before they are written.
    chunk: usize,
}

impl NodeWriter {
    /// A new file at `path` (replacing any there).
    pub fn create(path: &Path) -> Result<NodeWriter, NodeStoreError> {
        let file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(true)
            .open(path)
            .map_err(|source| NodeStoreError::Io {
                path: path.to_path_buf(),
                source,
            })?;
        Ok(NodeWriter {
            path: path.to_path_buf(),
            out: BufWriter::with_capacity(1 << 20, file),
            runs: Vec::new(),
            written: 0,
            pending: Vec::with_capacity(1024),
            chunk: CHUNK,
        })
    }

    fn io(&self, source: std::io::Error) -> NodeStoreError {
        NodeStoreError::Io {
            path: self.path.clone(),
            source,
        }
    }

    /// Appends one node.
    pub fn push(&mut self, id: i64, at: Decimicro) -> Result<(), NodeStoreError> {
        if self.pending.len() >= self.chunk {
            self.write_pending()?;
        }
        self.pending.push((id, at));
        Ok(())
    }

    /// Writes the nodes held, sorted by id; of one id given twice, the first stays.
    fn write_pending(&mut self) -> Result<(), NodeStoreError> {
        let mut pending = std::mem::take(&mut self.pending);
        if !pending.windows(2).all(|w| w[0].0 < w[1].0) {
            pending.sort_by_key(|&(id, _)| id);
            pending.dedup_by_key(|&mut (id, _)| id);
        }
        for &(id, at) in &pending {
            self.write(id, at)?;
        }
        pending.clear();
        self.pending = pending;
        Ok(())
    }

    fn write(&mut self, id: i64, at: Decimicro) -> Result<(), NodeStoreError> {
        let continues = self.runs.last().is_some_and(|run| id > run.last);
        if !continues {
            // A new run starts on a block boundary, so that blocks never mix runs.
            let pad =
                (BLOCK_RECORDS as u64 - self.written % BLOCK_RECORDS as u64) % BLOCK_RECORDS as u64;
            for _ in 0..pad {
                self.out.write_all(&[0; RECORD]).map_err(|e| self.io(e))?;
            }
            self.written += pad;
            self.runs.push(Run {
                start: self.written,
                len: 0,
                firsts: Vec::new(),
                last: id,
            });
        }
        let mut record = [0u8; RECORD];
        record[..8].copy_from_slice(&id.to_le_bytes());
        record[8..12].copy_from_slice(&at.lon.to_le_bytes());
        record[12..].copy_from_slice(&at.lat.to_le_bytes());
        self.out.write_all(&record).map_err(|e| self.io(e))?;
        self.written += 1;
        if let Some(run) = self.runs.last_mut() {
            if run.len % BLOCK_RECORDS as u64 == 0 {
                run.firsts.push(id);
            }
            run.len += 1;
            run.last = id;
        }
        Ok(())
    }

    /// Nodes taken so far.
    pub fn len(&self) -> u64 {
        self.runs.iter().map(|r| r.len).sum::<u64>() + self.pending.len() as u64
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The runs written; an extract not sorted by id makes many.
    pub fn runs(&self) -> usize {
        self.runs.len()
    }

    /// Ends writing; the locations can be read.
    pub fn finish(mut self) -> Result<NodeLocations, NodeStoreError> {
        self.write_pending()?;
        self.out.flush().map_err(|e| self.io(e))?;
        if self.runs.len() > MERGED_ABOVE {
            return self.merged();
        }
        let file = self.out.into_inner().map_err(|e| NodeStoreError::Io {
            path: self.path.clone(),
            source: e.into_error(),
        })?;
        Ok(NodeLocations {
            path: self.path,
            file,
            runs: self.runs,
            cache: (0..CACHED_BLOCKS).map(|_| None).collect(),
        })
    }
}

impl NodeWriter {
    /// The runs merged into one, in a file written beside and renamed over this one: of one
    /// id in several runs, the earliest run's position stays.
    fn merged(self) -> Result<NodeLocations, NodeStoreError> {
        let io = |path: &Path| {
            let path = path.to_path_buf();
            move |source| NodeStoreError::Io {
                path: path.clone(),
                source,
            }
        };
        let file = File::open(&self.path).map_err(io(&self.path))?;
        // Each run read in buffers of its own from one file: (next offset, records left,
        // buffer, place in it).
        let mut readers: Vec<(u64, u64, Vec<u8>, usize)> = self
            .runs
            .iter()
            .map(|run| (run.start * RECORD as u64, run.len, Vec::new(), 0))
            .collect();
        let mut next = |r: usize| -> Result<Option<(i64, Decimicro)>, NodeStoreError> {
            let (offset, left, buffer, at) = &mut readers[r];
            if *at == buffer.len() {
                if *left == 0 {
                    return Ok(None);
                }
                let records = (*left).min(4096);
                buffer.resize(records as usize * RECORD, 0);
                file.read_exact_at(buffer, *offset)
                    .map_err(io(&self.path))?;
                *offset += records * RECORD as u64;
                *left -= records;
                *at = 0;
            }
            let record = &buffer[*at..*at + RECORD];
            *at += RECORD;
            let mut id = [0u8; 8];
            let (mut lon, mut lat) = ([0u8; 4], [0u8; 4]);
            id.copy_from_slice(&record[..8]);
            lon.copy_from_slice(&record[8..12]);
            lat.copy_from_slice(&record[12..]);
            let at = Decimicro {
                lon: i32::from_le_bytes(lon),
                lat: i32::from_le_bytes(lat),
            };
            Ok(Some((i64::from_le_bytes(id), at)))
        };
        let mut heap = std::collections::BinaryHeap::new();
        for r in 0..self.runs.len() {
            if let Some((id, at)) = next(r)? {
                heap.push(std::cmp::Reverse((id, r, at.lon, at.lat)));
            }
        }
        let merged_path = {
            let mut name = self.path.as_os_str().to_owned();
            name.push(".merging");
            PathBuf::from(name)
        };
        let mut out = NodeWriter::create(&merged_path)?;
        let mut last = None;
        while let Some(std::cmp::Reverse((id, r, lon, lat))) = heap.pop() {
            if last != Some(id) {
                out.write(id, Decimicro { lon, lat })?;
                last = Some(id);
            }
            if let Some((id, at)) = next(r)? {
                heap.push(std::cmp::Reverse((id, r, at.lon, at.lat)));
            }
        }
        drop(self.out);
        std::fs::rename(&merged_path, &self.path).map_err(io(&self.path))?;
        out.path = self.path.clone();
        out.out.flush().map_err(|e| out.io(e))?;
        let file = out.out.into_inner().map_err(|e| NodeStoreError::Io {
            path: out.path.clone(),
            source: e.into_error(),
        })?;
        Ok(NodeLocations {
            path: out.path,
            file,
            runs: out.runs,
            cache: (0..CACHED_BLOCKS).map(|_| None).collect(),
        })
    }
}

/// Where one run lies in the file, as kept beside it: its first record, its length, its last
/// id and the first id of each of its blocks (little-endian).
#[derive(Debug, Clone, PartialEq)]
pub struct RunIndex {
    pub start: u64,
    pub len: u64,
    pub last: i64,
    pub firsts: Vec<u8>,
}

/// Node locations to read, by id.
#[derive(Debug)]
pub struct NodeLocations {
    path: PathBuf,
    file: File,
    runs: Vec<Run>,
    /// Blocks read lately, by block number (direct-mapped).
    cache: Vec<Option<(u64, Box<[u8]>)>>,
}

impl NodeLocations {
    /// Opens a file written before, with the index of its runs.
    pub fn open(path: &Path, index: &[RunIndex]) -> Result<NodeLocations, NodeStoreError> {
        let file = File::open(path).map_err(|source| NodeStoreError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let runs = index
            .iter()
            .map(|run| Run {
                start: run.start,
                len: run.len,
                last: run.last,
                firsts: run
                    .firsts
                    .chunks_exact(8)
                    .map(|c| i64::from_le_bytes(c.try_into().unwrap_or([0; 8])))
                    .collect(),
            })
            .collect();
        Ok(NodeLocations {
            path: path.to_path_buf(),
            file,
            runs,
            cache: (0..CACHED_BLOCKS).map(|_| None).collect(),
        })
    }

    /// The index of its runs, to open it again.
    pub fn index(&self) -> Vec<RunIndex> {
        self.runs
            .iter()
            .map(|run| RunIndex {
                start: run.start,
                len: run.len,
                last: run.last,
                firsts: run.firsts.iter().flat_map(|id| id.to_le_bytes()).collect(),
            })
            .collect()
    }

    /// Another reader of the same file, with a cache of `blocks` blocks of its own (for
    /// another thread).
    pub fn fork(&self, blocks: usize) -> Result<NodeLocations, NodeStoreError> {
        let file = self.file.try_clone().map_err(|source| NodeStoreError::Io {
            path: self.path.clone(),
            source,
        })?;
        Ok(NodeLocations {
            path: self.path.clone(),
            file,
            runs: self.runs.clone(),
            cache: (0..blocks.max(1)).map(|_| None).collect(),
        })
    }

    /// How many nodes it holds (of one id in several runs, each).
    pub fn len(&self) -> u64 {
        self.runs.iter().map(|r| r.len).sum()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Makes what was written durable.
    pub fn sync(&self) -> Result<(), NodeStoreError> {
        self.file.sync_all().map_err(|source| NodeStoreError::Io {
            path: self.path.clone(),
            source,
        })
    }

    /// The position of node `id`, from the first run that holds it.
    pub fn get(&mut self, id: i64) -> Result<Option<Decimicro>, NodeStoreError> {
        for r in 0..self.runs.len() {
            let run = &self.runs[r];
            if run.firsts.first().is_none_or(|&first| id < first) || id > run.last {
                continue;
            }
            let b = run.firsts.partition_point(|&first| first <= id) - 1;
            let block_number = run.start / BLOCK_RECORDS as u64 + b as u64;
            let records = (run.len - (b * BLOCK_RECORDS) as u64).min(BLOCK_RECORDS as u64);
            let block = self.block(block_number)?;
            let id_at = |k: usize| {
                let mut bytes = [0u8; 8];
                bytes.copy_from_slice(&block[k * RECORD..k * RECORD + 8]);
                i64::from_le_bytes(bytes)
            };
            let (mut low, mut high) = (0usize, records as usize);
            while low < high {
                let mid = (low + high) / 2;
                match id_at(mid).cmp(&id) {
                    std::cmp::Ordering::Less => low = mid + 1,
                    std::cmp::Ordering::Greater => high = mid,
                    std::cmp::Ordering::Equal => {
                        let at = &block[mid * RECORD + 8..(mid + 1) * RECORD];
                        let mut lon = [0u8; 4];
                        let mut lat = [0u8; 4];
                        lon.copy_from_slice(&at[..4]);
                        lat.copy_from_slice(&at[4..]);
                        return Ok(Some(Decimicro {
                            lon: i32::from_le_bytes(lon),
                            lat: i32::from_le_bytes(lat),
                        }));
                    }
                }
            }
        }
        Ok(None)
    }

    /// Block `number`, from memory or the file.
    fn block(&mut self, number: u64) -> Result<&[u8], NodeStoreError> {
        let slot = (number % self.cache.len().max(1) as u64) as usize;
        let held = matches!(&self.cache[slot], Some((n, _)) if *n == number);
        if !held {
            let mut buffer = vec![0u8; BLOCK].into_boxed_slice();
            let offset = number * BLOCK as u64;
            // The last block of the file may be short.
            let mut filled = 0;
            while filled < BLOCK {
                let n = self
                    .file
                    .read_at(&mut buffer[filled..], offset + filled as u64)
                    .map_err(|source| NodeStoreError::Io {
                        path: self.path.clone(),
                        source,
                    })?;
                if n == 0 {
                    break;
                }
                filled += n;
            }
            self.cache[slot] = Some((number, buffer));
        }
        Ok(self.cache[slot].as_ref().map_or(&[][..], |(_, b)| &b[..]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(k: i64) -> Decimicro {
        Decimicro {
            lon: (k * 7) as i32,
            lat: -(k as i32),
        }
    }

    #[test]
    fn every_node_written_is_found_again_when_the_file_is_opened_anew() {
        let dir = tempfile::tempdir().unwrap();
        let mut writer = NodeWriter::create(&dir.path().join("nodes")).unwrap();
        // Two sorted runs (as two extracts give), the second overlapping the first.
        for id in (1..2000).step_by(3) {
            writer.push(id, at(id)).unwrap();
        }
        for id in (1000..1300).step_by(2) {
            writer.push(id, at(-id)).unwrap();
        }
        let written = writer.finish().unwrap();
        let index = written.index();
        drop(written);
        let mut nodes = NodeLocations::open(&dir.path().join("nodes"), &index).unwrap();
        for id in 0..2100 {
            let expected = if id % 3 == 1 && id < 2000 {
                Some(at(id))
            } else if (1000..1300).contains(&id) && id % 2 == 0 {
                Some(at(-id))
            } else {
                None
            };
            assert_eq!(nodes.get(id).unwrap(), expected, "node {id}");
        }
    }

    #[test]
    fn an_unsorted_extract_is_merged_into_one_run_where_the_first_position_stays() {
        let dir = tempfile::tempdir().unwrap();
        let mut writer = NodeWriter::create(&dir.path().join("nodes")).unwrap();
        writer.chunk = 10;
        // Ids in a scrambled order, then some again with other positions (a second extract).
        let scrambled: Vec<i64> = (0..1000).map(|k| (k * 389) % 1000 + 1).collect();
        for &id in &scrambled {
            writer.push(id, at(id)).unwrap();
        }
        for id in (1..1000).step_by(7) {
            writer.push(id, at(-id)).unwrap();
        }
        let mut nodes = writer.finish().unwrap();
        assert_eq!(nodes.index().len(), 1, "one run");
        for id in 0..1002 {
            let expected = (1..=1000).contains(&id).then(|| at(id));
            assert_eq!(nodes.get(id).unwrap(), expected, "node {id}");
        }
    }

    #[test]
    fn a_fork_with_a_small_cache_finds_what_the_original_finds() {
        let dir = tempfile::tempdir().unwrap();
        let mut writer = NodeWriter::create(&dir.path().join("nodes")).unwrap();
        for id in (1..20_000).step_by(3) {
            writer.push(id, at(id)).unwrap();
        }
        let mut nodes = writer.finish().unwrap();
        let mut fork = nodes.fork(2).unwrap();
        assert_eq!(fork.len(), nodes.len());
        // Back and forth over many blocks, so the fork's two slots are reused.
        for id in (0..20_000).rev().chain(0..20_000) {
            assert_eq!(fork.get(id).unwrap(), nodes.get(id).unwrap(), "node {id}");
        }
    }

    #[test]
    fn positions_come_back_as_a_pbf_reader_gives_them() {
        let nano = (74_123_456_700_i64, 43_765_432_100_i64);
        let kept = Decimicro::from_nano(1, nano.0, nano.1).unwrap();
        assert_eq!(kept.lon_lat(), (1e-9 * nano.0 as f64, 1e-9 * nano.1 as f64));
        assert!(Decimicro::from_nano(1, 74_123_456_701, 0).is_err());
    }
}
