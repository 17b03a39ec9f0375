//! Bridges and tunnels as whole structures, found once over all the data.
//!
//! A bridge is often mapped as several ways in a row (a way per span, or split where a tag
//! changes), and what it passes over may lie beyond the tile that shows one end of it. So the
//! ways of one kind and layer that continue one another end to end are joined into *chains*,
//! and chains that share a node or cross one another into *groups*, each with the ways it
//! passes over. A group is what the elevation solver settles at once: everything it needs is
//! global data, so every tile that shows a part of a structure computes the same elevations.

use std::collections::HashMap;

use super::{Bounds, LonLat, Tags, Way};
use crate::tile::lon_lat_to_uv;

/// Whether a structure carries its way over or under what is around it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum StructureKind {
    Bridge,
    Tunnel,
}

/// One way of a chain, in the chain's direction or against it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ChainWay {
    /// Index into the data's ways.
    pub way: u32,
    pub reversed: bool,
}

/// Ways of one kind and layer that continue one another end to end.
#[derive(Debug, Clone, PartialEq)]
pub struct Chain {
    pub kind: StructureKind,
    pub layer: i32,
    pub ways: Vec<ChainWay>,
    /// Node ids and positions along the chain, each node once.
    pub nodes: Vec<i64>,
    pub positions: Vec<LonLat>,
    /// For each segment (`positions[k]` to `positions[k + 1]`), the index into `ways` it
    /// belongs to.
    pub segment_way: Vec<u32>,
}

/// Where a chain passes over or under something without sharing a node with it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Crossing {
    /// The chain (an index into the group's chains), its segment and how far along it.
    pub chain: u32,
    pub segment: u32,
    pub t: f64,
    pub other: Crossed,
}

/// What a chain crosses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Crossed {
    /// A way that is not part of a structure (an index into the data's ways).
    Way(u32),
    /// Another chain of the group, its segment and how far along it.
    Chain { chain: u32, segment: u32, t: f64 },
}

/// Chains that share nodes or cross, and the ways they cross.
#[derive(Debug, Clone, PartialEq)]
pub struct Group {
    pub chains: Vec<Chain>,
    pub crossings: Vec<Crossing>,
    pub bounds: Bounds,
    /// What reaches down into the ground over the group's tunnels (foundations, roots).
    pub above: Vec<Above>,
}

/// Something that reaches down into the ground: a building's outline or a tree's position,
/// and how deep.
#[derive(Debug, Clone, PartialEq)]
pub struct Above {
    /// The OSM element.
    pub id: i64,
    /// A closed outline, or one position.
    pub positions: Vec<LonLat>,
    pub depth_m: f64,
}

/// What makes a way part of a structure: its kind and layer, or `None`.
pub type Classify = fn(&Tags) -> Option<(StructureKind, i32)>;

/// What a chain may pass over: ways that carry traffic or water.
pub fn may_be_crossed(tags: &Tags) -> bool {
    tags.get("highway").is_some() || tags.get("railway").is_some() || tags.get("waterway").is_some()
}

