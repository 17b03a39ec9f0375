//! Resolving ways at import: each raw way (tags and node ids) given the positions of its nodes
//! from the node file, the cells its box meets and the facts the import keeps of it, on every
//! core; then written to the store in the order given, on one thread.

use rusqlite::{params, Statement};

use super::codec;
use super::import::{ImportError, Partial, Rules};
use crate::osm::index::{cells_of, is_coastline};
use crate::osm::structures::may_be_crossed;
use crate::osm::{bounds_of, Bounds, LonLat};
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

    /// Resolves `ways` (ids and raw rows), spread over the cores; in the order given.
    pub fn resolve(
        &mut self,
        ways: &[(i64, Vec<u8>)],
        n: f64,
        rules: &Rules,
    ) -> Result<Vec<Resolved>, ImportError> {
        let per_thread = ways.len().div_ceil(self.readers.len()).max(256);
        if ways.len() <= per_thread {
            return ways
                .iter()
                .map(|(id, data)| resolve(*id, data, &mut self.readers[0], n, rules))
                .collect();
        }
        std::thread::scope(|scope| {
            let workers: Vec<_> = ways
                .chunks(per_thread)
                .zip(self.readers.iter_mut())
                .map(|(chunk, reader)| {
                    scope.spawn(move || {
                        chunk
                            .iter()
                            .map(|(id, data)| resolve(*id, data, reader, n, rules))
                            .collect::<Result<Vec<_>, _>>()
                    })
                })
                .collect();
            let mut resolved = Vec::with_capacity(ways.len());
            for worker in workers {
                let part = worker.join().map_err(|_| {
                    ImportError::NodeFile(NodeStoreError::Io {
                        path: Default::default(),
                        source: std::io::Error::other("resolving ways panicked"),
                    })
                })?;
                resolved.extend(part?);
            }
            Ok(resolved)
        })
    }
}

/// A way resolved.
pub struct Resolved {
    id: i64,
    /// Its nodes missing from the extracts, and then its raw row (kept so that a diff adding
    /// them completes it).
    missing: Vec<i64>,
    raw: Option<Vec<u8>>,
    /// What is stored of it when two or more of its nodes were found.
    way: Option<ResolvedWay>,
}

struct ResolvedWay {
    row: Vec<u8>,
    bounds: Option<Bounds>,
    cells: Vec<(u32, u32)>,
    /// Its node references when it joins the road network (a node repeated next to itself
    /// once, as the in-memory index counts).
    joint_refs: Vec<i64>,
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

fn resolve(
    id: i64,
    data: &[u8],
    locations: &mut NodeLocations,
    n: f64,
    rules: &Rules,
) -> Result<Resolved, ImportError> {
    let (tags, refs) = codec::decode_raw_way(data)?;
    let mut nodes = Vec::with_capacity(refs.len());
    let mut at = Vec::with_capacity(refs.len());
    let mut missing = Vec::new();
    for &node in &refs {
        match locations.get(node)? {
            Some(p) => {
                nodes.push(node);
                at.push(p);
            }
            None => missing.push(node),
        }
    }
    let raw = (!missing.is_empty()).then(|| data.to_vec());
    if nodes.len() < 2 {
        return Ok(Resolved {
            id,
            missing,
            raw,
            way: None,
        });
    }
    let positions: Vec<LonLat> = at
        .iter()
        .map(|p| {
            let (lon, lat) = p.lon_lat();
            LonLat { lon, lat }
        })
        .collect();
    let bounds = bounds_of(&positions);
    let cells = bounds.map_or_else(Vec::new, |b| cells_of(&b, n).collect());
    let joint_refs = if (rules.joins)(&tags) {
        nodes
            .iter()
            .enumerate()
            .filter(|&(k, node)| k == 0 || nodes[k - 1] != *node)
            .map(|(_, &node)| node)
            .collect()
    } else {
        Vec::new()
    };
    let structure = (rules.classify)(&tags).is_some();
    let part = if structure || may_be_crossed(&tags) {
        Some(Part::Always)
    } else {
        (rules.depth)(&tags).map(|_| Part::NearTunnels)
    };
    Ok(Resolved {
        id,
        missing,
        raw,
        way: Some(ResolvedWay {
            row: codec::encode_way(&tags, &nodes, &at),
            bounds,
            cells,
            joint_refs,
            structure,
            coastline: is_coastline(&tags),
            part,
        }),
    })
}

/// Writes resolved ways to the store: the way, its cells, its joint references, whether it
/// is a coastline, how it may take part in groups, and what is missing of it.
pub struct ResolvedWriter<'a> {
    partial: &'a Partial,
    way: Statement<'a>,
    cell: Statement<'a>,
    joint_ref: Statement<'a>,
    coast: Statement<'a>,
    incomplete: Statement<'a>,
    missing: Statement<'a>,
    part: Statement<'a>,
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
            way: prepare("INSERT INTO ways (id, data) VALUES (?1, ?2)")?,
            cell: prepare("INSERT INTO cells (x, y, kind, id) VALUES (?1, ?2, 1, ?3)")?,
            joint_ref: prepare("INSERT INTO joint_refs (node, way) VALUES (?1, ?2)")?,
            coast: prepare("INSERT INTO coastlines (way) VALUES (?1)")?,
            incomplete: prepare("INSERT INTO incomplete_ways (way, data) VALUES (?1, ?2)")?,
            missing: prepare("INSERT OR IGNORE INTO missing_nodes (node, way) VALUES (?1, ?2)")?,
            part: prepare(
                "INSERT INTO parts (id, near_tunnels, west, south, east, north)
                 VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
            )?,
            structure_ways: Vec::new(),
            written: 0,
        })
    }

    pub fn write(&mut self, resolved: Resolved) -> Result<(), ImportError> {
        let sqlite = self.partial.sqlite();
        let id = resolved.id;
        if let Some(raw) = resolved.raw {
            self.incomplete.execute(params![id, raw]).map_err(&sqlite)?;
            for node in resolved.missing {
                self.missing.execute(params![node, id]).map_err(&sqlite)?;
            }
        }
        let Some(way) = resolved.way else {
            return Ok(());
        };
        self.way.execute(params![id, way.row]).map_err(&sqlite)?;
        for (x, y) in way.cells {
            self.cell.execute(params![x, y, id]).map_err(&sqlite)?;
        }
        for node in way.joint_refs {
            self.joint_ref.execute(params![node, id]).map_err(&sqlite)?;
        }
        if way.structure {
            self.structure_ways.push(id);
        }
        if way.coastline {
            self.coast.execute(params![id]).map_err(&sqlite)?;
        }
        if let (Some(part), Some(b)) = (way.part, way.bounds) {
            self.part
                .execute(params![
                    id,
                    part == Part::NearTunnels,
                    b.west,
                    b.south,
                    b.east,
                    b.north
                ])
                .map_err(&sqlite)?;
        }
        self.written += 1;
        Ok(())
    }
}
