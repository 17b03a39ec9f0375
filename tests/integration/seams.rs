//! Seamless tile edges: neighbouring tiles, each rendered in its own process, share exactly the
//! same edge vertices (bit-identical after translation by the tile size, no T-junctions).

use crate::common;

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use common::{
    along_side, decode, ground_edge as edge, render_afresh, render_in_process, repo, DecodedTile,
};

/// The ten Monaco tiles inside both the extract and N43E007, and the Ulm tile across the
/// N48E009/N48E010 seam with its neighbours.
fn monaco_tiles() -> Vec<(u32, u32)> {
    (8527..=8531)
        .flat_map(|x| (5973..=5974).map(move |y| (x, y)))
        .collect()
}

fn ulm_tiles() -> Vec<(u32, u32)> {
    vec![
        (8646, 5668),
        (8647, 5668),
        (8648, 5668),
        (8647, 5667),
        (8647, 5669),
    ]
}

/// A tile rendered with `srtm`: as first made in this run, or (`afresh`) in a new process.
fn render(tile: (u32, u32), srtm: &Path, out: &Path, afresh: bool) -> Vec<u8> {
    let tile = format!("14/{}/{}", tile.0, tile.1);
    let args = ["--srtm".as_ref(), srtm.as_os_str()];
    match afresh {
        true => render_afresh(&tile, &args, out),
        false => render_in_process(&tile, &args, out),
    }
}

/// Vertices of bridges, tunnels, painted lines, sidewalks and verges on one side of a tile,
/// as bit patterns of (y, along): a deck, a tube, a line or a sidewalk crossing the edge is
/// cut at the same points in both tiles.
fn structure_edge(tile: &DecodedTile, side: &str) -> BTreeSet<(u32, u32)> {
    let size = tile.tile_size() as f32;
    let mut vertices = BTreeSet::new();
    for node in ["bridge", "tunnel", "marking", "roadside"] {
        for primitive in tile.primitives(node) {
            for p in &primitive.positions {
                if let Some(along) = along_side(p, side, size) {
                    vertices.insert((p[1].to_bits(), along.to_bits()));
                }
            }
        }
    }
    vertices
}

/// Checks every pair of neighbours; returns how many pairs there were and how many bridge
/// and tunnel vertices their shared edges hold.
fn check_pairs(tiles: &BTreeMap<(u32, u32), DecodedTile>) -> (usize, usize) {
    let mut pairs = 0;
    let mut structure_vertices = 0;
    for (&(x, y), tile) in tiles {
        for (neighbour, mine, theirs) in
            [((x + 1, y), "east", "west"), ((x, y + 1), "south", "north")]
        {
            let Some(other) = tiles.get(&neighbour) else {
                continue;
            };
            let a = edge(tile, mine);
            let b = edge(other, theirs);
            assert!(
                a.len() >= 2,
                "{x}/{y} has {} vertices on its {mine} edge",
                a.len()
            );
            let only_a: Vec<_> = a.difference(&b).take(3).collect();
            let only_b: Vec<_> = b.difference(&a).take(3).collect();
            assert!(
                a == b,
                "14/{x}/{y} {mine} edge ({} vertices) differs from 14/{}/{} {theirs} edge ({}): only in the first {:?}, only in the second {:?}",
                a.len(),
                neighbour.0,
                neighbour.1,
                b.len(),
                only_a,
                only_b
            );
            let (a, b) = (structure_edge(tile, mine), structure_edge(other, theirs));
            assert!(
                a == b,
                "14/{x}/{y} {mine} edge's bridges and tunnels ({} vertices) differ from 14/{}/{}'s ({}): only in the first {:?}, only in the second {:?}",
                a.len(),
                neighbour.0,
                neighbour.1,
                b.len(),
                a.difference(&b).take(3).collect::<Vec<_>>(),
                b.difference(&a).take(3).collect::<Vec<_>>()
            );
            structure_vertices += a.len();
            pairs += 1;
        }
    }
    eprintln!("{structure_vertices} bridge and tunnel vertices on shared edges");
    (pairs, structure_vertices)
}

/// Decoded tiles and their bytes, by tile.
type Rendered = (
    BTreeMap<(u32, u32), DecodedTile>,
    BTreeMap<(u32, u32), Vec<u8>>,
);

