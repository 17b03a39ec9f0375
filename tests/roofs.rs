//! Roofs on real tiles: the straight skeleton of every building footprint, and pitched roofs
//! where the tags (or the kind of building) ask for them.

mod common;

use std::path::PathBuf;

use common::{decode, repo, sample_osm, sample_srtm};
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

/// The church of the Franciscans in Monaco (`building=church`, no `roof:shape`) gets a gabled
/// roof: sloped triangles rising above its walls, gables in the walls, and a closed shell.
#[test]
fn an_untagged_church_gets_a_gabled_roof() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let bytes = common::render_in_process("14/8529/5973", &[], dir.path());
    let tile = decode(&bytes);
    let church = tile
        .features
        .iter()
        .position(|f| f.name == "Église des Franciscains")
        .expect("the church is in the tile") as u32;
    let triangles = |material: &str| -> Vec<([[f32; 3]; 3], [f32; 3])> {
        tile.primitives("building")
            .iter()
            .filter(|p| p.material == material)
            .flat_map(|p| {
                p.indices
                    .chunks(3)
                    .filter(move |t| p.feature_ids[t[0] as usize] == church)
                    .map(move |t| {
                        (
                            [0, 1, 2].map(|k| p.positions[t[k] as usize]),
                            p.normals[t[0] as usize],
                        )
                    })
            })
            .collect()
    };
    let roofs = triangles("building_roofs");
    let walls = triangles("building_walls");
    let sloped = roofs
        .iter()
        .filter(|(_, n)| (0.3..0.95).contains(&n[1]))
        .count();
    assert!(
        sloped >= 4,
        "{sloped} sloped roof triangles of {}",
        roofs.len()
    );
    let eaves = roofs
        .iter()
        .flat_map(|(t, _)| t.map(|c| c[1]))
        .fold(f32::MAX, f32::min);
    let ridge = roofs
        .iter()
        .flat_map(|(t, _)| t.map(|c| c[1]))
        .fold(f32::MIN, f32::max);
    // The gables stand in the walls, up to the ridge.
    let gable_top = walls
        .iter()
        .flat_map(|(t, _)| t.map(|c| c[1]))
        .fold(f32::MIN, f32::max);
    assert!(
        (gable_top - ridge).abs() < 1e-3,
        "gables reach {gable_top}, the ridge {ridge}"
    );
    assert!(ridge > eaves + 1.0, "ridge {ridge}, eaves {eaves}");
}
