//! The adaptive ground of real tiles meets its error bound: every terrain sample lies within
//! `max_error_m` of the ground triangulation, checked by locating each sample in the final
//! triangles (independently of the refinement's own bookkeeping); and the ground covers the tile
//! exactly once.

use crate::common;

use std::collections::HashMap;

use common::{sample_osm, sample_srtm, GroundLocator};
use terrastitch::features;
use terrastitch::mesh::ground::{self, MeshSettings};
use terrastitch::provider::Inputs;
use terrastitch::terrain::{Interpolation, TerrainModel};
use terrastitch::TileId;

#[test]
fn every_sample_of_the_steepest_and_densest_tiles_is_within_the_bound() {
    let sources = Inputs::open(&[sample_osm()], &sample_srtm(), 14).expect("sample data");
    let settings = MeshSettings::default();
    for (x, y) in [(8527, 5974), (8529, 5973), (8529, 5974)] {
        let tile = TileId { z: 14, x, y };
        let frame = tile.frame();
        let mosaic = sources.mosaic(tile).unwrap();
        let terrain = TerrainModel::new(&mosaic, Interpolation::LeastSquares, 14);
        let selection = common::selection(&sources, tile);
        let feature_set = features::collect(&selection, tile, &Default::default());
        let ground = ground::triangulate(
            &frame,
            &settings,
            &feature_set.surfaces,
            &feature_set.nearby_outlines,
            &terrain,
            &|points| points.iter().map(|&p| terrain.elevation_uv(p)).collect(),
        )
        .unwrap();
        // Heights here are plain elevations (the locator interpolates whatever y it is given).
        let triangles: Vec<[[f64; 3]; 3]> = ground
            .triangles
            .iter()
            .map(|t| {
                t.vertices.map(|i| {
                    let [px, pz] = ground.vertices[i as usize];
                    [px, ground.elevations[i as usize], pz]
                })
            })
            .collect();
        let locator = GroundLocator::new(triangles, frame.size_m);
        let n = settings.sample_cells as usize;
        let mut worst: f64 = 0.0;
        let mut located = 0;
        for j in 0..=n {
            for i in 0..=n {
                let (u, v) = (
                    f64::from(x) + i as f64 / n as f64,
                    f64::from(y) + j as f64 / n as f64,
                );
                let (lx, lz) = frame.uv_to_local(u, v);
                let sample = terrain.elevation_uv([u, v]);
                let heights = locator.heights_at(lx, lz, 1e-7);
                if heights.is_empty() {
                    continue;
                }
                located += 1;
                for h in heights {
                    worst = worst.max((h - sample).abs());
                }
            }
        }
        assert!(
            located as f64 > 0.999 * ((n + 1) * (n + 1)) as f64,
            "{tile}: located only {located} samples"
        );
        assert!(
            worst <= settings.max_error_m + 1e-6,
            "{tile}: a sample is {worst} m from the ground"
        );
        assert!(
            ground.inserted > 100,
            "{tile}: only {} samples inserted",
            ground.inserted
        );

        // The ground partition: every triangle faces up (so none folds over another) and they
        // add up to the tile, building footprints included, within 0.1 %; each belongs to one
        // surface of a ground class, or to the default ground.
        let mut area = 0.0;
        for t in &ground.triangles {
            let [a, b, c] = t.vertices.map(|i| ground.vertices[i as usize]);
            let doubled = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
            assert!(
                doubled > 0.0,
                "{tile}: a triangle is folded over ({doubled})"
            );
            area += doubled / 2.0;
            if let Some(s) = t.surface {
                assert!(
                    feature_set.surfaces[s as usize].class.ground_priority() < 6,
                    "{tile}: a triangle of a class that is not ground"
                );
            }
        }
        let square = frame.size_m * frame.size_m;
        assert!(
            (area - square).abs() < 1e-3 * square,
            "{tile}: the ground covers {area} of {square}"
        );
    }
}

