//! A spatial index over the OSM data, built once at start in memory.
//!
//! Every way, tagged node and relation is registered in cells of a regular grid of slippy-map
//! tiles (at [`OsmIndex::zoom`]): a node in its own, a way in those its line passes through (and
//! a closed way in those inside it), a relation in those its bounding box touches. A tile query
//! then reads only the cells around the tile: no extract is reread per request. An in-memory grid
//! is the right size for city and region extracts (Monaco: 27k ways, under 100 MB); a country
//! would call for the same cells kept in SQLite instead.

use std::collections::HashMap;

use super::coast::{self, CoastBox};
use super::structures::{self, Classify, Group, StructureKind};
use super::{bounds_of, Bounds, LonLat, Node, OsmData, Relation, Way};
use crate::geometry::{grid_index, segment_cells};
use crate::tile::{lon_lat_to_uv, TileId};

/// The OSM data and its grid.
#[derive(Debug)]
pub struct OsmIndex {
    data: OsmData,
    zoom: u8,
    cells: HashMap<(u32, u32), CellContent>,
    /// The boxes of the `natural=coastline` ways, and beside each the way's index.
    coast_boxes: Vec<CoastBox>,
    coast_ways: Vec<u32>,
    /// Bridges and tunnels, whole.
    structures: Vec<Group>,
    /// The cells each structure group touches.
    structure_cells: HashMap<(u32, u32), Vec<u32>>,
    roads: RoadGraph,
}

/// The nodes where ways join (shared by two ways, or met twice by one), each with the indices
/// of the ways through it.
pub type Joints = HashMap<i64, Vec<u32>>;

/// What the profile of a road on the ground depends on beyond the road itself, for the whole
/// data: where it joins other ways, and where a bridge passes over it.
#[derive(Debug, Default)]
pub struct RoadGraph {
    pub joints: Joints,
    /// By way id, where a bridge crosses over the way.
    pub under_bridges: HashMap<i64, Vec<LonLat>>,
}

#[derive(Debug, Default)]
struct CellContent {
    ways: Vec<u32>,
    nodes: Vec<u32>,
    relations: Vec<u32>,
}

/// The elements near one tile, each in ascending id order.
#[derive(Debug, Default)]
pub struct Selection<'a> {
    pub nodes: Vec<&'a Node>,
    pub ways: Vec<&'a Way>,
    pub relations: Vec<&'a Relation>,
    /// Every `natural=coastline` way of the data, near or not: which side of the coast a tile
    /// lies on is decided by the nearest one, wherever it is.
    pub coastlines: Vec<&'a Way>,
    /// The bridges and tunnels that reach near the tile, whole, with what they cross.
    pub structures: Vec<&'a Group>,
    /// Every way of the data, for the indices in `structures` and `joints`.
    pub all_ways: &'a [Way],
    /// Where the ways of the data join and pass under bridges, near the tile or not (see
    /// [`OsmIndex::with_joints`]).
    pub roads: Option<&'a RoadGraph>,
    /// The blocks of a far tile when this is its generalised data (see [`super::far`]).
    pub blocks: Option<&'a [super::far::Block]>,
}

impl OsmIndex {
    /// Indexes `data` on a grid of zoom-`zoom` tiles; `classify` tells which ways make up
    /// bridges and tunnels.
    pub fn new(data: OsmData, zoom: u8, classify: Classify) -> OsmIndex {
        let coastlines = (0..data.ways.len() as u32)
            .filter(|&i| is_coastline(&data.ways[i as usize].tags))
            .collect();
        let structures = structures::find(&data.ways, classify);
        let roads = RoadGraph {
            joints: Joints::new(),
            under_bridges: under_bridges(&data.ways, &structures),
        };
        OsmIndex::from_parts(data, zoom, structures, roads, coastlines)
    }

