//! Roofs on real tiles: the straight skeleton of every building footprint, and pitched roofs
//! where the tags (or the kind of building) ask for them.

use crate::common;

use std::collections::HashMap;
use std::path::PathBuf;

use common::{decode, repo, sample_osm, sample_srtm};
use terrastitch::features::{self, buildings::RoofShape};
use terrastitch::mesh::buildings::{self, Solid};
use terrastitch::mesh::skeleton::skeleton;
use terrastitch::provider::Inputs;
use terrastitch::render::srtm_step_uv;
use terrastitch::terrain::{Interpolation, TerrainModel};
use terrastitch::TileId;

/// The footprints of a tile's buildings in metres (the projection is conformal, so shapes keep
/// their angles), each around its own first vertex.
fn footprints(osm: PathBuf, x: u32, y: u32) -> Vec<Vec<Vec<[f64; 2]>>> {
    let sources = Inputs::open(&[osm], &sample_srtm(), 14).expect("sample data");
    let tile = TileId { z: 14, x, y };
    let set = features::collect(
        &common::selection(&sources, tile),
        tile,
        &Default::default(),
    );
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
    // Walls with windows or blank, and their gables.
    let walls: Vec<_> = ["building_walls", "facade_punched"]
        .iter()
        .flat_map(|m| triangles(m))
        .collect();
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

/// Every directed edge of the shell's faces runs the other way in exactly one other face, and
/// the faces enclose a positive volume: closed, wound outwards. `None` when it holds, else what
/// is wrong.
fn shell_defect(solid: &Solid) -> Option<String> {
    type Key = [u64; 3];
    let key = |c: [f64; 3]| c.map(|x| (x + 0.0).to_bits());
    let mut edges: HashMap<(Key, Key), u32> = HashMap::new();
    let mut volume = 0.0;
    for face in solid.faces() {
        for i in 0..face.len() {
            let (a, b) = (face[i], face[(i + 1) % face.len()]);
            *edges.entry((key(a), key(b))).or_default() += 1;
        }
        for i in 1..face.len().saturating_sub(1) {
            let (a, b, c) = (face[0], face[i], face[i + 1]);
            volume += a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                + a[2] * (b[0] * c[1] - b[1] * c[0]);
        }
    }
    let open = edges
        .iter()
        .filter(|((a, b), &n)| n != 1 || edges.get(&(*b, *a)) != Some(&1))
        .count();
    if open > 0 {
        return Some(format!("{open} unmatched edges of {}", edges.len()));
    }
    (volume <= 0.0).then(|| format!("volume {volume}"))
}

/// Every building of 14/8529/5973 in the tag-rich extract (roof shapes, parts, heights) is a
/// closed shell, and its tagged height and floating parts' `min_height` are met within 1 cm:
/// with the roofs as tagged, and with every footprint given each roof shape in turn.
#[test]
fn every_building_of_a_tag_rich_tile_is_a_closed_shell_at_its_tagged_height() {
    let tag_rich = repo().join("tests/data/monaco-planetiler-2021.osm.pbf");
    let sources = Inputs::open(&[tag_rich], &sample_srtm(), 14).expect("sample data");
    let tile = TileId {
        z: 14,
        x: 8529,
        y: 5973,
    };
    let tagged = features::collect(
        &common::selection(&sources, tile),
        tile,
        &Default::default(),
    );
    let mosaic = sources.mosaic(tile).expect("SRTM");
    let terrain = TerrainModel::new(&mosaic, Interpolation::default(), tile.z);
    let mut failures = Vec::new();
    for forced in std::iter::once(None).chain(RoofShape::ALL.map(Some)) {
        let mut set = tagged.clone();
        if let Some(shape) = forced {
            for building in &mut set.buildings {
                building.roof.shape = shape;
            }
        }
        let solids = buildings::solids(
            &set.buildings,
            &tile.frame(),
            &terrain,
            &terrain,
            srtm_step_uv(tile),
        );
        let (mut checked, mut pitched) = (0, 0);
        for (index, (building, solid)) in set.buildings.iter().zip(&solids).enumerate() {
            let Some(solid) = solid else { continue };
            checked += 1;
            pitched += usize::from(!solid.flat_roof);
            let row = &set.features[building.feature as usize];
            let heights = || solid.faces().flatten().map(|c| c[2]);
            let top = heights().fold(f64::NEG_INFINITY, f64::max);
            let bottom = heights().fold(f64::INFINITY, f64::min);
            let what = format!("{:?} as {forced:?}", row.element);
            if let Some(defect) = shell_defect(solid) {
                failures.push(format!("{what}: {defect}"));
            }
            // Underground levels count where the slope shows them.
            let base = &set.buildings[building.base.unwrap_or(index)].footprint;
            let (low, high) = buildings::ground_range(base, &terrain, &terrain, srtm_step_uv(tile));
            assert_eq!(low, solid.ground);
            let tagged = building.height_m + building.basement_m.min(high - low);
            // A pitched roof stands on levels counted alone: its eaves at their top.
            let on_levels = building.roof.over_levels && !solid.flat_roof;
            let reached = if on_levels {
                solid
                    .roof
                    .iter()
                    .flatten()
                    .map(|c| c[2])
                    .fold(f64::INFINITY, f64::min)
            } else {
                top
            };
            if building.height_tagged && (reached - solid.ground - tagged).abs() > 0.01 {
                let what_reached = if on_levels { "eaves" } else { "top" };
                failures.push(format!(
                    "{what}: {what_reached} {:.3} m above the ground, tagged {tagged:.3} m",
                    reached - solid.ground,
                ));
            }
            if on_levels && top <= reached {
                failures.push(format!("{what}: no roof above the levels"));
            }
            if solid.floating && (bottom - solid.ground - building.min_height_m).abs() > 0.01 {
                failures.push(format!("{what}: floats at {bottom}"));
            }
        }
        assert!(checked > 100, "{checked} buildings");
        if forced.is_some_and(|s| s != RoofShape::Flat) {
            assert_eq!(pitched, checked, "{forced:?}");
        }
    }
    let mut by_shape: std::collections::BTreeMap<&str, usize> = Default::default();
    for failure in &failures {
        let shape = failure
            .split(" as ")
            .nth(1)
            .and_then(|r| r.split(':').next());
        *by_shape.entry(shape.unwrap_or("?")).or_default() += 1;
    }
    assert!(
        failures.is_empty(),
        "{} failures ({by_shape:?}): {:?}",
        failures.len(),
        &failures[..failures.len().min(12)]
    );
}

/// A `roof:material=metal` roof in 14/8530/5973 of the tag-rich extract is drawn with a
/// metallic material of its own; every other material says explicitly that it is not metal.
#[test]
fn metal_roofs_get_a_metallic_material() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let bytes = common::render_in_process(
        "14/8530/5973",
        &[
            "--osm".as_ref(),
            "tests/data/monaco-planetiler-2021.osm.pbf".as_ref(),
        ],
        dir.path(),
    );
    let json_length = u32::from_le_bytes([bytes[12], bytes[13], bytes[14], bytes[15]]) as usize;
    let root: serde_json::Value =
        serde_json::from_slice(&bytes[20..20 + json_length]).expect("glTF JSON");
    let materials = root["materials"].as_array().expect("materials");
    let metallic = |name: &str| {
        materials
            .iter()
            .find(|m| m["name"] == name)
            .map(|m| m["pbrMetallicRoughness"]["metallicFactor"].as_f64())
    };
    assert_eq!(metallic("building_roofs_metal"), Some(Some(0.8)));
    for material in materials {
        let factor = material["pbrMetallicRoughness"]["metallicFactor"].as_f64();
        if material["name"] != "building_roofs_metal" {
            assert_eq!(factor, Some(0.0), "{}", material["name"]);
        }
    }
    let tile = decode(&bytes);
    let metal_roofs = tile
        .primitives("building")
        .iter()
        .filter(|p| p.material == "building_roofs_metal")
        .map(|p| p.indices.len() / 3)
        .sum::<usize>();
    assert!(metal_roofs > 0);
}

