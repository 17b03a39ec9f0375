//! From features and terrain to triangles: the ground triangulation with the features stitched
//! into it ([`ground`]), extruded buildings ([`buildings`]), and the vertex buffers they fill.

pub mod buildings;
pub mod ground;

/// The parts of a tile's mesh, one glTF primitive each.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Part {
    Terrain,
    Road,
    Railway,
    Water,
    BuildingWalls,
    BuildingRoofs,
}

impl Part {
    pub const ALL: [Part; 6] = [
        Part::Terrain,
        Part::Road,
        Part::Railway,
        Part::Water,
        Part::BuildingWalls,
        Part::BuildingRoofs,
    ];

    /// The feature class (and glTF node) the part belongs to.
    pub fn class(self) -> crate::features::FeatureClass {
        use crate::features::FeatureClass;
        match self {
            Part::Terrain => FeatureClass::Terrain,
            Part::Road => FeatureClass::Road,
            Part::Railway => FeatureClass::Railway,
            Part::Water => FeatureClass::Water,
            Part::BuildingWalls | Part::BuildingRoofs => FeatureClass::Building,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Part::Terrain => "terrain",
            Part::Road => "road",
            Part::Railway => "railway",
            Part::Water => "water",
            Part::BuildingWalls => "building_walls",
            Part::BuildingRoofs => "building_roofs",
        }
    }

    pub fn of_ground_class(class: crate::features::FeatureClass) -> Option<Part> {
        use crate::features::FeatureClass;
        match class {
            FeatureClass::Terrain => Some(Part::Terrain),
            FeatureClass::Road => Some(Part::Road),
            FeatureClass::Railway => Some(Part::Railway),
            FeatureClass::Water => Some(Part::Water),
            FeatureClass::Building => None,
        }
    }
}

/// Indexed triangles with per-vertex normals and feature ids, in the tile's local frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MeshBuffers {
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    pub feature_ids: Vec<u32>,
    pub indices: Vec<u32>,
}

impl MeshBuffers {
    pub fn is_empty(&self) -> bool {
        self.indices.is_empty()
    }

    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    pub fn push_vertex(&mut self, position: [f64; 3], normal: [f64; 3], feature: u32) -> u32 {
        self.positions.push(position.map(|c| c as f32));
        self.normals.push(normal.map(|c| c as f32));
        self.feature_ids.push(feature);
        (self.positions.len() - 1) as u32
    }

    /// Adds a flat-shaded triangle whose front faces `facing` (the winding is chosen to match).
    /// Degenerate triangles are skipped.
    pub fn push_flat_triangle(&mut self, corners: [[f64; 3]; 3], facing: [f64; 3], feature: u32) {
        let normal = triangle_normal(corners);
        let Some(normal) = normalize(normal) else {
            return;
        };
        let flip = dot(normal, facing) < 0.0;
        let (normal, order) = if flip {
            (normal.map(|c| -c), [0, 2, 1])
        } else {
            (normal, [0, 1, 2])
        };
        for i in order {
            let index = self.push_vertex(corners[i], normal, feature);
            self.indices.push(index);
        }
    }
}

/// The cross product `(b − a) × (c − a)`.
pub fn triangle_normal([a, b, c]: [[f64; 3]; 3]) -> [f64; 3] {
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ]
}

pub fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The unit vector along `v`, `None` for a (near) zero vector.
pub fn normalize(v: [f64; 3]) -> Option<[f64; 3]> {
    let length = dot(v, v).sqrt();
    (length > 1e-12 && length.is_finite()).then(|| v.map(|c| c / length))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flat_triangles_face_the_requested_way() {
        let mut buffers = MeshBuffers::default();
        let corners = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]];
        buffers.push_flat_triangle(corners, [0.0, 1.0, 0.0], 7);
        let p = |i: usize| buffers.positions[buffers.indices[i] as usize].map(f64::from);
        let n = triangle_normal([p(0), p(1), p(2)]);
        assert!(n[1] > 0.0);
        assert_eq!(buffers.normals[0], [0.0, 1.0, 0.0]);
        buffers.push_flat_triangle([[0.0; 3]; 3], [0.0, 1.0, 0.0], 7);
        assert_eq!(buffers.triangle_count(), 1, "degenerate triangle skipped");
    }
}
