//! The imported OSM store: extracts read once ([`import`]) into SQLite, indexed by zoom-14
//! cell, with what was found once over all the data (road joints, bridge and tunnel groups,
//! where bridges pass over ways, coastlines). A tile reads what it needs from it and nothing
//! else: memory does not grow with the extract.
//!
//! [`OsmStore::tile_index`] gives the *closure* of a tile: every element near it (as the
//! in-memory index would select it), the whole of each bridge and tunnel group that reaches
//! near it with what the group crosses, the ways of its relations, the ways that meet its
//! ways at their joints, and the coastlines; indexed with the facts found over the whole data,
//! so a tile comes out byte for byte as from the extract in memory.

mod batch_insert;
pub mod codec;
pub mod far;
pub mod import;
mod resolve;
pub mod update;

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use rusqlite::{params, Connection, OpenFlags, OptionalExtension};

use crate::osm::coast::CoastBox;
use crate::osm::index::{cells_of, meets, relation_ways as model_relation_ways};
use crate::osm::{
    bounds_of, Bounds, ElementType, LonLat, Node, OsmData, OsmIndex, Relation, RoadGraph, Way,
};
use crate::tile::TileId;
use codec::DecodeError;

/// The schema of a store.
pub const SCHEMA: &str = include_str!("../../../migrations/osm_store.sql");
/// The store's format: a store of another is imported again.
pub const FORMAT: u32 = 6;

/// One extract as imported.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ExtractRecord {
    pub path: PathBuf,
    /// A digest of its bytes.
    pub digest: String,
    /// Its size and modification time when it was read.
    pub file_version: String,
    /// West, south, east, north: its header's box, else its nodes' extent.
    pub bounds: [f64; 4],
    /// The replication sequence it is current to, when its header says.
    #[serde(default)]
    pub replication_sequence: Option<u64>,
}

#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    #[error("OSM store {path}: {source}")]
    Sqlite {
        path: PathBuf,
        source: rusqlite::Error,
    },
    #[error("OSM store {path} is not a finished store of format {FORMAT}: {why}")]
    Format { path: PathBuf, why: String },
    #[error("OSM store {path}: {source}")]
    Decode { path: PathBuf, source: DecodeError },
}

/// An opened store.
#[derive(Debug)]
pub struct OsmStore {
    path: PathBuf,
    zoom: u8,
    extracts: Vec<ExtractRecord>,
    /// The version of the program that imported it (its facts follow that version's rules).
    program: String,
    /// How many diffs had been applied to it when it was opened.
    generation: u64,
    /// The boxes of the coastline ways, by id: which side of the coast a tile lies on is
    /// decided by the nearest one, wherever it is, and a tile reads the few that may be.
    coast: Vec<CoastBox>,
    /// Read-only connections not in use, all opened with the store: a store imported again
    /// is renamed over this one's path, and what was opened before reads on from the old file.
    idle: Mutex<Vec<Connection>>,
    returned: std::sync::Condvar,
}

/// Connections to a store: as many reads as may run at once.
fn connections() -> usize {
    2 * std::thread::available_parallelism().map_or(2, |n| n.get()) + 2
}

