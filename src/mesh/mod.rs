//! From features and terrain to triangles: the ground triangulation with the features stitched
//! into it ([`ground`]), extruded buildings ([`buildings`]), and the vertex buffers they fill.

pub mod barriers;
pub mod buildings;
pub mod drawn_ground;
pub mod facades;
pub mod flatten;
pub mod ground;
pub mod ground_look;
pub mod ground_parts;
pub mod instances;
pub mod markings;
pub mod models;
pub mod normals;
pub mod passages;
pub mod power;
pub mod roofs;
pub mod sidewalks;
pub mod skeleton;
pub mod stairs;
pub mod structure_lines;
pub mod structures;
pub mod tin;

use crate::features::barriers::BarrierKind;
use crate::features::buildings::Finish;
use crate::features::facades::Glazing;
use crate::features::landcover::Cover;
use crate::features::objects::ObjectKind;
use crate::features::roads::Paving;
use crate::features::vegetation::TreeKind;
use crate::features::FeatureClass;

/// The parts of a tile's mesh, one glTF primitive (and material) each.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Part {
    Terrain,
    /// Bare terrain too steep for soil, where nothing is mapped: rock.
    Rock,
    /// The strip hanging under the ground's edges along the tile's sides.
    Skirt,
    Road(Paving),
    Railway,
    Water,
    LandCover(Cover),
    BuildingWalls(Finish),
    BuildingRoofs(Finish),
    /// Walls with windows: textured a bay wide and a level high.
    Facade(Glazing),
    Barrier(BarrierKind),
    Object(ObjectKind),
    PowerLine,
    /// The treads and risers of a flight of steps.
    Stairs,
    /// The lines painted on roads.
    Marking,
    /// Pedestrian crossings painted on roads.
    Crossing,
    /// The tops of raised sidewalks, paved as the ways mapped as sidewalks are.
    Sidewalk,
    /// The kerbs and ends of raised sidewalks.
    Kerb,
    /// Grass verges beside roads outside built-up land.
    Verge,
    /// A bridge's deck: paved like its road, or a railway's bed.
    BridgeDeck(Option<Paving>),
    /// A bridge's sides, underside and piers.
    BridgeStructure,
    /// A tunnel's floor: paved like its road, or a railway's bed.
    TunnelFloor(Option<Paving>),
    /// A tunnel's walls and ceiling, seen from inside and out.
    TunnelLining,
    /// The dark opening of a tunnel's portal.
    TunnelPortal,
    TreeTrunk,
    /// A crown of a kind of tree in one of [`crate::features::vegetation::SHADES`] shades.
    TreeCrown(TreeKind, u8),
}

impl Part {
    /// The feature class (and glTF node) the part belongs to.
    pub fn class(self) -> FeatureClass {
        match self {
            Part::Terrain | Part::Rock | Part::Skirt => FeatureClass::Terrain,
            Part::Road(_) | Part::Sidewalk | Part::Kerb | Part::Verge => FeatureClass::Road,
            Part::Marking | Part::Crossing => FeatureClass::Marking,
            Part::Railway => FeatureClass::Railway,
            Part::Water => FeatureClass::Water,
            Part::LandCover(_) => FeatureClass::LandCover,
            Part::BuildingWalls(_) | Part::BuildingRoofs(_) | Part::Facade(_) => {
                FeatureClass::Building
            }
            Part::TreeTrunk | Part::TreeCrown(..) => FeatureClass::Vegetation,
            Part::Barrier(_) => FeatureClass::Barrier,
            Part::Object(_) | Part::PowerLine | Part::Stairs => FeatureClass::Object,
            Part::BridgeDeck(_) | Part::BridgeStructure => FeatureClass::Bridge,
            Part::TunnelFloor(_) | Part::TunnelLining | Part::TunnelPortal => FeatureClass::Tunnel,
        }
    }

