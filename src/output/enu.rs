//! A tile's geometry in a local east-north-up frame on the WGS 84 ellipsoid, for globe
//! viewers (3D Tiles): Web Mercator cannot be placed on a globe by one affine transform (the
//! scale changes with latitude and the ground curves away), so every vertex is carried through
//! longitude, latitude and height into a frame tangent to the ellipsoid at the tile's centre.
//!
//! The content stays glTF Y-up: `x` east, `y` up, `z` south of the centre, in metres. A 3D Tiles
//! runtime turns Y-up content to Z-up (`x`, `-z`, `y`) before it applies the tile's
//! [`EastNorthUp::transform`], which carries east-north-up into Earth-centred, Earth-fixed
//! coordinates. Heights are SRTM's (above the EGM96 geoid) used as heights above the ellipsoid,
//! so the tiles sit on a bare WGS 84 globe the way they sit at sea level in the flat frame; or,
//! with the `egm96` datum, heights above the ellipsoid (SRTM's plus the geoid's undulation at
//! each vertex), so they sit on a terrain in ellipsoid heights.

use std::collections::BTreeMap;

use crate::geodesy::{east_north_up, ecef, Vector};
use crate::geoid::VerticalDatum;
use crate::mesh::instances::Instances;
use crate::mesh::models::Model;
use crate::mesh::{MeshBuffers, Part};
use crate::tile::{TileFrame, TileId};

fn dot(a: Vector, b: Vector) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The east-north-up frame at a tile's centre, on the ellipsoid.
#[derive(Debug, Clone, Copy)]
pub struct EastNorthUp {
    frame: TileFrame,
    origin: Vector,
    /// East, north, up.
    axes: [Vector; 3],
    /// The tile's side in its flat frame, as written (f32): a vertex there is on the edge.
    edge_f32: f32,
    /// What heights are measured from.
    datum: VerticalDatum,
}

impl EastNorthUp {
    /// The frame, heights SRTM's.
    pub fn new(tile: TileId) -> EastNorthUp {
        EastNorthUp::in_datum(tile, VerticalDatum::Srtm)
    }

    /// The frame, heights measured from `datum`.
    pub fn in_datum(tile: TileId, datum: VerticalDatum) -> EastNorthUp {
        let frame = tile.frame();
        let half = frame.size_m / 2.0;
        let (lon, lat) = frame.to_lon_lat(half, half);
        EastNorthUp {
            frame,
            origin: ecef(lon, lat, 0.0),
            axes: east_north_up(lon, lat),
            edge_f32: frame.size_m as f32,
            datum,
        }
    }

    /// The tile transform of 3D Tiles: east-north-up to Earth-fixed, a 4×4 matrix in
    /// column-major order.
    pub fn transform(&self) -> [f64; 16] {
        let [e, n, u] = self.axes;
        let o = self.origin;
        [
            e[0], e[1], e[2], 0.0, n[0], n[1], n[2], 0.0, u[0], u[1], u[2], 0.0, o[0], o[1], o[2],
            1.0,
        ]
    }

    /// Flat-frame `x` or `z` as the tile's own metres, an edge vertex exactly on the edge (so
    /// neighbours, whose edges are written alike, carry it to the same place).
    fn exact(&self, v: f32) -> f64 {
        if v == self.edge_f32 {
            self.frame.size_m
        } else {
            f64::from(v)
        }
    }

    /// Longitude, latitude and height of a point of the flat frame.
    fn geodetic(&self, p: [f32; 3]) -> (f64, f64, f64) {
        let (x, z) = (self.exact(p[0]), self.exact(p[2]));
        let (lon, lat) = self.frame.to_lon_lat(x, z);
        let height = f64::from(p[1]) / self.frame.scale_at(z) + self.datum.offset(lon, lat);
        (lon, lat, height)
    }

    /// Earth-fixed coordinates into this frame, glTF Y-up (`x` east, `y` up, `z` south).
    fn local(&self, point: Vector) -> [f32; 3] {
        let d = [
            point[0] - self.origin[0],
            point[1] - self.origin[1],
            point[2] - self.origin[2],
        ];
        let [e, n, u] = self.axes;
        [dot(d, e) as f32, dot(d, u) as f32, -dot(d, n) as f32]
    }

    /// A point of the flat frame in this frame.
    pub fn point(&self, p: [f32; 3]) -> [f32; 3] {
        let (lon, lat, h) = self.geodetic(p);
        self.local(ecef(lon, lat, h))
    }

