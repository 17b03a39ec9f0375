//! `terrastitch import`: OSM extracts into the on-disk store, streaming, in bounded memory.
//!
//! 1. **Read** each extract once, block by block: node positions go to a file of
//!    [`NodeLocations`], tagged nodes, raw ways (tags and node ids) and relations to SQLite.
//!    Where several extracts hold an element, the first one listed wins.
//! 2. **Resolve** the ways in id order: their positions from the node file (nodes missing from
//!    the extracts are left out, and a way with fewer than two is dropped, as the in-memory
//!    reader does); each way, tagged node and relation is registered in every zoom-14 cell its
//!    box meets, and the node references of the ways that join the road network are kept.
//! 3. **Find once over all the data** what a tile needs from beyond itself: the joints of the
//!    road network (nodes met more than once by its ways), the bridge and tunnel groups with
//!    what they cross and what stands over their tunnels, where bridges pass over ways, and
//!    the coastlines. Groups are found a cluster of bridge and tunnel ways at a time (ways
//!    whose surroundings share a cell), among what can take part in one: the structure ways,
//!    the ways they may cross, and near tunnels what reaches into the ground.
//!
//! Everything is written to `PATH.partial` and renamed over the store when whole, so a store
//! at its path is always a finished one; an import that stops leaves the old store in use.
//! Memory holds SQLite's page cache, the node file's block cache and index, two batches of
//! blocks (one decoded while the other is written), a run each of the cells' rows and of the
//! joint references being sorted, the ids of the bridge and tunnel ways, one cluster's
//! surroundings while its groups are found, and the groups found until they are written.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use osmpbf::{BlobDecode, BlobReader, Element};
use rusqlite::types::Value;
use rusqlite::{params, Connection};

use super::batch_insert::BatchInsert;
use super::codec::{self, DecodeError};
use super::resolve::{Resolved, ResolvedWriter, Resolver};
use super::{ExtractRecord, FORMAT, SCHEMA};
use crate::osm::index::{cells_of, meets};
use crate::osm::structures::Classify;
use crate::osm::{bounds_of, Bounds, LonLat, OsmData, OsmIndex, Tags, Way};
use crate::source::external_sort::{ExternalSort, RUN_RECORDS};
use crate::source::node_locations::{Decimicro, NodeLocations, NodeStoreError, NodeWriter};
pub use crate::source::osm_pbf::ExtractRead;

/// The feature rules the store's extract-wide facts need (given by the layer that knows
/// tags' meanings).
#[derive(Debug, Clone, Copy)]
pub struct Rules {
    /// Which ways make up bridges and tunnels.
    pub classify: Classify,
    /// Which ways join the road network.
    pub joins: fn(&Tags) -> bool,
    /// How deep something reaches into the ground over a tunnel.
    pub depth: fn(&Tags) -> Option<f64>,
    /// Which relations tiles are made from (the others are not kept).
    pub relation: fn(&Tags) -> bool,
}

/// What the import is doing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Phase {
    #[default]
    Reading,
    Resolving,
    Indexing,
    Structures,
    Finishing,
}

impl Phase {
    pub fn as_str(self) -> &'static str {
        match self {
            Phase::Reading => "reading",
            Phase::Resolving => "resolving ways",
            Phase::Indexing => "indexing",
            Phase::Structures => "bridges and tunnels",
            Phase::Finishing => "finishing",
        }
    }
}

/// How far the import is.
#[derive(Debug, Clone, Copy, Default)]
pub struct Progress {
    pub phase: Phase,
    /// Bytes of the extracts read, of all of them.
    pub bytes: u64,
    pub total_bytes: u64,
    pub nodes: u64,
    pub ways: u64,
    pub relations: u64,
}

/// What an import wrote.
#[derive(Debug, Clone, Default)]
pub struct Imported {
    /// What each extract held, in the order read.
    pub read: Vec<ExtractRead>,
    pub nodes: u64,
    pub tagged_nodes: u64,
    pub ways: u64,
    pub relations: u64,
    pub groups: u64,
    pub joints: u64,
    /// Bytes of the store file.
    pub store_bytes: u64,
}

/// Elements of each kind a store holds: tagged nodes, ways, relations.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Held {
    pub tagged_nodes: u64,
    pub ways: u64,
    pub relations: u64,
}

impl std::fmt::Display for Held {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} tagged nodes, {} ways and {} relations",
            self.tagged_nodes, self.ways, self.relations
        )
    }
}

/// A kind of element the store held at least this many of is guarded: an import that would
/// keep fewer than half of them is refused unless forced.
const GUARDED_AT_LEAST: u64 = 10;

#[derive(Debug, thiserror::Error)]
pub enum ImportError {
    #[error("cannot read OSM extract {path} in the block that starts at byte {offset}: {message}")]
    Pbf {
        path: PathBuf,
        offset: u64,
        message: String,
    },
    #[error("cannot open OSM extract {path}: {source}")]
    Open {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("OSM extract {path} changed while it was imported; import it again")]
    Changed { path: PathBuf },
    #[error("OSM extract {path} holds no nodes")]
    Empty { path: PathBuf },
    #[error("OSM extract {path} {why}")]
    CutShort { path: PathBuf, why: String },
    #[error("importing would replace the {before} of the OSM store {store} with {after}: an extract cut short would do that. The store is unchanged; import with --force to replace it all the same")]
    WouldLose {
        store: PathBuf,
        before: Held,
        after: Held,
    },
    #[error("OSM extract {path} is not sorted by type then id")]
    Unsorted { path: PathBuf },
    #[error("OSM extract {path}: {source}")]
    Nodes {
        path: PathBuf,
        source: NodeStoreError,
    },
    #[error(transparent)]
    NodeFile(#[from] NodeStoreError),
    #[error("writing the OSM store {path}: {source}")]
    Sqlite {
        path: PathBuf,
        source: rusqlite::Error,
    },
    #[error("putting the OSM store in place at {path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error(transparent)]
    Decode(#[from] DecodeError),
}

/// Counts the bytes read and digests them (an extract's version is the digest of its bytes).
struct Counting<R> {
    inner: R,
    read: Arc<AtomicU64>,
    digest: Arc<std::sync::Mutex<sha2::Sha256>>,
}

impl<R: Read> Read for Counting<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        use sha2::Digest;
        let n = self.inner.read(buf)?;
        self.digest
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .update(&buf[..n]);
        self.read.fetch_add(n as u64, Ordering::Relaxed);
        Ok(n)
    }
}

/// The store being written.
pub(super) struct Partial {
    pub path: PathBuf,
    pub db: Connection,
}

impl Partial {
    /// The error of a file the import works in beside the store (a sort's runs).
    pub fn io(&self) -> impl Fn(std::io::Error) -> ImportError + '_ {
        move |source| ImportError::Io {
            path: self.path.clone(),
            source,
        }
    }

    pub fn sqlite(&self) -> impl Fn(rusqlite::Error) -> ImportError + '_ {
        move |source| ImportError::Sqlite {
            path: self.path.clone(),
            source,
        }
    }
}

