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

    /// Reads what the diff changes: its elements, the ways through the nodes it moves, the
    /// relations that hold changed ways, as they are and as they will be.
    fn plan(&mut self, change: &OsmChange) -> Result<Plan, UpdateError> {
        let mut plan = Plan::default();
        let mut sources: BTreeMap<i64, Option<(crate::osm::Tags, Vec<i64>)>> = BTreeMap::new();
        for c in change.changes.values() {
            if let Changed::Node { id, at, .. } = &c.element {
                let after = if c.action == Action::Delete {
                    None
                } else {
                    *at
                };
                self.diff_nodes.insert(*id, after);
            }
        }
        let mut cells_before: HashMap<(u32, u32), Vec<Way>> = HashMap::new();
        for c in change.changes.values() {
            match &c.element {
                Changed::Node { id, at, tags } => {
                    let before = self.stored_position(*id)?;
                    let after = if c.action == Action::Delete {
                        None
                    } else {
                        *at
                    };
                    let old = super::node(self.db, *id).map_err(self.decode())?;
                    let new = after.filter(|_| !tags.is_empty()).map(|at| {
                        let (lon, lat) = at.lon_lat();
                        let mut row = codec::Writer::default();
                        row.tags(tags);
                        (LonLat { lon, lat }, row)
                    });
                    plan.nodes.push(NodeEdit {
                        id: *id,
                        at: after,
                        old: old.map(|n| n.position),
                        new,
                    });
                    // A way that misses this node is resolved again with it.
                    if after.is_some() {
                        for way in self.ways_missing(*id)? {
                            if let std::collections::btree_map::Entry::Vacant(slot) =
                                sources.entry(way)
                            {
                                if let Some(named) = self.incomplete(way)? {
                                    slot.insert(Some(named));
                                }
                            }
                        }
                    }
                    if before == after {
                        continue;
                    }
                    // Every way through the node lies in the cell where it was.
                    let Some(cell) = before.and_then(|b| {
                        let (lon, lat) = b.lon_lat();
                        self.cell_of(LonLat { lon, lat })
                    }) else {
                        continue;
                    };
                    if let std::collections::hash_map::Entry::Vacant(slot) =
                        cells_before.entry(cell)
                    {
                        slot.insert(self.ways_in(cell)?);
                    }
                    for way in cells_before.get(&cell).map_or(&[][..], |w| &w[..]) {
                        if way.nodes.contains(id) && !sources.contains_key(&way.id) {
                            let named = match self.incomplete(way.id)? {
                                Some(named) => named,
                                None => (way.tags.clone(), way.nodes.clone()),
                            };
                            sources.insert(way.id, Some(named));
                        }
                    }
                }
                Changed::Way { id, nodes, tags } => {
                    let after = (c.action != Action::Delete).then(|| (tags.clone(), nodes.clone()));
                    sources.insert(*id, after);
                }
                Changed::Relation(relation) => {
                    // A relation tiles are not made from is not kept, as the import does.
                    let kept = c.action != Action::Delete && (self.rules.relation)(&relation.tags);
                    let after = kept.then(|| relation.clone());
                    plan.relations.insert(
                        relation.id,
                        RelationEdit {
                            old: None,
                            new: after,
                        },
                    );
                }
            }
        }
        for (id, source) in sources {
            let old = super::way(self.db, id).map_err(self.decode())?;
            let (new, missing) = match &source {
                Some((tags, refs)) => self.resolve(id, tags.clone(), refs)?,
                None => (None, Vec::new()),
            };
            let old_row = old.as_ref().map(|w| {
                let at: Vec<Decimicro> = w.positions.iter().map(|p| decimicro_of(*p)).collect();
                codec::encode_way(&w.tags, &w.nodes, &at)
            });
            let same_row = old_row.as_ref() == new.as_ref().map(|(_, row)| row);
            if same_row && missing.is_empty() && self.incomplete(id)?.is_none() {
                continue;
            }
            for w in [old.as_ref(), new.as_ref().map(|(w, _)| w)]
                .into_iter()
                .flatten()
            {
                for (_, through) in super::facts(self.db, w.id).map_err(self.decode())?.joints {
                    plan.joined_before.extend(through);
                }
            }
            plan.ways.insert(
                id,
                WayEdit {
                    old,
                    new,
                    named: source,
                    missing,
                },
            );
        }
        self.plan_relations(&mut plan)?;
        Ok(plan)
    }

    /// A way as the diff leaves it: its nodes found, the missing dropped (None with fewer
    /// than two), and the nodes it misses.
    fn resolve(
        &mut self,
        id: i64,
        tags: crate::osm::Tags,
        refs: &[i64],
    ) -> Result<Resolved, UpdateError> {
        let mut nodes = Vec::with_capacity(refs.len());
        let mut at = Vec::with_capacity(refs.len());
        let mut missing = Vec::new();
        for &node in refs {
            match self.position(node)? {
                Some(p) => {
                    nodes.push(node);
                    at.push(p);
                }
                None => missing.push(node),
            }
        }
        if nodes.len() < 2 {
            return Ok((None, missing));
        }
        let row = codec::encode_way(&tags, &nodes, &at);
        let positions = at
            .iter()
            .map(|p| {
                let (lon, lat) = p.lon_lat();
                LonLat { lon, lat }
            })
            .collect();
        Ok((
            Some((
                Way {
                    id,
                    tags,
                    nodes,
                    positions,
                },
                row,
            )),
            missing,
        ))
    }

    /// The tags and every node of a way the store holds incomplete.
    fn incomplete(&self, way: i64) -> Result<Option<(crate::osm::Tags, Vec<i64>)>, UpdateError> {
        let data: Option<Vec<u8>> = self
            .db
            .prepare_cached("SELECT data FROM incomplete_ways WHERE way = ?1")
            .and_then(|mut s| s.query_row([way], |row| row.get(0)).optional())
            .map_err(self.sqlite())?;
        data.map(|d| codec::decode_raw_way(&d))
            .transpose()
            .map_err(self.decode())
    }

    /// The ways that name `node` without the store holding it.
    fn ways_missing(&self, node: i64) -> Result<Vec<i64>, UpdateError> {
        self.ids_of(
            "SELECT way FROM missing_nodes WHERE node = ?1 ORDER BY way",
            node,
        )
    }

    /// The relations that name way `way` without the store holding it.
    fn relations_missing(&self, way: i64) -> Result<Vec<i64>, UpdateError> {
        self.ids_of(
            "SELECT relation FROM missing_members WHERE way = ?1 ORDER BY relation",
            way,
        )
    }

    fn ids_of(&self, sql: &str, id: i64) -> Result<Vec<i64>, UpdateError> {
        let mut statement = self.db.prepare_cached(sql).map_err(self.sqlite())?;
        let rows = statement
            .query_map([id], |row| row.get(0))
            .map_err(self.sqlite())?;
        rows.collect::<Result<_, _>>().map_err(self.sqlite())
    }

    /// Adds the relations holding a changed way or relation, to any depth, and reads each
    /// one's state before. A relation is registered in the cells of its ways' box, so it
    /// lies in the cells of each way and relation it holds.
    fn plan_relations(&mut self, plan: &mut Plan) -> Result<(), UpdateError> {
        // A relation that names a way the store did not hold, now brought, wherever it lies.
        let brought: Vec<i64> = plan
            .ways
            .iter()
            .filter(|(_, e)| e.old.is_none() && e.new.is_some())
            .map(|(&id, _)| id)
            .collect();
        for way in brought {
            for id in self.relations_missing(way)? {
                if plan.relations.contains_key(&id) {
                    continue;
                }
                if let Some(relation) = super::relation(self.db, id).map_err(self.decode())? {
                    plan.relations.insert(
                        id,
                        RelationEdit {
                            old: None,
                            new: Some(relation),
                        },
                    );
                }
            }
        }
        let mut looked = BTreeSet::new();
        loop {
            // The state before of the relations added last.
            let ids: Vec<i64> = plan
                .relations
                .iter()
                .filter(|(_, e)| e.old.is_none())
                .map(|(&id, _)| id)
                .collect();
            for id in ids {
                let old = match super::relation(self.db, id).map_err(self.decode())? {
                    Some(r) => {
                        let b = relation_bounds(self.db, &r).map_err(self.decode())?;
                        Some((r, b))
                    }
                    None => None,
                };
                if let Some(edit) = plan.relations.get_mut(&id) {
                    edit.old = old;
                }
            }
            // A relation is registered over its box, which holds each of its ways' cells.
            let mut cells = BTreeSet::new();
            for edit in plan.ways.values() {
                for way in [edit.old.as_ref(), edit.new.as_ref().map(|(w, _)| w)]
                    .into_iter()
                    .flatten()
                {
                    cells.extend(cells_of_way(way, self.n));
                }
            }
            for edit in plan.relations.values() {
                if let Some((_, Some(b))) = &edit.old {
                    cells.extend(cells_of(b, self.n));
                }
            }
            cells.retain(|c| !looked.contains(c));
            if cells.is_empty() {
                return Ok(());
            }
            looked.extend(cells.iter().copied());
            let mut added = false;
            for id in self.in_cells(2, &cells)? {
                if plan.relations.contains_key(&id) {
                    continue;
                }
                let Some(relation) = super::relation(self.db, id).map_err(self.decode())? else {
                    continue;
                };
                let holds = relation
                    .members
                    .iter()
                    .any(|m| match m.element.element_type {
                        ElementType::Way => plan.ways.contains_key(&m.element.id),
                        ElementType::Relation => plan.relations.contains_key(&m.element.id),
                        ElementType::Node => false,
                    });
                if holds {
                    plan.relations.insert(
                        id,
                        RelationEdit {
                            old: None,
                            new: Some(relation),
                        },
                    );
                    added = true;
                }
            }
            if !added {
                return Ok(());
            }
        }
    }

    /// The elements of `kind` registered in `cells`.
    fn in_cells(
        &self,
        kind: i64,
        cells: &BTreeSet<(u32, u32)>,
    ) -> Result<BTreeSet<i64>, UpdateError> {
        let mut s = self
            .db
            .prepare_cached("SELECT id FROM cells WHERE x = ?1 AND y = ?2 AND kind = ?3")
            .map_err(self.sqlite())?;
        let mut found = BTreeSet::new();
        for &(x, y) in cells {
            let rows = s
                .query_map(params![x, y, kind], |r| r.get::<_, i64>(0))
                .map_err(self.sqlite())?;
            for id in rows {
                found.insert(id.map_err(self.sqlite())?);
            }
        }
        Ok(found)
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

    /// Finds the joints again at every node of the changed ways of the road network, and the
    /// joints of each way through one that changed.
    fn settle_joints(&mut self, plan: &Plan, reach: &mut Reach) -> Result<(), UpdateError> {
        let joins = self.rules.joins;
        let mut touched = BTreeSet::new();
        for edit in plan.ways.values() {
            for way in [edit.old.as_ref(), edit.new.as_ref().map(|(w, _)| w)]
                .into_iter()
                .flatten()
            {
                if joins(&way.tags) {
                    touched.extend(way.nodes.iter().copied());
                }
            }
        }
        let mut changed_ways = BTreeSet::new();
        for node in touched {
            let through_now = self.road_ways_through(node)?;
            let through_before: Vec<i64> = {
                let mut s = self
                    .db
                    .prepare_cached("SELECT way FROM joints WHERE node = ?1 ORDER BY way")
                    .map_err(self.sqlite())?;
                let rows = s.query_map([node], |r| r.get(0)).map_err(self.sqlite())?;
                rows.collect::<Result<_, _>>().map_err(self.sqlite())?
            };
            if through_now == through_before {
                continue;
            }
            self.db
                .execute("DELETE FROM joints WHERE node = ?1", [node])
                .map_err(self.sqlite())?;
            for way in &through_now {
                self.db
                    .execute(
                        "INSERT INTO joints (node, way) VALUES (?1, ?2)",
                        params![node, way],
                    )
                    .map_err(self.sqlite())?;
            }
            changed_ways.extend(through_before);
            changed_ways.extend(through_now);
        }
        for &way in &changed_ways {
            self.write_joints(way)?;
            self.reach_way(way, reach)?;
        }
        self.reach_holders(&changed_ways, reach)?;
        for &way in &plan.joined_before {
            self.reach_way(way, reach)?;
        }
        Ok(())
    }

    /// The ways of the road network through `node` once the diff is applied, when it is a
    /// joint (the node counted more than once among them), ascending.
    fn road_ways_through(&mut self, node: i64) -> Result<Vec<i64>, UpdateError> {
        let Some(at) = self.position(node)? else {
            return Ok(Vec::new());
        };
        let (lon, lat) = at.lon_lat();
        let Some(cell) = self.cell_of(LonLat { lon, lat }) else {
            return Ok(Vec::new());
        };
        let joins = self.rules.joins;
        let mut refs = 0;
        let mut through = Vec::new();
        for way in self.ways_after(cell)? {
            if !joins(&way.tags) {
                continue;
            }
            // As the import counts: a node next to itself is a duplicated point.
            let count = way
                .nodes
                .iter()
                .enumerate()
                .filter(|&(k, &n)| n == node && (k == 0 || way.nodes[k - 1] != node))
                .count();
            if count > 0 {
                refs += count;
                through.push(way.id);
            }
        }
        through.sort_unstable();
        Ok(if refs > 1 { through } else { Vec::new() })
    }

    fn write_joints(&self, way: i64) -> Result<(), UpdateError> {
        let mut joints: codec::WayJoints = Vec::new();
        {
            let mut s = self
                .db
                .prepare_cached(
                    "SELECT j1.node, j2.way FROM joints j1 JOIN joints j2 ON j2.node = j1.node
                     WHERE j1.way = ?1 ORDER BY j1.node, j2.way",
                )
                .map_err(self.sqlite())?;
            let rows = s
                .query_map([way], |r| Ok((r.get::<_, i64>(0)?, r.get::<_, i64>(1)?)))
                .map_err(self.sqlite())?;
            for row in rows {
                let (node, through) = row.map_err(self.sqlite())?;
                match joints.last_mut() {
                    Some((n, ways)) if *n == node => ways.push(through),
                    _ => joints.push((node, vec![through])),
                }
            }
        }
        let row = (!joints.is_empty()).then(|| codec::encode_joints(&joints));
        self.set_fact(way, "joints", row)
    }

    /// Sets one column of a way's facts, dropping the row when it holds none.
    fn set_fact(&self, way: i64, column: &str, value: Option<Vec<u8>>) -> Result<(), UpdateError> {
        let sqlite = self.sqlite();
        self.db
            .execute(
                &format!(
                    "INSERT INTO way_facts (way, {column}) VALUES (?1, ?2)
                     ON CONFLICT (way) DO UPDATE SET {column} = excluded.{column}"
                ),
                params![way, value],
            )
            .map_err(&sqlite)?;
        self.db
            .execute(
                "DELETE FROM way_facts WHERE way = ?1 AND joints IS NULL AND under_bridges IS NULL",
                [way],
            )
            .map_err(&sqlite)?;
        Ok(())
    }

    /// Adds a way's box as the store holds it now.
    fn reach_way(&self, id: i64, reach: &mut Reach) -> Result<(), UpdateError> {
        let way = super::way(self.db, id).map_err(self.decode())?;
        reach.way(way.as_ref());
        Ok(())
    }

    /// Finds again the bridge and tunnel groups of every cluster the changes reach, and
    /// where their bridges pass over ways; returns how many groups were found.
    fn settle_groups(&mut self, plan: &Plan, reach: &mut Reach) -> Result<usize, UpdateError> {
        let mut seeds = BTreeSet::new();
        let mut look = BTreeSet::new();
        // Relations take no part in groups: the nodes and ways changed are what counts.
        let mut changed = Reach::new(self.zoom);
        plan.elements(&mut changed);
        for &(x, y) in &changed.cells {
            let cell = TileId { z: self.zoom, x, y }.bounds();
            look.extend(cells_of(&cell.expanded(ABOVE_TUNNEL_DEG), self.n));
        }
        for edit in plan.ways.values() {
            if let Some(w) = &edit.old {
                if structure_of(self.rules.classify, &w.tags, &w.positions).is_some() {
                    seeds.insert(w.id);
                }
            }
        }
        let classify = self.rules.classify;
        for &cell in &look {
            for way in self.ways_after(cell)? {
                if structure_of(classify, &way.tags, &way.positions).is_some() {
                    seeds.insert(way.id);
                }
            }
        }
        let mut members = BTreeSet::new();
        let mut old_groups: BTreeMap<i64, Vec<u8>> = BTreeMap::new();
        // The groups held before that hold a way found again or changed are found again, with
        // all their ways (a group's box holds its ways, so it is in their cells).
        let mut cells: BTreeSet<(u32, u32)> = BTreeSet::new();
        for edit in plan.ways.values() {
            if let Some(old) = &edit.old {
                cells.extend(cells_of_way(old, self.n));
            }
        }
        loop {
            let before = members.clone();
            self.grow_cluster(&mut seeds, &mut members)?;
            for id in members.difference(&before) {
                if let Some(way) = super::way(self.db, *id).map_err(self.decode())? {
                    cells.extend(cells_of_way(&way, self.n));
                }
            }
            let mut more = BTreeSet::new();
            for (id, row) in self.groups_in(&cells)? {
                if old_groups.contains_key(&id) {
                    continue;
                }
                let chain = chain_ways(&row).map_err(self.decode())?;
                let held = chain
                    .iter()
                    .any(|w| members.contains(w) || plan.ways.contains_key(w));
                if !held {
                    continue;
                }
                more.extend(chain.into_iter().filter(|w| !members.contains(w)));
                old_groups.insert(id, row);
            }
            if more.is_empty() {
                break;
            }
            seeds = more;
        }
        let ids: Vec<i64> = members.into_iter().collect();
        let mut new_groups: BTreeMap<i64, FoundGroup> = BTreeMap::new();
        for cluster in clusters(self.db, &ids, self.n, self.rules)? {
            let data = cluster_data(self.db, self.path, &cluster, self.rules, Candidates::Every)?;
            for group in cluster.groups(data, self.zoom, self.rules) {
                new_groups.insert(group.first_way, group);
            }
        }
        let count = new_groups.len();
        self.write_groups(old_groups, new_groups, reach)?;
        Ok(count)
    }

    /// Adds to `members` every structure way linked to `seeds` (their boxes, grown by what
    /// may stand over a tunnel, overlapping), as the import clusters them.
    fn grow_cluster(
        &mut self,
        seeds: &mut BTreeSet<i64>,
        members: &mut BTreeSet<i64>,
    ) -> Result<(), UpdateError> {
        let classify = self.rules.classify;
        let grow = |w: &Way| bounds_of(&w.positions).map(|b| b.expanded(ABOVE_TUNNEL_DEG));
        let mut frontier: Vec<i64> = seeds.iter().copied().collect();
        while let Some(id) = frontier.pop() {
            if members.contains(&id) {
                continue;
            }
            let Some(way) = super::way(self.db, id).map_err(self.decode())? else {
                continue;
            };
            if structure_of(classify, &way.tags, &way.positions).is_none() {
                continue;
            }
            members.insert(id);
            let Some(grown) = grow(&way) else {
                continue;
            };
            // A way whose grown box meets this one's lies in the cells of this one grown again.
            let near: Vec<(u32, u32)> =
                cells_of(&grown.expanded(ABOVE_TUNNEL_DEG), self.n).collect();
            for cell in near {
                for other in self.ways_after(cell)? {
                    let structure = structure_of(classify, &other.tags, &other.positions);
                    if members.contains(&other.id) || structure.is_none() {
                        continue;
                    }
                    if grow(other).is_some_and(|o| meets(&o, &grown)) {
                        frontier.push(other.id);
                    }
                }
            }
        }
        Ok(())
    }

    /// The groups registered in `cells`, with their rows.
    fn groups_in(
        &self,
        cells: &BTreeSet<(u32, u32)>,
    ) -> Result<BTreeMap<i64, Vec<u8>>, UpdateError> {
        let ids = self.in_cells(3, cells)?;
        let mut found = BTreeMap::new();
        for id in ids {
            let row: Option<Vec<u8>> = self
                .db
                .query_row("SELECT data FROM groups WHERE id = ?1", [id], |r| r.get(0))
                .optional()
                .map_err(self.sqlite())?;
            if let Some(row) = row {
                found.insert(id, row);
            }
        }
        Ok(found)
    }

    /// Replaces the groups that changed, and the facts of the ways they pass over.
    fn write_groups(
        &mut self,
        old: BTreeMap<i64, Vec<u8>>,
        new: BTreeMap<i64, FoundGroup>,
        reach: &mut Reach,
    ) -> Result<(), UpdateError> {
        let sqlite = self.sqlite();
        let mut under_changed = BTreeSet::new();
        for (&id, row) in &old {
            let bounds = group_bounds(row).map_err(self.decode())?;
            reach.boxes.push(bounds);
            if new.get(&id).is_some_and(|g| g.row == *row) {
                continue;
            }
            self.uncell(3, id, &cells_of(&bounds, self.n).collect::<Vec<_>>())?;
            self.db
                .execute("DELETE FROM groups WHERE id = ?1", [id])
                .map_err(&sqlite)?;
            let mut s = self
                .db
                .prepare_cached("DELETE FROM group_under WHERE grp = ?1 RETURNING way")
                .map_err(&sqlite)?;
            let rows = s.query_map([id], |r| r.get::<_, i64>(0)).map_err(&sqlite)?;
            for way in rows {
                under_changed.insert(way.map_err(&sqlite)?);
            }
        }
        for (&id, group) in &new {
            reach.boxes.push(group.bounds);
            if old.get(&id).is_some_and(|row| *row == group.row) {
                continue;
            }
            self.db
                .execute(
                    "INSERT INTO groups (id, data) VALUES (?1, ?2)",
                    params![id, group.row],
                )
                .map_err(&sqlite)?;
            self.encell(3, id, &cells_of(&group.bounds, self.n).collect::<Vec<_>>())?;
            for (way, positions) in &group.under {
                self.db
                    .execute(
                        "INSERT INTO group_under (way, grp, positions) VALUES (?1, ?2, ?3)",
                        params![way, id, codec::encode_positions(positions)],
                    )
                    .map_err(&sqlite)?;
                under_changed.insert(*way);
            }
        }
        for &way in &under_changed {
            let mut positions: Vec<LonLat> = Vec::new();
            {
                let mut s = self
                    .db
                    .prepare_cached("SELECT positions FROM group_under WHERE way = ?1 ORDER BY grp")
                    .map_err(&sqlite)?;
                let rows = s
                    .query_map([way], |r| r.get::<_, Vec<u8>>(0))
                    .map_err(&sqlite)?;
                for row in rows {
                    let bytes = row.map_err(&sqlite)?;
                    positions.extend(codec::decode_positions(&bytes).map_err(self.decode())?);
                }
            }
            let value = (!positions.is_empty()).then(|| codec::encode_positions(&positions));
            self.set_fact(way, "under_bridges", value)?;
            self.reach_way(way, reach)?;
            // The tiles near the ways joined to it read its facts too.
            for (_, through) in super::facts(self.db, way).map_err(self.decode())?.joints {
                for other in through {
                    self.reach_way(other, reach)?;
                }
            }
        }
        self.reach_holders(&under_changed, reach)?;
        Ok(())
    }

    /// Adds the boxes of the relations that hold one of `ways` and of the groups that name
    /// one: the tiles that read those read the ways' facts.
    fn reach_holders(&self, ways: &BTreeSet<i64>, reach: &mut Reach) -> Result<(), UpdateError> {
        let mut cells = BTreeSet::new();
        for &id in ways {
            if let Some(way) = super::way(self.db, id).map_err(self.decode())? {
                cells.extend(cells_of_way(&way, self.n));
            }
        }
        for id in self.in_cells(2, &cells)? {
            let Some(relation) = super::relation(self.db, id).map_err(self.decode())? else {
                continue;
            };
            let holds = super::relation_ways(self.db, &relation)
                .map_err(self.sqlite())?
                .iter()
                .any(|w| ways.contains(w));
            if holds {
                reach
                    .boxes
                    .extend(relation_bounds(self.db, &relation).map_err(self.decode())?);
            }
        }
        for (_, row) in self.groups_in(&cells)? {
            let mut named = false;
            let group = codec::decode_group(&row, &mut |id| {
                named |= ways.contains(&id);
                Some(0)
            })
            .map_err(self.decode())?;
            if named {
                reach.boxes.push(group.bounds);
            }
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
