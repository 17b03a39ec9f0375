//! A unit normal for every ground vertex. Inside the tile it is the mean of the normals of the
//! triangles around the vertex, each weighted by its area as seen from above, so the shading
//! follows the ground as it is drawn, and a steep narrow triangle (the face of a step the
//! ground takes at a wall or a cut) turns the normals of the flat ground beside it little. A
//! vertex on the tile's edge takes the terrain's gradient by central differences instead: the
//! triangles beyond the edge are the neighbour's, and depend on features this tile does not
//! hold, the terrain does not, so a vertex on a shared edge gets the same normal in both tiles.

use super::ground::Ground;
use super::{dot, normalize, triangle_normal};
use crate::terrain::Elevation;
use crate::tile::TileFrame;

/// The distance used for the central differences, in local metres, at zoom
/// [`NORMAL_STEP_ZOOM`] and above; it doubles with each coarser level, as the mesh does.
const NORMAL_STEP_M: f64 = 10.0;
const NORMAL_STEP_ZOOM: u8 = 14;

/// The normal of each of `ground`'s vertices in the local frame (x east, y up, z south): the
/// mean of its triangles' normals weighted by their areas seen from above, `terrain`'s gradient
/// on the tile's edge, up for a vertex no triangle uses.
pub fn ground_normals(
    ground: &Ground,
    frame: &TileFrame,
    terrain: &dyn Elevation,
) -> Vec<[f64; 3]> {
    let positions: Vec<[f64; 3]> = ground
        .vertices
        .iter()
        .zip(&ground.elevations)
        .map(|(&[x, z], &elevation)| [x, frame.elevation_to_y(elevation, z), z])
        .collect();
    let mut sums = vec![[0.0; 3]; positions.len()];
    for triangle in &ground.triangles {
        let [a, b, c] = triangle.vertices.map(|i| i as usize);
        let (Some(&pa), Some(&pb), Some(&pc)) =
            (positions.get(a), positions.get(b), positions.get(c))
        else {
            continue;
        };
        // Upward whichever way round its corners run, as long as twice the triangle's area
        // seen from above.
        let n = triangle_normal([pa, pb, pc]);
        let length = dot(n, n).sqrt();
        if length == 0.0 || !length.is_finite() {
            continue;
        }
        let n = n.map(|c| c * n[1] / length);
        for i in [a, b, c] {
            for (sum, c) in sums[i].iter_mut().zip(n) {
                *sum += c;
            }
        }
    }
    ground
        .vertices
        .iter()
        .zip(sums)
        .map(|(&vertex, sum)| {
            if frame.on_edge(vertex) {
                gradient_normal(vertex, frame, terrain)
            } else {
                normalize(sum).unwrap_or([0.0, 1.0, 0.0])
            }
        })
        .collect()
}