    /// Indexes `data` whose extract-wide facts were found over more data than it holds: its
    /// bridge and tunnel groups (their way indices into `data.ways`), where its ways join and
    /// pass under bridges, and which of its ways are coastlines.
    pub fn from_parts(
        data: OsmData,
        zoom: u8,
        structures: Vec<Group>,
        roads: RoadGraph,
        coastlines: Vec<u32>,
    ) -> OsmIndex {
        let n = f64::from(1u32 << zoom);
        let cells = grid(&data, n);
        let mut structure_cells: HashMap<(u32, u32), Vec<u32>> = HashMap::new();
        for (i, group) in structures.iter().enumerate() {
            for cell in cells_of(&group.bounds, n) {
                structure_cells.entry(cell).or_default().push(i as u32);
            }
        }
        let (coast_boxes, coast_ways) = coastlines
            .iter()
            .filter_map(|&i| {
                let way = &data.ways[i as usize];
                Some((CoastBox::of(way.id, &way.positions, n)?, i))
            })
            .unzip();
        OsmIndex {
            data,
            zoom,
            cells,
            coast_boxes,
            coast_ways,
            structures,
            structure_cells,
            roads,
        }
    }

    /// Finds where the ways that `joins` accepts join one another: the nodes such ways share
    /// or one of them meets twice.
    pub fn with_joints(mut self, joins: fn(&super::Tags) -> bool) -> OsmIndex {
        let mut through: HashMap<i64, (usize, Vec<u32>)> = HashMap::new();
        for (i, way) in self.data.ways.iter().enumerate() {
            if !joins(&way.tags) {
                continue;
            }
            for (k, &node) in way.nodes.iter().enumerate() {
                // A closed way meets its first node again at its end; any other repeat of a
                // node next to itself is a duplicated point, not a joint.
                if k > 0 && way.nodes[k - 1] == node {
                    continue;
                }
                let entry = through.entry(node).or_default();
                entry.0 += 1;
                if entry.1.last() != Some(&(i as u32)) {
                    entry.1.push(i as u32);
                }
            }
        }
        self.roads.joints = through
            .into_iter()
            .filter(|(_, (count, _))| *count > 1)
            .map(|(node, (_, ways))| (node, ways))
            .collect();
        self
    }

    /// Finds, for every group with a tunnel, the ways and nodes over its tunnels (within
    /// [`ABOVE_TUNNEL_DEG`] of a tunnel's line) that `depth` says reach down into the ground.
    pub fn with_foundations(mut self, depth: fn(&super::Tags) -> Option<f64>) -> OsmIndex {
        let n = f64::from(1u32 << self.zoom);
        for group in &mut self.structures {
            let tunnels: Vec<&structures::Chain> = group
                .chains
                .iter()
                .filter(|c| c.kind == StructureKind::Tunnel)
                .collect();
            if tunnels.is_empty() {
                continue;
            }
            // Each tunnel segment with the box around it that something near it meets.
            let segments: Vec<(LonLat, LonLat, Bounds)> = tunnels
                .iter()
                .flat_map(|chain| chain.positions.windows(2))
                .filter_map(|pair| {
                    let bounds = bounds_of(pair)?.expanded(ABOVE_TUNNEL_DEG);
                    Some((pair[0], pair[1], bounds))
                })
                .collect();
            // Near a tunnel's line, or an outline the line passes through.
            let near = |positions: &[LonLat]| {
                let Some(bounds) = bounds_of(positions) else {
                    return false;
                };
                segments
                    .iter()
                    .filter(|(_, _, around)| meets(around, &bounds))
                    .any(|&(a, b, _)| {
                        positions
                            .iter()
                            .any(|&p| degrees_to_segment(p, a, b) < ABOVE_TUNNEL_DEG)
                            || [a, b].iter().any(|p| holds(&bounds, *p))
                    })
            };
            let area = group.bounds.expanded(ABOVE_TUNNEL_DEG);
            let mut ways: Vec<u32> = Vec::new();
            let mut nodes: Vec<u32> = Vec::new();
            for cell in cells_of(&area, n) {
                if let Some(content) = self.cells.get(&cell) {
                    ways.extend(&content.ways);
                    nodes.extend(&content.nodes);
                }
            }
            ways.sort_unstable();
            ways.dedup();
            nodes.sort_unstable();
            nodes.dedup();
            for i in ways {
                let way = &self.data.ways[i as usize];
                let Some(depth_m) = depth(&way.tags) else {
                    continue;
                };
                if way.is_closed() && near(&way.positions) {
                    group.above.push(structures::Above {
                        id: way.id,
                        positions: way.positions.clone(),
                        depth_m,
                    });
                }
            }
            for i in nodes {
                let node = &self.data.nodes[i as usize];
                let Some(depth_m) = depth(&node.tags) else {
                    continue;
                };
                if near(&[node.position]) {
                    group.above.push(structures::Above {
                        id: node.id,
                        positions: vec![node.position],
                        depth_m,
                    });
                }
            }
        }
        self
    }

