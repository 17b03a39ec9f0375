//! Seamless tile edges: neighbouring tiles, each rendered in its own process, share exactly the
//! same edge vertices (bit-identical after translation by the tile size, no T-junctions).

mod common;

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use common::{decode, render_in_process, repo, DecodedTile, GROUND_NODES};

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

fn render(tile: (u32, u32), srtm: &Path, out: &Path) -> Vec<u8> {
    let tile = format!("14/{}/{}", tile.0, tile.1);
    render_in_process(&tile, &["--srtm".as_ref(), srtm.as_os_str()], out)
}

/// Where along a side of a tile of `size` a vertex lies, if it is on that side.
fn along_side(p: &[f32; 3], side: &str, size: f32) -> Option<f32> {
    let (on_side, along) = match side {
        "west" => (p[0] == 0.0, p[2]),
        "east" => (p[0] == size, p[2]),
        "north" => (p[2] == 0.0, p[0]),
        "south" => (p[2] == size, p[0]),
        _ => unreachable!(),
    };
    on_side.then_some(along)
}

/// Ground vertices (every ground class) on one side of a tile, as bit patterns of
/// (y, along, normal): a normal that differs would show as a lighting seam.
fn edge(tile: &DecodedTile, side: &str) -> BTreeSet<(u32, u32, [u32; 3])> {
    let size = tile.tile_size() as f32;
    let mut vertices = BTreeSet::new();
    for node in GROUND_NODES {
        for primitive in tile.primitives(node) {
            for (p, normal) in primitive.positions.iter().zip(&primitive.normals) {
                if let Some(along) = along_side(p, side, size) {
                    vertices.insert((p[1].to_bits(), along.to_bits(), normal.map(f32::to_bits)));
                }
            }
        }
    }
    vertices
}

/// Vertices of bridges and tunnels on one side of a tile, as bit patterns of (y, along):
/// a deck or tube crossing the edge is cut at the same points in both tiles.
fn structure_edge(tile: &DecodedTile, side: &str) -> BTreeSet<(u32, u32)> {
    let size = tile.tile_size() as f32;
    let mut vertices = BTreeSet::new();
    for node in ["bridge", "tunnel"] {
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

fn check_pairs(tiles: &BTreeMap<(u32, u32), DecodedTile>) -> usize {
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
    pairs
}

/// Decoded tiles and their bytes, by tile.
type Rendered = (
    BTreeMap<(u32, u32), DecodedTile>,
    BTreeMap<(u32, u32), Vec<u8>>,
);

fn render_all(tiles: &[(u32, u32)], srtm: &Path) -> Rendered {
    let dir = tempfile::tempdir().unwrap();
    let mut decoded = BTreeMap::new();
    let mut bytes = BTreeMap::new();
    for &tile in tiles {
        let glb = render(tile, srtm, dir.path());
        decoded.insert(tile, decode(&glb));
        bytes.insert(tile, glb);
    }
    (decoded, bytes)
}

fn check_region(tiles: Vec<(u32, u32)>, srtm: PathBuf, expected_pairs: usize) {
    let (forward, forward_bytes) = render_all(&tiles, &srtm);
    let reversed: Vec<_> = tiles.iter().rev().copied().collect();
    let (_, reverse_bytes) = render_all(&reversed, &srtm);
    assert_eq!(forward_bytes, reverse_bytes, "render order changed a tile");
    assert_eq!(check_pairs(&forward), expected_pairs);
}

#[test]
fn monaco_neighbours_share_their_edges_exactly() {
    check_region(monaco_tiles(), repo().join("data"), 13);
}

#[test]
fn tiles_across_two_srtm_files_share_their_edges_exactly() {
    check_region(ulm_tiles(), repo().join("tests/data"), 4);
}