/// Finds the structures among `ways`.
pub fn find(ways: &[Way], classify: Classify) -> Vec<Group> {
    let chains = chains(ways, classify);
    if chains.is_empty() {
        return Vec::new();
    }
    let uv = |p: LonLat| {
        let (u, v) = lon_lat_to_uv(p.lon, p.lat, 1.0);
        [u, v]
    };
    // Segments of every way that may be crossed, on a fine grid.
    let grid = SegmentGrid::new(ways, &uv);
    let mut parent: Vec<usize> = (0..chains.len()).collect();
    let mut raw: Vec<(usize, u32, f64, RawCrossed)> = Vec::new();
    let chain_of_way: HashMap<u32, usize> = chains
        .iter()
        .enumerate()
        .flat_map(|(c, chain)| chain.ways.iter().map(move |w| (w.way, c)))
        .collect();
    // Chains that share a node settle together.
    let mut chain_at_node: HashMap<i64, usize> = HashMap::new();
    for (c, chain) in chains.iter().enumerate() {
        for &node in &chain.nodes {
            if let Some(&other) = chain_at_node.get(&node) {
                union(&mut parent, c, other);
            } else {
                chain_at_node.insert(node, c);
            }
        }
    }
    for (c, chain) in chains.iter().enumerate() {
        for k in 0..chain.positions.len() - 1 {
            let (a, b) = (uv(chain.positions[k]), uv(chain.positions[k + 1]));
            let (na, nb) = (chain.nodes[k], chain.nodes[k + 1]);
            for (way, segment) in grid.near(a, b) {
                let w = &ways[way as usize];
                let (c0, c1) = (w.nodes[segment as usize], w.nodes[segment as usize + 1]);
                // A shared node is a junction, not a crossing.
                if [c0, c1].contains(&na) || [c0, c1].contains(&nb) {
                    continue;
                }
                let p0 = uv(w.positions[segment as usize]);
                let p1 = uv(w.positions[segment as usize + 1]);
                let Some((t, s)) = intersect(a, b, p0, p1) else {
                    continue;
                };
                match chain_of_way.get(&way) {
                    // Each pair once: from the chain of the higher layer.
                    Some(&other) if chain.layer > chains[other].layer => {
                        union(&mut parent, c, other);
                        raw.push((c, k as u32, t, RawCrossed::Chain(other, way, segment, s)));
                    }
                    Some(_) => {}
                    // What is under a tunnel's floor is its own business.
                    None if chain.kind == StructureKind::Bridge => {
                        raw.push((c, k as u32, t, RawCrossed::Way(way)))
                    }
                    None => {}
                }
            }
        }
    }
    // Gather the groups in the order of their first chain.
    let mut group_of_root: HashMap<usize, usize> = HashMap::new();
    let mut groups: Vec<Group> = Vec::new();
    let mut place: Vec<(usize, u32)> = Vec::with_capacity(chains.len());
    for (c, chain) in chains.iter().enumerate() {
        let root = find_root(&mut parent, c);
        let bounds = bounds_of_chain(chain);
        let g = *group_of_root.entry(root).or_insert_with(|| {
            groups.push(Group {
                chains: Vec::new(),
                crossings: Vec::new(),
                bounds,
                above: Vec::new(),
            });
            groups.len() - 1
        });
        place.push((g, groups[g].chains.len() as u32));
        let group = &mut groups[g];
        group.bounds = union_bounds(group.bounds, bounds);
        group.chains.push(chain.clone());
    }
    for (c, segment, t, crossed) in raw {
        let (g, index) = place[c];
        let other = match crossed {
            RawCrossed::Way(way) => Crossed::Way(way),
            RawCrossed::Chain(other, way, way_segment, s) => {
                let (_, other_index) = place[other];
                let Some((segment, t)) = chain_segment(
                    &groups[g].chains[other_index as usize],
                    ways,
                    way,
                    way_segment,
                    s,
                ) else {
                    continue;
                };
                Crossed::Chain {
                    chain: other_index,
                    segment,
                    t,
                }
            }
        };
        groups[g].crossings.push(Crossing {
            chain: index,
            segment,
            t,
            other,
        });
    }
    groups
}

enum RawCrossed {
    Way(u32),
    /// The other chain, and the way, segment of the way and share along it that was crossed.
    Chain(usize, u32, u32, f64),
}

/// The segment of `chain` (and share along it) that is segment `way_segment` of `way` at
/// share `s`.
fn chain_segment(
    chain: &Chain,
    ways: &[Way],
    way: u32,
    way_segment: u32,
    s: f64,
) -> Option<(u32, f64)> {
    let w = &ways[way as usize];
    let (n0, n1) = (
        w.nodes[way_segment as usize],
        w.nodes[way_segment as usize + 1],
    );
    (0..chain.nodes.len() - 1).find_map(|k| {
        let (a, b) = (chain.nodes[k], chain.nodes[k + 1]);
        if (a, b) == (n0, n1) {
            Some((k as u32, s))
        } else if (a, b) == (n1, n0) {
            Some((k as u32, 1.0 - s))
        } else {
            None
        }
    })
}

/// A way longer than this is no bridge or tunnel, whatever its tags say: the longest built is
/// about 165 km, and OSM maps it as many ways. One so tagged is drawn as a road on the ground,
/// so that no single way can make a group's LP as long as the data is wide.
pub const LONGEST_STRUCTURE_WAY_M: f64 = 200_000.0;

/// What `classify` makes of a way at `positions` tagged `tags`, if it may be a structure at all.
pub fn structure_of(
    classify: Classify,
    tags: &Tags,
    positions: &[LonLat],
) -> Option<(StructureKind, i32)> {
    classify(tags).filter(|_| super::length_m(positions) <= LONGEST_STRUCTURE_WAY_M)
}

