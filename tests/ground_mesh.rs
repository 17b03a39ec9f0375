//! The adaptive ground of real tiles meets its error bound: every terrain sample lies within
//! `max_error_m` of the ground triangulation, checked by locating each sample in the final
//! triangles (independently of the refinement's own bookkeeping); and the ground covers the tile
//! exactly once.

mod common;

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