/// Imports `extracts` into a store at `store` for tiles of zoom `zoom`, replacing the store
/// there when done. `progress` is told how far it is, often.
///
/// A store there that held at least ten of a kind of element (tagged nodes, ways, relations) is
/// not replaced by one holding fewer than half of them unless `force`: an extract cut at a
/// block boundary reads as a shorter one, and would otherwise empty the store.
pub fn import(
    extracts: &[PathBuf],
    store: &Path,
    zoom: u8,
    rules: &Rules,
    force: bool,
    progress: &dyn Fn(&Progress),
) -> Result<Imported, ImportError> {
    let partial_path = with_suffix(store, ".partial");
    let nodes_path = new_nodes_path(store);
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| ImportError::Io {
            path: path.clone(),
            source,
        }
    };
    if let Some(dir) = store.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(io(dir))?;
    }
    let sqlite = |source| ImportError::Sqlite {
        path: partial_path.clone(),
        source,
    };
    // One extract sorted by type then id (as published extracts are) is read in one pass,
    // its ways resolved as they come; others are read whole before their ways are resolved.
    let mut one_pass = extracts.len() == 1;
    let (partial, mut imported) = loop {
        let _ = std::fs::remove_file(&partial_path);
        let mut partial = begin(&partial_path)?;
        let outcome = write_all(
            &mut partial,
            extracts,
            &nodes_path,
            zoom,
            rules,
            one_pass,
            progress,
        );
        match outcome {
            Ok(imported) => break (partial, imported),
            Err(error) => {
                drop(partial);
                let _ = std::fs::remove_file(&partial_path);
                let _ = std::fs::remove_file(&nodes_path);
                if one_pass && matches!(error, ImportError::Unsorted { .. }) {
                    tracing::info!("{error}: reading it again, in two passes");
                    one_pass = false;
                    continue;
                }
                return Err(error);
            }
        }
    };
    partial
        .db
        .execute_batch("PRAGMA analysis_limit = 4000; ANALYZE;")
        .map_err(sqlite)?;
    if !force {
        if let Err(error) = keeps_most_of(store, &partial) {
            drop(partial);
            let _ = std::fs::remove_file(&partial_path);
            let _ = std::fs::remove_file(&nodes_path);
            return Err(error);
        }
    }
    drop(partial);
    // Durable before it replaces the store.
    std::fs::File::open(&partial_path)
        .and_then(|f| f.sync_all())
        .map_err(io(&partial_path))?;
    std::fs::rename(&partial_path, store).map_err(io(store))?;
    remove_other_node_files(store, &nodes_path);
    imported.store_bytes = std::fs::metadata(store).map_or(0, |m| m.len())
        + std::fs::metadata(&nodes_path).map_or(0, |m| m.len());
    Ok(imported)
}

/// What a store's database holds.
fn held(db: &Connection) -> rusqlite::Result<Held> {
    let count = |table: &str| {
        db.query_row(&format!("SELECT count(*) FROM {table}"), [], |row| {
            row.get::<_, i64>(0)
        })
        .map(|n| n.max(0) as u64)
    };
    Ok(Held {
        tagged_nodes: count("nodes")?,
        ways: count("ways")?,
        relations: count("relations")?,
    })
}

/// The new store keeps at least half of each kind of element the store at `store` holds, for
/// each kind it held [`GUARDED_AT_LEAST`] of; a store that cannot be read is not guarded.
fn keeps_most_of(store: &Path, partial: &Partial) -> Result<(), ImportError> {
    let flags = rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY;
    let Ok(before) = Connection::open_with_flags(store, flags).and_then(|db| held(&db)) else {
        return Ok(());
    };
    let after = held(&partial.db).map_err(partial.sqlite())?;
    let pairs = [
        (before.tagged_nodes, after.tagged_nodes),
        (before.ways, after.ways),
        (before.relations, after.relations),
    ];
    let loses = pairs
        .iter()
        .any(|&(before, after)| before >= GUARDED_AT_LEAST && after * 2 < before);
    match loses {
        true => Err(ImportError::WouldLose {
            store: store.to_path_buf(),
            before,
            after,
        }),
        false => Ok(()),
    }
}

/// A new store begun at `path`, with the tables the import works in.
fn begin(path: &Path) -> Result<Partial, ImportError> {
    let sqlite = |source| ImportError::Sqlite {
        path: path.to_path_buf(),
        source,
    };
    let db = Connection::open(path).map_err(sqlite)?;
    db.execute_batch(
        "PRAGMA journal_mode = OFF; PRAGMA synchronous = OFF; PRAGMA cache_size = -131072;
         PRAGMA temp_store = FILE; PRAGMA locking_mode = EXCLUSIVE;",
    )
    .map_err(sqlite)?;
    db.execute_batch(SCHEMA).map_err(sqlite)?;
    // The ways as read, the road network's node references, and the ways (with their boxes)
    // and nodes that may take part in bridge and tunnel groups (`near_tunnels`: only near a
    // tunnel).
    db.execute_batch(
        "CREATE TEMP TABLE raw_ways (id INTEGER PRIMARY KEY, data BLOB NOT NULL);
         CREATE TEMP TABLE parts (id INTEGER PRIMARY KEY, near_tunnels INTEGER NOT NULL,
             west REAL NOT NULL, south REAL NOT NULL, east REAL NOT NULL, north REAL NOT NULL);
         CREATE TEMP TABLE node_parts (id INTEGER PRIMARY KEY);",
    )
    .map_err(sqlite)?;
    Ok(Partial {
        path: path.to_path_buf(),
        db,
    })
}

/// A new name for the node file of the store at `store`: the store names the one it reads, so
/// a new import never writes over the file of the store in place.
fn new_nodes_path(store: &Path) -> PathBuf {
    let stamp = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos());
    with_suffix(store, &format!(".nodes-{stamp:x}-{}", std::process::id()))
}

