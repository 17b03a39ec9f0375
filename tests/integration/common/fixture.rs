//! Hand-written OSM data in one zoom-14 tile, on synthetic terrain: what the rule
//! specifications (`spec.rs`, `rules.rs`) are written on.

use std::sync::Arc;

use terrastitch::osm::{LonLat, Node, OsmData, Tags, Way};
use terrastitch::terrain::cell::{CellId, SrtmTile};
use terrastitch::terrain::Mosaic;
use terrastitch::TileId;

/// The tile the fixtures lie in.
pub const TILE: TileId = TileId {
    z: 14,
    x: 8529,
    y: 5973,
};

/// A place in [`TILE`] as fractions of it: east from its west edge, south from its north edge.
pub fn at(east: f64, south: f64) -> LonLat {
    let b = TILE.bounds();
    LonLat {
        lon: b.west + east * (b.east - b.west),
        lat: b.north - south * (b.north - b.south),
    }
}

/// Hand-written OSM data: ways given as tags and places in the tile; node ids are handed out
/// in order, so a place given twice is one node only when the same id is reused on purpose.
#[derive(Default)]
pub struct Fixture {
    ways: Vec<Way>,
    nodes: Vec<Node>,
    next_node: i64,
}

impl Fixture {
    pub fn way(&mut self, tags: &[(&str, &str)], places: &[(f64, f64)]) -> &mut Self {
        let positions: Vec<LonLat> = places.iter().map(|&(e, s)| at(e, s)).collect();
        let nodes = (0..positions.len() as i64)
            .map(|k| self.next_node + k + 1)
            .collect();
        self.next_node += positions.len() as i64;
        self.ways.push(Way {
            id: self.ways.len() as i64 + 1,
            tags: Tags::from_pairs(tags.iter().copied()),
            nodes,
            positions,
        });
        self
    }

    /// A closed way around the rectangle from `(east0, south0)` to `(east1, south1)`.
    pub fn area(&mut self, tags: &[(&str, &str)], from: (f64, f64), to: (f64, f64)) -> &mut Self {
        let corners = [
            (from.0, from.1),
            (to.0, from.1),
            (to.0, to.1),
            (from.0, to.1),
        ];
        self.way(tags, &corners);
        let way = self.ways.last_mut().expect("just added");
        way.nodes.push(way.nodes[0]);
        way.positions.push(way.positions[0]);
        self
    }

    /// Makes the ways through `place` meet there, at the node the first of them has.
    pub fn join(&mut self, place: (f64, f64)) -> &mut Self {
        let place = at(place.0, place.1);
        let mut shared = None;
        for way in &mut self.ways {
            for (node, _) in way
                .nodes
                .iter_mut()
                .zip(&way.positions)
                .filter(|p| *p.1 == place)
            {
                *node = *shared.get_or_insert(*node);
            }
        }
        self
    }

    /// A node of its own at `place`, on no way (a street lamp, say).
    pub fn node(&mut self, tags: &[(&str, &str)], place: (f64, f64)) -> &mut Self {
        self.next_node += 1;
        self.nodes.push(Node {
            id: self.next_node,
            position: at(place.0, place.1),
            tags: Tags::from_pairs(tags.iter().copied()),
        });
        self
    }

    /// Tags the node the first way through `place` has there (a crossing on a road, say).
    pub fn tag_node(&mut self, place: (f64, f64), tags: &[(&str, &str)]) -> &mut Self {
        let position = at(place.0, place.1);
        let id = self
            .ways
            .iter()
            .find_map(|w| {
                let k = w.positions.iter().position(|p| *p == position)?;
                Some(w.nodes[k])
            })
            .expect("a way passes through the place");
        self.nodes.push(Node {
            id,
            position,
            tags: Tags::from_pairs(tags.iter().copied()),
        });
        self
    }

    pub fn data(&self) -> OsmData {
        OsmData {
            nodes: self.nodes.clone(),
            ways: self.ways.clone(),
            relations: Vec::new(),
            coverage: vec![TILE.bounds().expanded(0.1)],
        }
    }
}

/// SRTM samples for the cell of [`TILE`] whose height at a longitude and latitude is `f`.
pub fn terrain(f: impl Fn(f64, f64) -> f64) -> Mosaic {
    let cell = CellId { lat: 43, lon: 7 };
    let size = 1201;
    let step = 1.0 / (size - 1) as f64;
    let mut heights = Vec::with_capacity(size * size);
    for row in 0..size {
        for column in 0..size {
            let lat = f64::from(cell.lat) + 1.0 - row as f64 * step;
            let lon = f64::from(cell.lon) + column as f64 * step;
            heights.push(f(lon, lat) as f32);
        }
    }
    Mosaic::new([Arc::new(SrtmTile {
        cell,
        size,
        heights,
    })])
}