    /// Where ways join (from [`OsmIndex::with_joints`]) and pass under bridges.
    pub fn roads(&self) -> &RoadGraph {
        &self.roads
    }

    pub fn data(&self) -> &OsmData {
        &self.data
    }

    /// Every bridge and tunnel of the data.
    pub fn structures(&self) -> &[Group] {
        &self.structures
    }

    pub fn zoom(&self) -> u8 {
        self.zoom
    }

    /// The elements whose bounding box meets `tile` grown by `margin_deg` degrees.
    pub fn query(&self, tile: TileId, margin_deg: f64) -> Selection<'_> {
        let area = tile.bounds().expanded(margin_deg);
        let n = f64::from(1u32 << self.zoom);
        let mut ways: Vec<u32> = Vec::new();
        let mut nodes: Vec<u32> = Vec::new();
        let mut relations: Vec<u32> = Vec::new();
        let mut groups: Vec<u32> = Vec::new();
        for cell in cells_of(&area, n) {
            if let Some(found) = self.structure_cells.get(&cell) {
                groups.extend(found);
            }
            if let Some(content) = self.cells.get(&cell) {
                ways.extend(&content.ways);
                nodes.extend(&content.nodes);
                relations.extend(&content.relations);
            }
        }
        for list in [&mut ways, &mut nodes, &mut relations, &mut groups] {
            list.sort_unstable();
            list.dedup();
        }
        let meets = |positions: &[LonLat]| bounds_of(positions).is_some_and(|b| meets(&b, &area));
        Selection {
            ways: ways
                .into_iter()
                .map(|i| &self.data.ways[i as usize])
                .filter(|w| meets(&w.positions))
                .collect(),
            nodes: nodes
                .into_iter()
                .map(|i| &self.data.nodes[i as usize])
                .filter(|n| meets(&[n.position]))
                .collect(),
            relations: relations
                .into_iter()
                .map(|i| &self.data.relations[i as usize])
                .collect(),
            coastlines: self.nearest_coast(tile),
            structures: groups
                .into_iter()
                .map(|i| &self.structures[i as usize])
                .filter(|g| self::meets(&g.bounds, &area))
                .collect(),
            all_ways: &self.data.ways,
            roads: Some(&self.roads),
            blocks: None,
        }
    }
}

impl super::far::FarTile {
    /// What the far tile is made from: its generalised data, with its blocks.
    pub fn selection(&self) -> Selection<'_> {
        Selection {
            ways: self.data.ways.iter().collect(),
            relations: self.data.relations.iter().collect(),
            coastlines: self.coast.iter().collect(),
            blocks: Some(&self.data.blocks),
            ..Selection::default()
        }
    }
}