/// Joins the structure ways into chains.
fn chains(ways: &[Way], classify: Classify) -> Vec<Chain> {
    type Key = (StructureKind, i32);
    let members: Vec<(u32, Key)> = ways
        .iter()
        .enumerate()
        .filter(|(_, w)| w.nodes.len() >= 2)
        .filter_map(|(i, w)| {
            structure_of(classify, &w.tags, &w.positions).map(|key| (i as u32, key))
        })
        .collect();
    let mut ends: HashMap<(Key, i64), Vec<u32>> = HashMap::new();
    for &(i, key) in &members {
        let w = &ways[i as usize];
        for node in [w.nodes[0], w.nodes[w.nodes.len() - 1]] {
            ends.entry((key, node)).or_default().push(i);
        }
    }
    // A chain goes on through a node where exactly two of its ways end.
    let next = |key: Key, node: i64, from: u32| -> Option<u32> {
        match ends.get(&(key, node)).map(Vec::as_slice) {
            Some(&[a, b]) if a != b => Some(if a == from { b } else { a }),
            _ => None,
        }
    };
    let mut used = vec![false; ways.len()];
    let mut chains = Vec::new();
    for &(first, key) in &members {
        if used[first as usize] {
            continue;
        }
        used[first as usize] = true;
        let mut sequence = std::collections::VecDeque::from([ChainWay {
            way: first,
            reversed: false,
        }]);
        // Forwards from the last node, then backwards from the first.
        for forwards in [true, false] {
            loop {
                let end = if forwards {
                    sequence.back()
                } else {
                    sequence.front()
                };
                let Some(&end) = end else { break };
                let w = &ways[end.way as usize];
                let node = if end.reversed == forwards {
                    w.nodes[0]
                } else {
                    w.nodes[w.nodes.len() - 1]
                };
                let Some(n) = next(key, node, end.way) else {
                    break;
                };
                if used[n as usize] {
                    break;
                }
                used[n as usize] = true;
                let nw = &ways[n as usize];
                let starts_there = nw.nodes[0] == node;
                if forwards {
                    sequence.push_back(ChainWay {
                        way: n,
                        reversed: !starts_there,
                    });
                } else {
                    sequence.push_front(ChainWay {
                        way: n,
                        reversed: starts_there,
                    });
                }
            }
        }
        let mut chain = Chain {
            kind: key.0,
            layer: key.1,
            ways: Vec::with_capacity(sequence.len()),
            nodes: Vec::new(),
            positions: Vec::new(),
            segment_way: Vec::new(),
        };
        for (k, cw) in sequence.into_iter().enumerate() {
            let w = &ways[cw.way as usize];
            let mut points: Vec<(i64, LonLat)> = w
                .nodes
                .iter()
                .copied()
                .zip(w.positions.iter().copied())
                .collect();
            if cw.reversed {
                points.reverse();
            }
            for (node, position) in points {
                if chain.nodes.last() == Some(&node) {
                    continue;
                }
                if !chain.nodes.is_empty() {
                    chain.segment_way.push(k as u32);
                }
                chain.nodes.push(node);
                chain.positions.push(position);
            }
            chain.ways.push(cw);
        }
        if chain.nodes.len() >= 2 {
            chains.push(chain);
        }
    }
    chains
}

/// Where segments `a`–`b` and `c`–`d` meet: the shares along each.
fn intersect(a: [f64; 2], b: [f64; 2], c: [f64; 2], d: [f64; 2]) -> Option<(f64, f64)> {
    let r = [b[0] - a[0], b[1] - a[1]];
    let s = [d[0] - c[0], d[1] - c[1]];
    let denominator = r[0] * s[1] - r[1] * s[0];
    if denominator == 0.0 {
        return None;
    }
    let q = [c[0] - a[0], c[1] - a[1]];
    let t = (q[0] * s[1] - q[1] * s[0]) / denominator;
    let u = (q[0] * r[1] - q[1] * r[0]) / denominator;
    ((0.0..=1.0).contains(&t) && (0.0..=1.0).contains(&u)).then_some((t, u))
}

/// Cells per axis of the whole world for the segment grid: cells of about 150 m.
const GRID_CELLS: f64 = 262_144.0;

/// The segments of every way that may be crossed, by grid cell.
struct SegmentGrid {
    cells: HashMap<(u32, u32), Vec<(u32, u32)>>,
}

impl SegmentGrid {
    fn new(ways: &[Way], uv: &dyn Fn(LonLat) -> [f64; 2]) -> SegmentGrid {
        let mut cells: HashMap<(u32, u32), Vec<(u32, u32)>> = HashMap::new();
        for (i, way) in ways.iter().enumerate() {
            if !may_be_crossed(&way.tags) {
                continue;
            }
            for k in 0..way.positions.len().saturating_sub(1) {
                let (a, b) = (uv(way.positions[k]), uv(way.positions[k + 1]));
                for cell in grid_cells(a, b) {
                    cells.entry(cell).or_default().push((i as u32, k as u32));
                }
            }
        }
        SegmentGrid { cells }
    }

    /// Segments in the cells that `a`–`b` passes through, each once: every segment it meets.
    fn near(&self, a: [f64; 2], b: [f64; 2]) -> Vec<(u32, u32)> {
        let mut found: Vec<(u32, u32)> = grid_cells(a, b)
            .filter_map(|cell| self.cells.get(&cell))
            .flatten()
            .copied()
            .collect();
        found.sort_unstable();
        found.dedup();
        found
    }
}

