//! Reading `.osm.pbf` extracts (with `osmpbf`) into [`OsmData`].
//!
//! Each file is read once, block by block. Node positions are kept only until the ways have been
//! resolved; ways that reference nodes missing from the extract keep the nodes that are there
//! (and are dropped if fewer than two remain), with a debug log. When several extracts hold the
//! same element, the first file listed wins.

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

use osmpbf::{BlobDecode, BlobReader, Element};
use tracing::debug;

use crate::osm::{
    Bounds, ElementRef, ElementType, LonLat, Member, Node, OsmData, Relation, Tags, Way,
};

#[derive(Debug, thiserror::Error)]
pub enum OsmReadError {
    #[error("cannot read OSM extract {path}: {message}")]
    Pbf { path: PathBuf, message: String },
    #[error("OSM extract {path} holds no nodes")]
    Empty { path: PathBuf },
    #[error("OSM extract {path} {why}")]
    CutShort { path: PathBuf, why: String },
}

/// What a PBF header lists among its optional features when the blocks hold nodes, then ways,
/// then relations, each by id.
pub const SORTED_BY_TYPE: &str = "Sort.Type_then_ID";

/// What one extract held, as read: a summary to tell a whole extract from a cut one.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ExtractRead {
    pub path: PathBuf,
    /// Blocks of data after the header.
    pub blocks: u64,
    pub nodes: u64,
    pub ways: u64,
    /// Every relation read, kept or not.
    pub relations: u64,
    /// Whether its header says it is sorted by type, then id.
    pub sorted: bool,
}

impl ExtractRead {
    /// Why the extract must have been cut short, when what it lacks says so: PBF has no end
    /// marker, so a file cut at a block boundary reads cleanly. One that holds no element, and
    /// one sorted by type that ends in its nodes, are cut (or were never whole).
    pub fn cut_short(&self) -> Option<String> {
        if self.nodes + self.ways + self.relations == 0 {
            return Some(format!(
                "holds no OSM elements ({} blocks of data after its header): it is cut short or empty",
                self.blocks
            ));
        }
        (self.sorted && self.ways == 0 && self.relations == 0).then(|| {
            format!(
                "is cut short: its header says it is sorted by type, and it ends in its nodes ({} \
                 of them) with no way after them",
                self.nodes
            )
        })
    }
}

