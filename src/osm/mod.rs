//! The OpenStreetMap data model as the renderer needs it: tagged nodes, ways with their node
//! coordinates resolved, relations with their members, and an index that answers "everything
//! near this tile" (thesis §2.1).

pub mod areas;
pub mod coast;
pub mod far;
#[cfg(test)]
pub(crate) mod fixture;
pub mod index;
pub mod multipolygon;
pub mod structures;
pub mod units;

pub use index::{Joints, OsmIndex, RoadGraph};

/// Tags written out as literal pairs, as the unit tests write them.
#[cfg(test)]
pub fn tags(pairs: &[(&str, &str)]) -> Tags {
    Tags::from_pairs(pairs.iter().copied())
}

/// An element's tags, sorted by key so lookups are a binary search and iteration is deterministic.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Tags(Vec<(String, String)>);

impl Tags {
    pub fn from_pairs<K: Into<String>, V: Into<String>>(
        pairs: impl IntoIterator<Item = (K, V)>,
    ) -> Tags {
        let mut pairs: Vec<(String, String)> = pairs
            .into_iter()
            .map(|(k, v)| (k.into(), v.into()))
            .collect();
        pairs.sort();
        pairs.dedup_by(|a, b| a.0 == b.0);
        Tags(pairs)
    }

    pub fn get(&self, key: &str) -> Option<&str> {
        self.0
            .binary_search_by(|(k, _)| k.as_str().cmp(key))
            .ok()
            .map(|i| self.0[i].1.as_str())
    }

    /// True when `key` is present with a value other than `no`.
    pub fn is_set(&self, key: &str) -> bool {
        self.get(key).is_some_and(|v| v != "no")
    }

    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    pub fn len(&self) -> usize {
        self.0.len()
    }

    pub fn iter(&self) -> impl Iterator<Item = (&str, &str)> {
        self.0.iter().map(|(k, v)| (k.as_str(), v.as_str()))
    }
}

/// Which kind of OSM element something came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ElementType {
    Node,
    Way,
    Relation,
}

impl ElementType {
    pub fn as_str(self) -> &'static str {
        match self {
            ElementType::Node => "node",
            ElementType::Way => "way",
            ElementType::Relation => "relation",
        }
    }
}

/// A reference to an OSM element.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ElementRef {
    pub element_type: ElementType,
    pub id: i64,
}

/// A position in degrees.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LonLat {
    pub lon: f64,
    pub lat: f64,
}

/// A node that carries tags (untagged nodes live only inside their ways).
#[derive(Debug, Clone)]
pub struct Node {
    pub id: i64,
    pub position: LonLat,
    pub tags: Tags,
}

/// A way with the positions of its nodes. Nodes missing from the extract were dropped when the
/// way was read; `nodes` and `positions` stay parallel.
#[derive(Debug, Clone, PartialEq)]
pub struct Way {
    pub id: i64,
    pub tags: Tags,
    pub nodes: Vec<i64>,
    pub positions: Vec<LonLat>,
}

impl Way {
    /// First and last node are the same (and there are at least four node references).
    pub fn is_closed(&self) -> bool {
        self.nodes.len() >= 4 && self.nodes.first() == self.nodes.last()
    }
}

/// A member of a relation.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Member {
    pub element: ElementRef,
    pub role: String,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Relation {
    pub id: i64,
    pub tags: Tags,
    pub members: Vec<Member>,
}

/// A rectangle in degrees.
pub use crate::tile::LonLatBounds as Bounds;

/// Mean radius of the Earth, metres (IUGG).
const EARTH_RADIUS_M: f64 = 6_371_008.8;

/// The length of a line through `positions` on the sphere, metres (great-circle distances
/// between consecutive positions).
pub fn length_m(positions: &[LonLat]) -> f64 {
    positions
        .windows(2)
        .map(|pair| {
            let (a, b) = (pair[0], pair[1]);
            let (lat_a, lat_b) = (a.lat.to_radians(), b.lat.to_radians());
            let half_lat = (lat_b - lat_a) / 2.0;
            let half_lon = (b.lon - a.lon).to_radians() / 2.0;
            let h = half_lat.sin().powi(2) + lat_a.cos() * lat_b.cos() * half_lon.sin().powi(2);
            2.0 * EARTH_RADIUS_M * h.sqrt().min(1.0).asin()
        })
        .sum()
}

/// The bounding box of some positions.
pub fn bounds_of(positions: &[LonLat]) -> Option<Bounds> {
    let first = positions.first()?;
    let mut bounds = Bounds {
        west: first.lon,
        east: first.lon,
        south: first.lat,
        north: first.lat,
    };
    for p in &positions[1..] {
        bounds.west = bounds.west.min(p.lon);
        bounds.east = bounds.east.max(p.lon);
        bounds.south = bounds.south.min(p.lat);
        bounds.north = bounds.north.max(p.lat);
    }
    Some(bounds)
}

/// Everything read from the OSM extracts.
#[derive(Debug, Default)]
pub struct OsmData {
    /// Tagged nodes, sorted by id.
    pub nodes: Vec<Node>,
    /// Ways with at least two resolved nodes, sorted by id.
    pub ways: Vec<Way>,
    /// Relations, sorted by id.
    pub relations: Vec<Relation>,
    /// The area each extract declares (its header box, else the extent of its nodes).
    pub coverage: Vec<Bounds>,
}

impl OsmData {
    pub fn way(&self, id: i64) -> Option<&Way> {
        self.ways
            .binary_search_by_key(&id, |w| w.id)
            .ok()
            .map(|i| &self.ways[i])
    }

    pub fn relation(&self, id: i64) -> Option<&Relation> {
        self.relations
            .binary_search_by_key(&id, |r| r.id)
            .ok()
            .map(|i| &self.relations[i])
    }

    /// True when some extract covers part of `bounds`.
    pub fn covers(&self, bounds: &Bounds) -> bool {
        self.coverage.iter().any(|c| c.intersects(bounds))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tags_are_sorted_and_searchable() {
        let tags = Tags::from_pairs([
            ("name", "Boulevard"),
            ("highway", "primary"),
            ("bridge", "no"),
        ]);
        assert_eq!(tags.get("highway"), Some("primary"));
        assert_eq!(tags.get("lanes"), None);
        assert!(!tags.is_set("bridge"));
        assert!(tags.is_set("name"));
        let keys: Vec<&str> = tags.iter().map(|(k, _)| k).collect();
        assert_eq!(keys, ["bridge", "highway", "name"]);
    }
}