impl<'a> Selection<'a> {
    /// The open ways of the selection longer than `longest_m` (coastlines aside: the side of
    /// the coast is read from whole ways), each cut to what lies within `box_` (the line,
    /// straight in Web Mercator as it is drawn, clipped where it leaves the box, at new points
    /// of their own): what a tile can draw of it, whatever its length. Inside the box each
    /// piece is the way's own line; a way that leaves the box and comes back gives a piece for
    /// each pass, all with its id. A point made by the cut has a node id below every OSM id
    /// (`i64::MIN` counted up), so it joins nothing. Ascending by id, in order along each way.
    pub fn cut_long_ways(&self, box_: &Bounds, longest_m: f64) -> Vec<Way> {
        let uv = |p: LonLat| {
            let (u, v) = lon_lat_to_uv(p.lon, p.lat, 1.0);
            [u, v]
        };
        let (low, high) = (
            uv(LonLat {
                lon: box_.west,
                lat: box_.north,
            }),
            uv(LonLat {
                lon: box_.east,
                lat: box_.south,
            }),
        );
        let back = |p: [f64; 2]| LonLat {
            lon: crate::tile::u_to_lon(p[0], 1.0),
            lat: crate::tile::v_to_lat(p[1], 1.0),
        };
        let mut made = i64::MIN;
        let mut cut = Vec::new();
        for way in &self.ways {
            let long = super::length_m(&way.positions) > longest_m;
            if !long || way.is_closed() || is_coastline(&way.tags) {
                continue;
            }
            let mut piece: Option<Way> = None;
            for k in 0..way.positions.len().saturating_sub(1) {
                let (a, b) = (uv(way.positions[k]), uv(way.positions[k + 1]));
                let Some((t0, t1)) = clip_segment(a, b, low, high) else {
                    cut.extend(piece.take());
                    continue;
                };
                let at = |t: f64| [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
                let current = piece.get_or_insert_with(|| Way {
                    id: way.id,
                    tags: way.tags.clone(),
                    nodes: Vec::new(),
                    positions: Vec::new(),
                });
                if current.positions.is_empty() {
                    let (node, position) = match t0 > 0.0 {
                        true => (post_inc(&mut made), back(at(t0))),
                        false => (way.nodes[k], way.positions[k]),
                    };
                    current.nodes.push(node);
                    current.positions.push(position);
                }
                let (node, position) = match t1 < 1.0 {
                    true => (post_inc(&mut made), back(at(t1))),
                    false => (way.nodes[k + 1], way.positions[k + 1]),
                };
                current.nodes.push(node);
                current.positions.push(position);
                if t1 < 1.0 {
                    cut.extend(piece.take());
                }
            }
            cut.extend(piece.take());
        }
        cut
    }

    /// The selection with the ways of `cut` (see [`Selection::cut_long_ways`]) in place of the
    /// whole ways of their ids.
    pub fn with_cut_ways<'b>(&self, cut: &'b [Way]) -> Selection<'b>
    where
        'a: 'b,
    {
        let cut_ids: std::collections::BTreeSet<i64> = cut.iter().map(|w| w.id).collect();
        let mut ways: Vec<&'b Way> = self
            .ways
            .iter()
            .copied()
            .filter(|w| !cut_ids.contains(&w.id))
            .collect();
        ways.extend(cut);
        ways.sort_by_key(|w| w.id);
        Selection {
            nodes: self.nodes.clone(),
            ways,
            relations: self.relations.clone(),
            coastlines: self.coastlines.clone(),
            structures: self.structures.clone(),
            all_ways: self.all_ways,
            roads: self.roads,
            blocks: self.blocks,
        }
    }
}

impl OsmIndex {
    /// The coastline ways that may hold the point of the coast nearest to the tile's centre,
    /// in index order.
    fn nearest_coast(&self, tile: TileId) -> Vec<&Way> {
        let n = f64::from(1u32 << self.zoom);
        let p = coast_point(tile, self.zoom);
        let way_of = |k: usize| &self.data.ways[self.coast_ways[k] as usize];
        coast::nearest(&self.coast_boxes, p, |k| {
            Some(coast::distance_to_way(way_of(k), p, n))
        })
        .into_iter()
        .map(way_of)
        .collect()
    }
}

/// The centre of `tile` in global tile units at `zoom`: where the side of the coast is asked.
pub fn coast_point(tile: TileId, zoom: u8) -> [f64; 2] {
    let scale = 2f64.powi(i32::from(zoom) - i32::from(tile.z));
    [
        (f64::from(tile.x) + 0.5) * scale,
        (f64::from(tile.y) + 0.5) * scale,
    ]
}