/// The ground of the ten Monaco tiles, as the glb draws it, is a partition of the tile:
/// with the buildings' floors (not the ceilings over roads through them) it covers random
/// points once (at most 0.01 % uncovered and
/// 0.01 % covered twice), and wherever an edge of a ground triangle has no neighbour inside
/// the tile (a sliver too thin for `f32` left out, or a point where the ground steps) the
/// ground beside it passes within 1 cm of its corners: no crack opens in it.
#[test]
fn ground_and_building_floors_cover_each_tile_once_without_cracks() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    for (x, y) in common::MONACO_TILES {
        let name = format!("14/{x}/{y}");
        let tile = common::decode(&common::render_in_process(&name, &[], dir.path()));
        let size = tile.tile_size();
        let ground: Vec<_> = common::GROUND_NODES
            .iter()
            .flat_map(|node| common::corners(tile.primitives(node)))
            .collect();
        let floors: Vec<_> = common::corners(tile.primitives("building"))
            .into_iter()
            .filter(faces_down)
            .collect();
        let (uncovered, twice) = coverage(&ground, &floors, size, 200_000);
        assert!(
            uncovered <= 1e-4 && twice <= 1e-4,
            "{name}: {:.4} % uncovered, {:.4} % covered twice",
            uncovered * 100.0,
            twice * 100.0
        );
        let cracks = Cracks::of(&ground, &floors, size);
        assert!(
            cracks.unexplained == 0 && cracks.widest_m <= 0.01,
            "{name}: of {} open edges, {} bound a hole; the widest crack is {:.3} m",
            cracks.open_edges,
            cracks.unexplained,
            cracks.widest_m
        );
    }
}

/// The shares of random points of a tile under no ground triangle or floor, and under two.
fn coverage(
    ground: &[[[f64; 3]; 3]],
    floors: &[[[f64; 3]; 3]],
    size: f64,
    samples: usize,
) -> (f64, f64) {
    let (ground, floors) = (
        GroundLocator::new(ground.to_vec(), size),
        GroundLocator::new(floors.to_vec(), size),
    );
    let mut seed = 0x2545_f491_4f6c_dd1d_u64;
    let mut next = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    let (mut uncovered, mut twice) = (0, 0);
    for _ in 0..samples {
        let (px, pz) = (next() * size, next() * size);
        // Floors of parts standing on other parts may lie over each other: one counts. A
        // ceiling over a road through a building, 2 m or more over the ground drawn there,
        // covers nothing of the ground.
        let drawn = ground.heights_at(px, pz, 0.0);
        let lowest = drawn.iter().copied().fold(f64::INFINITY, f64::min);
        let under_floor = floors
            .heights_at(px, pz, 0.0)
            .into_iter()
            .filter(|&h| h < lowest + 2.0)
            .count()
            .min(1);
        match drawn.len() + under_floor {
            0 => uncovered += 1,
            1 => {}
            _ => twice += 1,
        }
    }
    (
        uncovered as f64 / samples as f64,
        twice as f64 / samples as f64,
    )
}

/// The edges of a tile's ground triangles that no other ground triangle shares, leaving out
/// the tile's border and the buildings' floors: each should lie along another such edge or
/// have one lying along it (both corners on it, in plan), where a triangle too thin to draw
/// was left out; `widest_m` is the largest height between such a corner and the edge it lies
/// on, the width of the crack there. `unexplained` counts the edges that bound a hole.
struct Cracks {
    open_edges: usize,
    unexplained: usize,
    widest_m: f64,
}

