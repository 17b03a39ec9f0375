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

mod find;
mod read;
pub(super) use find::{cluster_data, clusters, Candidates, FoundGroup};
use find::{find_joints, find_structures};
use read::*;

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
    /// What far views draw, generalised (see [`super::far`]).
    pub generalise: crate::osm::far::Generalise,
}

/// What the import is doing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Phase {
    #[default]
    Reading,
    Resolving,
    Indexing,
    Structures,
    FarViews,
    Finishing,
}

impl Phase {
    pub fn as_str(self) -> &'static str {
        match self {
            Phase::Reading => "reading",
            Phase::Resolving => "resolving ways",
            Phase::Indexing => "indexing",
            Phase::Structures => "bridges and tunnels",
            Phase::FarViews => "far views",
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
    /// Rows of the far views' generalised data.
    pub far_rows: u64,
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
    #[error(transparent)]
    Store(#[from] super::StoreError),
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
    state.phase = Phase::FarViews;
    progress(&state);
    imported.far_rows = make_far(partial, zoom, rules)?;
    clock.done(Phase::FarViews);
    state.phase = Phase::Finishing;
    progress(&state);
    write_meta(partial, &records, zoom)?;
    Ok(imported)
}

/// The far views' rows of every tile holding data, in one transaction.
fn make_far(partial: &Partial, zoom: u8, rules: &Rules) -> Result<u64, ImportError> {
    let sqlite = partial.sqlite();
    partial.db.execute_batch("BEGIN").map_err(&sqlite)?;
    let made = super::far::make(
        &partial.db,
        &partial.path,
        zoom,
        rules.generalise,
        super::far::MARGIN_DEG,
        None,
    )?;
    partial.db.execute_batch("COMMIT").map_err(&sqlite)?;
    Ok(made.rows as u64)
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
