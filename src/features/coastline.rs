//! The sea, from `natural=coastline` ways (OSM draws them with the land on the left and the water
//! on the right; thesis §2.3.3).
//!
//! Coastline ways are joined end to end into chains, and each chain is clipped to the tile. In
//! global tile units, whose `v` axis points south, the water lies on the mathematical left of a
//! chain, so the sea inside the tile is made of counter-clockwise rings (positive
//! [`signed_area2`]): follow a clipped piece from where it enters the tile to where it leaves,
//! walk counter-clockwise along the tile's border to the next piece that enters, and so on until
//! the ring closes. Rings wholly inside the tile are islands (clockwise: holes in the sea around
//! them) or enclosed sea (counter-clockwise). A tile no coastline crosses is at sea when the
//! nearest coastline has the tile on its water side.
//!
//! Where the extract cut a coastline open inside the tile, the loose piece cannot be closed
//! without guessing; it is left out with a debug log, and the rest of the coast still counts.
//! Crossing points are computed by [`clip_segment`] in global units, so two tiles that share an
//! edge cut the coast at the same points.

use std::collections::HashMap;

use crate::geometry::{clip_segment, signed_area2, Point, Polygon, Rect};
use crate::osm::Way;

pub fn is_coastline(way: &Way) -> bool {
    way.tags.get("natural") == Some("coastline")
}

/// Coastline ways joined end to end, as node ids and points.
#[derive(Debug, Clone, PartialEq)]
pub struct Chain {
    pub points: Vec<Point>,
    /// The last point is the first (the chain is a ring).
    pub closed: bool,
}

/// Joins ways whose last node is another's first into chains, in a deterministic order (ways in
/// the order given, which is by id). `project` maps a way's positions to points.
pub fn chains(ways: &[&Way], project: &dyn Fn(&Way) -> Vec<Point>) -> Vec<Chain> {
    let usable: Vec<&&Way> = ways.iter().filter(|w| w.nodes.len() >= 2).collect();
    let mut by_first: HashMap<i64, usize> = HashMap::new();
    for (k, way) in usable.iter().enumerate() {
        by_first.entry(way.nodes[0]).or_insert(k);
    }
    let has_predecessor: Vec<bool> = {
        let mut has = vec![false; usable.len()];
        for way in &usable {
            if let Some(&next) = by_first.get(way.nodes.last().unwrap_or(&0)) {
                has[next] = true;
            }
        }
        has
    };
    let mut used = vec![false; usable.len()];
    let mut result = Vec::new();
    // Chains start at ways nothing leads into; what is left after that are rings.
    let starts = (0..usable.len())
        .filter(|&k| !has_predecessor[k])
        .chain(0..usable.len());
    for start in starts {
        if used[start] {
            continue;
        }
        let first_node = usable[start].nodes[0];
        let mut points: Vec<Point> = Vec::new();
        let mut k = start;
        let mut closed = false;
        loop {
            used[k] = true;
            let way = usable[k];
            let projected = project(way);
            let skip = usize::from(!points.is_empty());
            points.extend_from_slice(&projected[skip.min(projected.len())..]);
            let last = *way.nodes.last().unwrap_or(&first_node);
            if last == first_node {
                closed = true;
                break;
            }
            match by_first.get(&last) {
                Some(&next) if !used[next] => k = next,
                _ => break,
            }
        }
        if points.len() >= 2 {
            result.push(Chain { points, closed });
        }
    }
    result
}

/// A run of a chain inside the tile.
#[derive(Debug, Clone)]
struct Piece {
    points: Vec<Point>,
}

