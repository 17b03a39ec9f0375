//! The far views' generalised data (see [`crate::osm::far`]): a row for each tile of each zoom
//! far views are made at that holds data. The finest far zoom's rows are generalised from the
//! elements near each tile; each coarser zoom's from the rows of the finer tiles under it and
//! around it, so no row reads more than a few finer rows whatever the store holds. Made
//! whole by an import, and again for the tiles under which a diff changed something.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use rusqlite::{params, Connection, OptionalExtension};

use super::codec::{self, DecodeError, Reader, Writer};
use super::{decode_error, in_cells, relation, relation_ways, sqlite_error, way, StoreError};
use crate::geometry::Rect;
use crate::osm::far::{Block, FarSource, Generalise, Generalised};
use crate::osm::index::meets;
use crate::osm::{bounds_of, LonLat, Relation, Way};
use crate::tile::TileId;

/// How far around a far tile its ways are read: as around a tile of the served zoom.
pub const MARGIN_DEG: f64 = 0.002;

/// What making the rows did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Made {
    /// Rows holding something among those made (the empty ones are not kept).
    pub rows: usize,
}

/// Makes the rows of the far tiles over `changed` (tiles of the store's zoom `zoom` whose
/// elements near them changed; every tile holding data when `None`), finest zoom first, each
/// coarser zoom over the finer rows that changed. A row holds the same whichever way a store
/// came to hold its data, so a store updated holds the rows a store imported from the changed
/// data holds.
pub(crate) fn make(
    db: &Connection,
    path: &Path,
    zoom: u8,
    generalise: Generalise,
    margin_deg: f64,
    changed: Option<&[TileId]>,
) -> Result<Made, StoreError> {
    let sqlite = sqlite_error(path);
    let mut under: BTreeSet<TileId> = match changed {
        Some(tiles) => tiles.iter().copied().collect(),
        None => {
            let mut cells = db
                .prepare("SELECT DISTINCT x, y FROM cells")
                .map_err(&sqlite)?;
            let rows = cells
                .query_map([], |row| Ok((row.get::<_, u32>(0)?, row.get::<_, u32>(1)?)))
                .map_err(&sqlite)?;
            let mut tiles = BTreeSet::new();
            for row in rows {
                let (x, y) = row.map_err(&sqlite)?;
                tiles.insert(TileId { z: zoom, x, y });
            }
            tiles
        }
    };
    let mut made = Made::default();
    let mut finer: Option<u8> = None;
    for far_zoom in crate::tile::overview_zooms(zoom) {
        let started = std::time::Instant::now();
        // A row reads a little past its tile (the finer rows around it, a margin): the tiles
        // over the finer ones and their neighbours.
        let tiles: BTreeSet<TileId> = under
            .iter()
            .flat_map(|&t| with_neighbours(t))
            .map(|t| ancestor(t, far_zoom))
            .collect();
        let list: Vec<TileId> = tiles.iter().copied().collect();
        // Only the rows that changed reach the coarser zoom: its rows are made of these alone.
        let mut altered = BTreeSet::new();
        for batch in list.chunks(BATCH) {
            let mut inputs = Vec::with_capacity(batch.len());
            for &tile in batch {
                inputs.push(match finer {
                    None => from_elements(db, path, zoom, tile, margin_deg)?,
                    Some(finer) => from_finer(db, path, tile, finer, margin_deg)?,
                });
            }
            for (input, row) in inputs.iter().zip(generalise_all(&inputs, zoom, generalise)) {
                if write(db, path, input.tile, &row)? {
                    altered.insert(input.tile);
                }
                made.rows += usize::from(!is_empty(&row));
            }
        }
        tracing::debug!(
            zoom = far_zoom,
            tiles = tiles.len(),
            changed = altered.len(),
            ms = started.elapsed().as_millis() as u64,
            "far views generalised"
        );
        under = altered;
        finer = Some(far_zoom);
    }
    Ok(made)
}

/// Far tiles read, generalised over the cores, then written at once.
const BATCH: usize = 64;

/// What a far tile is generalised from, as read.
struct Input {
    tile: TileId,
    ways: Vec<Way>,
    relations: Vec<Relation>,
    /// The finer tiles' blocks; `None` for the finest far zoom.
    blocks: Option<Vec<Block>>,
}

/// The rows of `inputs`, in order, made over the cores (each on its own: the rows are those
/// one thread makes).
fn generalise_all(inputs: &[Input], served_zoom: u8, generalise: Generalise) -> Vec<Generalised> {
    let one = |input: &Input| {
        let ways: Vec<&Way> = input.ways.iter().collect();
        let relations: Vec<&Relation> = input.relations.iter().collect();
        let blocks: Option<Vec<&Block>> = input.blocks.as_ref().map(|b| b.iter().collect());
        generalise(&FarSource {
            tile: input.tile,
            served_zoom,
            ways: &ways,
            relations: &relations,
            blocks: blocks.as_deref(),
        })
    };
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(inputs.len());
    if threads <= 1 {
        return inputs.iter().map(one).collect();
    }
    let next = std::sync::atomic::AtomicUsize::new(0);
    let mut rows: Vec<(usize, Generalised)> = std::thread::scope(|scope| {
        let workers: Vec<_> = (0..threads)
            .map(|_| {
                scope.spawn(|| {
                    let mut made = Vec::new();
                    loop {
                        let k = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        let Some(input) = inputs.get(k) else {
                            return made;
                        };
                        made.push((k, one(input)));
                    }
                })
            })
            .collect();
        workers
            .into_iter()
            .flat_map(|w| w.join().unwrap_or_else(|p| std::panic::resume_unwind(p)))
            .collect()
    });
    rows.sort_by_key(|(k, _)| *k);
    rows.into_iter().map(|(_, row)| row).collect()
}