/// The normal of `model` at local `(x, z)` from its gradient by central differences.
fn gradient_normal([x, z]: [f64; 2], frame: &TileFrame, model: &dyn Elevation) -> [f64; 3] {
    let zoom = frame.tile.z;
    let h = NORMAL_STEP_M * 2f64.powi(i32::from(NORMAL_STEP_ZOOM.saturating_sub(zoom)));
    let height_at = |x: f64, z: f64| {
        let (u, v) = frame.local_to_uv(x, z);
        frame.elevation_to_y(model.elevation_uv([u, v]), z)
    };
    let dy_dx = (height_at(x + h, z) - height_at(x - h, z)) / (2.0 * h);
    let dy_dz = (height_at(x, z + h) - height_at(x, z - h)) / (2.0 * h);
    normalize([-dy_dx, 1.0, -dy_dz]).unwrap_or([0.0, 1.0, 0.0])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::ground::GroundTriangle;
    use crate::tile::TileId;

    /// Ground sloping up to the east, `slope` metres a metre.
    struct Sloping {
        frame: TileFrame,
        slope: f64,
    }

    impl Elevation for Sloping {
        fn elevation_uv(&self, p: [f64; 2]) -> f64 {
            let (x, _) = self.frame.uv_to_local(p[0], p[1]);
            100.0 + self.slope * x
        }
    }

    fn frame() -> TileFrame {
        TileId {
            z: 14,
            x: 8529,
            y: 5974,
        }
        .frame()
    }

    /// A square grid of `n` × `n` cells over the whole tile, elevations from `terrain`.
    fn grid(frame: &TileFrame, n: u32, terrain: &dyn Elevation) -> Ground {
        let size = frame.size_m;
        let mut ground = Ground::default();
        for j in 0..=n {
            for i in 0..=n {
                let [x, z] = [i, j].map(|k| size * f64::from(k) / f64::from(n));
                let (u, v) = frame.local_to_uv(x, z);
                ground.vertices.push([x, z]);
                ground.elevations.push(terrain.elevation_uv([u, v]));
            }
        }
        let at = |i: u32, j: u32| j * (n + 1) + i;
        for j in 0..n {
            for i in 0..n {
                for vertices in [
                    [at(i, j), at(i, j + 1), at(i + 1, j)],
                    [at(i + 1, j), at(i, j + 1), at(i + 1, j + 1)],
                ] {
                    ground.triangles.push(GroundTriangle {
                        vertices,
                        surface: None,
                    });
                }
            }
        }
        ground
    }

    #[test]
    fn a_plane_has_the_planes_normal_at_every_vertex() {
        let frame = frame();
        let terrain = Sloping { frame, slope: 0.25 };
        let ground = grid(&frame, 6, &terrain);
        let normals = ground_normals(&ground, &frame, &terrain);
        for ((&[_, z], n), e) in ground.vertices.iter().zip(&normals).zip(&ground.elevations) {
            let scale = frame.elevation_to_y(1.0, z);
            let expected = normalize([-0.25 * scale, 1.0, 0.0]).unwrap();
            let off = (0..3)
                .map(|k| (n[k] - expected[k]).abs())
                .fold(0.0, f64::max);
            assert!(off < 1e-3, "{n:?} against {expected:?} at elevation {e}");
        }
    }

    #[test]
    fn a_bump_inside_tilts_its_neighbours_but_not_the_edge() {
        let frame = frame();
        let terrain = Sloping { frame, slope: 0.0 };
        let flat = grid(&frame, 4, &terrain);
        let mut bumped = flat.clone();
        // Vertex (1, 2) rises: (2, 2) is beside it inside the tile, (0, 2) and (0, 3) beside
        // it on the western edge.
        bumped.elevations[11] += 300.0;
        let before = ground_normals(&flat, &frame, &terrain);
        let after = ground_normals(&bumped, &frame, &terrain);
        assert!(
            after[12][0] > 0.1,
            "the eastern neighbour leans east: {:?}",
            after[12]
        );
        assert!(
            after[6][2] < -0.1,
            "the northern neighbour leans north: {:?}",
            after[6]
        );
        for edge in [10, 15] {
            assert_eq!(after[edge], before[edge], "vertex {edge}");
            assert_eq!(
                after[edge],
                gradient_normal(flat.vertices[edge], &frame, &terrain)
            );
        }
    }

    #[test]
    fn a_steep_face_beside_flat_ground_turns_its_normal_little() {
        let frame = frame();
        let terrain = Sloping { frame, slope: 0.0 };
        let c = frame.size_m / 2.0;
        // Flat ground north-east of the vertex, a face rising 100 m over 17.6 m south-west of
        // it: their areas are about the same, the face's seen from above a sixth of the flat's.
        let ground = Ground {
            vertices: vec![
                [c, c],
                [c + 100.0, c],
                [c, c + 100.0],
                [c, c - 100.0],
                [c - 17.6, c - 50.0],
            ],
            elevations: vec![0.0, 0.0, 0.0, 0.0, 100.0],
            triangles: [[0, 1, 2], [0, 3, 4]]
                .map(|vertices| GroundTriangle {
                    vertices,
                    surface: None,
                })
                .to_vec(),
            ..Ground::default()
        };
        let normal = ground_normals(&ground, &frame, &terrain)[0];
        let tilt = normal[1].acos().to_degrees();
        assert!(
            (2.0..12.0).contains(&tilt),
            "{normal:?} leans {tilt} degrees"
        );
    }

    #[test]
    fn a_vertex_no_triangle_uses_points_up() {
        let frame = frame();
        let terrain = Sloping { frame, slope: 0.5 };
        let mut ground = grid(&frame, 2, &terrain);
        ground.triangles.clear();
        let normals = ground_normals(&ground, &frame, &terrain);
        assert_eq!(normals[4], [0.0, 1.0, 0.0]);
        assert!(
            normals[3][0] < -0.1,
            "an edge vertex keeps the terrain's slope"
        );
    }
}