impl Cracks {
    fn of(ground: &[[[f64; 3]; 3]], floors: &[[[f64; 3]; 3]], size: f64) -> Cracks {
        type Key = [u32; 3];
        let key = |p: [f64; 3]| p.map(|v| (v as f32).to_bits());
        let point = |k: Key| k.map(|v| f64::from(f32::from_bits(v)));
        let undirected = |a: Key, b: Key| if a < b { [a, b] } else { [b, a] };
        let mut uses: HashMap<[Key; 2], usize> = HashMap::new();
        for t in ground {
            for k in 0..3 {
                *uses
                    .entry(undirected(key(t[k]), key(t[(k + 1) % 3])))
                    .or_default() += 1;
            }
        }
        // A floor's outline may leave out a point the ground's keeps (three in a line).
        let floor_edges: Vec<[[f64; 3]; 2]> = floors
            .iter()
            .flat_map(|t| (0..3).map(move |k| [t[k], t[(k + 1) % 3]]))
            .collect();
        let floor_grid =
            GroundLocator::new(floor_edges.iter().map(|&[a, b]| [a, b, b]).collect(), size);
        let along_a_floor = |a: [f64; 3], b: [f64; 3]| {
            floor_grid.near(a, b).into_iter().any(|i| {
                let [p, q] = floor_edges[i];
                height_beside(p, q, a).is_some() && height_beside(p, q, b).is_some()
            })
        };
        let on_border = |k: Key| {
            let p = point(k);
            p[0] <= 1e-3 || p[2] <= 1e-3 || p[0] >= size - 1e-3 || p[2] >= size - 1e-3
        };
        let open: Vec<[Key; 2]> = uses
            .iter()
            .filter(|&(e, &n)| n == 1 && !(on_border(e[0]) && on_border(e[1])))
            .map(|(e, _)| *e)
            .filter(|e| !along_a_floor(point(e[0]), point(e[1])))
            .collect();
        let segments: Vec<[[f64; 3]; 2]> = open.iter().map(|e| e.map(point)).collect();
        let grid = GroundLocator::new(segments.iter().map(|&[a, b]| [a, b, b]).collect(), size);
        let mut explained = vec![false; segments.len()];
        let mut widest_m: f64 = 0.0;
        for (i, &[a, b]) in segments.iter().enumerate() {
            // Each edge that lies along this one, both its corners on it in plan.
            for j in grid.near(a, b).into_iter().filter(|&j| j != i) {
                let [p, q] = segments[j];
                if let (Some(hp), Some(hq)) = (height_beside(a, b, p), height_beside(a, b, q)) {
                    widest_m = widest_m.max(hp).max(hq);
                    explained[i] = true;
                    explained[j] = true;
                }
            }
        }
        Cracks {
            open_edges: open.len(),
            unexplained: explained.iter().filter(|e| !**e).count(),
            widest_m,
        }
    }
}

/// The height between `m` and the edge `a`–`b` where `m` lies along it in plan (within a
/// millimetre of the segment), or `None` when it does not.
fn height_beside(a: [f64; 3], b: [f64; 3], m: [f64; 3]) -> Option<f64> {
    let (dx, dz) = (b[0] - a[0], b[2] - a[2]);
    let length2 = dx * dx + dz * dz;
    let t = if length2 > 0.0 {
        (((m[0] - a[0]) * dx + (m[2] - a[2]) * dz) / length2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let (px, pz) = (a[0] + t * dx, a[2] + t * dz);
    let off = ((m[0] - px).powi(2) + (m[2] - pz).powi(2)).sqrt();
    (off <= 1e-3).then(|| (m[1] - (a[1] + t * (b[1] - a[1]))).abs())
}

/// Whether a triangle faces more down than sideways: a floor or a ceiling, not a wall. A wall
/// at one elevation along its top is not quite vertical in the tile's flat frame, whose up
/// leans away from the centre with the earth's curvature, so the sign of its plan area alone
/// does not tell.
fn faces_down(t: &[[f64; 3]; 3]) -> bool {
    let [a, b, c] = t;
    let (u, v) = (
        [b[0] - a[0], b[1] - a[1], b[2] - a[2]],
        [c[0] - a[0], c[1] - a[1], c[2] - a[2]],
    );
    let normal = [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ];
    let length = normal.iter().map(|n| n * n).sum::<f64>().sqrt();
    length > 0.0 && normal[1] < -0.5 * length
}