impl OsmStore {
    /// Opens a store; one of another format, or not finished, is an error naming it.
    pub fn open(path: &Path) -> Result<OsmStore, StoreError> {
        let db = connect(path)?;
        let sqlite = |source| StoreError::Sqlite {
            path: path.to_path_buf(),
            source,
        };
        let format_error = |why: String| StoreError::Format {
            path: path.to_path_buf(),
            why,
        };
        let meta = |key: &str| -> Result<Option<String>, StoreError> {
            db.query_row("SELECT value FROM meta WHERE key = ?1", [key], |row| {
                row.get(0)
            })
            .optional()
            .map_err(sqlite)
        };
        let format = meta("format").map_err(|e| format_error(e.to_string()))?;
        if format.as_deref() != Some(&FORMAT.to_string()) {
            return Err(format_error(format!("its format is {format:?}")));
        }
        let zoom = meta("zoom")?
            .and_then(|z| z.parse().ok())
            .ok_or_else(|| format_error("it names no zoom".to_string()))?;
        let program = meta("program")?.unwrap_or_default();
        let generation = meta("generation")?
            .and_then(|g| g.parse().ok())
            .unwrap_or(0);
        let extracts: Vec<ExtractRecord> = meta("extracts")?
            .and_then(|e| serde_json::from_str(&e).ok())
            .ok_or_else(|| format_error("it names no extracts".to_string()))?;
        let ids: Vec<i64> = {
            let mut statement = db
                .prepare("SELECT way FROM coastlines ORDER BY way")
                .map_err(sqlite)?;
            let rows = statement.query_map([], |row| row.get(0)).map_err(sqlite)?;
            rows.collect::<Result<_, _>>().map_err(sqlite)?
        };
        let decode = |source| StoreError::Decode {
            path: path.to_path_buf(),
            source,
        };
        let n = f64::from(1u32 << zoom);
        let mut coast = Vec::with_capacity(ids.len());
        for id in ids {
            if let Some(way) = way(&db, id).map_err(decode)? {
                coast.extend(CoastBox::of(way.id, &way.positions, n));
            }
        }
        let mut idle = vec![db];
        for _ in 1..connections() {
            idle.push(connect(path)?);
        }
        Ok(OsmStore {
            path: path.to_path_buf(),
            zoom,
            extracts,
            program,
            generation,
            coast,
            idle: Mutex::new(idle),
            returned: std::sync::Condvar::new(),
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The zoom of the cells it is indexed by.
    pub fn zoom(&self) -> u8 {
        self.zoom
    }

    /// The version of the program that imported it.
    pub fn program(&self) -> &str {
        &self.program
    }

    /// How many diffs had been applied to it when it was opened.
    pub fn generation(&self) -> u64 {
        self.generation
    }

    /// How many diffs have been applied to it by now (another process may apply them).
    pub fn current_generation(&self) -> Result<u64, StoreError> {
        self.with_connection(|db| {
            let value: Option<String> = db
                .query_row("SELECT value FROM meta WHERE key = 'generation'", [], |r| {
                    r.get(0)
                })
                .optional()
                .map_err(sqlite_error(&self.path))?;
            Ok(value.and_then(|g| g.parse().ok()).unwrap_or(0))
        })
    }

    /// The last diff that changed what a tile of the store's zoom inside `tile` reads, 0 when
    /// none did.
    pub fn tile_generation(&self, tile: TileId) -> Result<u64, StoreError> {
        let (x0, y0, x1, y1) = if tile.z >= self.zoom {
            let shift = tile.z - self.zoom;
            let (x, y) = (tile.x >> shift, tile.y >> shift);
            (x, y, x, y)
        } else {
            let shift = self.zoom - tile.z;
            let span = (1u32 << shift) - 1;
            (
                tile.x << shift,
                tile.y << shift,
                (tile.x << shift) + span,
                (tile.y << shift) + span,
            )
        };
        self.with_connection(|db| {
            db.prepare_cached(
                "SELECT coalesce(max(generation), 0) FROM expired
                 WHERE x BETWEEN ?1 AND ?3 AND y BETWEEN ?2 AND ?4",
            )
            .and_then(|mut s| s.query_row(params![x0, y0, x1, y1], |r| r.get::<_, i64>(0)))
            .map(|g| g as u64)
            .map_err(sqlite_error(&self.path))
        })
    }

    /// The extracts it was imported from, in the order given.
    pub fn extracts(&self) -> &[ExtractRecord] {
        &self.extracts
    }

    /// The area each extract declares.
    pub fn coverage(&self) -> Vec<Bounds> {
        self.extracts
            .iter()
            .map(|e| Bounds {
                west: e.bounds[0],
                south: e.bounds[1],
                east: e.bounds[2],
                north: e.bounds[3],
            })
            .collect()
    }

    fn decode(&self) -> impl Fn(DecodeError) -> StoreError + '_ {
        |source| StoreError::Decode {
            path: self.path.clone(),
            source,
        }
    }

    /// Runs `read` on a connection of its own, waiting for one when all are in use; the
    /// connection goes back to the pool however `read` ends, a panic included.
    fn with_connection<T>(
        &self,
        read: impl FnOnce(&Connection) -> Result<T, StoreError>,
    ) -> Result<T, StoreError> {
        struct Lent<'a> {
            store: &'a OsmStore,
            db: Option<Connection>,
        }
        impl Drop for Lent<'_> {
            fn drop(&mut self) {
                if let Some(db) = self.db.take() {
                    self.store
                        .idle
                        .lock()
                        .unwrap_or_else(|p| p.into_inner())
                        .push(db);
                    self.store.returned.notify_one();
                }
            }
        }
        let db = {
            let mut idle = self.idle.lock().unwrap_or_else(|p| p.into_inner());
            loop {
                if let Some(db) = idle.pop() {
                    break db;
                }
                idle = self.returned.wait(idle).unwrap_or_else(|p| p.into_inner());
            }
        };
        let lent = Lent {
            store: self,
            db: Some(db),
        };
        match &lent.db {
            Some(db) => read(db),
            None => unreachable!("a lent connection is held until it is dropped"),
        }
    }

