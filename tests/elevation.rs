//! Elevations settled on real tiles: checked from the decoded glb and its feature table.

mod common;

use std::collections::HashMap;

use common::{decode, GROUND_NODES};
use terrastitch::TileId;

/// Monaco's tiles along the coast, with the sea, the harbours and ponds.
const COASTAL_TILES: [(u32, u32); 4] = [(8529, 5973), (8530, 5973), (8529, 5974), (8530, 5974)];

/// Every water area (not a waterway drawn at its width) is flat within 1 cm, and the ground
/// that meets it at its shore is at its level: the water never stands above its banks.
#[test]
fn water_areas_lie_flat_and_meet_their_shore() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let mut areas = 0;
    for (x, y) in COASTAL_TILES {
        let name = format!("14/{x}/{y}");
        let tile = decode(&common::render_in_process(&name, &[], dir.path()));
        let frame = TileId { z: 14, x, y }.frame();
        let elevation = |p: [f32; 3]| f64::from(p[1]) / frame.scale_at(f64::from(p[2]));
        // Elevations of each water area's vertices, and the level at each water position.
        let mut by_feature: HashMap<u32, Vec<f64>> = HashMap::new();
        for primitive in tile.primitives("water") {
            for (k, &p) in primitive.positions.iter().enumerate() {
                let feature = primitive.feature_ids[k];
                let tags = &tile.features[feature as usize].tags;
                if !tags.contains_key("waterway") {
                    by_feature.entry(feature).or_default().push(elevation(p));
                }
            }
        }
        let mut levels: HashMap<[u32; 2], f64> = HashMap::new();
        for (feature, heights) in &by_feature {
            let low = heights.iter().copied().fold(f64::INFINITY, f64::min);
            let high = heights.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            assert!(
                high - low < 0.01,
                "{name}: water feature {feature} (way {} {:?}) spans {low:.3}..{high:.3} m",
                tile.features[*feature as usize].osm_id,
                tile.features[*feature as usize].tags
            );
            areas += 1;
        }
        for primitive in tile.primitives("water") {
            for (k, &p) in primitive.positions.iter().enumerate() {
                if by_feature.contains_key(&primitive.feature_ids[k]) {
                    levels.insert([p[0].to_bits(), p[2].to_bits()], elevation(p));
                }
            }
        }
        // The shore: ground vertices of other surfaces where the water's vertices are.
        let mut shore = 0;
        for node in GROUND_NODES.iter().filter(|n| **n != "water") {
            for primitive in tile.primitives(node) {
                for &p in &primitive.positions {
                    if let Some(&level) = levels.get(&[p[0].to_bits(), p[2].to_bits()]) {
                        shore += 1;
                        assert!(
                            (elevation(p) - level).abs() < 0.01,
                            "{name}: {node} at {p:?} is {:.3} m, the water {level:.3} m",
                            elevation(p)
                        );
                    }
                }
            }
        }
        assert!(shore > 0 || levels.is_empty(), "{name}: no shore found");
    }
    assert!(areas >= 4, "{areas} water areas");
}