    /// The name of the node that draws the part: its class's, but for what stands along a
    /// road's sides over its surface (`roadside`), which is not ground.
    pub fn node(self) -> &'static str {
        match self {
            Part::Sidewalk | Part::Kerb | Part::Verge => "roadside",
            _ => self.class().as_str(),
        }
    }

    /// The name of the part's material.
    pub fn name(self) -> &'static str {
        match self {
            Part::Terrain => "terrain",
            Part::Rock => "terrain_rock",
            Part::Skirt => "terrain_skirt",
            Part::Road(paving) => paving.as_str(),
            Part::Railway => "railway",
            Part::Water => "water",
            Part::LandCover(cover) => cover.as_str(),
            Part::BuildingWalls(Finish::Matte) => "building_walls",
            Part::BuildingWalls(Finish::Metal) => "building_walls_metal",
            Part::BuildingWalls(Finish::Glass) => "building_walls_glass",
            Part::BuildingRoofs(Finish::Matte) => "building_roofs",
            Part::BuildingRoofs(Finish::Metal) => "building_roofs_metal",
            Part::BuildingRoofs(Finish::Glass) => "building_roofs_glass",
            Part::Facade(Glazing::Punched) => "facade_punched",
            Part::Facade(Glazing::Ribbon) => "facade_ribbon",
            Part::Facade(Glazing::Shopfront) => "facade_shopfront",
            Part::Facade(Glazing::CurtainWall) => "facade_curtain_wall",
            Part::TreeTrunk => "tree_trunk",
            Part::Barrier(kind) => kind.as_str(),
            Part::Object(kind) => kind.as_str(),
            Part::PowerLine => "power_line",
            Part::Stairs => "stairs",
            Part::Marking => "marking",
            Part::Crossing => "crossing",
            Part::Sidewalk => "sidewalk",
            Part::Kerb => "kerb",
            Part::Verge => "verge",
            Part::BridgeDeck(None) => "bridge_deck_railway",
            Part::BridgeDeck(Some(Paving::Asphalt)) => "bridge_deck_asphalt",
            Part::BridgeDeck(Some(Paving::Concrete)) => "bridge_deck_concrete",
            Part::BridgeDeck(Some(Paving::Stones)) => "bridge_deck_stones",
            Part::BridgeDeck(Some(Paving::Unpaved)) => "bridge_deck_unpaved",
            Part::BridgeDeck(Some(Paving::Sidewalk)) => "bridge_deck_sidewalk",
            Part::BridgeStructure => "bridge_structure",
            Part::TunnelFloor(None) => "tunnel_floor_railway",
            Part::TunnelFloor(Some(Paving::Asphalt)) => "tunnel_floor_asphalt",
            Part::TunnelFloor(Some(Paving::Concrete)) => "tunnel_floor_concrete",
            Part::TunnelFloor(Some(Paving::Stones)) => "tunnel_floor_stones",
            Part::TunnelFloor(Some(Paving::Unpaved)) => "tunnel_floor_unpaved",
            Part::TunnelFloor(Some(Paving::Sidewalk)) => "tunnel_floor_sidewalk",
            Part::TunnelLining => "tunnel_lining",
            Part::TunnelPortal => "tunnel_portal",
            Part::TreeCrown(TreeKind::Broadleaved, 0) => "broadleaved_crown_0",
            Part::TreeCrown(TreeKind::Broadleaved, 1) => "broadleaved_crown_1",
            Part::TreeCrown(TreeKind::Broadleaved, _) => "broadleaved_crown_2",
            Part::TreeCrown(TreeKind::Needleleaved, 0) => "needleleaved_crown_0",
            Part::TreeCrown(TreeKind::Needleleaved, 1) => "needleleaved_crown_1",
            Part::TreeCrown(TreeKind::Needleleaved, _) => "needleleaved_crown_2",
        }
    }

    /// The part of a ground surface of `class` (with its land cover or paving, if any); `None`
    /// for the ground under buildings, which the 3D tile leaves out.
    pub fn of_ground(
        class: FeatureClass,
        cover: Option<Cover>,
        paving: Option<Paving>,
    ) -> Option<Part> {
        match class {
            FeatureClass::Terrain => Some(Part::Terrain),
            FeatureClass::Road => Some(Part::Road(paving.unwrap_or(Paving::Asphalt))),
            FeatureClass::Railway => Some(Part::Railway),
            FeatureClass::Water => Some(Part::Water),
            FeatureClass::LandCover => Some(cover.map_or(Part::Terrain, Part::LandCover)),
            FeatureClass::Building
            | FeatureClass::Vegetation
            | FeatureClass::Barrier
            | FeatureClass::Object
            | FeatureClass::Bridge
            | FeatureClass::Tunnel
            | FeatureClass::Marking => None,
        }
    }
}