/// Where on the border of `rect` a point lies, as a position `0..4` counter-clockwise (in the
/// mathematical sense of `u`, `v`) from the `min` corner; `None` off the border.
fn border_position(p: Point, rect: &Rect) -> Option<f64> {
    let (w, h) = (rect.max[0] - rect.min[0], rect.max[1] - rect.min[1]);
    if p[1] == rect.min[1] {
        Some((p[0] - rect.min[0]) / w)
    } else if p[0] == rect.max[0] {
        Some(1.0 + (p[1] - rect.min[1]) / h)
    } else if p[1] == rect.max[1] {
        Some(2.0 + (rect.max[0] - p[0]) / w)
    } else if p[0] == rect.min[0] {
        Some(3.0 + (rect.max[1] - p[1]) / h)
    } else {
        None
    }
}

/// The corner at border position 1, 2, 3 or 4 (= 0).
fn corner(k: u8, rect: &Rect) -> Point {
    match k % 4 {
        0 => rect.min,
        1 => [rect.max[0], rect.min[1]],
        2 => rect.max,
        _ => [rect.min[0], rect.max[1]],
    }
}

/// The runs of `chain` inside `rect`.
fn clip_chain(chain: &Chain, rect: &Rect) -> Vec<Piece> {
    let mut pieces: Vec<Piece> = Vec::new();
    let mut current: Vec<Point> = Vec::new();
    for pair in chain.points.windows(2) {
        let Some((p, q)) = clip_segment(pair[0], pair[1], rect) else {
            continue;
        };
        if current.last() != Some(&p) {
            if current.len() >= 2 {
                pieces.push(Piece {
                    points: std::mem::take(&mut current),
                });
            }
            current = vec![p];
        }
        if current.last() != Some(&q) {
            current.push(q);
        }
    }
    if current.len() >= 2 {
        pieces.push(Piece { points: current });
    }
    // A ring that starts inside the tile: its last run continues into its first.
    if chain.closed && pieces.len() >= 2 {
        let first_point = pieces[0].points[0];
        let last = pieces.len() - 1;
        if pieces[last].points.last() == Some(&first_point)
            && border_position(first_point, rect).is_none()
        {
            let first = pieces.remove(0);
            pieces[last - 1]
                .points
                .extend_from_slice(&first.points[1..]);
        }
    }
    pieces
}

/// The sea inside a tile.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Sea {
    pub polygons: Vec<Polygon>,
    /// The coastline's runs inside the tile (the sea's border off the tile's edges).
    pub coast: Vec<Vec<Point>>,
}

/// The sea inside `rect` (global tile units), from the coastline chains that cross or lie in it;
/// `all` gives every coastline chain known, to decide a tile no coastline crosses.
pub fn sea(near: &[Chain], all: &dyn Fn() -> Vec<Chain>, rect: &Rect) -> Sea {
    let mut crossing: Vec<(Piece, f64, f64)> = Vec::new();
    let mut rings: Vec<Vec<Point>> = Vec::new();
    let mut coast = Vec::new();
    for chain in near {
        for piece in clip_chain(chain, rect) {
            coast.push(piece.points.clone());
            let (first, last) = (piece.points[0], piece.points[piece.points.len() - 1]);
            match (border_position(first, rect), border_position(last, rect)) {
                (Some(start), Some(end)) if piece.points.len() >= 2 => {
                    crossing.push((piece, start, end))
                }
                _ if first == last && piece.points.len() >= 4 => {
                    let mut ring = piece.points;
                    ring.pop();
                    rings.push(ring);
                }
                _ => tracing::debug!(
                    at = ?first,
                    "coastline ends inside the tile (cut by the extract); left out"
                ),
            }
        }
    }

    let mut seas: Vec<Polygon> = assemble(&crossing, rect);
    let (islands, enclosed): (Vec<_>, Vec<_>) =
        rings.into_iter().partition(|r| signed_area2(r) < 0.0);
    let surrounded_by_sea = if crossing.is_empty() {
        if !islands.is_empty() {
            true
        } else if !enclosed.is_empty() {
            false
        } else {
            let centre = [
                (rect.min[0] + rect.max[0]) / 2.0,
                (rect.min[1] + rect.max[1]) / 2.0,
            ];
            water_side(&all(), centre).unwrap_or(false)
        }
    } else {
        false
    };
    if surrounded_by_sea {
        seas.push(Polygon {
            outer: (0..4).map(|k| corner(k, rect)).collect(),
            holes: Vec::new(),
        });
    }
    for ring in enclosed {
        seas.push(Polygon {
            outer: ring,
            holes: Vec::new(),
        });
    }
    for island in islands {
        if let Some(sea) = seas.iter_mut().find(|s| s.contains(island[0])) {
            sea.holes.push(island);
        }
    }
    Sea {
        polygons: seas,
        coast,
    }
}