/// Removes the node files of stores replaced or never finished, all but `keep`.
fn remove_other_node_files(store: &Path, keep: &Path) {
    let (Some(dir), Some(name)) = (store.parent(), store.file_name()) else {
        return;
    };
    let dir = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    let prefix = format!("{}.nodes-", name.to_string_lossy());
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let ours = entry.file_name().to_string_lossy().starts_with(&prefix);
        if ours && entry.file_name() != keep.file_name().unwrap_or_default() {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// Logs how long each phase took.
struct PhaseClock(std::time::Instant);

impl PhaseClock {
    fn start() -> PhaseClock {
        PhaseClock(std::time::Instant::now())
    }

    fn done(&mut self, phase: Phase) {
        tracing::info!(
            phase = phase.as_str(),
            ms = self.0.elapsed().as_millis() as u64,
            "import phase done"
        );
        self.0 = std::time::Instant::now();
    }
}

fn with_suffix(path: &Path, suffix: &str) -> PathBuf {
    let mut name = path.as_os_str().to_owned();
    name.push(suffix);
    PathBuf::from(name)
}

fn write_all(
    partial: &mut Partial,
    extracts: &[PathBuf],
    nodes_path: &Path,
    zoom: u8,
    rules: &Rules,
    one_pass: bool,
    progress: &dyn Fn(&Progress),
) -> Result<Imported, ImportError> {
    let total_bytes = extracts
        .iter()
        .map(|p| std::fs::metadata(p).map_or(0, |m| m.len()))
        .sum();
    let mut state = Progress {
        total_bytes,
        ..Progress::default()
    };
    let n = f64::from(1u32 << zoom);
    let mut nodes = Nodes::Writing(NodeWriter::create(nodes_path)?);
    let mut ways = ResolvedWriter::new(partial)?;
    let mut records = Vec::new();
    let mut read = Vec::new();
    let mut clock = PhaseClock::start();
    for path in extracts {
        let mut reading = Reading {
            partial,
            decoder: Decoder {
                path,
                rules,
                n,
                one_pass,
            },
        };
        let (record, held) = reading.extract(&mut nodes, &mut ways, &mut state, progress)?;
        records.push(record);
        read.push(held);
    }
    let mut resolver = nodes.into_resolver()?;
    let mut imported = Imported {
        read,
        nodes: resolver.locations().len(),
        ..Imported::default()
    };
    write_node_runs(partial, resolver.locations(), nodes_path)?;
    clock.done(Phase::Reading);
    if !one_pass {
        state.phase = Phase::Resolving;
        progress(&state);
        resolve_ways(
            partial,
            &mut resolver,
            &mut ways,
            n,
            rules,
            &state,
            progress,
        )?;
        clock.done(Phase::Resolving);
    }
    resolver.locations().sync()?;
    drop(resolver);
    let ResolvedWriter {
        structure_ways,
        joint_refs,
        mut cells,
        written,
        ..
    } = ways;
    state.ways = written;
    state.phase = Phase::Indexing;
    progress(&state);
    imported.tagged_nodes = index_nodes(partial, n, &mut cells)?;
    imported.relations = index_relations(partial, n, &mut cells)?;
    write_cells(partial, cells)?;
    imported.joints = find_joints(partial, joint_refs)?;
    imported.ways = state.ways;
    clock.done(Phase::Indexing);
    state.phase = Phase::Structures;
    progress(&state);
    imported.groups = find_structures(partial, &structure_ways, zoom, rules)?;
    clock.done(Phase::Structures);
    state.phase = Phase::Finishing;
    progress(&state);
    write_meta(partial, &records, zoom)?;
    Ok(imported)
}

/// The node file: written while nodes come, read once ways come.
enum Nodes {
    Writing(NodeWriter),
    Reading(Resolver),
    /// Between the two.
    Closed,
}

impl Nodes {
    /// Ends writing, once; the nodes can be read.
    fn resolver(&mut self) -> Result<&mut Resolver, ImportError> {
        if let Nodes::Writing(_) = self {
            if let Nodes::Writing(writer) = std::mem::replace(self, Nodes::Closed) {
                *self = Nodes::Reading(Resolver::new(writer.finish()?)?);
            }
        }
        match self {
            Nodes::Reading(resolver) => Ok(resolver),
            _ => Err(Nodes::closed()),
        }
    }

    fn into_resolver(mut self) -> Result<Resolver, ImportError> {
        self.resolver()?;
        match self {
            Nodes::Reading(resolver) => Ok(resolver),
            _ => Err(Nodes::closed()),
        }
    }

    /// A node file whose writing failed is not read.
    fn closed() -> ImportError {
        ImportError::NodeFile(NodeStoreError::Io {
            path: PathBuf::new(),
            source: std::io::Error::other("the node file was not finished"),
        })
    }
}

/// One block's elements, ready to write.
#[derive(Default)]
struct Rows {
    header: Option<Bounds>,
    /// Whether the header says the extract is sorted by type, then id.
    sorted: bool,
    /// A block of data (not the header).
    data: bool,
    /// Relations read, kept or not.
    relations_read: u64,
    /// The replication sequence the extract is current to, when its header says.
    sequence: Option<u64>,
    nodes: Vec<NodeRow>,
    ways: Vec<(i64, Vec<u8>)>,
    relations: Vec<(i64, Vec<u8>)>,
}

struct NodeRow {
    id: i64,
    at: Decimicro,
    position: LonLat,
    /// Its tags' row, when it has tags.
    tags: Option<Vec<u8>>,
    /// Whether it reaches into the ground (and may stand over a tunnel).
    deep: bool,
}

enum RowsError {
    Pbf(String),
    Nodes(NodeStoreError),
}

/// Blobs decoded at once, spread over the cores.
const BATCH: usize = 32;

/// Decodes a blob into rows.
fn rows_of(blob: &osmpbf::Blob, rules: &Rules) -> Result<Rows, RowsError> {
    let mut rows = Rows::default();
    match blob.decode().map_err(|e| RowsError::Pbf(e.to_string()))? {
        BlobDecode::OsmHeader(header) => {
            rows.header = crate::source::osm_pbf::bounds_in(&header);
            rows.sorted = header
                .optional_features()
                .iter()
                .any(|f| f == crate::source::osm_pbf::SORTED_BY_TYPE);
            rows.sequence = header
                .osmosis_replication_sequence_number()
                .and_then(|s| u64::try_from(s).ok());
        }
        BlobDecode::OsmData(block) => {
            rows.data = true;
            for element in block.elements() {
                let (id, nano, position, tags) = match &element {
                    Element::Node(n) => (
                        n.id(),
                        (n.nano_lon(), n.nano_lat()),
                        LonLat {
                            lon: n.lon(),
                            lat: n.lat(),
                        },
                        Tags::from_pairs(n.tags()),
                    ),
                    Element::DenseNode(n) => (
                        n.id(),
                        (n.nano_lon(), n.nano_lat()),
                        LonLat {
                            lon: n.lon(),
                            lat: n.lat(),
                        },
                        Tags::from_pairs(n.tags()),
                    ),
                    Element::Way(way) => {
                        let tags = Tags::from_pairs(way.tags());
                        let refs: Vec<i64> = way.refs().collect();
                        rows.ways
                            .push((way.id(), codec::encode_raw_way(&tags, &refs)));
                        continue;
                    }
                    Element::Relation(relation) => {
                        rows.relations_read += 1;
                        let relation = crate::source::osm_pbf::relation_of(relation);
                        if !(rules.relation)(&relation.tags) {
                            continue;
                        }
                        rows.relations
                            .push((relation.id, codec::encode_relation(&relation)));
                        continue;
                    }
                };
                let at = Decimicro::from_nano(id, nano.0, nano.1).map_err(RowsError::Nodes)?;
                let element_tags = tags;
                let tags = (!element_tags.is_empty()).then(|| {
                    let mut w = codec::Writer::default();
                    w.tags(&element_tags);
                    w.0
                });
                rows.nodes.push(NodeRow {
                    id,
                    at,
                    position,
                    deep: tags.is_some() && (rules.depth)(&element_tags).is_some(),
                    tags,
                });
            }
        }
        BlobDecode::Unknown(_) => {}
    }
    Ok(rows)
}

/// Decodes blobs on every core, in their order.
fn decode_all(blobs: &[(u64, osmpbf::Blob)], rules: &Rules) -> Vec<Result<Rows, (u64, RowsError)>> {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let per_thread = blobs.len().div_ceil(threads.max(1)).max(1);
    std::thread::scope(|scope| {
        let workers: Vec<_> = blobs
            .chunks(per_thread)
            .map(|chunk| {
                scope.spawn(move || {
                    chunk
                        .iter()
                        .map(|(offset, blob)| rows_of(blob, rules).map_err(|e| (*offset, e)))
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        workers
            .into_iter()
            .flat_map(|w| {
                w.join().unwrap_or_else(|_| {
                    vec![Err((
                        0,
                        RowsError::Pbf("decoding a block panicked".to_string()),
                    ))]
                })
            })
            .collect()
    })
}

/// One extract being read: a thread reads and decodes its blocks (on every core), writes the
/// node file and resolves the ways, while this one writes the store.
struct Reading<'a> {
    partial: &'a Partial,
    decoder: Decoder<'a>,
}

/// What the decoding thread hands the store's: a batch of blocks decoded (only the tagged
/// nodes kept), their ways resolved when they come after every node.
struct Decoded {
    rows: Vec<Rows>,
    resolved: Vec<Resolved>,
    /// Nodes and resolved ways in the batch.
    nodes: u64,
    ways: u64,
    /// Bytes of the extract read so far.
    read: u64,
}

/// What the decoding thread found of the whole extract.
#[derive(Default)]
struct Decoding {
    header: Option<Bounds>,
    extent: Option<Bounds>,
    sequence: Option<u64>,
    read: ExtractRead,
}

/// Reads and decodes one extract's blocks.
struct Decoder<'a> {
    path: &'a Path,
    rules: &'a Rules,
    n: f64,
    /// Whether its ways are resolved as they come (all its nodes come before them).
    one_pass: bool,
}

impl Decoder<'_> {
    fn failed(&self, offset: u64, error: RowsError) -> ImportError {
        match error {
            RowsError::Pbf(message) => ImportError::Pbf {
                path: self.path.to_path_buf(),
                offset,
                message,
            },
            RowsError::Nodes(source) => ImportError::Nodes {
                path: self.path.to_path_buf(),
                source,
            },
        }
    }

    fn unsorted(&self) -> ImportError {
        ImportError::Unsorted {
            path: self.path.to_path_buf(),
        }
    }

    /// Decodes the blocks `reader` gives, a batch at a time, and sends them on `send` until
    /// the extract ends or the receiver hangs up.
    fn run<R: Read + Send>(
        &self,
        mut reader: BlobReader<R>,
        read: &AtomicU64,
        nodes: &mut Nodes,
        send: std::sync::mpsc::SyncSender<Decoded>,
    ) -> Result<Decoding, ImportError> {
        let mut found = Decoding::default();
        let mut last_way = None;
        loop {
            let mut batch = Vec::with_capacity(BATCH);
            while batch.len() < BATCH {
                let offset = read.load(Ordering::Relaxed);
                let Some(blob) = reader.next() else { break };
                let blob = blob.map_err(|e| self.failed(offset, RowsError::Pbf(e.to_string())))?;
                batch.push((offset, blob));
            }
            if batch.is_empty() {
                return Ok(found);
            }
            let mut decoded = Decoded {
                rows: Vec::with_capacity(batch.len()),
                resolved: Vec::new(),
                nodes: 0,
                ways: 0,
                read: 0,
            };
            let mut batch_ways = Vec::new();
            for rows in decode_all(&batch, self.rules) {
                let mut rows = rows.map_err(|(offset, e)| self.failed(offset, e))?;
                found.header = rows.header.or(found.header);
                found.sequence = rows.sequence.or(found.sequence);
                found.read.sorted |= rows.sorted;
                found.read.blocks += u64::from(rows.data);
                found.read.nodes += rows.nodes.len() as u64;
                found.read.ways += rows.ways.len() as u64;
                found.read.relations += rows.relations_read;
                if self.one_pass && last_way.is_some() && !rows.nodes.is_empty() {
                    return Err(self.unsorted());
                }
                if self.one_pass {
                    for &(id, _) in &rows.ways {
                        if last_way.is_some_and(|last| id <= last) {
                            return Err(self.unsorted());
                        }
                        last_way = Some(id);
                    }
                    batch_ways.append(&mut rows.ways);
                }
                if !rows.nodes.is_empty() {
                    let Nodes::Writing(node_writer) = nodes else {
                        return Err(self.unsorted());
                    };
                    for node in &rows.nodes {
                        node_writer.push(node.id, node.at)?;
                        crate::source::osm_pbf::grow(&mut found.extent, node.position);
                    }
                    decoded.nodes += rows.nodes.len() as u64;
                    rows.nodes.retain(|node| node.tags.is_some());
                }
                decoded.rows.push(rows);
            }
            if !batch_ways.is_empty() {
                decoded.ways = batch_ways.len() as u64;
                decoded.resolved = nodes.resolver()?.resolve(&batch_ways, self.n, self.rules)?;
            }
            decoded.read = read.load(Ordering::Relaxed);
            if send.send(decoded).is_err() {
                // The store's thread stopped, with an error of its own.
                return Ok(found);
            }
        }
    }
}

impl Reading<'_> {
    /// Reads the extract: node positions to the node file, the rest to the store.
    fn extract(
        &mut self,
        nodes: &mut Nodes,
        ways: &mut ResolvedWriter,
        state: &mut Progress,
        progress: &dyn Fn(&Progress),
    ) -> Result<(ExtractRecord, ExtractRead), ImportError> {
        use sha2::Digest;
        let path = self.decoder.path;
        let file = std::fs::File::open(path).map_err(|source| ImportError::Open {
            path: path.to_path_buf(),
            source,
        })?;
        let read = Arc::new(AtomicU64::new(0));
        let digest = Arc::new(std::sync::Mutex::new(sha2::Sha256::new()));
        let counting = Counting {
            inner: std::io::BufReader::with_capacity(1 << 20, file),
            read: read.clone(),
            digest: digest.clone(),
        };
        let before = state.bytes;
        let reader = BlobReader::new(counting);
        // The version the store records is the one read: taken before, checked after.
        let file_version = crate::source::srtm::file_version(path).unwrap_or_default();
        let sqlite = self.partial.sqlite();
        self.partial.db.execute_batch("BEGIN").map_err(&sqlite)?;
        let found = std::thread::scope(|scope| {
            // Two batches in flight: one being decoded while one is written.
            let (send, receive) = std::sync::mpsc::sync_channel(1);
            let decoder = &self.decoder;
            let decoding = scope.spawn(move || decoder.run(reader, &read, nodes, send));
            let written = self.write_decoded(receive, ways, before, state, progress);
            let found = decoding.join().map_err(|_| ImportError::Io {
                path: path.to_path_buf(),
                source: std::io::Error::other("decoding the extract panicked"),
            });
            // The store's error first: the decoder only stops early because of it.
            written?;
            found?
        })?;
        self.partial.db.execute_batch("COMMIT").map_err(&sqlite)?;
        let digest = std::mem::take(&mut *digest.lock().unwrap_or_else(|p| p.into_inner()));
        let digest: String = digest.finalize()[..8]
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect();
        let read = ExtractRead {
            path: path.to_path_buf(),
            ..found.read
        };
        if let Some(why) = read.cut_short() {
            return Err(ImportError::CutShort {
                path: path.to_path_buf(),
                why,
            });
        }
        let bounds = found
            .header
            .or(found.extent)
            .ok_or_else(|| ImportError::Empty {
                path: path.to_path_buf(),
            })?;
        if crate::source::srtm::file_version(path).unwrap_or_default() != file_version {
            return Err(ImportError::Changed {
                path: path.to_path_buf(),
            });
        }
        let record = ExtractRecord {
            // Absolute, so the store is found current whichever directory a later command
            // runs in (a relative path would name another file there, and the store would be
            // imported again, losing the diffs applied to it).
            path: std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf()),
            digest,
            file_version,
            bounds: [bounds.west, bounds.south, bounds.east, bounds.north],
            replication_sequence: found.sequence,
        };
        Ok((record, read))
    }

    /// Writes what the decoder sends, as it comes; returns at its first error (dropping
    /// `receive`, which stops the decoder).
    fn write_decoded(
        &self,
        receive: std::sync::mpsc::Receiver<Decoded>,
        ways: &mut ResolvedWriter,
        before: u64,
        state: &mut Progress,
        progress: &dyn Fn(&Progress),
    ) -> Result<(), ImportError> {
        let mut writer = RowWriter::new(self.partial)?;
        for decoded in receive {
            for rows in decoded.rows {
                writer.write(rows, state)?;
            }
            for resolved in &decoded.resolved {
                ways.write(resolved)?;
            }
            state.nodes += decoded.nodes;
            state.ways += decoded.ways;
            state.bytes = before + decoded.read;
            progress(state);
        }
        ways.flush()
    }
}

/// Writes decoded rows: where an element is already stored (from an extract listed before),
/// the first one stays. Raw ways are kept to be resolved when all nodes are read, unless they
/// were taken to be resolved at once.
struct RowWriter<'a> {
    partial: &'a Partial,
    node: rusqlite::Statement<'a>,
    node_part: rusqlite::Statement<'a>,
    way: rusqlite::Statement<'a>,
    relation: rusqlite::Statement<'a>,
}

