//! Tiles for far views: the glb parents at zooms 13, 12, 10 and 8, generalised from the same
//! data as the zoom-14 content. Neighbours at one level share their edges exactly, as at 14;
//! every level stays within its size budget; a parent holds fewer, coarser things than its
//! children together, and its sea lies where theirs does.

use crate::common;

use common::{decode, ground_edge, render_in_process, repo, DecodedTile};

/// Largest glb-meshopt parent tile allowed, bytes.
const PARENT_BUDGET: usize = 1_500_000;

fn render(tile: &str, variant: &str, out: &std::path::Path) -> Vec<u8> {
    render_in_process(
        tile,
        &[
            "--variant".as_ref(),
            variant.as_ref(),
            "--srtm".as_ref(),
            repo().join("data").as_os_str(),
        ],
        out,
    )
}

fn triangles(tile: &DecodedTile) -> usize {
    tile.placed_nodes()
        .flat_map(|(_, primitives)| primitives)
        .map(|p| p.indices.len() / 3)
        .sum()
}

/// Pairs whose shared edge does not meet the end of a coastline the extract cut open (west of
/// Monaco, at 7.383° E): there a parent decides the sea by the coast nearest to it, and two
/// parents may find different ones.
#[test]
fn neighbouring_parents_share_their_edges_exactly() {
    let dir = tempfile::tempdir().unwrap();
    for (z, pairs) in [
        (
            13,
            vec![((4264, 2986), (4265, 2986)), ((4264, 2986), (4264, 2987))],
        ),
        (
            12,
            vec![((2132, 1493), (2133, 1493)), ((2132, 1493), (2132, 1494))],
        ),
    ] {
        for ((ax, ay), (bx, by)) in pairs {
            let a = decode(&render(&format!("{z}/{ax}/{ay}"), "glb", dir.path()));
            let b = decode(&render(&format!("{z}/{bx}/{by}"), "glb", dir.path()));
            let (mine, theirs) = if bx > ax {
                ("east", "west")
            } else {
                ("south", "north")
            };
            let (ea, eb) = (ground_edge(&a, mine), ground_edge(&b, theirs));
            assert!(
                ea.len() >= 2,
                "{z}/{ax}/{ay} has {} edge vertices",
                ea.len()
            );
            assert!(
                ea == eb,
                "{z}/{ax}/{ay} {mine} edge ({} vertices) differs from {z}/{bx}/{by} ({}): only in the first {:?}, only in the second {:?}",
                ea.len(),
                eb.len(),
                ea.difference(&eb).take(3).collect::<Vec<_>>(),
                eb.difference(&ea).take(3).collect::<Vec<_>>()
            );
        }
    }
}

/// The height of a flat-frame vertex of `tile` ("Z/X/Y"): its `y` over the Mercator scale at
/// its latitude.
fn height_m(tile: &str, decoded: &DecodedTile, vertex: [f32; 3]) -> f64 {
    let parts: Vec<f64> = tile.split('/').map(|p| p.parse().unwrap()).collect();
    let (z, y) = (parts[0], parts[2]);
    let v = (y + f64::from(vertex[2]) / decoded.tile_size()) / 2f64.powf(z);
    let latitude = (std::f64::consts::PI * (1.0 - 2.0 * v)).sinh().atan();
    f64::from(vertex[1]) * latitude.cos()
}

/// Places (zoom-14 tile coordinates) the zoom-14 tiles find on land, inland of where the
/// extract cuts the coastline open west and east of Monaco, and one they find at sea.
const LAND_WEST: (f64, f64) = (8528.5, 5974.5);
const LAND_EAST: (f64, f64) = (8530.5, 5972.5);
const SEA_SOUTH: (f64, f64) = (8530.5, 5975.5);

