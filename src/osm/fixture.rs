//! Ways written by hand for the unit tests: tags as pairs, nodes as `(id, lon, lat)`.

use super::{LonLat, Tags, Way};

pub fn way(id: i64, tags: &[(&str, &str)], nodes: &[(i64, f64, f64)]) -> Way {
    Way {
        id,
        tags: Tags::from_pairs(tags.iter().copied()),
        nodes: nodes.iter().map(|n| n.0).collect(),
        positions: nodes
            .iter()
            .map(|&(_, lon, lat)| LonLat { lon, lat })
            .collect(),
    }
}
