//! Straight skeletons of every building footprint of real tiles.

mod common;

use std::path::PathBuf;

use common::{repo, sample_osm, sample_srtm};
use terrastitch::features;
use terrastitch::mesh::skeleton::skeleton;
use terrastitch::source::Sources;
use terrastitch::TileId;

/// The footprints of a tile's buildings in metres (the projection is conformal, so shapes keep
/// their angles), each around its own first vertex.
fn footprints(osm: PathBuf, x: u32, y: u32) -> Vec<Vec<Vec<[f64; 2]>>> {
    let sources = Sources::open(&[osm], &sample_srtm(), 14).expect("sample data");
    let tile = TileId { z: 14, x, y };
    let set = features::collect(&sources.selection(tile), tile, &Default::default());
    let metres = tile.frame().size_m;
    set.buildings
        .iter()
        .map(|b| {
            let origin = b.footprint.outer[0];
            b.footprint
                .rings()
                .map(|ring| {
                    ring.iter()
                        .map(|p| [(p[0] - origin[0]) * metres, (p[1] - origin[1]) * metres])
                        .collect()
                })
                .collect()
        })
        .collect()
}

#[test]
fn the_footprints_of_monaco_have_valid_skeletons() {
    let tag_rich = repo().join("tests/data/monaco-planetiler-2021.osm.pbf");
    for (osm, x, y) in [
        (sample_osm(), 8529, 5973),
        (sample_osm(), 8529, 5974),
        (tag_rich.clone(), 8529, 5973),
        (tag_rich, 8529, 5974),
    ] {
        let all = footprints(osm.clone(), x, y);
        assert!(all.len() > 100, "{} footprints", all.len());
        let mut failures = Vec::new();
        for (i, rings) in all.iter().enumerate() {
            match skeleton(rings).and_then(|s| s.verify().map(|()| s)) {
                Ok(_) => {}
                Err(e) => failures.push((i, rings[0].len(), rings.len(), e.to_string())),
            }
        }
        assert!(
            failures.is_empty(),
            "{} of {} footprints in {}: {:?}",
            failures.len(),
            all.len(),
            osm.display(),
            &failures[..failures.len().min(10)]
        );
    }
}