/// A digest of an extract's bytes: its version (the same data downloaded again or touched
/// keeps it).
pub fn content_digest(path: &std::path::Path) -> Result<String, OsmReadError> {
    use sha2::Digest;
    use std::io::Read;
    let failed = |e: std::io::Error| OsmReadError::Pbf {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    let mut file = std::fs::File::open(path).map_err(failed)?;
    let mut digest = sha2::Sha256::new();
    let mut buffer = vec![0u8; 1 << 16];
    loop {
        let n = file.read(&mut buffer).map_err(failed)?;
        if n == 0 {
            break;
        }
        digest.update(&buffer[..n]);
    }
    Ok(digest.finalize()[..8]
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect())
}

/// Ways as read, before their nodes are resolved.
struct RawWay {
    tags: Tags,
    nodes: Vec<i64>,
}

#[derive(Default)]
struct Accumulator {
    positions: HashMap<i64, LonLat>,
    nodes: BTreeMap<i64, Node>,
    ways: BTreeMap<i64, RawWay>,
    relations: BTreeMap<i64, Relation>,
}

/// Reads and merges several extracts.
pub fn read_extracts(paths: &[PathBuf]) -> Result<OsmData, OsmReadError> {
    let mut accumulator = Accumulator::default();
    let mut coverage = Vec::new();
    for path in paths {
        coverage.push(read_one(path, &mut accumulator)?);
    }
    let Accumulator {
        positions,
        nodes,
        ways,
        relations,
    } = accumulator;

    let mut resolved = Vec::with_capacity(ways.len());
    for (id, raw) in ways {
        let mut node_ids = Vec::with_capacity(raw.nodes.len());
        let mut way_positions = Vec::with_capacity(raw.nodes.len());
        for node in &raw.nodes {
            if let Some(position) = positions.get(node) {
                node_ids.push(*node);
                way_positions.push(*position);
            }
        }
        if node_ids.len() < raw.nodes.len() {
            debug!(
                way = id,
                missing = raw.nodes.len() - node_ids.len(),
                "way references nodes missing from the extract; keeping the nodes that are present"
            );
        }
        if node_ids.len() < 2 {
            debug!(way = id, "way has fewer than two resolvable nodes; dropped");
            continue;
        }
        resolved.push(Way {
            id,
            tags: raw.tags,
            nodes: node_ids,
            positions: way_positions,
        });
    }
    Ok(OsmData {
        nodes: nodes.into_values().collect(),
        ways: resolved,
        relations: relations.into_values().collect(),
        coverage,
    })
}

/// Reads one file into the accumulator and returns the area it covers.
fn read_one(path: &Path, acc: &mut Accumulator) -> Result<Bounds, OsmReadError> {
    let error = |message: String| OsmReadError::Pbf {
        path: path.to_path_buf(),
        message,
    };
    let reader = BlobReader::from_path(path).map_err(|e| error(e.to_string()))?;
    let mut header_bounds: Option<Bounds> = None;
    let mut extent: Option<Bounds> = None;
    let mut read = ExtractRead::default();
    for blob in reader {
        let blob = blob.map_err(|e| error(e.to_string()))?;
        match blob.decode().map_err(|e| error(e.to_string()))? {
            BlobDecode::OsmHeader(header) => {
                if let Some(b) = bounds_in(&header) {
                    header_bounds = Some(b);
                }
                read.sorted |= header
                    .optional_features()
                    .iter()
                    .any(|f| f == SORTED_BY_TYPE);
            }
            BlobDecode::OsmData(block) => {
                read.blocks += 1;
                for element in block.elements() {
                    match &element {
                        Element::Node(_) | Element::DenseNode(_) => read.nodes += 1,
                        Element::Way(_) => read.ways += 1,
                        Element::Relation(_) => read.relations += 1,
                    }
                    match element {
                        Element::Node(node) => {
                            let position = LonLat {
                                lon: node.lon(),
                                lat: node.lat(),
                            };
                            on_the_earth(node.id(), position).map_err(error)?;
                            grow(&mut extent, position);
                            add_node(acc, node.id(), position, node.tags());
                        }
                        Element::DenseNode(node) => {
                            let position = LonLat {
                                lon: node.lon(),
                                lat: node.lat(),
                            };
                            on_the_earth(node.id(), position).map_err(error)?;
                            grow(&mut extent, position);
                            add_node(acc, node.id(), position, node.tags());
                        }
                        Element::Way(way) => {
                            acc.ways.entry(way.id()).or_insert_with(|| RawWay {
                                tags: Tags::from_pairs(way.tags()),
                                nodes: way.refs().collect(),
                            });
                        }
                        Element::Relation(relation) => {
                            acc.relations
                                .entry(relation.id())
                                .or_insert_with(|| relation_of(&relation));
                        }
                    }
                }
            }
            BlobDecode::Unknown(kind) => {
                debug!(path = %path.display(), kind, "skipping unknown blob");
            }
        }
    }
    if let Some(why) = read.cut_short() {
        return Err(OsmReadError::CutShort {
            path: path.to_path_buf(),
            why,
        });
    }
    header_bounds.or(extent).ok_or_else(|| OsmReadError::Empty {
        path: path.to_path_buf(),
    })
}

/// A node lies on the Earth, or its error says where it lies instead.
fn on_the_earth(id: i64, p: LonLat) -> Result<(), String> {
    match crate::source::node_locations::on_the_earth(p.lon, p.lat) {
        true => Ok(()),
        false => Err(
            crate::source::node_locations::NodeStoreError::OutsideTheWorld {
                id,
                lon: p.lon,
                lat: p.lat,
            }
            .to_string(),
        ),
    }
}

/// The box a header declares.
pub(crate) fn bounds_in(header: &osmpbf::HeaderBlock) -> Option<Bounds> {
    header.bbox().map(|b| Bounds {
        west: b.left,
        east: b.right,
        south: b.bottom,
        north: b.top,
    })
}

/// Grows `extent` to hold `p`.
pub(crate) fn grow(extent: &mut Option<Bounds>, p: LonLat) {
    let b = extent.get_or_insert(Bounds {
        west: p.lon,
        east: p.lon,
        south: p.lat,
        north: p.lat,
    });
    b.west = b.west.min(p.lon);
    b.east = b.east.max(p.lon);
    b.south = b.south.min(p.lat);
    b.north = b.north.max(p.lat);
}

/// A relation as the model keeps it.
pub(crate) fn relation_of(relation: &osmpbf::Relation<'_>) -> Relation {
    let members = relation
        .members()
        .map(|m| Member {
            element: ElementRef {
                element_type: match m.member_type {
                    osmpbf::RelMemberType::Node => ElementType::Node,
                    osmpbf::RelMemberType::Way => ElementType::Way,
                    osmpbf::RelMemberType::Relation => ElementType::Relation,
                },
                id: m.member_id,
            },
            role: m.role().unwrap_or_default().to_string(),
        })
        .collect();
    Relation {
        id: relation.id(),
        tags: Tags::from_pairs(relation.tags()),
        members,
    }
}

fn add_node<'a>(
    acc: &mut Accumulator,
    id: i64,
    position: LonLat,
    tags: impl Iterator<Item = (&'a str, &'a str)>,
) {
    if acc.positions.contains_key(&id) {
        return;
    }
    acc.positions.insert(id, position);
    let tags = Tags::from_pairs(tags);
    if !tags.is_empty() {
        acc.nodes.insert(id, Node { id, position, tags });
    }
}