/// A segment of global tile units placed in a tile's local frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalSpan {
    /// Local `(x, z)` of both ends.
    pub a: (f64, f64),
    pub b: (f64, f64),
    /// Unit direction from `a` to `b` in the `x`/`z` plane.
    pub direction: (f64, f64),
    pub length: f64,
    /// Local units per true metre at the span's middle (the Mercator scale factor).
    pub scale: f64,
}

impl LocalSpan {
    /// The span from `a` to `b` (global tile units), `None` when it has no length.
    pub fn new(frame: &crate::tile::TileFrame, a: [f64; 2], b: [f64; 2]) -> Option<LocalSpan> {
        let (a, b) = (frame.uv_to_local(a[0], a[1]), frame.uv_to_local(b[0], b[1]));
        let (dx, dz) = (b.0 - a.0, b.1 - a.1);
        let length = (dx * dx + dz * dz).sqrt();
        (length >= 1e-6).then(|| LocalSpan {
            a,
            b,
            direction: (dx / length, dz / length),
            length,
            scale: frame.scale_at((a.1 + b.1) / 2.0),
        })
    }
}

/// Keeps the items whose mark is set (`items` as long as `marks`, or empty).
pub(crate) fn retain_marked<T>(items: &mut Vec<T>, marks: &[bool]) {
    let mut at = 0;
    items.retain(|_| {
        at += 1;
        marks[at - 1]
    });
}

/// Indexed triangles with per-vertex normals and feature ids, in the tile's local frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MeshBuffers {
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    pub feature_ids: Vec<u32>,
    pub indices: Vec<u32>,
    /// Linear RGBA per vertex, when [`MeshBuffers::paint`] has been called: the material's
    /// base colour is then white and each feature carries its own colour.
    pub colours: Vec<[u8; 4]>,
    paint: Option<[u8; 4]>,
    /// Texture coordinates per vertex, when the buffers are textured (every vertex pushed by
    /// [`MeshBuffers::push_textured_polygon`]); empty otherwise.
    pub uvs: Vec<[f32; 2]>,
}

impl MeshBuffers {
    pub fn is_empty(&self) -> bool {
        self.indices.is_empty()
    }

    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// The bytes of the buffers as they are held.
    pub fn byte_len(&self) -> usize {
        use std::mem::size_of_val;
        size_of_val(self.positions.as_slice())
            + size_of_val(self.normals.as_slice())
            + size_of_val(self.feature_ids.as_slice())
            + size_of_val(self.indices.as_slice())
            + size_of_val(self.colours.as_slice())
            + size_of_val(self.uvs.as_slice())
    }

    /// The colour of the vertices pushed from now on (linear RGBA). Once painted, every
    /// vertex of these buffers has a colour.
    pub fn paint(&mut self, colour: [u8; 4]) {
        if self.paint.is_none() {
            self.colours = vec![[255; 4]; self.positions.len()];
        }
        self.paint = Some(colour);
    }

