//! OSM diffs applied to a store in place, in one transaction: the elements a change file
//! names, the ways whose nodes it moves and the relations that hold them are written again;
//! the joints at their nodes and the bridge and tunnel groups of their clusters are found
//! again; and the tiles whose closure changed are listed, exactly: each tile that a change
//! may reach is read before and after, and listed when what it reads differs.
//!
//! A diff is refused whole, the store unchanged, when it is older than the last one applied or
//! out of its replication sequence.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::{Path, PathBuf};
use std::time::Duration;

use rusqlite::{params, Connection, OpenFlags, OptionalExtension};

use super::import::{cluster_data, clusters, Candidates, FoundGroup, ImportError, Rules};
use super::{codec, StoreError, FORMAT};
use crate::osm::index::{cells_of, cells_of_way, is_coastline, meets, ABOVE_TUNNEL_DEG};
use crate::osm::structures::structure_of;
use crate::osm::{bounds_of, Bounds, ElementType, LonLat, Relation, Way};
use crate::source::node_locations::{Decimicro, NodeLocations, NodeStoreError, RunIndex};
use crate::source::osc::{Action, Changed, OsmChange};
use crate::tile::TileId;

mod plan;
mod settle;

#[derive(Debug, thiserror::Error)]
pub enum UpdateError {
    #[error("OSM store {path}: {source}")]
    Sqlite {
        path: PathBuf,
        source: rusqlite::Error,
    },
    #[error(transparent)]
    Store(#[from] StoreError),
    #[error(transparent)]
    Structures(#[from] ImportError),
    #[error(transparent)]
    Nodes(#[from] NodeStoreError),
    #[error("OSM store {path} cannot take diffs: {why}; import it again")]
    NotUpdatable { path: PathBuf, why: String },
    #[error("{diff} is out of order for the OSM store {path}: {why}; the store is unchanged")]
    OutOfOrder {
        path: PathBuf,
        diff: String,
        why: String,
    },
}

/// How much older than the newest change applied before a diff of a replication sequence may
/// be, seconds: an upload that takes long is published after quicker ones made later, but
/// not an hour later.
const SEQUENCE_TIME_SLACK_S: i64 = 3600;

/// A diff with its place in a replication sequence, when it has one.
#[derive(Debug, Clone)]
pub struct DiffOrigin {
    /// How errors name it: its file or URL.
    pub name: String,
    pub sequence: Option<u64>,
}

/// What a diff did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Applied {
    /// The diffs applied to the store so far, this one included.
    pub generation: u64,
    /// The tiles of the store's zoom whose closure changed, ascending.
    pub expired: Vec<TileId>,
    pub nodes: usize,
    pub ways: usize,
    pub relations: usize,
    /// Bridge and tunnel groups found again (changed or not).
    pub groups: usize,
    /// The tiles read before and after.
    pub candidates: usize,
}

/// Applies `change` to the store at `store`; `margin_deg` is the margin of a tile's query.
pub fn apply(
    store: &Path,
    change: &OsmChange,
    origin: &DiffOrigin,
    rules: &Rules,
    margin_deg: f64,
) -> Result<Applied, UpdateError> {
    let sqlite = |source| UpdateError::Sqlite {
        path: store.to_path_buf(),
        source,
    };
    // The state before, read beside the change: a read transaction held open.
    let before =
        Connection::open_with_flags(store, OpenFlags::SQLITE_OPEN_READ_ONLY).map_err(sqlite)?;
    before.execute_batch("BEGIN").map_err(sqlite)?;
    before
        .query_row("SELECT count(*) FROM meta", [], |row| row.get::<_, i64>(0))
        .map_err(sqlite)?;
    let db = Connection::open(store).map_err(sqlite)?;
    db.busy_timeout(Duration::from_secs(60)).map_err(sqlite)?;
    // The change stays in memory until it commits, so that the state before stays readable.
    db.execute_batch("PRAGMA cache_spill = OFF; BEGIN IMMEDIATE;")
        .map_err(sqlite)?;
    let meta = Meta::read(&db, store)?;
    meta.check_order(store, change, origin)?;
    let locations = NodeLocations::open(&meta.nodes_file, &node_runs(&db).map_err(sqlite)?)?;
    let mut update = Update {
        path: store,
        db: &db,
        zoom: meta.zoom,
        n: f64::from(1u32 << meta.zoom),
        rules,
        locations,
        diff_nodes: HashMap::new(),
        cells_after: HashMap::new(),
    };
    let plan = update.plan(change)?;
    let mut reach = Reach::new(meta.zoom);
    plan.reach(&mut reach);
    update.write(&plan, &mut reach)?;
    update.settle_joints(&plan, &mut reach)?;
    let groups = update.settle_groups(&plan, &mut reach)?;
    let candidates = reach.tiles(meta.zoom, margin_deg);
    let mut expired = Vec::new();
    for &tile in &candidates {
        let was = super::closure_digest(&before, store, meta.zoom, tile, margin_deg)?;
        let is = super::closure_digest(&db, store, meta.zoom, tile, margin_deg)?;
        if was != is {
            expired.push(tile);
        }
    }
    drop(before);
    super::far::make(
        &db,
        store,
        meta.zoom,
        rules.generalise,
        super::far::MARGIN_DEG,
        Some(&expired),
    )?;
    let generation = meta.generation + 1;
    meta.write(&db, store, generation, change, origin, &expired)?;
    db.execute_batch("COMMIT").map_err(sqlite)?;
    Ok(Applied {
        generation,
        expired,
        nodes: plan.nodes.len(),
        ways: plan.ways.len(),
        relations: plan.relations.len(),
        groups,
        candidates: candidates.len(),
    })
}

/// What the store says of itself.
struct Meta {
    zoom: u8,
    generation: u64,
    nodes_file: PathBuf,
    newest_change: Option<String>,
    sequence: Option<u64>,
}

impl Meta {
    fn read(db: &Connection, path: &Path) -> Result<Meta, UpdateError> {
        let get = |key: &str| -> Result<Option<String>, UpdateError> {
            db.query_row("SELECT value FROM meta WHERE key = ?1", [key], |row| {
                row.get(0)
            })
            .optional()
            .map_err(|source| UpdateError::Sqlite {
                path: path.to_path_buf(),
                source,
            })
        };
        let not = |why: &str| UpdateError::NotUpdatable {
            path: path.to_path_buf(),
            why: why.to_string(),
        };
        if get("format")? != Some(FORMAT.to_string()) {
            return Err(not("it is of another format"));
        }
        let nodes_file = get("nodes_file")?.ok_or_else(|| not("it keeps no node file"))?;
        let nodes_file = path.with_file_name(nodes_file);
        if !nodes_file.is_file() {
            return Err(not(&format!(
                "its node file {} is missing",
                nodes_file.display()
            )));
        }
        Ok(Meta {
            zoom: get("zoom")?
                .and_then(|z| z.parse().ok())
                .ok_or_else(|| not("it names no zoom"))?,
            generation: get("generation")?.and_then(|g| g.parse().ok()).unwrap_or(0),
            nodes_file,
            newest_change: get("newest_change")?,
            sequence: get("replication_sequence")?.and_then(|s| s.parse().ok()),
        })
    }

    /// Refuses a diff older than the last one applied, or out of its sequence.
    fn check_order(
        &self,
        path: &Path,
        change: &OsmChange,
        origin: &DiffOrigin,
    ) -> Result<(), UpdateError> {
        let refuse = |why: String| UpdateError::OutOfOrder {
            path: path.to_path_buf(),
            diff: origin.name.clone(),
            why,
        };
        if let (Some(sequence), Some(last)) = (origin.sequence, self.sequence) {
            if sequence <= last {
                return Err(refuse(format!(
                    "its sequence {sequence} was applied already (the last is {last})"
                )));
            }
            if sequence != last + 1 {
                return Err(refuse(format!(
                    "its sequence {sequence} does not follow the last applied, {last}"
                )));
            }
        }
        // Time orders diffs: one whose changes all predate a diff applied before is out of
        // order. In a sequence, a diff may hold only an upload that took long and is a little
        // older than the last one's newest change, but not older by more than an upload
        // takes: that is a source that went back in time.
        let slack = match origin.sequence {
            Some(_) => SEQUENCE_TIME_SLACK_S,
            None => 0,
        };
        if let (Some(newest), Some(applied)) = (&change.newest, &self.newest_change) {
            let seconds = |t: &str| crate::source::osc::seconds_of(t);
            let older = match (seconds(newest), seconds(applied)) {
                (Some(newest), Some(applied)) => newest + slack < applied,
                _ => slack == 0 && newest < applied,
            };
            if older {
                return Err(refuse(format!(
                    "its newest change ({newest}) is older than one applied before ({applied})"
                )));
            }
        }
        Ok(())
    }

    fn write(
        &self,
        db: &Connection,
        path: &Path,
        generation: u64,
        change: &OsmChange,
        origin: &DiffOrigin,
        expired: &[TileId],
    ) -> Result<(), UpdateError> {
        let sqlite = |source| UpdateError::Sqlite {
            path: path.to_path_buf(),
            source,
        };
        let set = |key: &str, value: String| {
            db.execute(
                "INSERT INTO meta (key, value) VALUES (?1, ?2)
                 ON CONFLICT (key) DO UPDATE SET value = excluded.value",
                params![key, value],
            )
            .map(|_| ())
        };
        set("generation", generation.to_string()).map_err(sqlite)?;
        let newest = change.newest.clone().max(self.newest_change.clone());
        if let Some(newest) = newest {
            set("newest_change", newest).map_err(sqlite)?;
        }
        if let Some(sequence) = origin.sequence {
            set("replication_sequence", sequence.to_string()).map_err(sqlite)?;
        }
        let mut insert = db
            .prepare(
                "INSERT INTO expired (x, y, generation) VALUES (?1, ?2, ?3)
                 ON CONFLICT (x, y) DO UPDATE SET generation = excluded.generation",
            )
            .map_err(sqlite)?;
        for tile in expired {
            insert
                .execute(params![tile.x, tile.y, generation as i64])
                .map_err(sqlite)?;
        }
        Ok(())
    }
}

/// The replication sequence of the last diff applied to the store (or of its extract, when
/// none was), if it knows one.
pub fn replication_sequence(store: &Path) -> Result<Option<u64>, UpdateError> {
    let sqlite = |source| UpdateError::Sqlite {
        path: store.to_path_buf(),
        source,
    };
    let db =
        Connection::open_with_flags(store, OpenFlags::SQLITE_OPEN_READ_ONLY).map_err(sqlite)?;
    db.busy_timeout(Duration::from_secs(60)).map_err(sqlite)?;
    let value: Option<String> = db
        .query_row(
            "SELECT value FROM meta WHERE key = 'replication_sequence'",
            [],
            |r| r.get(0),
        )
        .optional()
        .map_err(sqlite)?;
    Ok(value.and_then(|v| v.parse().ok()))
}

/// Records that the store is current to `sequence` of its replication source, without a
/// diff: where a store that knows none starts.
pub fn start_replication_at(store: &Path, sequence: u64) -> Result<(), UpdateError> {
    let sqlite = |source| UpdateError::Sqlite {
        path: store.to_path_buf(),
        source,
    };
    let db = Connection::open(store).map_err(sqlite)?;
    db.busy_timeout(Duration::from_secs(60)).map_err(sqlite)?;
    db.execute(
        "INSERT INTO meta (key, value) VALUES ('replication_sequence', ?1)
         ON CONFLICT (key) DO NOTHING",
        params![sequence.to_string()],
    )
    .map_err(sqlite)?;
    Ok(())
}

fn node_runs(db: &Connection) -> Result<Vec<RunIndex>, rusqlite::Error> {
    let mut statement =
        db.prepare("SELECT start, len, last, firsts FROM node_runs ORDER BY run")?;
    let rows = statement.query_map([], |row| {
        Ok(RunIndex {
            start: row.get::<_, i64>(0)? as u64,
            len: row.get::<_, i64>(1)? as u64,
            last: row.get(2)?,
            firsts: row.get(3)?,
        })
    })?;
    rows.collect()
}

/// A tagged node's change: its row before and after (None when it has no tags or is gone).
struct NodeEdit {
    id: i64,
    /// Its position after, None when deleted.
    at: Option<Decimicro>,
    old: Option<LonLat>,
    new: Option<(LonLat, codec::Writer)>,
}

/// A way's change: before, and after with its row.
struct WayEdit {
    old: Option<Way>,
    new: Option<(Way, Vec<u8>)>,
    /// Its tags and every node it names, unless it is deleted.
    named: Option<(crate::osm::Tags, Vec<i64>)>,
    /// The nodes it names that the store does not hold.
    missing: Vec<i64>,
}

/// A way resolved: the way and its row (None with fewer than two nodes held), and the nodes it
/// names that the store does not hold.
type Resolved = (Option<(Way, Vec<u8>)>, Vec<i64>);

/// A relation's change, with the box of its ways before.
struct RelationEdit {
    old: Option<(Relation, Option<Bounds>)>,
    new: Option<Relation>,
}

/// Everything a diff changes, read before anything is written.
#[derive(Default)]
struct Plan {
    nodes: Vec<NodeEdit>,
    ways: BTreeMap<i64, WayEdit>,
    relations: BTreeMap<i64, RelationEdit>,
    /// The ways that met the changed ways at their joints before.
    joined_before: BTreeSet<i64>,
}

impl Plan {
    /// The boxes the plan's elements had and have.
    fn reach(&self, reach: &mut Reach) {
        self.elements(reach);
        for edit in self.relations.values() {
            if let Some((_, Some(b))) = &edit.old {
                reach.boxes.push(*b);
            }
        }
    }

    /// The boxes its nodes and ways had and have.
    fn elements(&self, reach: &mut Reach) {
        for node in &self.nodes {
            reach.point(node.old);
            reach.point(node.new.as_ref().map(|(p, _)| *p));
            if let Some(at) = node.at {
                let (lon, lat) = at.lon_lat();
                reach.point(Some(LonLat { lon, lat }));
            }
        }
        for edit in self.ways.values() {
            reach.way(edit.old.as_ref());
            reach.way(edit.new.as_ref().map(|(w, _)| w));
        }
    }
}

/// Where a diff reached: the cells of the nodes and ways it changed (where they are
/// registered), and the boxes of the relations and groups (registered over their box), whose
/// tiles may read something changed.
struct Reach {
    n: f64,
    cells: BTreeSet<(u32, u32)>,
    boxes: Vec<Bounds>,
}

impl Reach {
    fn new(zoom: u8) -> Reach {
        Reach {
            n: f64::from(1u32 << zoom),
            cells: BTreeSet::new(),
            boxes: Vec::new(),
        }
    }

    fn point(&mut self, p: Option<LonLat>) {
        if let Some(b) = p.and_then(|p| bounds_of(&[p])) {
            self.cells.extend(cells_of(&b, self.n));
        }
    }

    fn way(&mut self, way: Option<&Way>) {
        if let Some(way) = way {
            self.cells.extend(cells_of_way(way, self.n));
        }
    }

    /// The tiles whose query reads a cell reached: those cells and their neighbours.
    fn tiles(&self, zoom: u8, margin_deg: f64) -> BTreeSet<TileId> {
        let n = f64::from(1u32 << zoom);
        let mut cells = self.cells.clone();
        for b in &self.boxes {
            cells.extend(cells_of(b, n));
        }
        let mut tiles = BTreeSet::new();
        let last = (1u32 << zoom) - 1;
        for &(x, y) in &cells {
            for tx in x.saturating_sub(1)..=(x + 1).min(last) {
                for ty in y.saturating_sub(1)..=(y + 1).min(last) {
                    let tile = TileId {
                        z: zoom,
                        x: tx,
                        y: ty,
                    };
                    let area = tile.bounds().expanded(margin_deg);
                    if cells_of(&area, n).any(|c| c == (x, y)) {
                        tiles.insert(tile);
                    }
                }
            }
        }
        tiles
    }
}

/// The store being changed.
struct Update<'a> {
    path: &'a Path,
    db: &'a Connection,
    zoom: u8,
    n: f64,
    rules: &'a Rules,
    locations: NodeLocations,
    /// Nodes as the diff leaves them (None: deleted).
    diff_nodes: HashMap<i64, Option<Decimicro>>,
    /// The ways in each cell once the elements are written.
    cells_after: HashMap<(u32, u32), Vec<Way>>,
}

impl Update<'_> {
    fn sqlite(&self) -> impl Fn(rusqlite::Error) -> UpdateError + '_ {
        |source| UpdateError::Sqlite {
            path: self.path.to_path_buf(),
            source,
        }
    }

    fn decode(&self) -> impl Fn(codec::DecodeError) -> UpdateError + '_ {
        |source| {
            UpdateError::Store(StoreError::Decode {
                path: self.path.to_path_buf(),
                source,
            })
        }
    }

    /// Where a node is in the store (before the diff's nodes are written).
    fn stored_position(&mut self, id: i64) -> Result<Option<Decimicro>, UpdateError> {
        let moved: Option<(Option<i32>, Option<i32>)> = self
            .db
            .prepare_cached("SELECT lon, lat FROM node_moves WHERE id = ?1")
            .and_then(|mut s| s.query_row([id], |r| Ok((r.get(0)?, r.get(1)?))).optional())
            .map_err(self.sqlite())?;
        match moved {
            Some((Some(lon), Some(lat))) => Ok(Some(Decimicro { lon, lat })),
            Some(_) => Ok(None),
            None => Ok(self.locations.get(id)?),
        }
    }

    /// Where a node is once the diff is applied.
    fn position(&mut self, id: i64) -> Result<Option<Decimicro>, UpdateError> {
        match self.diff_nodes.get(&id) {
            Some(at) => Ok(*at),
            None => self.stored_position(id),
        }
    }

    /// The ways registered in a cell, as the store holds them now.
    fn ways_in(&self, cell: (u32, u32)) -> Result<Vec<Way>, UpdateError> {
        let ids: Vec<i64> = {
            let mut s = self
                .db
                .prepare_cached("SELECT id FROM cells WHERE x = ?1 AND y = ?2 AND kind = 1")
                .map_err(self.sqlite())?;
            let rows = s
                .query_map(params![cell.0, cell.1], |r| r.get(0))
                .map_err(self.sqlite())?;
            rows.collect::<Result<_, _>>().map_err(self.sqlite())?
        };
        let mut ways = Vec::with_capacity(ids.len());
        for id in ids {
            if let Some(way) = super::way(self.db, id).map_err(self.decode())? {
                ways.push(way);
            }
        }
        Ok(ways)
    }

    /// The ways in a cell once the elements are written (read once).
    fn ways_after(&mut self, cell: (u32, u32)) -> Result<&[Way], UpdateError> {
        if !self.cells_after.contains_key(&cell) {
            let ways = self.ways_in(cell)?;
            self.cells_after.insert(cell, ways);
        }
        Ok(self.cells_after.get(&cell).map_or(&[][..], |w| &w[..]))
    }

    fn cell_of(&self, p: LonLat) -> Option<(u32, u32)> {
        bounds_of(&[p]).and_then(|b| cells_of(&b, self.n).next())
    }

    /// Writes the nodes, ways and relations as the diff leaves them.
    fn write(&self, plan: &Plan, reach: &mut Reach) -> Result<(), UpdateError> {
        let sqlite = self.sqlite();
        let db = self.db;
        let n = self.n;
        let cell = |p: LonLat| bounds_of(&[p]).and_then(|b| cells_of(&b, n).next());
        for edit in &plan.nodes {
            let (lon, lat) = match edit.at {
                Some(at) => (Some(at.lon), Some(at.lat)),
                None => (None, None),
            };
            db.execute(
                "INSERT OR REPLACE INTO node_moves (id, lon, lat) VALUES (?1, ?2, ?3)",
                params![edit.id, lon, lat],
            )
            .map_err(&sqlite)?;
            if let Some((x, y)) = edit.old.and_then(cell) {
                db.execute(
                    "DELETE FROM cells WHERE x = ?1 AND y = ?2 AND kind = 0 AND id = ?3",
                    params![x, y, edit.id],
                )
                .map_err(&sqlite)?;
            }
            db.execute("DELETE FROM nodes WHERE id = ?1", [edit.id])
                .map_err(&sqlite)?;
            if let Some((p, row)) = &edit.new {
                db.execute(
                    "INSERT INTO nodes (id, lon, lat, tags) VALUES (?1, ?2, ?3, ?4)",
                    params![edit.id, p.lon, p.lat, row.0],
                )
                .map_err(&sqlite)?;
                if let Some((x, y)) = cell(*p) {
                    db.execute(
                        "INSERT OR IGNORE INTO cells (x, y, kind, id) VALUES (?1, ?2, 0, ?3)",
                        params![x, y, edit.id],
                    )
                    .map_err(&sqlite)?;
                }
            }
        }
        for (&id, edit) in &plan.ways {
            if let Some(old) = &edit.old {
                self.uncell(1, id, &cells_of_way(old, n))?;
            }
            db.execute("DELETE FROM ways WHERE id = ?1", [id])
                .map_err(&sqlite)?;
            db.execute("DELETE FROM coastlines WHERE way = ?1", [id])
                .map_err(&sqlite)?;
            db.execute("DELETE FROM incomplete_ways WHERE way = ?1", [id])
                .map_err(&sqlite)?;
            db.execute("DELETE FROM missing_nodes WHERE way = ?1", [id])
                .map_err(&sqlite)?;
            if let (Some((tags, refs)), false) = (&edit.named, edit.missing.is_empty()) {
                db.execute(
                    "INSERT INTO incomplete_ways (way, data) VALUES (?1, ?2)",
                    params![id, codec::encode_raw_way(tags, refs)],
                )
                .map_err(&sqlite)?;
                for node in &edit.missing {
                    db.execute(
                        "INSERT OR IGNORE INTO missing_nodes (node, way) VALUES (?1, ?2)",
                        params![node, id],
                    )
                    .map_err(&sqlite)?;
                }
            }
            if let Some((way, row)) = &edit.new {
                db.execute(
                    "INSERT INTO ways (id, data) VALUES (?1, ?2)",
                    params![id, row],
                )
                .map_err(&sqlite)?;
                let reached = cells_of_way(way, n);
                crate::osm::index::warn_if_unbounded(id, &way.positions, reached.len());
                self.encell(1, id, &reached)?;
                if is_coastline(&way.tags) {
                    db.execute("INSERT INTO coastlines (way) VALUES (?1)", [id])
                        .map_err(&sqlite)?;
                }
            } else {
                db.execute("DELETE FROM way_facts WHERE way = ?1", [id])
                    .map_err(&sqlite)?;
            }
        }
        self.write_relations(plan, reach)
    }

    fn write_relations(&self, plan: &Plan, reach: &mut Reach) -> Result<(), UpdateError> {
        let sqlite = self.sqlite();
        for (&id, edit) in &plan.relations {
            if let Some((_, Some(b))) = &edit.old {
                self.uncell(2, id, &cells_of(b, self.n).collect::<Vec<_>>())?;
            }
            self.db
                .execute("DELETE FROM relations WHERE id = ?1", [id])
                .map_err(&sqlite)?;
            if let Some(relation) = &edit.new {
                self.db
                    .execute(
                        "INSERT INTO relations (id, data) VALUES (?1, ?2)",
                        params![id, codec::encode_relation(relation)],
                    )
                    .map_err(&sqlite)?;
            }
        }
        // Their boxes, and the ways they name that the store does not hold, once all are
        // written (one may hold another).
        for (&id, edit) in &plan.relations {
            self.db
                .execute("DELETE FROM missing_members WHERE relation = ?1", [id])
                .map_err(&sqlite)?;
            if let Some(relation) = &edit.new {
                for way in super::relation_ways(self.db, relation).map_err(&sqlite)? {
                    if super::way(self.db, way).map_err(self.decode())?.is_none() {
                        self.db
                            .execute(
                                "INSERT OR IGNORE INTO missing_members (way, relation) VALUES (?1, ?2)",
                                params![way, id],
                            )
                            .map_err(&sqlite)?;
                    }
                }
                if let Some(b) = relation_bounds(self.db, relation).map_err(self.decode())? {
                    self.encell(2, id, &cells_of(&b, self.n).collect::<Vec<_>>())?;
                    reach.boxes.push(b);
                }
            }
        }
        Ok(())
    }

    /// Registers an element of `kind` in `cells`.
    fn encell(&self, kind: i64, id: i64, cells: &[(u32, u32)]) -> Result<(), UpdateError> {
        self.each_cell(
            "INSERT OR IGNORE INTO cells (x, y, kind, id) VALUES (?1, ?2, ?3, ?4)",
            kind,
            id,
            cells,
        )
    }

    /// Takes an element of `kind` out of the cells it was registered in.
    fn uncell(&self, kind: i64, id: i64, cells: &[(u32, u32)]) -> Result<(), UpdateError> {
        let sql = "DELETE FROM cells WHERE x = ?1 AND y = ?2 AND kind = ?3 AND id = ?4";
        self.each_cell(sql, kind, id, cells)
    }

    fn each_cell(
        &self,
        sql: &str,
        kind: i64,
        id: i64,
        cells: &[(u32, u32)],
    ) -> Result<(), UpdateError> {
        let mut s = self.db.prepare_cached(sql).map_err(self.sqlite())?;
        for &(x, y) in cells {
            s.execute(params![x, y, kind, id]).map_err(self.sqlite())?;
        }
        Ok(())
    }
}