fn render_all(tiles: &[(u32, u32)], srtm: &Path, afresh: bool) -> Rendered {
    let dir = tempfile::tempdir().unwrap();
    let mut decoded = BTreeMap::new();
    let mut bytes = BTreeMap::new();
    for &tile in tiles {
        let glb = render(tile, srtm, dir.path(), afresh);
        decoded.insert(tile, decode(&glb));
        bytes.insert(tile, glb);
    }
    (decoded, bytes)
}

/// Renders the tiles in both orders and checks their shared edges; returns the bridge and
/// tunnel vertices on them.
fn check_region(tiles: Vec<(u32, u32)>, srtm: PathBuf, expected_pairs: usize) -> usize {
    let (forward, forward_bytes) = render_all(&tiles, &srtm, false);
    // Made again in other processes, in the other order: the same bytes.
    let reversed: Vec<_> = tiles.iter().rev().copied().collect();
    let (_, reverse_bytes) = render_all(&reversed, &srtm, true);
    assert_eq!(forward_bytes, reverse_bytes, "render order changed a tile");
    let (pairs, structure_vertices) = check_pairs(&forward);
    assert_eq!(pairs, expected_pairs);
    structure_vertices
}

#[test]
fn monaco_neighbours_share_their_edges_exactly() {
    let structure_vertices = check_region(monaco_tiles(), repo().join("data"), 13);
    // Monaco's tunnels and bridges cross these tiles' edges: the structures' seams are tested.
    assert!(
        structure_vertices > 0,
        "no bridge or tunnel crosses an edge"
    );
}

#[test]
fn tiles_across_two_srtm_files_share_their_edges_exactly() {
    check_region(ulm_tiles(), repo().join("tests/data"), 4);
}

/// The SRTM3 sample of an `.hgt` file nearest to a point.
fn hgt_sample(hgt: &[u8], cell: (f64, f64), lon: f64, lat: f64) -> f64 {
    let row = ((cell.1 + 1.0 - lat) * 1200.0).round() as usize;
    let column = ((lon - cell.0) * 1200.0).round() as usize;
    let k = 2 * (row * 1201 + column);
    f64::from(i16::from_be_bytes([hgt[k], hgt[k + 1]]))
}

/// The tiles rendered from `extract` over the Ulm SRTM files, each in its own process.
fn render_with(
    extract: &Path,
    tiles: &[(u32, u32)],
    out: &Path,
) -> BTreeMap<(u32, u32), DecodedTile> {
    let srtm = repo().join("tests/data");
    let args = [
        "--osm".as_ref(),
        extract.as_os_str(),
        "--srtm".as_ref(),
        srtm.as_os_str(),
    ];
    tiles
        .iter()
        .map(|&(x, y)| {
            let glb = render_in_process(&format!("14/{x}/{y}"), &args, out);
            ((x, y), decode(&glb))
        })
        .collect()
}

#[test]
fn a_river_across_two_srtm_files_runs_at_the_same_level_in_tiles_that_read_one_or_both() {
    // A river flowing east across 10° E, from N48E009 into N48E010: 14/8647/5668 straddles the
    // two files, 14/8648/5668 (east of it) lies in N48E010 alone, but the river's fall is
    // found along the whole way.
    let (west, east, lat) = (9.985, 10.035, 48.3925);
    let dir = tempfile::tempdir().unwrap();
    let extract = dir.path().join("river.osm.pbf");
    common::write_extract(
        &serde_json::json!([{
            "tags": {"waterway": "river", "name": "Across"},
            "nodes": [[west, lat], [9.999, lat + 0.001], [10.002, lat - 0.001], [east, lat]],
        }]),
        &extract,
    );
    let srtm = repo().join("tests/data");
    let tiles = render_with(&extract, &[(8647, 5668), (8648, 5668)], dir.path());
    assert_eq!(check_pairs(&tiles).0, 1);
    // No vertex of the river's water below the lowest ground along it (SRTM samples every
    // 20 m of the line; the terrain between samples may dip a little below them).
    let files = [
        (
            (9.0, 48.0),
            std::fs::read(srtm.join("N48E009.hgt")).unwrap(),
        ),
        (
            (10.0, 48.0),
            std::fs::read(srtm.join("N48E010.hgt")).unwrap(),
        ),
    ];
    let lowest_ground = (0..=200)
        .map(|k| west + (east - west) * f64::from(k) / 200.0)
        .map(|lon| {
            let (cell, hgt) = &files[usize::from(lon >= 10.0)];
            hgt_sample(hgt, *cell, lon, lat)
        })
        .fold(f64::INFINITY, f64::min);
    let scale = lat.to_radians().cos();
    for ((x, y), tile) in &tiles {
        let water: Vec<f64> = tile
            .primitives("water")
            .iter()
            .flat_map(|p| p.positions.iter().map(|v| f64::from(v[1]) * scale))
            .collect();
        assert!(!water.is_empty(), "14/{x}/{y} draws the river");
        let low = water.iter().copied().fold(f64::INFINITY, f64::min);
        assert!(
            low > lowest_ground - 5.0,
            "14/{x}/{y}: the river's water reaches down to {low:.1} m, the ground along it no lower than {lowest_ground:.1} m"
        );
    }
}