/// A tile and the eight around it (those that exist).
fn with_neighbours(tile: TileId) -> impl Iterator<Item = TileId> {
    let last = (1u32 << tile.z) - 1;
    let xs = tile.x.saturating_sub(1)..=(tile.x + 1).min(last);
    xs.flat_map(move |x| {
        let ys = tile.y.saturating_sub(1)..=(tile.y + 1).min(last);
        ys.map(move |y| TileId { z: tile.z, x, y })
    })
}

/// The tile of `zoom` holding `tile` (at `zoom` or finer).
fn ancestor(tile: TileId, zoom: u8) -> TileId {
    let shift = tile.z.saturating_sub(zoom);
    TileId {
        z: zoom.min(tile.z),
        x: tile.x >> shift,
        y: tile.y >> shift,
    }
}

/// What a tile of the finest far zoom is generalised from: the elements near it.
fn from_elements(
    db: &Connection,
    path: &Path,
    zoom: u8,
    tile: TileId,
    margin_deg: f64,
) -> Result<Input, StoreError> {
    let decode = decode_error(path);
    let area = tile.bounds().expanded(margin_deg);
    let [_, way_ids, relation_ids, _] = in_cells(db, path, zoom, &area)?;
    let mut ways: BTreeMap<i64, Way> = BTreeMap::new();
    for id in way_ids {
        if let Some(w) = way(db, id).map_err(&decode)? {
            if bounds_of(&w.positions).is_some_and(|b| meets(&b, &area)) {
                ways.insert(id, w);
            }
        }
    }
    let mut relations = Vec::new();
    for id in relation_ids {
        let Some(relation) = relation(db, id).map_err(&decode)? else {
            continue;
        };
        for id in relation_ways(db, &relation).map_err(sqlite_error(path))? {
            if let std::collections::btree_map::Entry::Vacant(slot) = ways.entry(id) {
                if let Some(w) = way(db, id).map_err(&decode)? {
                    slot.insert(w);
                }
            }
        }
        relations.push(relation);
    }
    Ok(Input {
        tile,
        ways: ways.into_values().collect(),
        relations,
        blocks: None,
    })
}

/// What a coarser far tile is generalised from: the rows of the tiles of `finer` under it and
/// one tile around (of those around, the blocks near enough to join its own).
fn from_finer(
    db: &Connection,
    path: &Path,
    tile: TileId,
    finer: u8,
    margin_deg: f64,
) -> Result<Input, StoreError> {
    let shift = finer - tile.z;
    let last = (1u32 << finer) - 1;
    let (x0, y0) = (tile.x << shift, tile.y << shift);
    let (x1, y1) = (((tile.x + 1) << shift) - 1, ((tile.y + 1) << shift) - 1);
    let area = tile.bounds().expanded(margin_deg);
    // Blocks of the tiles around reaching this near the tile may join its own.
    let near = world_rect(tile, BLOCKS_REACH_TILES);
    let mut ways: BTreeMap<i64, Way> = BTreeMap::new();
    let mut elsewhere: BTreeMap<i64, Way> = BTreeMap::new();
    let mut relations: BTreeMap<i64, Relation> = BTreeMap::new();
    let mut blocks: Vec<Block> = Vec::new();
    for x in x0.saturating_sub(1)..=(x1 + 1).min(last) {
        for y in y0.saturating_sub(1)..=(y1 + 1).min(last) {
            let Some(row) = read(db, path, TileId { z: finer, x, y })? else {
                continue;
            };
            for w in row.ways {
                let near = bounds_of(&w.positions).is_some_and(|b| meets(&b, &area));
                let into = if near { &mut ways } else { &mut elsewhere };
                into.entry(w.id).or_insert(w);
            }
            for r in row.relations {
                relations.entry(r.id).or_insert(r);
            }
            let inside = (x0..=x1).contains(&x) && (y0..=y1).contains(&y);
            blocks.extend(
                row.blocks
                    .into_iter()
                    .filter(|b| inside || reaches(b, &near)),
            );
        }
    }
    // A relation's members are kept beside it wherever they lie.
    for member in relations.values().flat_map(|r| &r.members) {
        if let Some(w) = elsewhere.remove(&member.element.id) {
            ways.entry(w.id).or_insert(w);
        }
    }
    Ok(Input {
        tile,
        ways: ways.into_values().collect(),
        relations: relations.into_values().collect(),
        blocks: Some(blocks),
    })
}

