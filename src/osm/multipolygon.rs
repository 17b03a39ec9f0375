//! Assembling areas: closed ways and multipolygon relations become polygons with holes.
//!
//! The ring assembly follows the OSM wiki's algorithm: member ways are joined end to end at
//! shared nodes into closed rings (any direction, several ways per ring); a ring that does not
//! close is dropped with a debug log naming the relation. Roles are only a hint: a ring is a hole
//! when it lies inside an odd number of other rings, so wrong or missing roles still give the
//! right polygons.

use tracing::debug;

use super::{ElementRef, ElementType, LonLat, Relation, Way};

/// A ring as node ids and positions, closed (the last node repeats the first).
#[derive(Debug, Clone)]
pub struct NodeRing {
    pub nodes: Vec<i64>,
    pub positions: Vec<LonLat>,
}

/// A polygon in degrees: an outer ring and the holes inside it.
#[derive(Debug, Clone)]
pub struct AreaPolygon {
    pub outer: Vec<LonLat>,
    pub holes: Vec<Vec<LonLat>>,
}

/// The area of a closed way, `None` for an open one or a ring of fewer than three points.
pub fn way_area(way: &Way) -> Option<AreaPolygon> {
    if !way.is_closed() || way.positions.len() < 4 {
        return None;
    }
    Some(AreaPolygon {
        outer: way.positions[..way.positions.len() - 1].to_vec(),
        holes: Vec::new(),
    })
}

/// Checks the rings of an area's polygons, logging each repair with the OSM element: duplicate
/// consecutive nodes are dropped; a ring left with fewer than three points or no area is dropped
/// (with its holes, if it is an outer ring); a ring that crosses or touches itself is kept and
/// filled by the even-odd rule, as the ground stage fills every polygon.
pub fn checked(element: ElementRef, polygons: Vec<AreaPolygon>) -> Vec<AreaPolygon> {
    let clean = |ring: &[LonLat]| -> Option<Vec<LonLat>> {
        let mut out: Vec<LonLat> = Vec::with_capacity(ring.len());
        for &p in ring {
            if out.last() != Some(&p) {
                out.push(p);
            }
        }
        while out.len() > 1 && out.first() == out.last() {
            out.pop();
        }
        let points: Vec<[f64; 2]> = out.iter().map(|q| [q.lon, q.lat]).collect();
        if points.len() < 3 || crate::geometry::is_collinear(&points) {
            debug!(
                osm_type = element.element_type.as_str(),
                osm_id = element.id,
                "ring without area; dropped"
            );
            return None;
        }
        if crate::geometry::ring_self_intersects(&points) {
            debug!(
                osm_type = element.element_type.as_str(),
                osm_id = element.id,
                "ring crosses itself; filled by the even-odd rule"
            );
        }
        Some(out)
    };
    polygons
        .into_iter()
        .filter_map(|polygon| {
            Some(AreaPolygon {
                outer: clean(&polygon.outer)?,
                holes: polygon.holes.iter().filter_map(|h| clean(h)).collect(),
            })
        })
        .collect()
}

/// Assembles a multipolygon relation from its member ways (looked up with `way_of`).
pub fn assemble<'a>(
    relation: &Relation,
    way_of: impl Fn(i64) -> Option<&'a Way>,
) -> Vec<AreaPolygon> {
    let members: Vec<&Way> = relation
        .members
        .iter()
        .filter(|m| m.element.element_type == ElementType::Way)
        .filter(|m| matches!(m.role.as_str(), "outer" | "inner" | ""))
        .filter_map(|m| {
            let way = way_of(m.element.id);
            if way.is_none() {
                debug!(
                    relation = relation.id,
                    way = m.element.id,
                    "multipolygon member missing"
                );
            }
            way
        })
        .collect();
    let rings = join_rings(relation.id, &members);
    nest(rings)
}