impl<'a> RowWriter<'a> {
    fn new(partial: &'a Partial) -> Result<RowWriter<'a>, ImportError> {
        let sqlite = partial.sqlite();
        let prepare = |sql: &str| partial.db.prepare(sql).map_err(&sqlite);
        Ok(RowWriter {
            partial,
            node: prepare(
                "INSERT OR IGNORE INTO nodes (id, lon, lat, tags) VALUES (?1, ?2, ?3, ?4)",
            )?,
            node_part: prepare("INSERT OR IGNORE INTO node_parts (id) VALUES (?1)")?,
            way: prepare("INSERT OR IGNORE INTO raw_ways (id, data) VALUES (?1, ?2)")?,
            relation: prepare("INSERT OR IGNORE INTO relations (id, data) VALUES (?1, ?2)")?,
        })
    }

    /// Writes the tagged nodes, raw ways and relations of `rows`.
    fn write(&mut self, rows: Rows, state: &mut Progress) -> Result<(), ImportError> {
        let sqlite = self.partial.sqlite();
        for node in rows.nodes {
            if let Some(tags) = node.tags {
                let p = node.position;
                self.node
                    .execute(params![node.id, p.lon, p.lat, tags])
                    .map_err(&sqlite)?;
                if node.deep {
                    self.node_part.execute(params![node.id]).map_err(&sqlite)?;
                }
            }
        }
        for (id, row) in rows.ways {
            self.way.execute(params![id, row]).map_err(&sqlite)?;
            state.ways += 1;
        }
        for (id, row) in rows.relations {
            self.relation.execute(params![id, row]).map_err(&sqlite)?;
            state.relations += 1;
        }
        Ok(())
    }
}

/// Ways resolved at once, over the cores.
const RESOLVE_BATCH: usize = 16_384;

/// Resolves the raw ways kept while the extracts were read, in id order.
fn resolve_ways(
    partial: &Partial,
    resolver: &mut Resolver,
    writer: &mut ResolvedWriter,
    n: f64,
    rules: &Rules,
    state: &Progress,
    progress: &dyn Fn(&Progress),
) -> Result<(), ImportError> {
    let sqlite = partial.sqlite();
    let db = &partial.db;
    db.execute_batch("BEGIN").map_err(&sqlite)?;
    let mut read = db
        .prepare("SELECT id, data FROM raw_ways ORDER BY id")
        .map_err(&sqlite)?;
    let mut rows = read.query([]).map_err(&sqlite)?;
    let mut batch = Vec::with_capacity(RESOLVE_BATCH);
    loop {
        let row = rows.next().map_err(&sqlite)?;
        if let Some(row) = row {
            batch.push((
                row.get::<_, i64>(0).map_err(&sqlite)?,
                row.get::<_, Vec<u8>>(1).map_err(&sqlite)?,
            ));
            if batch.len() < RESOLVE_BATCH {
                continue;
            }
        }
        for resolved in resolver.resolve(&batch, n, rules)? {
            writer.write(&resolved)?;
        }
        writer.flush()?;
        progress(state);
        if batch.len() < RESOLVE_BATCH {
            break;
        }
        batch.clear();
    }
    drop(rows);
    db.execute_batch("COMMIT; DROP TABLE raw_ways;")
        .map_err(&sqlite)?;
    Ok(())
}

/// The rows of the cells table, (x, y, kind, id), sorted before they are written: the table
/// is a B-tree on all four, filled in order.
pub(super) type CellRows = ExternalSort<4>;

/// Registers every row `select` gives (an id and a blob or two coordinates) as an element of
/// `kind` in the cells of the box `bounds` makes of it; returns how many rows there were.
fn register(
    partial: &Partial,
    n: f64,
    cells: &mut CellRows,
    select: &str,
    kind: i64,
    bounds: &dyn Fn(&rusqlite::Row<'_>) -> Result<Option<Bounds>, ImportError>,
) -> Result<u64, ImportError> {
    let sqlite = partial.sqlite();
    let db = &partial.db;
    db.execute_batch("BEGIN").map_err(&sqlite)?;
    let mut read = db.prepare(select).map_err(&sqlite)?;
    let mut rows = read.query([]).map_err(&sqlite)?;
    let mut count = 0u64;
    while let Some(row) = rows.next().map_err(&sqlite)? {
        let id: i64 = row.get(0).map_err(&sqlite)?;
        if let Some(b) = bounds(row)? {
            for (x, y) in cells_of(&b, n) {
                cells
                    .push([i64::from(x), i64::from(y), kind, id])
                    .map_err(partial.io())?;
            }
        }
        count += 1;
    }
    drop(rows);
    db.execute_batch("COMMIT").map_err(&sqlite)?;
    Ok(count)
}

/// Registers the tagged nodes in their cells; returns how many there are.
fn index_nodes(partial: &Partial, n: f64, cells: &mut CellRows) -> Result<u64, ImportError> {
    let sqlite = partial.sqlite();
    register(
        partial,
        n,
        cells,
        "SELECT id, lon, lat FROM nodes",
        0,
        &|row| {
            let position = LonLat {
                lon: row.get(1).map_err(&sqlite)?,
                lat: row.get(2).map_err(&sqlite)?,
            };
            Ok(bounds_of(&[position]))
        },
    )
}

/// Registers each relation in the cells of its ways' box (and its member relations' ways');
/// returns how many relations there are.
fn index_relations(partial: &Partial, n: f64, cells: &mut CellRows) -> Result<u64, ImportError> {
    let sqlite = partial.sqlite();
    let db = &partial.db;
    register(
        partial,
        n,
        cells,
        "SELECT id, data FROM relations",
        2,
        &|row| {
            let id: i64 = row.get(0).map_err(&sqlite)?;
            let data: Vec<u8> = row.get(1).map_err(&sqlite)?;
            let relation = codec::decode_relation(id, &data)?;
            let mut positions = Vec::new();
            for way in super::relation_ways(db, &relation).map_err(&sqlite)? {
                match super::way(db, way)? {
                    Some(way) => positions.extend(way.positions),
                    None => {
                        db.prepare_cached(
                            "INSERT OR IGNORE INTO missing_members (way, relation) VALUES (?1, ?2)",
                        )
                        .and_then(|mut insert| insert.execute(params![way, id]))
                        .map_err(&sqlite)?;
                    }
                }
            }
            Ok(bounds_of(&positions))
        },
    )
}

/// Writes the cells table, in its order.
fn write_cells(partial: &Partial, cells: CellRows) -> Result<(), ImportError> {
    let (sqlite, io) = (partial.sqlite(), partial.io());
    let db = &partial.db;
    db.execute_batch("BEGIN").map_err(&sqlite)?;
    {
        let mut insert =
            BatchInsert::new(db, "INSERT INTO cells (x, y, kind, id)", 4).map_err(&sqlite)?;
        for row in cells.sorted().map_err(&io)? {
            insert
                .push(row.map_err(&io)?.map(Value::Integer))
                .map_err(&sqlite)?;
        }
        insert.flush().map_err(&sqlite)?;
    }
    db.execute_batch("COMMIT").map_err(&sqlite)
}

/// The joints: nodes the road network's ways meet more than once (`refs`: each way's node
/// references, as (node, way)), with the ways through each; and for each way, its joints with
/// the ways through them. Returns how many joints there are.
fn find_joints(partial: &Partial, refs: ExternalSort<2>) -> Result<u64, ImportError> {
    let (sqlite, io) = (partial.sqlite(), partial.io());
    let db = &partial.db;
    db.execute_batch("BEGIN").map_err(&sqlite)?;
    // (way, joint, a way through it), for each way through each joint.
    let mut facts = ExternalSort::<3>::new(&partial.path, RUN_RECORDS);
    let mut joints = 0u64;
    {
        let mut insert = db
            .prepare("INSERT INTO joints (node, way) VALUES (?1, ?2)")
            .map_err(&sqlite)?;
        let mut joint = |node: i64, ways: &mut Vec<i64>| -> Result<(), ImportError> {
            if ways.len() > 1 {
                ways.dedup();
                for &way in ways.iter() {
                    insert.execute(params![node, way]).map_err(&sqlite)?;
                    for &through in ways.iter() {
                        facts.push([way, node, through]).map_err(&io)?;
                    }
                }
                joints += 1;
            }
            ways.clear();
            Ok(())
        };
        let mut current: Option<i64> = None;
        let mut ways = Vec::new();
        for r in refs.sorted().map_err(&io)? {
            let [node, way] = r.map_err(&io)?;
            if let Some(before) = current.filter(|&c| c != node) {
                joint(before, &mut ways)?;
            }
            current = Some(node);
            ways.push(way);
        }
        if let Some(node) = current {
            joint(node, &mut ways)?;
        }
    }
    {
        let mut insert = db
            .prepare("INSERT INTO way_facts (way, joints) VALUES (?1, ?2)")
            .map_err(&sqlite)?;
        let mut current: Option<(i64, codec::WayJoints)> = None;
        for fact in facts.sorted().map_err(&io)? {
            let [way, node, through] = fact.map_err(&io)?;
            if current.as_ref().is_some_and(|(w, _)| *w != way) {
                if let Some((w, joints)) = current.take() {
                    insert
                        .execute(params![w, codec::encode_joints(&joints)])
                        .map_err(&sqlite)?;
                }
            }
            let (_, joints) = current.get_or_insert_with(|| (way, Vec::new()));
            match joints.last_mut() {
                Some((n, ways)) if *n == node => ways.push(through),
                _ => joints.push((node, vec![through])),
            }
        }
        if let Some((w, joints)) = current {
            insert
                .execute(params![w, codec::encode_joints(&joints)])
                .map_err(&sqlite)?;
        }
    }
    db.execute_batch("COMMIT").map_err(&sqlite)?;
    Ok(joints)
}

/// A group found, ready to store: its place in the order of the whole data (its smallest
/// structure way id), its row, its box, and where its bridges pass over ways.
pub(super) struct FoundGroup {
    pub first_way: i64,
    pub row: Vec<u8>,
    pub bounds: Bounds,
    pub under: std::collections::HashMap<i64, Vec<LonLat>>,
}

/// Finds the bridge and tunnel groups, a cluster of nearby structure ways at a time, among
/// the elements near them, and stores them in the order the whole data's index finds them,
/// with where bridges pass over ways; returns how many groups there are.
///
/// A group's chains share nodes or cross, so its ways' boxes meet: the clusters of structure
/// ways whose boxes (grown by what may stand over a tunnel) overlap hold whole groups, and
/// memory holds one cluster's surroundings at a time.
fn find_structures(
    partial: &Partial,
    structure_ways: &[i64],
    zoom: u8,
    rules: &Rules,
) -> Result<u64, ImportError> {
    let n = f64::from(1u32 << zoom);
    // The store is read for one cluster while the groups of the one before are found.
    let clusters = batches(clusters(&partial.db, structure_ways, n, rules)?);
    // Found on every core (their order is restored below).
    let finders = std::thread::available_parallelism().map_or(1, |n| n.get());
    let (send, receive) = std::sync::mpsc::sync_channel::<(&Cluster, OsmData)>(finders);
    let receive = std::sync::Mutex::new(receive);
    let receive = &receive;
    let mut found: Vec<FoundGroup> = std::thread::scope(|scope| {
        let workers: Vec<_> = (0..finders)
            .map(|_| {
                scope.spawn(move || {
                    let mut found = Vec::new();
                    loop {
                        let next = receive.lock().unwrap_or_else(|p| p.into_inner()).recv();
                        let Ok((cluster, data)) = next else { break };
                        found.extend(cluster.groups(data, zoom, rules));
                    }
                    found
                })
            })
            .collect();
        for cluster in &clusters {
            let data = cluster_data(
                &partial.db,
                &partial.path,
                cluster,
                rules,
                Candidates::Marked,
            )?;
            if send.send((cluster, data)).is_err() {
                break;
            }
        }
        drop(send);
        let mut found = Vec::new();
        for worker in workers {
            found.extend(worker.join().map_err(|_| ImportError::Io {
                path: partial.path.clone(),
                source: std::io::Error::other("finding bridge and tunnel groups panicked"),
            })?);
        }
        Ok::<_, ImportError>(found)
    })?;
    found.sort_by_key(|g| g.first_way);
    let sqlite = partial.sqlite();
    let db = &partial.db;
    let mut under: std::collections::HashMap<i64, Vec<LonLat>> = Default::default();
    db.execute_batch("BEGIN").map_err(&sqlite)?;
    {
        let mut insert_group = db
            .prepare("INSERT INTO groups (id, data) VALUES (?1, ?2)")
            .map_err(&sqlite)?;
        let mut insert_cell = db
            .prepare("INSERT INTO cells (x, y, kind, id) VALUES (?1, ?2, 3, ?3)")
            .map_err(&sqlite)?;
        let mut insert_under = db
            .prepare("INSERT INTO group_under (way, grp, positions) VALUES (?1, ?2, ?3)")
            .map_err(&sqlite)?;
        for group in &found {
            let g = group.first_way;
            insert_group
                .execute(params![g, group.row])
                .map_err(&sqlite)?;
            for (x, y) in cells_of(&group.bounds, n) {
                insert_cell.execute(params![x, y, g]).map_err(&sqlite)?;
            }
            let mut ways: Vec<_> = group.under.iter().collect();
            ways.sort_by_key(|(way, _)| **way);
            for (way, positions) in ways {
                under.entry(*way).or_default().extend(positions);
                insert_under
                    .execute(params![way, g, codec::encode_positions(positions)])
                    .map_err(&sqlite)?;
            }
        }
        let mut insert_under = db
            .prepare(
                "INSERT INTO way_facts (way, under_bridges) VALUES (?1, ?2)
                 ON CONFLICT (way) DO UPDATE SET under_bridges = excluded.under_bridges",
            )
            .map_err(&sqlite)?;
        for (way, positions) in &under {
            insert_under
                .execute(params![way, codec::encode_positions(positions)])
                .map_err(&sqlite)?;
        }
    }
    db.execute_batch("COMMIT").map_err(&sqlite)?;
    Ok(found.len() as u64)
}

/// The cells of a cluster of structure ways: those their boxes meet, grown by what may stand
/// over a tunnel, and among them those near its tunnels.
#[derive(Debug, Default)]
pub(super) struct Cluster {
    /// Its structure ways.
    pub ways: BTreeSet<i64>,
    pub cells: BTreeSet<(u32, u32)>,
    pub near_tunnels: BTreeSet<(u32, u32)>,
    /// In each cell, the grown boxes of its structure ways there.
    pub boxes: BTreeMap<(u32, u32), Vec<Bounds>>,
}

impl Cluster {
    /// The groups of the cluster's ways among what was read around them (the same cells may
    /// hold ways of other clusters, whose groups are found with theirs).
    pub fn groups(&self, data: OsmData, zoom: u8, rules: &Rules) -> Vec<FoundGroup> {
        let mut groups = found_groups(data, zoom, rules);
        groups.retain(|g| self.ways.contains(&g.first_way));
        groups
    }
}

/// The clusters of structure ways: ways whose boxes, grown by what may stand over a tunnel,
/// overlap are in one cluster (a group's ways share nodes or cross, so their boxes meet).
pub(super) fn clusters(
    db: &Connection,
    structure_ways: &[i64],
    n: f64,
    rules: &Rules,
) -> Result<Vec<Cluster>, ImportError> {
    use crate::osm::structures::StructureKind;
    // Each way's grown box and whether it is a tunnel.
    let mut grown: Vec<(i64, Bounds, bool)> = Vec::with_capacity(structure_ways.len());
    for &id in structure_ways {
        let Some(way) = super::way(db, id)? else {
            continue;
        };
        let tunnel = matches!(
            (rules.classify)(&way.tags),
            Some((StructureKind::Tunnel, _))
        );
        if let Some(b) = bounds_of(&way.positions) {
            grown.push((id, b.expanded(crate::osm::index::ABOVE_TUNNEL_DEG), tunnel));
        }
    }
    let mut sets = DisjointSets::new(grown.len());
    // The cells find the pairs that may overlap; their boxes decide.
    let mut in_cell: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
    for (i, (_, b, _)) in grown.iter().enumerate() {
        for cell in cells_of(b, n) {
            let others = in_cell.entry(cell).or_default();
            for &other in others.iter() {
                if meets(b, &grown[other].1) {
                    sets.union(i, other);
                }
            }
            others.push(i);
        }
    }
    let mut by_root: BTreeMap<usize, Cluster> = BTreeMap::new();
    for (i, (id, b, tunnel)) in grown.iter().enumerate() {
        let cluster = by_root.entry(sets.find(i)).or_default();
        cluster.ways.insert(*id);
        let cells: Vec<(u32, u32)> = cells_of(b, n).collect();
        if *tunnel {
            cluster.near_tunnels.extend(cells.iter().copied());
        }
        for &cell in &cells {
            cluster.boxes.entry(cell).or_default().push(*b);
        }
        cluster.cells.extend(cells);
    }
    Ok(by_root.into_values().collect())
}

/// Clusters that share a cell, merged: the import reads each cell's elements once for all
/// the clusters there.
fn batches(clusters: Vec<Cluster>) -> Vec<Cluster> {
    let mut sets = DisjointSets::new(clusters.len());
    let mut owner: HashMap<(u32, u32), usize> = HashMap::new();
    for (i, cluster) in clusters.iter().enumerate() {
        for cell in &cluster.cells {
            match owner.get(cell) {
                Some(&other) => sets.union(i, other),
                None => {
                    owner.insert(*cell, i);
                }
            }
        }
    }
    let mut merged: BTreeMap<usize, Cluster> = BTreeMap::new();
    for (i, cluster) in clusters.into_iter().enumerate() {
        let batch = merged.entry(sets.find(i)).or_default();
        batch.ways.extend(cluster.ways);
        batch.cells.extend(cluster.cells);
        batch.near_tunnels.extend(cluster.near_tunnels);
        for (cell, boxes) in cluster.boxes {
            batch.boxes.entry(cell).or_default().extend(boxes);
        }
    }
    merged.into_values().collect()
}

/// Disjoint sets of indices.
struct DisjointSets(Vec<usize>);

impl DisjointSets {
    fn new(n: usize) -> DisjointSets {
        DisjointSets((0..n).collect())
    }

    fn find(&mut self, mut i: usize) -> usize {
        while self.0[i] != i {
            self.0[i] = self.0[self.0[i]];
            i = self.0[i];
        }
        i
    }

    fn union(&mut self, a: usize, b: usize) {
        let (a, b) = (self.find(a), self.find(b));
        self.0[a] = b;
    }
}

/// Which of a cell's elements are read to find groups.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Candidates {
    /// Every one (the store as a diff finds it).
    Every,
    /// Those the import marked as able to take part (its `parts` and `node_parts`).
    Marked,
}

impl Candidates {
    /// The query of a cell's nodes and ways: `kind`, `id`, whether it takes part only near
    /// tunnels, and a way's box when known.
    fn query(self) -> &'static str {
        match self {
            Candidates::Every => {
                "SELECT kind, id, 0, NULL, NULL, NULL, NULL FROM cells
                     WHERE x = ?1 AND y = ?2 AND kind < 2"
            }
            Candidates::Marked => {
                "SELECT c.kind, c.id, p.near_tunnels, p.west, p.south, p.east, p.north
                     FROM cells c JOIN parts p ON p.id = c.id
                     WHERE c.x = ?1 AND c.y = ?2 AND c.kind = 1
                 UNION ALL
                 SELECT c.kind, c.id, 1, NULL, NULL, NULL, NULL
                     FROM cells c JOIN node_parts p ON p.id = c.id
                     WHERE c.x = ?1 AND c.y = ?2 AND c.kind = 0"
            }
        }
    }
}