    /// The closure of `tile` (see the module's notes), indexed: its query for the tile with
    /// `margin_deg` selects what the whole data's index would.
    pub fn tile_index(&self, tile: TileId, margin_deg: f64) -> Result<OsmIndex, StoreError> {
        // One read transaction for the whole closure: one snapshot of the store (an update
        // committing meanwhile is seen whole or not at all), and SQLite takes its lock and
        // checks its files once, not at each of the closure's thousands of reads.
        self.with_connection(|db| {
            db.execute_batch("BEGIN")
                .map_err(|source| StoreError::Sqlite {
                    path: self.path.clone(),
                    source,
                })?;
            let closure = self.closure(db, tile, margin_deg);
            if db.execute_batch("COMMIT").is_err() {
                let _ = db.execute_batch("ROLLBACK");
            }
            closure
        })
    }

    /// The generalised data of `tile`, a tile of a zoom far views are made at (see [`far`]),
    /// with the coastline ways that may decide its side of the coast.
    pub fn far_tile(&self, tile: TileId) -> Result<crate::osm::far::FarTile, StoreError> {
        self.with_connection(|db| {
            let data = far::read(db, &self.path, tile)?.unwrap_or_default();
            let mut coast = BTreeMap::new();
            self.add_nearest_coast(db, tile, &mut coast)?;
            Ok(crate::osm::far::FarTile {
                data,
                coast: coast.into_values().collect(),
            })
        })
    }

    fn closure(
        &self,
        db: &Connection,
        tile: TileId,
        margin_deg: f64,
    ) -> Result<OsmIndex, StoreError> {
        let Selected {
            mut ways,
            relations,
            groups,
            known,
            nodes,
        } = select(db, &self.path, self.zoom, tile, margin_deg)?;
        self.add_nearest_coast(db, tile, &mut ways)?;
        let data = OsmData {
            nodes,
            ways: ways.into_values().collect(),
            relations: relations.into_values().collect(),
            coverage: self.coverage(),
        };
        let groups: Vec<Vec<u8>> = groups.into_iter().map(|(_, row)| row).collect();
        self.index(db, data, &groups, known)
    }

    /// Adds to a closure's ways the coastline ways that may hold the point of the coast
    /// nearest to the tile's centre (see [`crate::osm::coast`]).
    fn add_nearest_coast(
        &self,
        db: &Connection,
        tile: TileId,
        ways: &mut BTreeMap<i64, Way>,
    ) -> Result<(), StoreError> {
        let n = f64::from(1u32 << self.zoom);
        let p = crate::osm::index::coast_point(tile, self.zoom);
        let mut read: HashMap<i64, Way> = HashMap::new();
        let mut failed = None;
        let kept = crate::osm::coast::nearest(&self.coast, p, |k| {
            let id = self.coast[k].id;
            if let Some(way) = ways.get(&id).or(read.get(&id)) {
                return Some(crate::osm::coast::distance_to_way(way, p, n));
            }
            match way(db, id) {
                Ok(Some(found)) => {
                    let d = crate::osm::coast::distance_to_way(&found, p, n);
                    read.insert(id, found);
                    Some(d)
                }
                Ok(None) => None,
                Err(error) => {
                    failed.get_or_insert(error);
                    None
                }
            }
        });
        if let Some(error) = failed {
            return Err(decode_error(&self.path)(error));
        }
        for k in kept {
            let id = self.coast[k].id;
            if ways.contains_key(&id) {
                continue;
            }
            let found = match read.remove(&id) {
                Some(found) => Some(found),
                None => way(db, id).map_err(decode_error(&self.path))?,
            };
            if let Some(found) = found {
                ways.insert(id, found);
            }
        }
        Ok(())
    }