/// Joins ways into closed rings at shared end nodes.
fn join_rings(relation: i64, ways: &[&Way]) -> Vec<NodeRing> {
    let mut open: Vec<NodeRing> = Vec::new();
    let mut closed: Vec<NodeRing> = Vec::new();
    for way in ways {
        let ring = NodeRing {
            nodes: way.nodes.clone(),
            positions: way.positions.clone(),
        };
        if ring.nodes.len() >= 4 && ring.nodes.first() == ring.nodes.last() {
            closed.push(ring);
        } else if ring.nodes.len() >= 2 {
            open.push(ring);
        }
    }
    while let Some(mut current) = open.pop() {
        loop {
            if current.nodes.first() == current.nodes.last() {
                break;
            }
            let (Some(&start), Some(&end)) = (current.nodes.first(), current.nodes.last()) else {
                break;
            };
            let next = open.iter().position(|r| {
                r.nodes.first() == Some(&end)
                    || r.nodes.last() == Some(&end)
                    || r.nodes.first() == Some(&start)
                    || r.nodes.last() == Some(&start)
            });
            let Some(index) = next else { break };
            let mut piece = open.swap_remove(index);
            if piece.nodes.first() == Some(&end) {
            } else if piece.nodes.last() == Some(&end) {
                piece.nodes.reverse();
                piece.positions.reverse();
            } else {
                // Joins at the start: flip the current ring so its end is the shared node.
                current.nodes.reverse();
                current.positions.reverse();
                if piece.nodes.last() == Some(&start) {
                    piece.nodes.reverse();
                    piece.positions.reverse();
                }
            }
            current.nodes.extend_from_slice(&piece.nodes[1..]);
            current.positions.extend_from_slice(&piece.positions[1..]);
        }
        if current.nodes.len() >= 4 && current.nodes.first() == current.nodes.last() {
            closed.push(current);
        } else {
            debug!(
                relation,
                nodes = current.nodes.len(),
                "multipolygon ring does not close; dropped"
            );
        }
    }
    closed
}

/// Sorts rings into polygons: a ring inside an even number of others is an outer ring, and each
/// hole belongs to the smallest outer ring that contains it.
fn nest(rings: Vec<NodeRing>) -> Vec<AreaPolygon> {
    let rings: Vec<Vec<LonLat>> = rings
        .into_iter()
        .map(|r| r.positions[..r.positions.len() - 1].to_vec())
        .filter(|r| r.len() >= 3)
        .collect();
    let inside = |inner: &[LonLat], outer: &[LonLat]| {
        // A vertex of `inner` that is not on `outer` decides (rings may touch at vertices).
        inner
            .iter()
            .find(|p| !outer.contains(p))
            .is_some_and(|p| contains(outer, *p))
    };
    let depth: Vec<usize> = (0..rings.len())
        .map(|i| {
            (0..rings.len())
                .filter(|&j| j != i && inside(&rings[i], &rings[j]))
                .count()
        })
        .collect();
    let mut polygons: Vec<(usize, AreaPolygon)> = Vec::new();
    for (i, ring) in rings.iter().enumerate() {
        if depth[i] % 2 == 0 {
            polygons.push((
                i,
                AreaPolygon {
                    outer: ring.clone(),
                    holes: Vec::new(),
                },
            ));
        }
    }
    for (i, ring) in rings.iter().enumerate() {
        if depth[i] % 2 == 1 {
            let owner = polygons
                .iter_mut()
                .filter(|(j, _)| depth[*j] + 1 == depth[i] && inside(ring, &rings[*j]))
                .min_by(|(a, _), (b, _)| area(&rings[*a]).total_cmp(&area(&rings[*b])));
            if let Some((_, polygon)) = owner {
                polygon.holes.push(ring.clone());
            }
        }
    }
    polygons.into_iter().map(|(_, p)| p).collect()
}

fn contains(ring: &[LonLat], p: LonLat) -> bool {
    let points: Vec<[f64; 2]> = ring.iter().map(|q| [q.lon, q.lat]).collect();
    crate::geometry::ring_contains(&points, [p.lon, p.lat])
}