/// Rings of pieces joined along the border, counter-clockwise.
fn assemble(crossing: &[(Piece, f64, f64)], rect: &Rect) -> Vec<Polygon> {
    let mut used = vec![false; crossing.len()];
    let mut polygons = Vec::new();
    for first in 0..crossing.len() {
        if used[first] {
            continue;
        }
        let mut ring: Vec<Point> = Vec::new();
        let mut k = first;
        let closed = loop {
            used[k] = true;
            let (piece, _, end) = &crossing[k];
            for &p in &piece.points {
                if ring.last() != Some(&p) {
                    ring.push(p);
                }
            }
            // The next piece to enter, counter-clockwise from where this one leaves.
            let next = (0..crossing.len())
                .filter(|&j| j == first || !used[j])
                .min_by(|&a, &b| {
                    let da = (crossing[a].1 - end).rem_euclid(4.0);
                    let db = (crossing[b].1 - end).rem_euclid(4.0);
                    da.total_cmp(&db).then(a.cmp(&b))
                });
            let Some(next) = next else { break false };
            let distance = (crossing[next].1 - end).rem_euclid(4.0);
            // The corners passed on the way.
            let mut c = end.floor() + 1.0;
            while c < end + distance {
                let p = corner(c as u8, rect);
                if ring.last() != Some(&p) {
                    ring.push(p);
                }
                c += 1.0;
            }
            if next == first {
                break true;
            }
            k = next;
        };
        if !closed {
            tracing::debug!("coastline pieces do not close into a ring; left out");
            continue;
        }
        while ring.len() > 1 && ring.first() == ring.last() {
            ring.pop();
        }
        if ring.len() >= 3 && signed_area2(&ring) > 0.0 {
            polygons.push(Polygon {
                outer: ring,
                holes: Vec::new(),
            });
        }
    }
    polygons
}