/// Whether `tile` ("Z/X/Y") draws water at `place` (zoom-14 tile coordinates); `None` when the
/// place lies outside it.
fn water_at(tile: &str, decoded: &DecodedTile, place: (f64, f64)) -> Option<bool> {
    let parts: Vec<f64> = tile.split('/').map(|p| p.parse().unwrap()).collect();
    let shrink = 2f64.powf(14.0 - parts[0]);
    let (east, south) = (place.0 / shrink - parts[1], place.1 / shrink - parts[2]);
    if !(0.0..1.0).contains(&east) || !(0.0..1.0).contains(&south) {
        return None;
    }
    let size = decoded.tile_size();
    let water = common::GroundLocator::new(common::corners(decoded.primitives("water")), size);
    Some(!water.heights_at(east * size, south * size, 1e-9).is_empty())
}

#[test]
fn every_level_of_far_views_stays_within_its_budget_coarser_than_the_next_with_the_childrens_sea() {
    let dir = tempfile::tempdir().unwrap();
    // The tile over Monaco at each level, finest first.
    let levels = [
        "14/8529/5974",
        "13/4264/2987",
        "12/2132/1493",
        "10/533/373",
        "8/133/93",
    ];
    let mut buildings_before = usize::MAX;
    for (k, tile) in levels.iter().enumerate() {
        let bytes = render(tile, "glb-meshopt", dir.path());
        let plain = decode(&render(tile, "glb", dir.path()));
        let triangles = triangles(&plain);
        let buildings = plain
            .features
            .iter()
            .filter(|f| f.class == "building")
            .count();
        eprintln!(
            "{tile}: {} bytes with meshopt, {triangles} triangles, {buildings} buildings",
            bytes.len()
        );
        if k == 0 {
            buildings_before = buildings;
            continue;
        }
        assert!(
            bytes.len() <= PARENT_BUDGET,
            "{tile} takes {} bytes",
            bytes.len()
        );
        assert!(triangles > 0, "{tile} is empty");
        // Blocks merge buildings: each level has fewer than the one below it (none at 8).
        assert!(
            buildings < buildings_before || buildings == 0,
            "{tile} has {buildings} buildings, the level below {buildings_before}"
        );
        buildings_before = buildings;
        // The sea where the zoom-14 tiles find it, none on the land between coast and hills.
        for (place, sea) in [(LAND_WEST, false), (LAND_EAST, false), (SEA_SOUTH, true)] {
            if let Some(found) = water_at(tile, &plain, place) {
                assert_eq!(found, sea, "{tile}: water at {place:?}: {found}");
            }
        }
        // Blocks have flat roofs: each block's upward faces lie at one height.
        let mut roofs: std::collections::BTreeMap<u32, (f32, f32)> = Default::default();
        for primitive in plain.primitives("building") {
            for [a, b, c] in primitive.triangles() {
                let [p, q, r] = [a, b, c].map(|i| primitive.positions[i]);
                let u = [q[0] - p[0], q[1] - p[1], q[2] - p[2]];
                let v = [r[0] - p[0], r[1] - p[1], r[2] - p[2]];
                let n = [
                    u[1] * v[2] - u[2] * v[1],
                    u[2] * v[0] - u[0] * v[2],
                    u[0] * v[1] - u[1] * v[0],
                ];
                let length = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                if length == 0.0 || n[1] / length < 0.999 {
                    continue;
                }
                let feature = primitive.feature_ids[a];
                // Heights in the flat frame are scaled by the Mercator factor at each vertex.
                let y = [p, q, r]
                    .map(|v| height_m(tile, &plain, v))
                    .into_iter()
                    .fold(f64::MIN, f64::max) as f32;
                let entry = roofs.entry(feature).or_insert((y, y));
                *entry = (entry.0.min(y), entry.1.max(y));
            }
        }
        assert_eq!(
            !roofs.is_empty(),
            buildings > 0,
            "{tile}: roofs of {buildings} blocks"
        );
        for (feature, (low, high)) in roofs {
            assert!(
                high - low < 0.01,
                "{tile}: block {feature} has level faces from {low} to {high} m"
            );
        }
    }
    assert_eq!(buildings_before, 0, "buildings drawn at zoom 8");
}