fn area(ring: &[LonLat]) -> f64 {
    let points: Vec<[f64; 2]> = ring.iter().map(|q| [q.lon, q.lat]).collect();
    crate::geometry::signed_area2(&points).abs() / 2.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::osm::{ElementRef, Member, Tags};

    fn way(id: i64, nodes: &[(i64, f64, f64)]) -> Way {
        crate::osm::fixture::way(id, &[], nodes)
    }

    fn relation(members: &[(i64, &str)]) -> Relation {
        Relation {
            id: 1,
            tags: Tags::from_pairs([("type", "multipolygon")]),
            members: members
                .iter()
                .map(|&(id, role)| Member {
                    element: ElementRef {
                        element_type: ElementType::Way,
                        id,
                    },
                    role: role.to_string(),
                })
                .collect(),
        }
    }

    #[test]
    fn checking_drops_rings_without_area_and_keeps_crossing_ones() {
        let at = |lon: f64, lat: f64| LonLat { lon, lat };
        let element = ElementRef {
            element_type: ElementType::Way,
            id: 7,
        };
        let bow_tie = vec![
            at(0.0, 0.0),
            at(1.0, 1.0),
            at(1.0, 1.0),
            at(1.0, 0.0),
            at(0.0, 1.0),
        ];
        let flat = vec![at(0.0, 0.0), at(1.0, 0.0), at(2.0, 0.0)];
        let square = vec![at(0.0, 0.0), at(2.0, 0.0), at(2.0, 2.0), at(0.0, 2.0)];
        let checked = checked(
            element,
            vec![
                AreaPolygon {
                    outer: bow_tie,
                    holes: Vec::new(),
                },
                AreaPolygon {
                    outer: flat.clone(),
                    holes: Vec::new(),
                },
                AreaPolygon {
                    outer: square,
                    holes: vec![flat],
                },
            ],
        );
        assert_eq!(checked.len(), 2);
        // The repeated node is gone; the crossing ring stays.
        assert_eq!(checked[0].outer.len(), 4);
        assert!(checked[1].holes.is_empty());
    }

    #[test]
    fn joins_an_outer_ring_from_two_ways_and_finds_a_hole_with_a_wrong_role() {
        let ways = [
            way(10, &[(1, 0.0, 0.0), (2, 4.0, 0.0), (3, 4.0, 4.0)]),
            // Drawn the wrong way round: must be reversed to join.
            way(11, &[(1, 0.0, 0.0), (4, 0.0, 4.0), (3, 4.0, 4.0)]),
            way(
                12,
                &[
                    (5, 1.0, 1.0),
                    (6, 2.0, 1.0),
                    (7, 2.0, 2.0),
                    (8, 1.0, 2.0),
                    (5, 1.0, 1.0),
                ],
            ),
        ];
        let polygons = assemble(&relation(&[(10, "outer"), (11, ""), (12, "outer")]), |id| {
            ways.iter().find(|w| w.id == id)
        });
        assert_eq!(polygons.len(), 1);
        assert_eq!(polygons[0].outer.len(), 4);
        assert_eq!(polygons[0].holes.len(), 1);
    }

    #[test]
    fn an_unclosed_ring_and_a_missing_member_are_skipped() {
        let ways = [way(10, &[(1, 0.0, 0.0), (2, 4.0, 0.0), (3, 4.0, 4.0)])];
        let polygons = assemble(&relation(&[(10, "outer"), (99, "outer")]), |id| {
            ways.iter().find(|w| w.id == id)
        });
        assert!(polygons.is_empty());
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(256))]

        /// Member ways made of random node sequences over a few shared nodes (rings that close,
        /// rings that do not, ways repeated, nodes repeated, wrong roles, missing members):
        /// assembly never panics and every polygon it gives is made of real rings.
        #[test]
        fn any_members_assemble_into_valid_polygons(
            positions in proptest::collection::vec((0.0f64..1.0, 0.0f64..1.0), 12),
            ways in proptest::collection::vec(proptest::collection::vec(0usize..12, 2..7), 1..8),
            roles in proptest::collection::vec(0usize..4, 8),
        ) {
            let node = |i: usize| (i as i64 + 1, positions[i].0, positions[i].1);
            let ways: Vec<Way> = ways
                .iter()
                .enumerate()
                .map(|(k, nodes)| {
                    let nodes: Vec<(i64, f64, f64)> = nodes.iter().map(|&i| node(i)).collect();
                    way(100 + k as i64, &nodes)
                })
                .collect();
            let role_names = ["outer", "inner", "", "label"];
            let members: Vec<(i64, &str)> = (0..ways.len() + 1)
                .map(|k| (100 + k as i64, role_names[roles[k % roles.len()]]))
                .collect();
            let polygons = assemble(&relation(&members), |id| ways.iter().find(|w| w.id == id));
            for polygon in &polygons {
                proptest::prop_assert!(polygon.outer.len() >= 3, "{:?}", polygon);
                for hole in &polygon.holes {
                    proptest::prop_assert!(hole.len() >= 3, "{:?}", polygon);
                }
                for p in polygon.outer.iter().chain(polygon.holes.iter().flatten()) {
                    proptest::prop_assert!(p.lon.is_finite() && p.lat.is_finite());
                }
            }
        }
    }
}
