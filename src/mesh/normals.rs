//! A unit normal for every ground vertex, from the gradient of the settled ground by central
//! differences. A vertex on the tile's edge takes the terrain's gradient instead: the settled
//! ground beyond the edge depends on features this tile does not hold, the terrain does not, so
//! a vertex on a shared edge gets the same normal in both tiles.

use super::ground::Ground;
use super::normalize;
use crate::terrain::Elevation;
use crate::tile::TileFrame;

/// The distance used for the central differences, in local metres, at zoom
/// [`NORMAL_STEP_ZOOM`] and above; it doubles with each coarser level, as the mesh does.
const NORMAL_STEP_M: f64 = 10.0;
const NORMAL_STEP_ZOOM: u8 = 14;

/// The normal of each of `ground`'s vertices in the local frame (x east, y up, z south).
pub fn ground_normals(
    ground: &Ground,
    frame: &TileFrame,
    terrain: &dyn Elevation,
    settled: &dyn Elevation,
) -> Vec<[f64; 3]> {
    normals_at(&ground.vertices, frame, terrain, settled)
}

/// The normals at `vertices` (local metres): the settled ground's gradient, the terrain's on
/// the tile's edge.
pub fn normals_at(
    vertices: &[[f64; 2]],
    frame: &TileFrame,
    terrain: &dyn Elevation,
    settled: &dyn Elevation,
) -> Vec<[f64; 3]> {
    let zoom = frame.tile.z;
    let step = NORMAL_STEP_M * 2f64.powi(i32::from(NORMAL_STEP_ZOOM.saturating_sub(zoom)));
    let size = frame.size_m;
    vertices
        .iter()
        .map(|&[x, z]| {
            let on_edge = x == 0.0 || z == 0.0 || x == size || z == size;
            let model: &dyn Elevation = if on_edge { terrain } else { settled };
            let height_at = |x: f64, z: f64| {
                let (u, v) = frame.local_to_uv(x, z);
                frame.elevation_to_y(model.elevation_uv([u, v]), z)
            };
            let h = step;
            let dy_dx = (height_at(x + h, z) - height_at(x - h, z)) / (2.0 * h);
            let dy_dz = (height_at(x, z + h) - height_at(x, z - h)) / (2.0 * h);
            normalize([-dy_dx, 1.0, -dy_dz]).unwrap_or([0.0, 1.0, 0.0])
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tile::TileId;
    use std::cell::Cell;

    /// Rolling ground that counts its reads: not to be shared between threads.
    struct Rolling {
        reads: Cell<usize>,
    }

    impl Elevation for Rolling {
        fn elevation_uv(&self, p: [f64; 2]) -> f64 {
            self.reads.set(self.reads.get() + 1);
            100.0 * (p[0] * 40.0).sin() * (p[1] * 30.0).cos()
        }
    }

    #[test]
    fn normals_spread_over_threads_are_the_normals_of_one_thread() {
        let frame = TileId {
            z: 14,
            x: 8529,
            y: 5974,
        }
        .frame();
        let size = frame.size_m;
        let vertices: Vec<[f64; 2]> = (0..5000)
            .map(|k| {
                let t = f64::from(k) / 5000.0;
                [size * t, size * ((t * 37.0).fract())]
            })
            .chain([[0.0, 0.0], [size, size / 2.0]])
            .collect();
        let ground = Ground {
            vertices,
            ..Ground::default()
        };
        let one = Rolling {
            reads: Cell::new(0),
        };
        let alone = ground_normals(&ground, &frame, &one, &one);
        for threads in [2, 3, 7] {
            // Each thread with a model of its own, as a render shares them out.
            let spread = crate::parallel::map_chunks(&ground.vertices, threads, &|chunk| {
                let own = Rolling {
                    reads: Cell::new(0),
                };
                normals_at(chunk, &frame, &own, &own)
            });
            assert_eq!(spread, alone, "{threads} threads");
        }
        assert!(
            alone.iter().any(|n| n[0].abs() > 0.01),
            "the ground is not flat"
        );
    }
}