    /// Indexes a closure with the facts found over the whole data.
    fn index(
        &self,
        db: &Connection,
        data: OsmData,
        groups: &[Vec<u8>],
        mut known: std::collections::HashMap<i64, WayFacts>,
    ) -> Result<OsmIndex, StoreError> {
        let decode = self.decode();
        let index_of = |id: i64| -> Option<u32> {
            data.ways
                .binary_search_by_key(&id, |w| w.id)
                .ok()
                .map(|i| i as u32)
        };
        let mut structures = Vec::with_capacity(groups.len());
        for bytes in groups {
            structures.push(codec::decode_group(bytes, &mut |id| index_of(id)).map_err(&decode)?);
        }
        let mut roads = RoadGraph::default();
        for way in &data.ways {
            let facts = match known.remove(&way.id) {
                Some(facts) => facts,
                None => facts(db, way.id).map_err(&decode)?,
            };
            for (node, through) in facts.joints {
                roads
                    .joints
                    .entry(node)
                    .or_insert_with(|| through.into_iter().filter_map(index_of).collect());
            }
            if let Some(under) = facts.under_bridges {
                roads.under_bridges.insert(way.id, under);
            }
        }
        let coastlines: Vec<u32> = self.coast.iter().filter_map(|b| index_of(b.id)).collect();
        Ok(OsmIndex::from_parts(
            data, self.zoom, structures, roads, coastlines,
        ))
    }
}

/// What the cells around `area` hold, by kind (node, way, relation, group).
fn in_cells(
    db: &Connection,
    path: &Path,
    zoom: u8,
    area: &Bounds,
) -> Result<[BTreeSet<i64>; 4], StoreError> {
    let sqlite = sqlite_error(path);
    let n = f64::from(1u32 << zoom);
    let mut found: [BTreeSet<i64>; 4] = Default::default();
    let mut in_cell = db
        .prepare_cached("SELECT kind, id FROM cells WHERE x = ?1 AND y = ?2")
        .map_err(&sqlite)?;
    for (x, y) in cells_of(area, n) {
        let rows = in_cell
            .query_map(params![x, y], |row| {
                Ok((row.get::<_, i64>(0)?, row.get::<_, i64>(1)?))
            })
            .map_err(&sqlite)?;
        for row in rows {
            let (kind, id) = row.map_err(&sqlite)?;
            if let Some(set) = found.get_mut(kind as usize) {
                set.insert(id);
            }
        }
    }
    Ok(found)
}

fn sqlite_error(path: &Path) -> impl Fn(rusqlite::Error) -> StoreError + '_ {
    move |source| StoreError::Sqlite {
        path: path.to_path_buf(),
        source,
    }
}

fn decode_error(path: &Path) -> impl Fn(DecodeError) -> StoreError + '_ {
    move |source| StoreError::Decode {
        path: path.to_path_buf(),
        source,
    }
}

/// A tile's closure as read (the coastlines apart): its ways by id, relations by id, groups
/// by id with their rows, the facts of its near ways, and its tagged nodes.
pub(crate) struct Selected {
    pub ways: BTreeMap<i64, Way>,
    pub relations: BTreeMap<i64, Relation>,
    pub groups: Vec<(i64, Vec<u8>)>,
    pub known: std::collections::HashMap<i64, WayFacts>,
    pub nodes: Vec<Node>,
}

