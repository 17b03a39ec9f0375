//! Elevations settled on real tiles: checked from the decoded glb and its feature table.

mod common;

use std::collections::HashMap;

use common::{decode, sample_osm, sample_srtm, GROUND_NODES};
use terrastitch::elevation::settled::Stations;
use terrastitch::features;
use terrastitch::source::Sources;
use terrastitch::TileId;

/// The ten Monaco tiles: the coast with the sea and the harbours, ponds, streams.
const TILES: [(u32, u32); 10] = [
    (8527, 5973),
    (8528, 5973),
    (8529, 5973),
    (8530, 5973),
    (8531, 5973),
    (8527, 5974),
    (8528, 5974),
    (8529, 5974),
    (8530, 5974),
    (8531, 5974),
];

/// Every water area (not a waterway drawn at its width) is flat within 1 cm, and the ground
/// that meets it at its shore is at its level: the water never stands above its banks. Every
/// waterway drawn at its width runs down (or level) along its way and is level across.
#[test]
fn water_lies_flat_and_meets_its_shore_and_waterways_run_down() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let sources = Sources::open(&[sample_osm()], &sample_srtm(), 14).expect("sample data");
    let (mut areas, mut waterways, mut shores) = (0, 0, 0);
    for (x, y) in TILES {
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
        shores += shore;

        // Waterways: the elevation of each vertex against how far down the way it lies, where
        // no other water shares the vertex (where two meet, the lower takes the shared ones).
        let mut owners: HashMap<[u32; 2], std::collections::BTreeSet<u32>> = HashMap::new();
        for primitive in tile.primitives("water") {
            for (k, &p) in primitive.positions.iter().enumerate() {
                owners
                    .entry([p[0].to_bits(), p[2].to_bits()])
                    .or_default()
                    .insert(primitive.feature_ids[k]);
            }
        }
        let id = TileId { z: 14, x, y };
        let set = features::collect(&sources.selection(id), id, &Default::default());
        for primitive in tile.primitives("water") {
            let mut by_feature: HashMap<u32, Vec<(f64, f64)>> = HashMap::new();
            for (k, &p) in primitive.positions.iter().enumerate() {
                let row = &tile.features[primitive.feature_ids[k] as usize];
                if !row.tags.contains_key("waterway")
                    || owners[&[p[0].to_bits(), p[2].to_bits()]].len() > 1
                {
                    continue;
                }
                let line = set
                    .surfaces
                    .iter()
                    .find(|s| {
                        set.features[s.feature as usize]
                            .element
                            .is_some_and(|e| e.id == row.osm_id)
                    })
                    .map(|s| Stations::new(&s.centreline))
                    .expect("the waterway's surface");
                let (u, v) = frame.local_to_uv(f64::from(p[0]), f64::from(p[2]));
                by_feature
                    .entry(primitive.feature_ids[k])
                    .or_default()
                    .push((line.at([u, v]), elevation(p)));
            }
            for (feature, mut points) in by_feature {
                waterways += 1;
                points.sort_by(|a, b| a.0.total_cmp(&b.0));
                for pair in points.windows(2) {
                    assert!(
                        pair[1].1 <= pair[0].1 + 0.01,
                        "{name}: waterway {feature} rises from {:.3} to {:.3} m",
                        pair[0].1,
                        pair[1].1
                    );
                }
            }
        }
    }
    assert!(areas >= 4, "{areas} water areas");
    assert!(shores > 100, "{shores} shore vertices");
    assert!(waterways >= 1, "{waterways} waterways");
}