/// Whether `p` lies on the water side of the nearest coastline; `None` without coastlines.
fn water_side(chains: &[Chain], p: Point) -> Option<bool> {
    let cross = |a: Point, b: Point, c: Point| {
        (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    };
    // (distance², chain, segment, at the segment's start, at its end)
    let mut best: Option<(f64, usize, usize, bool, bool)> = None;
    for (c, chain) in chains.iter().enumerate() {
        for s in 0..chain.points.len().saturating_sub(1) {
            let (a, b) = (chain.points[s], chain.points[s + 1]);
            let d = [b[0] - a[0], b[1] - a[1]];
            let length2 = d[0] * d[0] + d[1] * d[1];
            if length2 == 0.0 {
                continue;
            }
            let t = (((p[0] - a[0]) * d[0] + (p[1] - a[1]) * d[1]) / length2).clamp(0.0, 1.0);
            let q = [a[0] + t * d[0], a[1] + t * d[1]];
            let distance2 = (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2);
            if best.is_none_or(|b| distance2 < b.0) {
                best = Some((distance2, c, s, t == 0.0, t == 1.0));
            }
        }
    }
    let (_, c, s, at_start, at_end) = best?;
    let points = &chains[c].points;
    let segments = points.len() - 1;
    let left_of = |s: usize| cross(points[s], points[s + 1], p) > 0.0;
    // At a vertex, the side comes from both segments that meet there.
    let neighbour = if at_start {
        (s > 0)
            .then(|| s - 1)
            .or((chains[c].closed).then(|| segments - 1))
            .map(|before| (before, s))
    } else if at_end {
        (s + 1 < segments)
            .then_some(s + 1)
            .or((chains[c].closed).then_some(0))
            .map(|after| (s, after))
    } else {
        None
    };
    Some(match neighbour {
        None => left_of(s),
        Some((before, after)) => {
            let (a, v, b) = (points[before], points[after], points[after + 1]);
            let turn = cross(a, v, b);
            if turn > 0.0 {
                left_of(before) && left_of(after)
            } else {
                left_of(before) || left_of(after)
            }
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::signed_area2;
    use crate::osm::{LonLat, Tags};

    fn unit() -> Rect {
        Rect {
            min: [0.0, 0.0],
            max: [1.0, 1.0],
        }
    }

    fn open(points: &[Point]) -> Chain {
        Chain {
            points: points.to_vec(),
            closed: false,
        }
    }

    /// The sea of the unit square with one chain, the only one known.
    fn sea_of(chain: &Chain) -> Vec<Polygon> {
        sea(
            std::slice::from_ref(chain),
            &|| vec![chain.clone()],
            &unit(),
        )
        .polygons
    }

    fn area(polygons: &[Polygon]) -> f64 {
        polygons
            .iter()
            .map(|p| {
                signed_area2(&p.outer).abs() / 2.0
                    - p.holes
                        .iter()
                        .map(|h| signed_area2(h).abs() / 2.0)
                        .sum::<f64>()
            })
            .sum()
    }

    #[test]
    fn the_water_is_on_the_right_of_the_way() {
        // Heading east on the map (+u) with the water on the right: the sea is south (+v).
        let coast = open(&[[-0.5, 0.5], [1.5, 0.5]]);
        let seas = sea_of(&coast);
        assert_eq!(seas.len(), 1);
        assert!((area(&seas) - 0.5).abs() < 1e-12);
        assert!(seas[0].contains([0.5, 0.9]));
        assert!(!seas[0].contains([0.5, 0.1]));
        // The other way round, the sea is north.
        let coast = open(&[[1.5, 0.5], [-0.5, 0.5]]);
        let seas = sea_of(&coast);
        assert!(seas[0].contains([0.5, 0.1]));
    }

    #[test]
    fn a_bay_and_a_cape_close_along_the_border() {
        // Walking north on the map along u = 0.3 with the water on the right (east), then east,
        // then south: a bay reaching into the tile from the south.
        let coast = open(&[[0.3, 1.5], [0.3, 0.4], [0.7, 0.4], [0.7, 1.5]]);
        let seas = sea_of(&coast);
        assert!((area(&seas) - 0.4 * 0.6).abs() < 1e-12);
        assert!(seas.iter().any(|s| s.contains([0.5, 0.8])));
        // Reversed, the same line bounds a cape with the sea all around it.
        let coast = open(&[[0.7, 1.5], [0.7, 0.4], [0.3, 0.4], [0.3, 1.5]]);
        let seas = sea_of(&coast);
        let total = area(&seas);
        assert!((total - (1.0 - 0.4 * 0.6)).abs() < 1e-12, "{total}");
        assert!(!seas.iter().any(|s| s.contains([0.5, 0.8])));
    }

    #[test]
    fn islands_are_holes_and_open_sea_is_decided_by_the_nearest_coast() {
        // An island (clockwise in u, v: land on the left of the way).
        let island = Chain {
            points: vec![[0.4, 0.4], [0.4, 0.6], [0.6, 0.6], [0.6, 0.4], [0.4, 0.4]],
            closed: true,
        };
        assert!(signed_area2(&island.points[..4]) < 0.0);
        let seas = sea_of(&island);
        assert!((area(&seas) - (1.0 - 0.04)).abs() < 1e-12);
        assert!(!seas[0].contains([0.5, 0.5]));
        // A tile far from any coast, on its sea side, then on its land side.
        let coast = open(&[[-10.0, -3.0], [10.0, -3.0]]);
        let far = Rect {
            min: [0.0, 0.0],
            max: [1.0, 1.0],
        };
        assert_eq!(area(&sea(&[], &|| vec![coast.clone()], &far).polygons), 1.0);
        let reversed = open(&[[10.0, -3.0], [-10.0, -3.0]]);
        assert!(sea(&[], &|| vec![reversed.clone()], &far)
            .polygons
            .is_empty());
        // No coastline anywhere: land.
        assert!(sea(&[], &Vec::new, &far).polygons.is_empty());
    }

    #[test]
    fn the_side_at_a_corner_of_the_coast_follows_both_segments() {
        // A coast running +u, then −v: its water (the mathematical left) is on the +v side of
        // the first segment and the +u side of the second. (3, 3) is nearest to the corner
        // (2, 2), where the two sides meet, and lies on the water side of both.
        let coast = open(&[[0.0, 2.0], [2.0, 2.0], [2.0, 0.0]]);
        let water = water_side(std::slice::from_ref(&coast), [3.0, 3.0]);
        assert_eq!(water, Some(true));
        assert_eq!(water_side(&[coast], [1.0, 1.0]), Some(false));
    }

    #[test]
    fn ways_join_end_to_end_and_rings_close() {
        let way = |id: i64, nodes: &[i64]| Way {
            id,
            tags: Tags::from_pairs([("natural", "coastline")]),
            nodes: nodes.to_vec(),
            positions: nodes
                .iter()
                .map(|&n| LonLat {
                    lon: n as f64,
                    lat: 0.0,
                })
                .collect(),
        };
        let ways = [way(1, &[3, 4]), way(2, &[1, 2, 3]), way(3, &[7, 8, 9, 7])];
        let refs: Vec<&Way> = ways.iter().collect();
        let project =
            |w: &Way| -> Vec<Point> { w.positions.iter().map(|p| [p.lon, p.lat]).collect() };
        let joined = chains(&refs, &project);
        assert_eq!(joined.len(), 2);
        assert_eq!(
            joined[0].points,
            vec![[1.0, 0.0], [2.0, 0.0], [3.0, 0.0], [4.0, 0.0]]
        );
        assert!(!joined[0].closed);
        assert!(joined[1].closed);
        assert_eq!(joined[1].points.len(), 4);
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(256))]

        /// Random coastlines (crossing each other, touching the border, ending inside the tile,
        /// closed or not): the sea never panics, stays inside the tile, and its rings are real.
        #[test]
        fn any_coastlines_give_sea_inside_the_tile(
            chains in proptest::collection::vec(
                (proptest::collection::vec((-0.5f64..1.5, -0.5f64..1.5), 2..9), proptest::bool::ANY),
                0..5),
            snap in proptest::bool::ANY,
        ) {
            let q = |v: f64| if snap { (v * 4.0).round() / 4.0 } else { v };
            let chains: Vec<Chain> = chains
                .into_iter()
                .map(|(points, closed)| {
                    let mut points: Vec<Point> = points.into_iter().map(|(u, v)| [q(u), q(v)]).collect();
                    if closed {
                        points.push(points[0]);
                    }
                    Chain { points, closed }
                })
                .collect();
            let all = chains.clone();
            let sea = sea(&chains, &|| all.clone(), &unit());
            for polygon in &sea.polygons {
                proptest::prop_assert!(polygon.outer.len() >= 3);
                for p in polygon.outer.iter().chain(polygon.holes.iter().flatten()) {
                    proptest::prop_assert!(unit().contains(*p), "{:?} outside the tile", p);
                }
            }
            // One coast that is a simple line across the tile splits it in two, whichever way.
            let across = open(&[[-0.5, q(0.3)], [1.5, q(0.7)]]);
            let one = sea_of(&across);
            let other = sea_of(&open(&[[1.5, q(0.7)], [-0.5, q(0.3)]]));
            proptest::prop_assert!((area(&one) + area(&other) - 1.0).abs() < 1e-9);
        }
    }
}