    /// Drops every vertex whose position or normal is not a finite number, with the triangles
    /// that use it, so nothing written of the buffers is NaN or infinite; returns how many
    /// triangles went. Buffers of finite numbers are left as they are.
    pub fn drop_non_finite(&mut self) -> usize {
        let finite = |v: &[f32; 3]| v.iter().all(|c| c.is_finite());
        let kept: Vec<bool> = (self.positions.iter().zip(&self.normals))
            .map(|(p, n)| finite(p) && finite(n))
            .collect();
        if kept.iter().all(|&k| k) {
            return 0;
        }
        let mut renumbered = vec![u32::MAX; kept.len()];
        let slots = renumbered.iter_mut().zip(&kept).filter(|(_, &k)| k);
        for (next, (slot, _)) in slots.enumerate() {
            *slot = next as u32;
        }
        retain_marked(&mut self.positions, &kept);
        retain_marked(&mut self.normals, &kept);
        retain_marked(&mut self.feature_ids, &kept);
        retain_marked(&mut self.colours, &kept);
        retain_marked(&mut self.uvs, &kept);
        let before = self.triangle_count();
        self.indices = self
            .indices
            .chunks_exact(3)
            .filter(|t| t.iter().all(|&v| kept[v as usize]))
            .flatten()
            .map(|&v| renumbered[v as usize])
            .collect();
        before - self.triangle_count()
    }

    pub fn push_vertex(&mut self, position: [f64; 3], normal: [f64; 3], feature: u32) -> u32 {
        if let Some(colour) = self.paint {
            self.colours.push(colour);
        }
        self.positions.push(position.map(|c| c as f32));
        self.normals.push(normal.map(|c| c as f32));
        self.feature_ids.push(feature);
        (self.positions.len() - 1) as u32
    }

    /// Adds a flat convex polygon (corners in order, either winding) as a fan sharing its
    /// vertices, front towards `facing`. Degenerate polygons are skipped.
    pub fn push_flat_polygon(&mut self, corners: &[[f64; 3]], facing: [f64; 3], feature: u32) {
        self.push_polygon(corners, None, facing, feature);
    }

    /// Adds a flat convex polygon as [`MeshBuffers::push_flat_polygon`] does, with a texture
    /// coordinate at each corner. Buffers are either textured throughout or not at all.
    pub fn push_textured_polygon(
        &mut self,
        corners: &[[f64; 3]],
        uvs: &[[f64; 2]],
        facing: [f64; 3],
        feature: u32,
    ) {
        debug_assert_eq!(corners.len(), uvs.len());
        self.push_polygon(corners, Some(uvs), facing, feature);
    }

    fn push_polygon(
        &mut self,
        corners: &[[f64; 3]],
        uvs: Option<&[[f64; 2]]>,
        facing: [f64; 3],
        feature: u32,
    ) {
        if corners.len() < 3 {
            return;
        }
        let Some(normal) = normalize(newell(corners)) else {
            return;
        };
        let reversed = dot(normal, facing) < 0.0;
        let normal = if reversed { normal.map(|c| -c) } else { normal };
        let first = self.positions.len() as u32;
        for &corner in corners {
            self.push_vertex(corner, normal, feature);
        }
        if let Some(uvs) = uvs {
            self.uvs.extend(uvs.iter().map(|uv| uv.map(|c| c as f32)));
        }
        for i in 1..corners.len() as u32 - 1 {
            // Corners in a row on one side (a wall's top passing through a roof's bends) would
            // give triangles without area.
            let [p, q, r] = [0, i, i + 1].map(|k| corners[k as usize]);
            if normalize(triangle_normal([p, q, r])).is_none() {
                continue;
            }
            let (b, c) = if reversed { (i + 1, i) } else { (i, i + 1) };
            self.indices
                .extend_from_slice(&[first, first + b, first + c]);
        }
    }

    /// Two triangles over four vertices already pushed, in order round a quad, wound to face
    /// `facing`.
    pub fn push_quad(&mut self, [a, b, c, d]: [u32; 4], facing: [f64; 3]) {
        let corner = |i: u32| self.positions[i as usize].map(f64::from);
        let normal = triangle_normal([corner(a), corner(b), corner(c)]);
        if dot(normal, facing) >= 0.0 {
            self.indices.extend_from_slice(&[a, b, c, a, c, d]);
        } else {
            self.indices.extend_from_slice(&[a, c, b, a, d, c]);
        }
    }