/// What can take part in a cluster's groups: the structure ways, the ways they may cross, and
/// near tunnels what reaches down into the ground.
pub(super) fn cluster_data(
    db: &Connection,
    path: &Path,
    cluster: &Cluster,
    rules: &Rules,
    candidates: Candidates,
) -> Result<OsmData, ImportError> {
    use crate::osm::structures::may_be_crossed;
    let sqlite = |source| ImportError::Sqlite {
        path: path.to_path_buf(),
        source,
    };
    // Each element in the cluster's cells, and whether it is near a tunnel.
    let mut way_ids: Vec<(i64, bool)> = Vec::new();
    let mut node_ids: Vec<(i64, bool)> = Vec::new();
    {
        let mut in_cell = db.prepare_cached(candidates.query()).map_err(&sqlite)?;
        for &cell in &cluster.cells {
            let tunnel = cluster.near_tunnels.contains(&cell);
            let structures = cluster.boxes.get(&cell).map_or(&[][..], Vec::as_slice);
            let rows = in_cell
                .query_map(params![cell.0, cell.1], |row| {
                    let bounds = match row.get::<_, Option<f64>>(3)? {
                        Some(west) => Some(Bounds {
                            west,
                            south: row.get(4)?,
                            east: row.get(5)?,
                            north: row.get(6)?,
                        }),
                        None => None,
                    };
                    Ok((
                        row.get::<_, i64>(0)?,
                        row.get::<_, i64>(1)?,
                        row.get::<_, bool>(2)?,
                        bounds,
                    ))
                })
                .map_err(&sqlite)?;
            for row in rows {
                let (kind, id, near_tunnels_only, bounds) = row.map_err(&sqlite)?;
                // One near tunnels only is left out where there are none (were it near one
                // in another cell, that cell gives it), and a way whose box meets no grown box
                // of a structure way here (it neither crosses one nor stands over a tunnel;
                // where it meets one in another cell, that cell gives it).
                if near_tunnels_only && !tunnel {
                    continue;
                }
                if bounds.is_some_and(|b| !structures.iter().any(|s| meets(s, &b))) {
                    continue;
                }
                match kind {
                    0 => node_ids.push((id, tunnel)),
                    _ => way_ids.push((id, tunnel)),
                }
            }
        }
    }
    for ids in [&mut way_ids, &mut node_ids] {
        // Near a tunnel in any of its cells counts.
        ids.sort_unstable_by_key(|&(id, tunnel)| (id, !tunnel));
        ids.dedup_by_key(|(id, _)| *id);
    }
    let mut data = OsmData::default();
    for (id, tunnel) in way_ids {
        if let Some(way) = super::way(db, id)? {
            let takes_part = (rules.classify)(&way.tags).is_some()
                || may_be_crossed(&way.tags)
                || (tunnel && (rules.depth)(&way.tags).is_some());
            if takes_part {
                data.ways.push(way);
            }
        }
    }
    for (id, tunnel) in node_ids {
        if !tunnel {
            continue;
        }
        if let Some(node) = super::node(db, id)? {
            if (rules.depth)(&node.tags).is_some() {
                data.nodes.push(node);
            }
        }
    }
    Ok(data)
}