/// Reads the closure of `tile` (see the module's notes) but for the coastlines.
pub(crate) fn select(
    db: &Connection,
    path: &Path,
    zoom: u8,
    tile: TileId,
    margin_deg: f64,
) -> Result<Selected, StoreError> {
    let sqlite = sqlite_error(path);
    let decode = decode_error(path);
    let area = tile.bounds().expanded(margin_deg);
    let [node_ids, way_ids, relation_ids, group_ids] = in_cells(db, path, zoom, &area)?;
    let mut ways: BTreeMap<i64, Way> = BTreeMap::new();
    let load = |ways: &mut BTreeMap<i64, Way>, id: i64| {
        if let std::collections::btree_map::Entry::Vacant(slot) = ways.entry(id) {
            if let Some(w) = way(db, id).map_err(&decode)? {
                slot.insert(w);
            }
        }
        Ok::<_, StoreError>(())
    };
    // The ways the tile's query selects: in its cells, their box meeting its area.
    let mut near = Vec::new();
    for id in way_ids {
        if let Some(w) = way(db, id).map_err(&decode)? {
            if bounds_of(&w.positions).is_some_and(|b| meets(&b, &area)) {
                near.push(id);
                ways.insert(id, w);
            }
        }
    }
    // Relations (the query takes every one in its cells), with the relations they hold,
    // and all their ways.
    let mut relations: BTreeMap<i64, Relation> = BTreeMap::new();
    for id in relation_ids {
        let Some(relation) = relation(db, id).map_err(&decode)? else {
            continue;
        };
        for member in &relation.members {
            if member.element.element_type == ElementType::Relation {
                if let Some(inner) = self::relation(db, member.element.id).map_err(&decode)? {
                    relations.insert(inner.id, inner);
                }
            }
        }
        for id in relation_ways(db, &relation).map_err(&sqlite)? {
            load(&mut ways, id)?;
        }
        relations.insert(relation.id, relation);
    }
    // Groups, whole, with what they cross.
    let mut groups = Vec::new();
    for id in group_ids {
        let data: Option<Vec<u8>> = db
            .prepare_cached("SELECT data FROM groups WHERE id = ?1")
            .and_then(|mut s| s.query_row([id], |row| row.get(0)).optional())
            .map_err(&sqlite)?;
        let Some(data) = data else { continue };
        // As the query: a group in the cells whose box misses the area is not the tile's.
        let mut named = Vec::new();
        let bounds = codec::decode_group(&data, &mut |id| {
            named.push(id);
            Some(0)
        })
        .map_err(&decode)?
        .bounds;
        if !meets(&bounds, &area) {
            continue;
        }
        named.sort_unstable();
        named.dedup();
        for way_id in named {
            load(&mut ways, way_id)?;
        }
        groups.push((id, data));
    }
    // The ways that meet the selected ways at their joints (their facts, read here, are
    // not read again when the closure is indexed).
    let mut known = std::collections::HashMap::with_capacity(near.len());
    for id in near {
        let found = facts(db, id).map_err(&decode)?;
        for (_, through) in &found.joints {
            for &other in through {
                load(&mut ways, other)?;
            }
        }
        known.insert(id, found);
    }
    let mut nodes = Vec::with_capacity(node_ids.len());
    for id in node_ids {
        if let Some(n) = node(db, id).map_err(&decode)? {
            if bounds_of(&[n.position]).is_some_and(|b| meets(&b, &area)) {
                nodes.push(n);
            }
        }
    }
    Ok(Selected {
        ways,
        relations,
        groups,
        known,
        nodes,
    })
}

/// A digest of everything the closure of `tile` holds but the coastlines not near it, with
/// the facts of all its ways: a tile whose digest is unchanged has the same bytes.
pub(crate) fn closure_digest(
    db: &Connection,
    path: &Path,
    zoom: u8,
    tile: TileId,
    margin_deg: f64,
) -> Result<[u8; 32], StoreError> {
    use sha2::Digest;
    let selected = select(db, path, zoom, tile, margin_deg)?;
    let mut digest = sha2::Sha256::new();
    for way in selected.ways.values() {
        let facts = match selected.known.get(&way.id) {
            Some(facts) => facts.clone(),
            None => facts(db, way.id).map_err(decode_error(path))?,
        };
        digest.update(format!("{way:?}{facts:?}").as_bytes());
    }
    for relation in selected.relations.values() {
        digest.update(format!("{relation:?}").as_bytes());
    }
    for (id, row) in &selected.groups {
        digest.update(id.to_le_bytes());
        digest.update(row);
    }
    for node in &selected.nodes {
        digest.update(format!("{node:?}").as_bytes());
    }
    Ok(digest.finalize().into())
}