/// Every building wholly inside a tile is a closed shell in the glb itself: each edge (by the
/// bits of its two positions) is met by exactly one other triangle's edge running the other way.
/// A building the tile's edge cuts is open there only.
#[test]
fn every_building_inside_a_tile_is_a_closed_shell_in_the_glb() {
    use std::collections::BTreeMap;
    let dir = tempfile::tempdir().expect("a temporary directory");
    let bytes = common::render_in_process(
        "14/8529/5973",
        &[
            "--osm".as_ref(),
            "tests/data/monaco-planetiler-2021.osm.pbf".as_ref(),
        ],
        dir.path(),
    );
    let tile = decode(&bytes);
    let size = tile.tile_size() as f32;
    type Key = [u32; 3];
    let key = |p: [f32; 3]| p.map(f32::to_bits);
    let on_border = |p: [f32; 3]| p[0] == 0.0 || p[0] == size || p[2] == 0.0 || p[2] == size;
    // Directed edges of each building, and whether the building touches the tile's edge.
    let mut edges: BTreeMap<u32, BTreeMap<(Key, Key), i32>> = BTreeMap::new();
    let mut cut: std::collections::BTreeSet<u32> = Default::default();
    for primitive in tile.primitives("building") {
        for t in primitive.indices.chunks_exact(3) {
            let feature = primitive.feature_ids[t[0] as usize];
            let corners = [0, 1, 2].map(|k| primitive.positions[t[k] as usize]);
            if corners.iter().any(|&p| on_border(p)) {
                cut.insert(feature);
            }
            let building = edges.entry(feature).or_default();
            for k in 0..3 {
                let (a, b) = (key(corners[k]), key(corners[(k + 1) % 3]));
                if a == b {
                    continue;
                }
                *building.entry((a, b)).or_default() += 1;
            }
        }
    }
    let (mut closed, mut open) = (0, Vec::new());
    for (feature, building) in &edges {
        if cut.contains(feature) {
            continue;
        }
        let unmatched = building
            .iter()
            .filter(|(&(a, b), &n)| building.get(&(b, a)).copied().unwrap_or(0) != n)
            .count();
        if unmatched == 0 {
            closed += 1;
        } else {
            open.push((tile.features[*feature as usize].osm_id, unmatched));
        }
    }
    assert!(closed > 50, "{closed} closed buildings");
    assert!(
        open.is_empty(),
        "{} of {} buildings inside the tile are open (way, unmatched edges): {:?}",
        open.len(),
        open.len() + closed,
        &open[..open.len().min(10)]
    );
}
