//! Resolving ways at import: each raw way (tags and node ids) given the positions of its nodes
//! from the node file, the cells its box meets and the facts the import keeps of it, on every
//! core; then written to the store in the order given, on one thread.

use std::ops::Range;

use rusqlite::types::Value;
use rusqlite::{params, Statement};

use super::batch_insert::BatchInsert;
use super::codec;
use super::import::{CellRows, ImportError, Partial, Rules};
use crate::osm::index::{cells_of_line, is_coastline, warn_if_unbounded};
use crate::osm::structures::{may_be_crossed, structure_of};
use crate::osm::{bounds_of, Bounds, LonLat};
use crate::source::external_sort::{ExternalSort, RUN_RECORDS};
use crate::source::node_locations::{NodeLocations, NodeStoreError, CACHED_BLOCKS};

/// Readers of the node file, one for each thread that resolves ways.
pub struct Resolver {
    readers: Vec<NodeLocations>,
}

impl Resolver {
    /// One reader of `locations` for each core, sharing its cache's size between them.
    pub fn new(locations: NodeLocations) -> Result<Resolver, NodeStoreError> {
        let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
        let blocks = (CACHED_BLOCKS / threads).max(64);
        let readers = (0..threads)
            .map(|_| locations.fork(blocks))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Resolver { readers })
    }

    /// The node file as written (for its index and to make it durable).
    pub fn locations(&self) -> &NodeLocations {
        &self.readers[0]
    }

    /// Resolves `ways` (ids and raw rows), spread over the cores: one [`Resolved`] for each
    /// thread's share, in the order given.
    pub fn resolve(
        &mut self,
        ways: &[(i64, Vec<u8>)],
        n: f64,
        rules: &Rules,
    ) -> Result<Vec<Resolved>, ImportError> {
        let per_thread = ways.len().div_ceil(self.readers.len()).max(256);
        let resolve_all = |chunk: &[(i64, Vec<u8>)], reader: &mut NodeLocations| {
            let mut resolved = Resolved::default();
            for (id, data) in chunk {
                resolved.push(*id, data, reader, n, rules)?;
            }
            Ok::<_, ImportError>(resolved)
        };
        if ways.len() <= per_thread {
            return Ok(vec![resolve_all(ways, &mut self.readers[0])?]);
        }
        std::thread::scope(|scope| {
            let workers: Vec<_> = ways
                .chunks(per_thread)
                .zip(self.readers.iter_mut())
                .map(|(chunk, reader)| scope.spawn(move || resolve_all(chunk, reader)))
                .collect();
            let mut resolved = Vec::with_capacity(workers.len());
            for worker in workers {
                let part = worker.join().map_err(|_| {
                    ImportError::NodeFile(NodeStoreError::Io {
                        path: Default::default(),
                        source: std::io::Error::other("resolving ways panicked"),
                    })
                })?;
                resolved.push(part?);
            }
            Ok(resolved)
        })
    }
}

/// Ways resolved, in order, kept in a few buffers rather than a few allocations a way: they
/// are resolved on one thread and freed on another, and glibc frees memory another thread
/// allocated slowly, under a lock the allocating threads contend for.
#[derive(Default)]
pub struct Resolved {
    ways: Vec<Entry>,
    /// Rows and raw rows.
    bytes: Vec<u8>,
    cells: Vec<(u32, u32)>,
    /// Missing nodes and joint references.
    nodes: Vec<i64>,
}

/// A way resolved: where its parts lie in the buffers of its [`Resolved`].
struct Entry {
    id: i64,
    /// Its nodes missing from the extracts, and then its raw row (kept so that a diff adding
    /// them completes it).
    missing: Range<usize>,
    raw: Option<Range<usize>>,
    /// What is stored of it when two or more of its nodes were found.
    way: Option<ResolvedWay>,
}

struct ResolvedWay {
    row: Range<usize>,
    bounds: Option<Bounds>,
    cells: Range<usize>,
    /// Its node references when it joins the road network (a node repeated next to itself
    /// once, as the in-memory index counts).
    joint_refs: Range<usize>,
    structure: bool,
    coastline: bool,
    part: Option<Part>,
}

/// How a way may take part in bridge and tunnel groups.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Part {
    /// A bridge or tunnel way, or a way one may cross.
    Always,
    /// Something reaching into the ground: only near a tunnel.
    NearTunnels,
}

impl Resolved {
    /// Resolves way `id`, given as `data` (its raw row), and adds it.
    fn push(
        &mut self,
        id: i64,
        data: &[u8],
        locations: &mut NodeLocations,
        n: f64,
        rules: &Rules,
    ) -> Result<(), ImportError> {
        let (tags, refs) = codec::decode_raw_way(data)?;
        let mut nodes = Vec::with_capacity(refs.len());
        let mut at = Vec::with_capacity(refs.len());
        let missing_from = self.nodes.len();
        for &node in &refs {
            match locations.get(node)? {
                Some(p) => {
                    nodes.push(node);
                    at.push(p);
                }
                None => self.nodes.push(node),
            }
        }
        let missing = missing_from..self.nodes.len();
        let raw = (!missing.is_empty()).then(|| self.bytes_of(data));
        if nodes.len() < 2 {
            self.ways.push(Entry {
                id,
                missing,
                raw,
                way: None,
            });
            return Ok(());
        }
        let positions: Vec<LonLat> = at
            .iter()
            .map(|p| {
                let (lon, lat) = p.lon_lat();
                LonLat { lon, lat }
            })
            .collect();
        let bounds = bounds_of(&positions);
        let cells_from = self.cells.len();
        let closed = nodes.len() >= 4 && nodes.first() == nodes.last();
        let reached = cells_of_line(&positions, closed, n);
        warn_if_unbounded(id, &positions, reached.len());
        self.cells.extend(reached);
        let joints_from = self.nodes.len();
        if (rules.joins)(&tags) {
            self.nodes.extend(
                nodes
                    .iter()
                    .enumerate()
                    .filter(|&(k, node)| k == 0 || nodes[k - 1] != *node)
                    .map(|(_, &node)| node),
            );
        }
        let structure = structure_of(rules.classify, &tags, &positions).is_some();
        let part = if structure || may_be_crossed(&tags) {
            Some(Part::Always)
        } else {
            (rules.depth)(&tags).map(|_| Part::NearTunnels)
        };
        let way = ResolvedWay {
            row: self.bytes_of(&codec::encode_way(&tags, &nodes, &at)),
            bounds,
            cells: cells_from..self.cells.len(),
            joint_refs: joints_from..self.nodes.len(),
            structure,
            coastline: is_coastline(&tags),
            part,
        };
        self.ways.push(Entry {
            id,
            missing,
            raw,
            way: Some(way),
        });
        Ok(())
    }