    /// Adds flat triangles that share one normal (a flat roof, say), sharing vertices between
    /// them; each triangle is wound to face `normal`. Degenerate triangles are skipped.
    pub fn push_flat_triangles(
        &mut self,
        triangles: &[[[f64; 3]; 3]],
        normal: [f64; 3],
        feature: u32,
    ) {
        let mut slots: std::collections::HashMap<[u64; 3], u32> = std::collections::HashMap::new();
        for &corners in triangles {
            let Some(own) = normalize(triangle_normal(corners)) else {
                continue;
            };
            let order = if dot(own, normal) < 0.0 {
                [0, 2, 1]
            } else {
                [0, 1, 2]
            };
            for i in order {
                let corner = corners[i];
                let slot = *slots
                    .entry(corner.map(f64::to_bits))
                    .or_insert_with(|| self.push_vertex(corner, normal, feature));
                self.indices.push(slot);
            }
        }
    }
}

/// The normal of a planar polygon by Newell's method (robust for any polygon, whatever vertex
/// it starts at); its length is twice the area.
pub fn newell(polygon: &[[f64; 3]]) -> [f64; 3] {
    let mut normal = [0.0; 3];
    for i in 0..polygon.len() {
        let (a, b) = (polygon[i], polygon[(i + 1) % polygon.len()]);
        normal[0] += (a[1] - b[1]) * (a[2] + b[2]);
        normal[1] += (a[2] - b[2]) * (a[0] + b[0]);
        normal[2] += (a[0] - b[0]) * (a[1] + b[1]);
    }
    normal
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
    fn vertices_that_are_not_finite_go_with_their_triangles() {
        let mut buffers = MeshBuffers::default();
        for (k, x) in [0.0, 1.0, f64::NAN, 0.0].into_iter().enumerate() {
            buffers.push_vertex([x, 0.0, k as f64], [0.0, 1.0, 0.0], k as u32);
        }
        buffers.indices = vec![0, 1, 3, 1, 2, 3];
        let unchanged = buffers.clone();
        let mut finite = unchanged.clone();
        finite.positions[2][0] = 2.0;
        let mut kept = finite.clone();
        assert_eq!(kept.drop_non_finite(), 0);
        assert_eq!(kept, finite);
        assert_eq!(buffers.drop_non_finite(), 1);
        assert_eq!(buffers.indices, vec![0, 1, 2]);
        assert_eq!(buffers.feature_ids, vec![0, 1, 3]);
        assert!(buffers.positions.iter().flatten().all(|c| c.is_finite()));
    }

    #[test]
    fn flat_polygons_share_vertices_and_face_the_requested_way() {
        let mut buffers = MeshBuffers::default();
        let quad = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ];
        buffers.push_flat_polygon(&quad, [0.0, 0.0, -1.0], 3);
        assert_eq!((buffers.positions.len(), buffers.triangle_count()), (4, 2));
        for t in buffers.indices.chunks(3) {
            let p = |i: u32| buffers.positions[i as usize].map(f64::from);
            assert!(triangle_normal([p(t[0]), p(t[1]), p(t[2])])[2] < 0.0);
        }
        assert_eq!(buffers.normals[0], [0.0, 0.0, -1.0]);
    }

    #[test]
    fn flat_triangles_share_vertices_and_face_up() {
        let mut buffers = MeshBuffers::default();
        let a = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]];
        let b = [[1.0, 0.0, 0.0], [1.0, 0.0, 1.0], [0.0, 0.0, 1.0]];
        buffers.push_flat_triangles(&[a, b, [[0.0; 3]; 3]], [0.0, 1.0, 0.0], 7);
        assert_eq!(buffers.triangle_count(), 2, "degenerate triangle skipped");
        assert_eq!(buffers.positions.len(), 4);
        for t in buffers.indices.chunks(3) {
            let p = |i: u32| buffers.positions[i as usize].map(f64::from);
            assert!(triangle_normal([p(t[0]), p(t[1]), p(t[2])])[1] > 0.0);
        }
    }
}