/// Whether a way is a stretch of coastline.
pub fn is_coastline(tags: &super::Tags) -> bool {
    tags.get("natural") == Some("coastline")
}

/// Every element of `data` in each cell of a grid of `n` × `n` tiles it reaches: a way in
/// the cells of [`cells_of_way`], a node in its own, a relation in each its bounding box meets
/// (a relation's box is its member ways', and theirs of its member relations).
fn grid(data: &OsmData, n: f64) -> HashMap<(u32, u32), CellContent> {
    let mut cells: HashMap<(u32, u32), CellContent> = HashMap::new();
    for (i, way) in data.ways.iter().enumerate() {
        let reached = cells_of_way(way, n);
        warn_if_unbounded(way.id, &way.positions, reached.len());
        for cell in reached {
            cells.entry(cell).or_default().ways.push(i as u32);
        }
    }
    let mut register = |bounds: Bounds, push: &mut dyn FnMut(&mut CellContent)| {
        for cell in cells_of(&bounds, n) {
            push(cells.entry(cell).or_default());
        }
    };
    for (i, node) in data.nodes.iter().enumerate() {
        let bounds = bounds_of(&[node.position]).expect("one position has bounds");
        register(bounds, &mut |c| c.nodes.push(i as u32));
    }
    for (i, relation) in data.relations.iter().enumerate() {
        let member_positions: Vec<LonLat> = relation_ways(data, relation)
            .iter()
            .filter_map(|&id| data.way(id))
            .flat_map(|w| w.positions.iter().copied())
            .collect();
        if let Some(bounds) = bounds_of(&member_positions) {
            register(bounds, &mut |c| c.relations.push(i as u32));
        }
    }
    cells
}

/// The ways of a relation: its member ways, and those of its member relations (a building's
/// multipolygon outline).
pub fn relation_ways(data: &OsmData, relation: &Relation) -> Vec<i64> {
    let member_ways = |members: &'_ [super::Member]| -> Vec<i64> {
        members
            .iter()
            .filter(|m| m.element.element_type == super::ElementType::Way)
            .map(|m| m.element.id)
            .collect()
    };
    let mut ways = member_ways(&relation.members);
    for member in &relation.members {
        if member.element.element_type == super::ElementType::Relation {
            if let Some(inner) = data.relation(member.element.id) {
                ways.extend(member_ways(&inner.members));
            }
        }
    }
    ways
}

/// By way id, where the bridges of `groups` pass over the ways of `ways` (the ways the groups'
/// indices point into).
pub fn under_bridges(ways: &[Way], groups: &[Group]) -> HashMap<i64, Vec<LonLat>> {
    let mut under: HashMap<i64, Vec<LonLat>> = HashMap::new();
    for group in groups {
        for crossing in &group.crossings {
            let chain = &group.chains[crossing.chain as usize];
            let (structures::Crossed::Way(below), StructureKind::Bridge) =
                (crossing.other, chain.kind)
            else {
                continue;
            };
            let k = crossing.segment as usize;
            let (Some(a), Some(b), Some(way)) = (
                chain.positions.get(k),
                chain.positions.get(k + 1),
                ways.get(below as usize),
            ) else {
                continue;
            };
            let t = crossing.t;
            under.entry(way.id).or_default().push(LonLat {
                lon: a.lon + t * (b.lon - a.lon),
                lat: a.lat + t * (b.lat - a.lat),
            });
        }
    }
    under
}

/// How far (degrees) from a tunnel's line a building's vertex or a tree may stand and still
/// reach down over it: about 40 m, a wide tunnel's half width and a building's size.
pub const ABOVE_TUNNEL_DEG: f64 = 0.0004;

