//! The road network of a real tile: ways cut back where they meet and joined by junction
//! polygons, so road surfaces do not overlap.

use crate::common;

use common::{sample_osm, sample_srtm};
use terrastitch::features::{self, roads, FeatureClass, FeatureSet, Surface};
use terrastitch::osm::ElementType;
use terrastitch::provider::Inputs;
use terrastitch::TileId;

fn feature_set(x: u32, y: u32) -> FeatureSet {
    let sources = Inputs::open(&[sample_osm()], &sample_srtm(), 14).expect("sample data");
    let tile = TileId { z: 14, x, y };
    features::collect(
        &common::selection(&sources, tile),
        tile,
        &Default::default(),
    )
}

/// Of the sample points on a grid over the tile that lie on a road surface, how many lie on
/// two or more, and how many on one.
fn road_coverage(set: &FeatureSet, x: u32, y: u32, steps: usize) -> (usize, usize) {
    let roads: Vec<&Surface> = set
        .surfaces
        .iter()
        .filter(|s| s.class == FeatureClass::Road && !s.embedded)
        .collect();
    // Surfaces by grid row, to keep the lookups short.
    let rows = 64;
    let mut by_row: Vec<Vec<&Surface>> = vec![Vec::new(); rows];
    for surface in &roads {
        let from = ((surface.bounds.min[1] - f64::from(y)) * rows as f64)
            .floor()
            .max(0.0) as usize;
        let to = ((surface.bounds.max[1] - f64::from(y)) * rows as f64)
            .floor()
            .max(0.0) as usize;
        for row in by_row.iter_mut().take(to.min(rows - 1) + 1).skip(from) {
            row.push(surface);
        }
    }
    let (mut twice, mut once) = (0, 0);
    for j in 0..steps {
        let v = f64::from(y) + (j as f64 + 0.37) / steps as f64;
        let row = &by_row[((v - f64::from(y)) * rows as f64) as usize];
        for i in 0..steps {
            let u = f64::from(x) + (i as f64 + 0.61) / steps as f64;
            match row.iter().filter(|s| s.contains([u, v])).count() {
                0 => {}
                1 => once += 1,
                _ => twice += 1,
            }
        }
    }
    (twice, once)
}

#[test]
fn road_surfaces_of_a_dense_tile_barely_overlap() {
    let (x, y) = (8529, 5973);
    let set = feature_set(x, y);
    let junctions = set
        .surfaces
        .iter()
        .filter(|s| {
            s.class == FeatureClass::Road
                && set.features[s.feature as usize]
                    .element
                    .is_some_and(|e| e.element_type == ElementType::Node)
        })
        .count();
    assert!(junctions > 100, "{junctions} junction polygons");
    // A sample every 2.4 m.
    let (twice, once) = road_coverage(&set, x, y, 1000);
    assert!(once > 20_000, "{once} samples on roads");
    let overlap = twice as f64 / (twice + once) as f64;
    assert!(
        overlap < 0.005,
        "{twice} of {} road samples on two surfaces",
        twice + once
    );
}

#[test]
fn a_named_road_is_as_wide_as_its_tags_say() {
    let (x, y) = (8529, 5974);
    let sources = Inputs::open(&[sample_osm()], &sample_srtm(), 14).expect("sample data");
    let tile = TileId { z: 14, x, y };
    let selection = common::selection(&sources, tile);
    let set = features::collect(&selection, tile, &Default::default());
    let projection = features::Projection::new(14);
    let settings = features::FeatureSettings::default();
    // The named road with the longest straight stretch inside the tile: the middle of that
    // stretch is far from any junction or bend.
    let rect = features::tile_rect(tile);
    struct Stretch<'a> {
        length: f64,
        surface: &'a Surface,
        middle: [f64; 2],
        across: [f64; 2],
        expected: f64,
    }
    let mut best: Option<Stretch> = None;
    for surface in set
        .surfaces
        .iter()
        .filter(|s| s.class == FeatureClass::Road)
    {
        let info = &set.features[surface.feature as usize];
        let Some(element) = info.element.filter(|e| e.element_type == ElementType::Way) else {
            continue;
        };
        if info.name().is_none() {
            continue;
        }
        let Some(way) = selection.ways.iter().find(|w| w.id == element.id) else {
            continue;
        };
        for pair in way.positions.windows(2) {
            let (a, b) = (projection.point(pair[0]), projection.point(pair[1]));
            let length = (b[0] - a[0]).hypot(b[1] - a[1]);
            let middle = [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0];
            if rect.contains(middle) && best.as_ref().is_none_or(|best| length > best.length) {
                best = Some(Stretch {
                    length,
                    surface,
                    middle,
                    across: [-(b[1] - a[1]) / length, (b[0] - a[0]) / length],
                    expected: roads::width_m(&way.tags, &settings).expect("a drawn road"),
                });
            }
        }
    }
    let Stretch {
        length,
        surface,
        middle,
        across,
        expected,
    } = best.expect("a named road in the tile");
    let metre = projection.metres(1.0, 43.73);
    assert!(
        length > 40.0 * metre,
        "the longest stretch is {} m",
        length / metre
    );
    // Walk out from the centre line in 2 cm steps until the surface ends, on both sides.
    let half = |sign: f64| {
        let mut t = 0.0;
        while surface.contains([
            middle[0] + sign * across[0] * (t + 0.02) * metre,
            middle[1] + sign * across[1] * (t + 0.02) * metre,
        ]) {
            t += 0.02;
        }
        t
    };
    let width = half(1.0) + half(-1.0);
    assert!(
        (width - expected).abs() < 0.1,
        "{} is {width} m wide, its tags say {expected} m",
        set.features[surface.feature as usize]
            .name()
            .unwrap_or_default()
    );
}