/// A river's area (its riverbank mapped round the river, east across 10° E on real SRTM):
/// seamless across the tiles, its water never rising downstream along the river and level
/// across it (points of the water at one station along the river within 1 cm).
#[test]
fn a_river_area_runs_down_along_its_river_and_lies_level_across_it() {
    let (west, east, lat) = (9.985, 10.035, 48.3925);
    let river = [
        [west, lat],
        [9.999, lat + 0.001],
        [10.002, lat - 0.001],
        [east, lat],
    ];
    let side = |offset: f64| river.iter().map(move |p| [p[0], p[1] + offset]);
    let mut bank: Vec<[f64; 2]> = side(0.0004).collect();
    bank.extend(side(-0.0004).rev());
    bank.push(bank[0]);
    let dir = tempfile::tempdir().unwrap();
    let extract = dir.path().join("riverbank.osm.pbf");
    common::write_extract(
        &serde_json::json!([
            {"tags": {"waterway": "river", "name": "Across"}, "nodes": river},
            {"tags": {"waterway": "riverbank"}, "nodes": bank},
        ]),
        &extract,
    );
    let tiles = render_with(
        &extract,
        &[(8646, 5668), (8647, 5668), (8648, 5668)],
        dir.path(),
    );
    assert_eq!(check_pairs(&tiles).0, 2);
    // Each vertex of the water at its station along the river (global tile units).
    let projection = terrastitch::features::Projection::new(14);
    let line: Vec<[f64; 2]> = river
        .iter()
        .map(|p| {
            projection.point(terrastitch::osm::LonLat {
                lon: p[0],
                lat: p[1],
            })
        })
        .collect();
    let stations = terrastitch::elevation::settled::Stations::new(&line);
    let mut water: Vec<(f64, f64)> = Vec::new();
    for (&(x, y), tile) in &tiles {
        let frame = terrastitch::TileId { z: 14, x, y }.frame();
        for primitive in tile.primitives("water") {
            for p in &primitive.positions {
                let (u, v) = frame.local_to_uv(f64::from(p[0]), f64::from(p[2]));
                let metres = f64::from(p[1]) / frame.scale_at(f64::from(p[2]));
                water.push((stations.at([u, v]), metres));
            }
        }
    }
    assert!(water.len() > 20, "only {} water vertices", water.len());
    water.sort_by(|a, b| a.0.total_cmp(&b.0));
    let metre = projection.metres(1.0, lat);
    let mut upstream_low = f64::INFINITY;
    let mut across = 0;
    for (k, &(station, h)) in water.iter().enumerate() {
        assert!(
            h <= upstream_low + 0.01,
            "the water rises to {h:.3} m at {:.1} m along the river, {upstream_low:.3} m upstream",
            station / metre
        );
        upstream_low = upstream_low.min(h);
        for &(other, g) in &water[k + 1..] {
            if other - station > 0.05 * metre {
                break;
            }
            across += 1;
            assert!(
                (g - h).abs() <= 0.01,
                "across the river at {:.1} m: {h:.3} and {g:.3} m",
                station / metre
            );
        }
    }
    let (low, high) = (water[water.len() - 1].1, water[0].1);
    eprintln!(
        "{} water vertices from {high:.2} m down to {low:.2} m, {across} pairs across",
        water.len()
    );
    assert!(across > 0, "no two water vertices across the river");
    // The ground falls by some metres along the river's first few hundred metres.
    assert!(high - low > 3.0, "the water lies flat at {low:.2} m");
}