/// The share of `a`–`b` (from `t0` to `t1` along it) inside the box `low`–`high`
/// (Liang–Barsky), if any of it is.
fn clip_segment(a: [f64; 2], b: [f64; 2], low: [f64; 2], high: [f64; 2]) -> Option<(f64, f64)> {
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for axis in 0..2 {
        let d = b[axis] - a[axis];
        for (p, q) in [(-d, a[axis] - low[axis]), (d, high[axis] - a[axis])] {
            if p == 0.0 {
                if q < 0.0 {
                    return None;
                }
            } else if p < 0.0 {
                t0 = t0.max(q / p);
            } else {
                t1 = t1.min(q / p);
            }
        }
    }
    (t0 <= t1).then_some((t0, t1))
}

/// `counter`, then counts it up.
fn post_inc(counter: &mut i64) -> i64 {
    *counter += 1;
    *counter - 1
}

/// True when `p` lies in the box (on its border too).
fn holds(bounds: &Bounds, p: LonLat) -> bool {
    (bounds.west..=bounds.east).contains(&p.lon) && (bounds.south..=bounds.north).contains(&p.lat)
}

/// Distance from `p` to the segment `a`–`b` in degrees, longitude scaled by the latitude.
fn degrees_to_segment(p: LonLat, a: LonLat, b: LonLat) -> f64 {
    let k = p.lat.to_radians().cos();
    let (px, py) = (p.lon * k, p.lat);
    let (ax, ay) = (a.lon * k, a.lat);
    let (bx, by) = (b.lon * k, b.lat);
    let (dx, dy) = (bx - ax, by - ay);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((px - ax) * dx + (py - ay) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (px - ax - t * dx).hypot(py - ay - t * dy)
}

/// Like [`Bounds::intersects`], but a box of zero width (a node, a north–south way) counts.
pub fn meets(a: &Bounds, b: &Bounds) -> bool {
    a.west <= b.east && b.west <= a.east && a.south <= b.north && b.south <= a.north
}

/// Warns of a way whose work is bounded rather than done whole: one longer than any bridge or
/// tunnel (so taken for neither), or one registered along only part of its line.
pub fn warn_if_unbounded(id: i64, positions: &[LonLat], cells: usize) {
    let length_km = super::length_m(positions) / 1000.0;
    if cells as u64 >= MAX_LINE_CELLS {
        tracing::warn!(
            way = id,
            length_km,
            cells,
            "a way reaches so many tiles that it is found only along the first part of its line"
        );
    } else if length_km * 1000.0 > super::structures::LONGEST_STRUCTURE_WAY_M {
        tracing::warn!(
            way = id,
            length_km,
            "a way longer than any bridge or tunnel: it is drawn as a line on the ground, tile by tile"
        );
    }
}

/// A closed way is registered in the cells inside it when its box holds at most this many
/// (256 × 256: some 600 km a side at the equator at zoom 14, more than any one way encloses);
/// past it, only along its outline, so that no single way can fill the index.
pub const MAX_FILLED_CELLS: u64 = 1 << 16;

/// A way is registered along its line until it has passed this many cells (a line four times
/// around the world at zoom 14); what lies beyond is not found from the tiles there. No way
/// mapped on the Earth comes near it: it bounds what one hostile way can cost.
pub const MAX_LINE_CELLS: u64 = 1 << 17;

/// The cells of a grid of `n` × `n` tiles a way reaches: every cell one of its segments (a
/// straight line in Web Mercator, as it is drawn) passes through or touches, and for a closed
/// way every cell whose centre lies inside it (when its box holds at most
/// [`MAX_FILLED_CELLS`]). A tile's query reads the cells around it: a way is found where its
/// line or its inside reaches, and what it costs to register a way grows with its length,
/// never with its box. Ascending, each once.
pub fn cells_of_way(way: &Way, n: f64) -> Vec<(u32, u32)> {
    cells_of_line(&way.positions, way.is_closed(), n)
}

/// [`cells_of_way`] of a way at `positions`, closed or not.
pub fn cells_of_line(positions: &[LonLat], closed: bool, n: f64) -> Vec<(u32, u32)> {
    let uv: Vec<[f64; 2]> = positions
        .iter()
        .map(|p| {
            let (u, v) = lon_lat_to_uv(p.lon, p.lat, n);
            [u, v]
        })
        .collect();
    let mut cells = Vec::new();
    for pair in uv.windows(2) {
        if cells.len() as u64 >= MAX_LINE_CELLS {
            break;
        }
        segment_cells(pair[0], pair[1], n, &mut cells);
    }
    if let [only] = uv.as_slice() {
        segment_cells(*only, *only, n, &mut cells);
    }
    if closed {
        inside_cells(&uv, n, &mut cells);
    }
    cells.sort_unstable();
    cells.dedup();
    cells
}

/// The cells whose centre lies inside the ring `uv` (even–odd), row by row, when its box
/// holds at most [`MAX_FILLED_CELLS`].
fn inside_cells(uv: &[[f64; 2]], n: f64, cells: &mut Vec<(u32, u32)>) {
    let (mut low, mut high) = ([f64::MAX; 2], [f64::MIN; 2]);
    for p in uv {
        for axis in 0..2 {
            low[axis] = low[axis].min(p[axis]);
            high[axis] = high[axis].max(p[axis]);
        }
    }
    let columns = u64::from(grid_index(high[0], n) - grid_index(low[0], n)) + 1;
    let rows = u64::from(grid_index(high[1], n) - grid_index(low[1], n)) + 1;
    if columns * rows > MAX_FILLED_CELLS {
        return;
    }
    for y in grid_index(low[1], n)..=grid_index(high[1], n) {
        let centre = f64::from(y) + 0.5;
        let mut crossings: Vec<f64> = uv
            .windows(2)
            .filter(|e| (e[0][1] > centre) != (e[1][1] > centre))
            .map(|e| e[0][0] + (centre - e[0][1]) / (e[1][1] - e[0][1]) * (e[1][0] - e[0][0]))
            .collect();
        crossings.sort_by(f64::total_cmp);
        for pair in crossings.chunks_exact(2) {
            // Columns whose centre lies between the two crossings.
            let from = (pair[0] - 0.5).ceil().max(0.0);
            let to = (pair[1] - 0.5).floor().min(n - 1.0);
            let mut x = from;
            while x <= to {
                cells.push((x as u32, y));
                x += 1.0;
            }
        }
    }
}

/// The cells of a grid of `n` × `n` tiles that a box meets.
pub fn cells_of(bounds: &Bounds, n: f64) -> impl Iterator<Item = (u32, u32)> {
    let max = n - 1.0;
    let (u0, v0) = lon_lat_to_uv(bounds.west, bounds.north, n);
    let (u1, v1) = lon_lat_to_uv(bounds.east, bounds.south, n);
    let clamp = |t: f64| t.floor().clamp(0.0, max) as u32;
    let (x0, x1, y0, y1) = (clamp(u0), clamp(u1), clamp(v0), clamp(v1));
    (x0..=x1).flat_map(move |x| (y0..=y1).map(move |y| (x, y)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn way(id: i64, points: &[(f64, f64)]) -> Way {
        let nodes: Vec<(i64, f64, f64)> = (0..)
            .zip(points)
            .map(|(k, &(lon, lat))| (k, lon, lat))
            .collect();
        crate::osm::fixture::way(id, &[("highway", "residential")], &nodes)
    }

    #[test]
    fn finds_ways_near_a_tile_and_not_far_ones() {
        let data = OsmData {
            ways: vec![
                way(1, &[(7.41, 43.745), (7.42, 43.746)]),
                way(2, &[(7.60, 43.745), (7.61, 43.746)]),
                // Crosses the tile without a node in it.
                way(3, &[(7.39, 43.747), (7.44, 43.747)]),
            ],
            ..OsmData::default()
        };
        let index = OsmIndex::new(data, 14, |_| None);
        let selection = index.query(
            TileId {
                z: 14,
                x: 8529,
                y: 5973,
            },
            0.0005,
        );
        let ids: Vec<i64> = selection.ways.iter().map(|w| w.id).collect();
        assert_eq!(ids, [1, 3]);
    }

    #[test]
    fn a_long_way_is_cut_to_what_lies_near_the_tile_and_a_short_one_is_not() {
        let tile = TileId {
            z: 14,
            x: 8529,
            y: 5973,
        };
        let near = tile.bounds().expanded(0.02);
        let ways = [
            // To the pole and back into the tile: two passes.
            way(1, &[(7.415, 43.745), (7.415, 90.0), (7.416, 43.746)]),
            // Short: kept whole.
            way(2, &[(7.41, 43.745), (7.42, 43.746)]),
        ];
        let selection = Selection {
            ways: ways.iter().collect(),
            ..Selection::default()
        };
        let cut = selection.cut_long_ways(&near, 100_000.0);
        assert_eq!(cut.len(), 2, "a piece for each pass");
        for piece in &cut {
            assert_eq!(piece.id, 1);
            assert_eq!(piece.positions.len(), 2);
            assert!(super::super::length_m(&piece.positions) < 5_000.0);
            for p in &piece.positions {
                assert!(holds(&near.expanded(1e-9), *p), "{p:?}");
            }
        }
        assert_eq!(cut[0].positions[0], ways[0].positions[0]);
        assert_eq!(cut[0].nodes[0], ways[0].nodes[0]);
        assert!(cut[0].nodes[1] < 0, "a point of the cut joins nothing");
        assert_eq!(cut[1].positions[1], ways[0].positions[2]);
        let drawn = selection.with_cut_ways(&cut);
        let ids: Vec<i64> = drawn.ways.iter().map(|w| w.id).collect();
        assert_eq!(ids, [1, 1, 2]);
    }

    #[test]
    fn a_way_is_registered_where_its_line_passes_not_over_its_box() {
        let n = 16.0;
        let at = |u: f64, v: f64| LonLat {
            lon: crate::tile::u_to_lon(u, n),
            lat: crate::tile::v_to_lat(v, n),
        };
        // A diagonal across the grid: the cells along it, not the 256 of its box.
        let diagonal = way(1, &[]);
        let diagonal = Way {
            positions: vec![at(0.5, 0.5), at(15.5, 15.5)],
            nodes: vec![1, 2],
            ..diagonal
        };
        let cells = cells_of_way(&diagonal, n);
        assert!(cells.len() <= 16 * 3, "{}", cells.len());
        for k in 0..16 {
            assert!(cells.contains(&(k, k)));
        }
        assert!(!cells.contains(&(15, 0)) && !cells.contains(&(0, 15)));
    }

    #[test]
    fn a_closed_way_is_registered_inside_too_unless_its_box_is_huge() {
        let n = 64.0;
        let at = |u: f64, v: f64| LonLat {
            lon: crate::tile::u_to_lon(u, n),
            lat: crate::tile::v_to_lat(v, n),
        };
        let ring = |corners: [(f64, f64); 4]| Way {
            id: 1,
            tags: Default::default(),
            nodes: vec![1, 2, 3, 4, 1],
            positions: corners
                .iter()
                .chain(&corners[..1])
                .map(|&(u, v)| at(u, v))
                .collect(),
        };
        let square = ring([(10.2, 10.2), (20.8, 10.2), (20.8, 20.8), (10.2, 20.8)]);
        let cells = cells_of_way(&square, n);
        assert_eq!(cells.len(), 11 * 11, "outline and inside");
        assert!(cells.contains(&(15, 15)));
        // A square a whole world wide: its inside is too large to fill; its outline is kept.
        let n = 16384.0;
        let world = Way {
            positions: [
                (1.0, 1.0),
                (16383.0, 1.0),
                (16383.0, 16383.0),
                (1.0, 16383.0),
                (1.0, 1.0),
            ]
            .iter()
            .map(|&(u, v)| LonLat {
                lon: crate::tile::u_to_lon(u, n),
                lat: crate::tile::v_to_lat(v, n),
            })
            .collect(),
            ..square
        };
        let cells = cells_of_way(&world, n);
        assert!(cells.len() < 4 * 16384 + 8, "{}", cells.len());
        assert!(!cells.contains(&(8192, 8192)));
    }
}
