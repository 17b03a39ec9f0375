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
    let zoom = frame.tile.z;
    let step = NORMAL_STEP_M * 2f64.powi(i32::from(NORMAL_STEP_ZOOM.saturating_sub(zoom)));
    let size = frame.size_m;
    ground
        .vertices
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