    fn bytes_of(&mut self, bytes: &[u8]) -> Range<usize> {
        let from = self.bytes.len();
        self.bytes.extend_from_slice(bytes);
        from..self.bytes.len()
    }
}

/// Writes resolved ways to the store: the way, whether it is a coastline, how it may take part
/// in groups, and what is missing of it; and gathers its cells and joint references, to be
/// sorted before they are written.
pub struct ResolvedWriter<'a> {
    partial: &'a Partial,
    way: BatchInsert<'a>,
    coast: Statement<'a>,
    incomplete: Statement<'a>,
    missing: Statement<'a>,
    part: BatchInsert<'a>,
    /// The cells of the ways, as rows of the cells table.
    pub cells: CellRows,
    /// The node references of the ways that join the road network, as (node, way).
    pub joint_refs: ExternalSort<2>,
    /// The ids of the bridge and tunnel ways written.
    pub structure_ways: Vec<i64>,
    /// How many ways were written.
    pub written: u64,
}

impl<'a> ResolvedWriter<'a> {
    pub fn new(partial: &'a Partial) -> Result<ResolvedWriter<'a>, ImportError> {
        let sqlite = partial.sqlite();
        let prepare = |sql: &str| partial.db.prepare(sql).map_err(&sqlite);
        Ok(ResolvedWriter {
            partial,
            way: BatchInsert::new(&partial.db, "INSERT INTO ways (id, data)", 2)
                .map_err(&sqlite)?,
            coast: prepare("INSERT INTO coastlines (way) VALUES (?1)")?,
            incomplete: prepare("INSERT INTO incomplete_ways (way, data) VALUES (?1, ?2)")?,
            missing: prepare("INSERT OR IGNORE INTO missing_nodes (node, way) VALUES (?1, ?2)")?,
            part: BatchInsert::new(
                &partial.db,
                "INSERT INTO parts (id, near_tunnels, west, south, east, north)",
                6,
            )
            .map_err(&sqlite)?,
            cells: ExternalSort::new(&partial.path, RUN_RECORDS),
            joint_refs: ExternalSort::new(&partial.path, RUN_RECORDS),
            structure_ways: Vec::new(),
            written: 0,
        })
    }

    /// Writes the rows held (before the transaction commits).
    pub fn flush(&mut self) -> Result<(), ImportError> {
        let sqlite = self.partial.sqlite();
        self.way.flush().map_err(&sqlite)?;
        self.part.flush().map_err(&sqlite)
    }

    /// Writes the ways of `resolved`, in order.
    pub fn write(&mut self, resolved: &Resolved) -> Result<(), ImportError> {
        for entry in &resolved.ways {
            self.write_way(resolved, entry)?;
        }
        Ok(())
    }

    fn write_way(&mut self, resolved: &Resolved, entry: &Entry) -> Result<(), ImportError> {
        let sqlite = self.partial.sqlite();
        let id = entry.id;
        if let Some(raw) = &entry.raw {
            self.incomplete
                .execute(params![id, &resolved.bytes[raw.clone()]])
                .map_err(&sqlite)?;
            for &node in &resolved.nodes[entry.missing.clone()] {
                self.missing.execute(params![node, id]).map_err(&sqlite)?;
            }
        }
        let Some(way) = &entry.way else {
            return Ok(());
        };
        self.way
            .push([
                Value::Integer(id),
                Value::Blob(resolved.bytes[way.row.clone()].to_vec()),
            ])
            .map_err(&sqlite)?;
        let io = self.partial.io();
        for &(x, y) in &resolved.cells[way.cells.clone()] {
            self.cells
                .push([i64::from(x), i64::from(y), 1, id])
                .map_err(&io)?;
        }
        for &node in &resolved.nodes[way.joint_refs.clone()] {
            self.joint_refs.push([node, id]).map_err(&io)?;
        }
        if way.structure {
            self.structure_ways.push(id);
        }
        if way.coastline {
            self.coast.execute(params![id]).map_err(&sqlite)?;
        }
        if let (Some(part), Some(b)) = (way.part, way.bounds) {
            self.part
                .push([
                    Value::Integer(id),
                    Value::Integer(i64::from(part == Part::NearTunnels)),
                    Value::Real(b.west),
                    Value::Real(b.south),
                    Value::Real(b.east),
                    Value::Real(b.north),
                ])
                .map_err(&sqlite)?;
        }
        self.written += 1;
        Ok(())
    }
}