/// The groups among a cluster's elements, as they will be stored.
fn found_groups(data: OsmData, zoom: u8, rules: &Rules) -> Vec<FoundGroup> {
    let index = OsmIndex::new(data, zoom, rules.classify).with_foundations(rules.depth);
    let ways: &[Way] = &index.data().ways;
    let way_id = |i: u32| ways.get(i as usize).map_or(0, |w| w.id);
    index
        .structures()
        .iter()
        .map(|group| FoundGroup {
            first_way: group
                .chains
                .iter()
                .flat_map(|c| c.ways.iter().map(|w| way_id(w.way)))
                .min()
                .unwrap_or(i64::MAX),
            row: codec::encode_group(group, &way_id),
            bounds: group.bounds,
            under: crate::osm::index::under_bridges(ways, std::slice::from_ref(group)),
        })
        .collect()
}

/// Keeps the node file and the index of its runs, for diffs to read.
fn write_node_runs(
    partial: &Partial,
    locations: &NodeLocations,
    nodes_path: &Path,
) -> Result<(), ImportError> {
    let sqlite = partial.sqlite();
    let mut insert = partial
        .db
        .prepare(
            "INSERT INTO node_runs (run, start, len, last, firsts) VALUES (?1, ?2, ?3, ?4, ?5)",
        )
        .map_err(&sqlite)?;
    for (k, run) in locations.index().iter().enumerate() {
        insert
            .execute(params![
                k as i64,
                run.start as i64,
                run.len as i64,
                run.last,
                run.firsts
            ])
            .map_err(&sqlite)?;
    }
    let name = nodes_path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    partial
        .db
        .execute(
            "INSERT INTO meta (key, value) VALUES ('nodes_file', ?1)",
            params![name],
        )
        .map_err(&sqlite)?;
    Ok(())
}

fn write_meta(partial: &Partial, records: &[ExtractRecord], zoom: u8) -> Result<(), ImportError> {
    let sqlite = partial.sqlite();
    // Diffs apply from the sequence the extracts are current to, when they all give one
    // (several extracts of one source current to different sequences give none).
    let sequences: Option<BTreeSet<u64>> = records.iter().map(|r| r.replication_sequence).collect();
    let one = sequences
        .filter(|s| s.len() == 1)
        .and_then(|s| s.first().copied());
    if let Some(first) = one {
        partial
            .db
            .execute(
                "INSERT INTO meta (key, value) VALUES ('replication_sequence', ?1)",
                params![first.to_string()],
            )
            .map_err(&sqlite)?;
    }
    let extracts = serde_json::to_string(records).unwrap_or_default();
    for (key, value) in [
        ("format", FORMAT.to_string()),
        ("zoom", zoom.to_string()),
        ("extracts", extracts),
        ("program", env!("CARGO_PKG_VERSION").to_string()),
        ("generation", "0".to_string()),
    ] {
        partial
            .db
            .execute(
                "INSERT INTO meta (key, value) VALUES (?1, ?2)",
                params![key, value],
            )
            .map_err(&sqlite)?;
    }
    Ok(())
}