/// The cells of the fine grid the segment `a`–`b` (global units of one tile) passes through
/// or touches: as many as its length crosses, never its box (a segment a degree long across
/// the grid's diagonal would otherwise fill millions).
fn grid_cells(a: [f64; 2], b: [f64; 2]) -> impl Iterator<Item = (u32, u32)> {
    let scaled = |p: [f64; 2]| [p[0] * GRID_CELLS, p[1] * GRID_CELLS];
    let mut cells = Vec::new();
    crate::geometry::segment_cells(scaled(a), scaled(b), GRID_CELLS, &mut cells);
    cells.into_iter()
}

fn bounds_of_chain(chain: &Chain) -> Bounds {
    super::bounds_of(&chain.positions).expect("a chain has positions")
}

fn union_bounds(a: Bounds, b: Bounds) -> Bounds {
    Bounds {
        west: a.west.min(b.west),
        east: a.east.max(b.east),
        south: a.south.min(b.south),
        north: a.north.max(b.north),
    }
}

fn find_root(parent: &mut [usize], mut i: usize) -> usize {
    while parent[i] != i {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    i
}

fn union(parent: &mut [usize], a: usize, b: usize) {
    let (ra, rb) = (find_root(parent, a), find_root(parent, b));
    if ra != rb {
        parent[ra.max(rb)] = ra.min(rb);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::osm::fixture::way;

    fn classify(tags: &Tags) -> Option<(StructureKind, i32)> {
        if tags.is_set("bridge") {
            Some((StructureKind::Bridge, 1))
        } else if tags.is_set("tunnel") {
            Some((StructureKind::Tunnel, -1))
        } else {
            None
        }
    }

    #[test]
    fn ways_in_a_row_make_one_chain_over_what_they_cross() {
        let bridge = [("highway", "primary"), ("bridge", "yes")];
        let ways = vec![
            // Two spans, the second drawn backwards, and a road and a river below.
            way(1, &bridge, &[(1, 7.400, 43.7), (2, 7.401, 43.7)]),
            way(2, &bridge, &[(3, 7.402, 43.7), (2, 7.401, 43.7)]),
            way(
                3,
                &[("highway", "residential")],
                &[(10, 7.4005, 43.699), (11, 7.4005, 43.701)],
            ),
            way(
                4,
                &[("waterway", "river")],
                &[(12, 7.4015, 43.699), (13, 7.4015, 43.701)],
            ),
            // A road that ends on the bridge's first node: a junction, not a crossing.
            way(
                5,
                &[("highway", "service")],
                &[(1, 7.400, 43.7), (14, 7.400, 43.699)],
            ),
        ];
        let groups = find(&ways, classify);
        assert_eq!(groups.len(), 1);
        let chain = &groups[0].chains[0];
        assert_eq!(chain.nodes, [1, 2, 3]);
        assert_eq!(chain.segment_way, [0, 1]);
        assert!(chain.ways[1].reversed);
        let crossed: Vec<(u32, Crossed)> = groups[0]
            .crossings
            .iter()
            .map(|c| (c.segment, c.other))
            .collect();
        assert_eq!(crossed, [(0, Crossed::Way(2)), (1, Crossed::Way(3))]);
        assert!((groups[0].crossings[0].t - 0.5).abs() < 1e-6);
    }

    #[test]
    fn a_tunnel_under_another_joins_its_group() {
        let upper = [("highway", "primary"), ("tunnel", "yes")];
        let lower = [("railway", "rail"), ("tunnel", "yes"), ("layer", "-2")];
        fn classify_layers(tags: &Tags) -> Option<(StructureKind, i32)> {
            let layer = tags.get("layer").and_then(|l| l.parse().ok()).unwrap_or(-1);
            tags.is_set("tunnel")
                .then_some((StructureKind::Tunnel, layer))
        }
        let ways = vec![
            way(1, &upper, &[(1, 7.400, 43.7), (2, 7.402, 43.7)]),
            way(2, &lower, &[(3, 7.401, 43.699), (4, 7.401, 43.701)]),
            way(3, &upper, &[(5, 7.500, 43.7), (6, 7.502, 43.7)]),
        ];
        let groups = find(&ways, classify_layers);
        assert_eq!(groups.len(), 2);
        assert_eq!(groups[0].chains.len(), 2);
        assert_eq!(groups[0].crossings.len(), 1);
        let crossing = groups[0].crossings[0];
        assert_eq!(crossing.chain, 0);
        let Crossed::Chain { chain, segment, t } = crossing.other else {
            panic!("{crossing:?}");
        };
        assert_eq!((chain, segment), (1, 0));
        assert!((t - 0.5).abs() < 1e-3);
    }
}