/// How far past a coarser tile's edge the finer tiles' blocks are read, in tiles.
const BLOCKS_REACH_TILES: f64 = 1.0 / 16.0;

/// The square of `tile` grown by `grown` of its width, in world coordinates.
fn world_rect(tile: TileId, grown: f64) -> Rect {
    let size = 1.0 / f64::from(1u32 << tile.z);
    let (x, y) = (f64::from(tile.x) * size, f64::from(tile.y) * size);
    let pad = grown * size;
    Rect {
        min: [x - pad, y - pad],
        max: [x + size + pad, y + size + pad],
    }
}

/// Whether the bounds of a block's outline meet `rect`.
fn reaches(block: &Block, rect: &Rect) -> bool {
    Rect::around(&block.outer).intersects(rect)
}

/// The row of a far tile; `None` when it holds nothing.
pub(crate) fn read(
    db: &Connection,
    path: &Path,
    tile: TileId,
) -> Result<Option<Generalised>, StoreError> {
    held(db, path, tile)?
        .map(|bytes| decode(&bytes))
        .transpose()
        .map_err(decode_error(path))
}

/// The bytes of a far tile's row, as kept.
fn held(db: &Connection, path: &Path, tile: TileId) -> Result<Option<Vec<u8>>, StoreError> {
    db.prepare_cached("SELECT data FROM far WHERE zoom = ?1 AND x = ?2 AND y = ?3")
        .and_then(|mut s| {
            s.query_row(params![tile.z, tile.x, tile.y], |row| row.get(0))
                .optional()
        })
        .map_err(sqlite_error(path))
}

fn is_empty(row: &Generalised) -> bool {
    row.ways.is_empty() && row.blocks.is_empty()
}

/// Keeps a tile's row (none for an empty one); true when that changed what the store held.
fn write(
    db: &Connection,
    path: &Path,
    tile: TileId,
    row: &Generalised,
) -> Result<bool, StoreError> {
    let bytes = (!is_empty(row)).then(|| encode(row));
    if held(db, path, tile)? == bytes {
        return Ok(false);
    }
    match bytes {
        None => db
            .prepare_cached("DELETE FROM far WHERE zoom = ?1 AND x = ?2 AND y = ?3")
            .and_then(|mut s| s.execute(params![tile.z, tile.x, tile.y])),
        Some(bytes) => db
            .prepare_cached("INSERT OR REPLACE INTO far (zoom, x, y, data) VALUES (?1, ?2, ?3, ?4)")
            .and_then(|mut s| s.execute(params![tile.z, tile.x, tile.y, bytes])),
    }
    .map_err(sqlite_error(path))?;
    Ok(true)
}

/// A row's bytes: its ways (positions as floats, bit for bit), relations and blocks.
pub(crate) fn encode(row: &Generalised) -> Vec<u8> {
    let mut w = Writer::default();
    w.unsigned(row.ways.len() as u64);
    for way in &row.ways {
        w.signed(way.id);
        w.tags(&way.tags);
        w.ids(&way.nodes);
        for p in &way.positions {
            w.float(p.lon);
            w.float(p.lat);
        }
    }
    w.unsigned(row.relations.len() as u64);
    for relation in &row.relations {
        w.signed(relation.id);
        w.bytes(&codec::encode_relation(relation));
    }
    w.unsigned(row.blocks.len() as u64);
    for block in &row.blocks {
        w.float(block.height_m);
        w.unsigned(1 + block.holes.len() as u64);
        for ring in std::iter::once(&block.outer).chain(&block.holes) {
            w.unsigned(ring.len() as u64);
            for p in ring {
                w.float(p[0]);
                w.float(p[1]);
            }
        }
    }
    w.0
}

pub(crate) fn decode(bytes: &[u8]) -> Result<Generalised, DecodeError> {
    let mut r = Reader::new(bytes, "far view row");
    let mut row = Generalised::default();
    for _ in 0..r.count()? {
        let id = r.signed()?;
        let tags = r.tags()?;
        let nodes = r.ids()?;
        let mut positions = Vec::with_capacity(nodes.len().min(bytes.len() / 16));
        for _ in 0..nodes.len() {
            positions.push(LonLat {
                lon: r.float()?,
                lat: r.float()?,
            });
        }
        row.ways.push(Way {
            id,
            tags,
            nodes,
            positions,
        });
    }
    for _ in 0..r.count()? {
        let id = r.signed()?;
        row.relations.push(codec::decode_relation(id, r.bytes()?)?);
    }
    for _ in 0..r.count()? {
        let height_m = r.float()?;
        let mut rings = Vec::new();
        for _ in 0..r.count()? {
            let n = r.count()?;
            let mut ring = Vec::with_capacity(n.min(bytes.len() / 16));
            for _ in 0..n {
                ring.push([r.float()?, r.float()?]);
            }
            rings.push(ring);
        }
        if rings.is_empty() {
            return Err(DecodeError {
                what: "far view row",
                why: "a block has no outline",
            });
        }
        let outer = rings.remove(0);
        row.blocks.push(Block {
            outer,
            holes: rings,
            height_m,
        });
    }
    r.done()?;
    Ok(row)
}

#[cfg(test)]
mod tests;