    /// A direction at flat-frame point `at` (the flat frame is conformal with its heights
    /// scaled alike, so a direction there is one in the east-up-south frame at that point) in
    /// this frame.
    pub fn direction(&self, at: [f32; 3], d: [f32; 3]) -> [f32; 3] {
        let (lon, lat, _) = self.geodetic(at);
        let [e, n, u] = east_north_up(lon, lat);
        let d = d.map(f64::from);
        let world: Vector = std::array::from_fn(|i| d[0] * e[i] + d[1] * u[i] - d[2] * n[i]);
        let [e0, n0, u0] = self.axes;
        let v = [dot(world, e0), dot(world, u0), -dot(world, n0)];
        let length = dot(v, v).sqrt();
        if length > 0.0 {
            v.map(|c| (c / length) as f32)
        } else {
            [0.0, 1.0, 0.0]
        }
    }

    /// Carries a tile's meshes and instances from the flat frame into this one. Models stay in
    /// their own frames; an instance's scale loses the flat frame's exaggeration.
    pub fn carry(
        &self,
        parts: &mut BTreeMap<Part, MeshBuffers>,
        instanced: &mut BTreeMap<Model, Instances>,
    ) {
        for buffers in parts.values_mut() {
            for (p, n) in buffers.positions.iter_mut().zip(&mut buffers.normals) {
                *n = self.direction(*p, *n);
                *p = self.point(*p);
            }
        }
        for instances in instanced.values_mut() {
            for (t, s) in instances.translations.iter_mut().zip(&mut instances.scales) {
                let exaggeration = self.frame.scale_at(self.exact(t[2])) as f32;
                *s = s.map(|c| c / exaggeration);
                *t = self.point(*t);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn apply(m: &[f64; 16], p: [f32; 3]) -> Vector {
        // Y-up content turned Z-up as a 3D Tiles runtime does: (x, -z, y).
        let q = [f64::from(p[0]), -f64::from(p[2]), f64::from(p[1])];
        std::array::from_fn(|i| m[i] * q[0] + m[4 + i] * q[1] + m[8 + i] * q[2] + m[12 + i])
    }

    fn distance(a: Vector, b: Vector) -> f64 {
        ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
    }

    #[test]
    fn the_transform_puts_points_where_their_coordinates_say() {
        let tile = TileId::new(14, 8529, 5973).unwrap();
        let enu = EastNorthUp::new(tile);
        let frame = tile.frame();
        let m = enu.transform();
        for (x, z, elevation) in [
            (0.0, 0.0, 0.0),
            (1200.0, 300.0, 85.0),
            (2445.0, 2445.0, 160.0),
            (10.0, 2000.0, -20.0),
        ] {
            let y = frame.elevation_to_y(elevation, z);
            let p = enu.point([x as f32, y as f32, z as f32]);
            let (lon, lat) = frame.to_lon_lat(x, z);
            let expected = ecef(lon, lat, elevation);
            let error = distance(apply(&m, p), expected);
            assert!(error < 0.002, "{x},{z}: {error} m");
        }
    }

    #[test]
    fn shared_edge_vertices_meet_on_the_globe() {
        let west = TileId::new(14, 8529, 5973).unwrap();
        let east = TileId::new(14, 8530, 5973).unwrap();
        let (a, b) = (EastNorthUp::new(west), EastNorthUp::new(east));
        let size = west.frame().size_m as f32;
        for z in [0.0f32, 333.3, 1222.9, size] {
            let pa = apply(&a.transform(), a.point([size, 120.0, z]));
            let pb = apply(&b.transform(), b.point([0.0, 120.0, z]));
            assert!(distance(pa, pb) < 0.002, "{z}: {}", distance(pa, pb));
        }
    }

    #[test]
    fn up_stays_nearly_up_and_directions_stay_unit() {
        let enu = EastNorthUp::new(TileId::new(14, 8529, 5973).unwrap());
        let up = enu.direction([1222.0, 50.0, 1222.0], [0.0, 1.0, 0.0]);
        assert!(up[1] > 0.999_999, "{up:?}");
        let corner = enu.direction([0.0, 50.0, 0.0], [0.0, 1.0, 0.0]);
        // A corner's up leans away from the centre by the angle the Earth turns over ~1.2 km.
        assert!(
            corner[0] < 0.0 && corner[2] < 0.0 && corner[1] > 0.99999,
            "{corner:?}"
        );
        let slanted = enu.direction([100.0, 0.0, 900.0], [0.6, 0.0, 0.8]);
        let length: f32 = slanted.iter().map(|c| c * c).sum();
        assert!((length - 1.0).abs() < 1e-6);
    }
}
