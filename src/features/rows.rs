//! Rows of buildings: buildings that share a wall with another (a terrace, a street front of
//! town houses). A building in a row takes its roof with its neighbours: one style, its ridge
//! along the row (across the walls it shares), so the roofs of a row meet at their party walls.
//!
//! A shared wall is an edge of the outline that another building's outline has too, between the
//! same two points (OSM draws it with the same nodes). Only a building's own walls count, so a
//! tile that draws one building of a row sees the same shared walls as its neighbour does.

use std::collections::HashMap;

use super::buildings::{is_building, is_building_part};
use super::Area;
use crate::osm::{ElementRef, LonLat};

/// An edge of an outline by its two ends, in either order.
type EdgeKey = ([u64; 2], [u64; 2]);

fn key(a: LonLat, b: LonLat) -> EdgeKey {
    let (a, b) = (
        [a.lon.to_bits(), a.lat.to_bits()],
        [b.lon.to_bits(), b.lat.to_bits()],
    );
    if a <= b {
        (a, b)
    } else {
        (b, a)
    }
}

/// For each building of `areas` that shares a wall with another, the compass bearing of its
/// longest shared wall, degrees in `[0, 180)`: its row runs across it.
pub fn shared_walls(areas: &[Area<'_>]) -> HashMap<ElementRef, f64> {
    let buildings: Vec<&Area<'_>> = areas
        .iter()
        .filter(|a| is_building(a.tags) && !is_building_part(a.tags))
        .collect();
    let mut owners: HashMap<EdgeKey, Vec<usize>> = HashMap::new();
    for (index, area) in buildings.iter().enumerate() {
        for polygon in &area.polygons {
            for (a, b) in edges(&polygon.outer) {
                owners.entry(key(a, b)).or_default().push(index);
            }
        }
    }
    let mut rows: HashMap<ElementRef, (f64, f64)> = HashMap::new();
    for (index, area) in buildings.iter().enumerate() {
        for polygon in &area.polygons {
            for (a, b) in edges(&polygon.outer) {
                let Some(sharing) = owners.get(&key(a, b)) else {
                    continue;
                };
                if !sharing.iter().any(|&other| other != index) {
                    continue;
                }
                let (length, bearing) = length_and_bearing(a, b);
                let longest = rows.entry(area.element).or_insert((0.0, bearing));
                if length > longest.0 {
                    *longest = (length, bearing);
                }
            }
        }
    }
    rows.into_iter()
        .map(|(element, (_, b))| (element, b))
        .collect()
}

/// The edges of a ring, closed or not, without those of no length.
fn edges(ring: &[LonLat]) -> impl Iterator<Item = (LonLat, LonLat)> + '_ {
    (0..ring.len())
        .map(|i| (ring[i], ring[(i + 1) % ring.len()]))
        .filter(|(a, b)| a != b)
}

/// The length (metres) and the compass bearing (degrees in `[0, 180)`) of a short segment.
fn length_and_bearing(a: LonLat, b: LonLat) -> (f64, f64) {
    const METRES_A_DEGREE: f64 = 111_320.0;
    let east = (b.lon - a.lon) * a.lat.to_radians().cos() * METRES_A_DEGREE;
    let north = (b.lat - a.lat) * METRES_A_DEGREE;
    let bearing = east.atan2(north).to_degrees().rem_euclid(180.0);
    (east.hypot(north), bearing)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::osm::multipolygon::AreaPolygon;
    use crate::osm::{ElementType, Tags};

    fn square(west: f64, east: f64) -> AreaPolygon {
        let p = |lon: f64, lat: f64| LonLat { lon, lat };
        let (south, north) = (47.0, 47.0001);
        AreaPolygon {
            outer: vec![
                p(west, south),
                p(east, south),
                p(east, north),
                p(west, north),
            ],
            holes: Vec::new(),
        }
    }

    #[test]
    fn houses_sharing_a_wall_are_in_a_row_across_it_and_a_lone_house_is_not() {
        let house = Tags::from_pairs([("building", "house")]);
        let element = |id| ElementRef {
            element_type: ElementType::Way,
            id,
        };
        let area = |id, west, east| Area {
            element: element(id),
            tags: &house,
            polygons: vec![square(west, east)],
        };
        let areas = [
            area(1, 9.0, 9.0001),
            area(2, 9.0001, 9.0002),
            area(3, 9.0005, 9.0006),
        ];
        let rows = shared_walls(&areas);
        assert_eq!(rows.len(), 2, "{rows:?}");
        // The shared wall runs north–south: bearing 0.
        for id in [1, 2] {
            let bearing = rows[&element(id)];
            assert!(bearing.min(180.0 - bearing) < 1e-6, "{bearing}");
        }
        assert!(!rows.contains_key(&element(3)));
    }
}