/// The box of a relation's ways (and its member relations' ways), as the import registers it.
fn relation_bounds(
    db: &Connection,
    relation: &Relation,
) -> Result<Option<Bounds>, codec::DecodeError> {
    let ways = super::relation_ways(db, relation).map_err(|_| codec::DecodeError {
        what: "relation",
        why: "its ways cannot be read",
    })?;
    let mut positions = Vec::new();
    for id in ways {
        if let Some(way) = super::way(db, id)? {
            positions.extend(way.positions);
        }
    }
    Ok(bounds_of(&positions))
}

/// The structure ways of a stored group (its chains', not those it crosses).
fn chain_ways(row: &[u8]) -> Result<Vec<i64>, codec::DecodeError> {
    let mut ids = Vec::new();
    let group = codec::decode_group(row, &mut |id| {
        ids.push(id);
        Some((ids.len() - 1) as u32)
    })?;
    let mut chain: Vec<i64> = group
        .chains
        .iter()
        .flat_map(|c| c.ways.iter().map(|w| ids[w.way as usize]))
        .collect();
    chain.sort_unstable();
    chain.dedup();
    Ok(chain)
}

fn group_bounds(row: &[u8]) -> Result<Bounds, codec::DecodeError> {
    Ok(codec::decode_group(row, &mut |_| Some(0))?.bounds)
}

/// A position in 10⁻⁷ degrees, as it was read (the store keeps exactly those).
fn decimicro_of(p: LonLat) -> Decimicro {
    Decimicro {
        lon: (p.lon * 1e7).round() as i32,
        lat: (p.lat * 1e7).round() as i32,
    }
}

#[cfg(test)]
mod tests;