/// A read-only connection.
fn connect(path: &Path) -> Result<Connection, StoreError> {
    let db = Connection::open_with_flags(
        path,
        OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX,
    )
    .map_err(|source| StoreError::Sqlite {
        path: path.to_path_buf(),
        source,
    })?;
    // A failed pragma leaves SQLite's default page cache: slower, not wrong.
    let _ = db.execute_batch("PRAGMA cache_size = -32768;");
    // A tile read while an update commits waits for it rather than failing.
    let _ = db.busy_timeout(std::time::Duration::from_secs(60));
    Ok(db)
}

/// A stored way.
pub(crate) fn way(db: &Connection, id: i64) -> Result<Option<Way>, DecodeError> {
    let bytes: Option<Vec<u8>> = db
        .prepare_cached("SELECT data FROM ways WHERE id = ?1")
        .and_then(|mut s| s.query_row([id], |row| row.get(0)).optional())
        .map_err(|_| DecodeError {
            what: "way",
            why: "it cannot be read",
        })?;
    bytes.map(|b| codec::decode_way(id, &b)).transpose()
}

/// What was found over the whole data about one way.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct WayFacts {
    /// Its nodes that are joints, each with every way through it (ascending ids).
    pub joints: codec::WayJoints,
    /// Where bridges pass over it.
    pub under_bridges: Option<Vec<LonLat>>,
}

/// The facts of a way (none for most).
pub(crate) fn facts(db: &Connection, id: i64) -> Result<WayFacts, DecodeError> {
    type Row = (Option<Vec<u8>>, Option<Vec<u8>>);
    let row: Option<Row> = db
        .prepare_cached("SELECT joints, under_bridges FROM way_facts WHERE way = ?1")
        .and_then(|mut s| {
            s.query_row([id], |row| Ok((row.get(0)?, row.get(1)?)))
                .optional()
        })
        .map_err(|_| DecodeError {
            what: "way's facts",
            why: "they cannot be read",
        })?;
    let Some((joints, under)) = row else {
        return Ok(WayFacts::default());
    };
    Ok(WayFacts {
        joints: joints
            .map(|bytes| codec::decode_joints(&bytes))
            .transpose()?
            .unwrap_or_default(),
        under_bridges: under.map(|b| codec::decode_positions(&b)).transpose()?,
    })
}

/// A stored tagged node.
pub(crate) fn node(db: &Connection, id: i64) -> Result<Option<Node>, DecodeError> {
    let row: Option<(f64, f64, Vec<u8>)> = db
        .prepare_cached("SELECT lon, lat, tags FROM nodes WHERE id = ?1")
        .and_then(|mut s| {
            s.query_row([id], |row| Ok((row.get(0)?, row.get(1)?, row.get(2)?)))
                .optional()
        })
        .map_err(|_| DecodeError {
            what: "node",
            why: "it cannot be read",
        })?;
    let Some((lon, lat, tags)) = row else {
        return Ok(None);
    };
    let mut r = codec::Reader::new(&tags, "node");
    let tags = r.tags()?;
    r.done()?;
    Ok(Some(Node {
        id,
        position: LonLat { lon, lat },
        tags,
    }))
}

/// A stored relation.
pub(crate) fn relation(db: &Connection, id: i64) -> Result<Option<Relation>, DecodeError> {
    let bytes: Option<Vec<u8>> = db
        .prepare_cached("SELECT data FROM relations WHERE id = ?1")
        .and_then(|mut s| s.query_row([id], |row| row.get(0)).optional())
        .map_err(|_| DecodeError {
            what: "relation",
            why: "it cannot be read",
        })?;
    bytes.map(|b| codec::decode_relation(id, &b)).transpose()
}

/// The ways of a relation, with those of its member relations, as the in-memory index counts
/// them.
pub(crate) fn relation_ways(
    db: &Connection,
    relation: &Relation,
) -> Result<Vec<i64>, rusqlite::Error> {
    let mut data = OsmData::default();
    for member in &relation.members {
        if member.element.element_type == ElementType::Relation {
            if let Ok(Some(inner)) = self::relation(db, member.element.id) {
                data.relations.push(inner);
            }
        }
    }
    data.relations.sort_by_key(|r| r.id);
    data.relations.dedup_by_key(|r| r.id);
    Ok(model_relation_ways(&data, relation))
}
