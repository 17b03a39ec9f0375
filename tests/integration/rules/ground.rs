//! Rules of how the ground looks: farmland mapped whole shows the crops of the parcels it
//! spans and a field mapped on its own one crop; residential land is paved round its houses
//! and gardened between.

use super::*;

/// Each vertex of the primitives drawn in `material`, with its feature row and colour.
fn coloured(tile: &DecodedTile, material: &str) -> Vec<([f32; 3], u32, [u8; 4])> {
    let mut vertices = Vec::new();
    for (_, primitives) in tile.placed_nodes() {
        for p in primitives.iter().filter(|p| p.material == material) {
            assert_eq!(p.colours.len(), p.positions.len(), "{material} has colours");
            for k in 0..p.positions.len() {
                vertices.push((p.positions[k], p.feature_ids[k], p.colours[k]));
            }
        }
    }
    assert!(!vertices.is_empty(), "no {material} drawn");
    vertices
}

/// Green over red: how lush a colour looks.
fn lushness(c: [u8; 4]) -> f64 {
    f64::from(c[1]) / f64::from(c[0])
}

#[test]
fn farmland_mapped_whole_is_a_patchwork_and_a_field_mapped_alone_one_crop() {
    let mut fixture = Fixture::default();
    fixture
        .area(&[("landuse", "farmland")], (0.05, 0.05), (0.95, 0.45))
        .area(&[("landuse", "farmland")], (0.1, 0.6), (0.14, 0.64));
    let tile = drawn(&fixture, &terrain(|_, _| 100.0));
    let vertices = coloured(&tile, "farmland");
    let colours_of = |way: i64| -> std::collections::BTreeSet<[u8; 4]> {
        vertices
            .iter()
            .filter(|(_, row, _)| tile.features[*row as usize].osm_id == way)
            .map(|&(_, _, colour)| colour)
            .collect()
    };
    let (whole, alone) = (colours_of(1), colours_of(2));
    assert!(whole.len() >= 4, "farmland mapped whole: {whole:?}");
    assert_eq!(alone.len(), 1, "a field mapped alone: {alone:?}");
}

#[test]
fn residential_land_is_paved_round_its_houses_and_gardened_between() {
    let mut fixture = Fixture::default();
    fixture
        .area(&[("landuse", "residential")], (0.3, 0.3), (0.7, 0.7))
        .area(&[("building", "house")], (0.48, 0.48), (0.49, 0.49));
    let tile = drawn(&fixture, &terrain(|_, _| 100.0));
    let size = tile.tile_size() as f32;
    let near = |v: [f32; 3], (east, south): (f32, f32)| {
        (v[0] - east * size).hypot(v[2] - south * size) < 0.5
    };
    let vertices = coloured(&tile, "residential");
    let (mut houses, mut gardens) = (0, 0);
    for &(v, _, colour) in &vertices {
        if [(0.48, 0.48), (0.49, 0.48), (0.49, 0.49), (0.48, 0.49)]
            .iter()
            .any(|&c| near(v, c))
        {
            houses += 1;
            assert!(lushness(colour) < 1.05, "paved round the house: {colour:?}");
        }
        if [(0.3, 0.3), (0.7, 0.3), (0.7, 0.7), (0.3, 0.7)]
            .iter()
            .any(|&c| near(v, c))
        {
            gardens += 1;
            assert!(lushness(colour) > 1.2, "gardened: {colour:?}");
        }
    }
    assert!(houses >= 4 && gardens >= 4, "{houses} {gardens}");
}
