//! What each part of a tile looks like: its base colour, roughness and metallic factor.

use crate::features::landcover::Cover;
use crate::features::vegetation::TreeKind;
use crate::mesh::Part;

/// The metallic factor, set on every material (glTF's default is 1): only metal and glass
/// finishes of buildings differ from 0.
pub(super) fn metallic_of(part: Part) -> f32 {
    match part {
        Part::BuildingWalls(finish) | Part::BuildingRoofs(finish) => finish.metallic_roughness().0,
        _ => 0.0,
    }
}

/// Base colour, roughness per part.
pub(super) fn material_of(part: Part) -> ([f32; 4], f32) {
    match part {
        Part::Terrain => (crate::mesh::ground_look::TERRAIN, 0.95),
        Part::Rock => Cover::BareRock.material(),
        Part::Skirt => material_of(Part::Terrain),
        Part::Road(paving) => paving.material(),
        Part::Railway => ([0.45, 0.40, 0.35, 1.0], 0.95),
        Part::Water => ([0.16, 0.36, 0.62, 1.0], 0.15),
        Part::LandCover(cover) => cover.material(),
        Part::BuildingWalls(finish) => ([0.86, 0.80, 0.70, 1.0], finish.metallic_roughness().1),
        Part::BuildingRoofs(finish) => ([0.62, 0.36, 0.30, 1.0], finish.metallic_roughness().1),
        Part::Facade(glazing) => ([0.86, 0.80, 0.70, 1.0], super::facades::roughness(glazing)),
        Part::TreeTrunk => ([0.22, 0.15, 0.09, 1.0], 0.95),
        Part::Barrier(kind) => kind.material(),
        Part::Object(kind) => kind.material(),
        Part::PowerLine => ([0.12, 0.12, 0.13, 1.0], 0.5),
        Part::Stairs => ([0.66, 0.64, 0.60, 1.0], 0.9),
        Part::Marking | Part::Crossing => ([0.86, 0.86, 0.82, 1.0], 0.7),
        Part::Sidewalk => crate::features::roads::Paving::Sidewalk.material(),
        Part::Kerb => ([0.70, 0.69, 0.66, 1.0], 0.85),
        Part::Verge => ([0.36, 0.47, 0.24, 1.0], 0.95),
        Part::BridgeDeck(Some(paving)) | Part::TunnelFloor(Some(paving)) => paving.material(),
        Part::BridgeDeck(None) | Part::TunnelFloor(None) => material_of(Part::Railway),
        Part::BridgeStructure => ([0.58, 0.57, 0.55, 1.0], 0.9),
        Part::TunnelLining => ([0.50, 0.49, 0.47, 1.0], 0.9),
        Part::TunnelPortal => ([0.02, 0.02, 0.02, 1.0], 1.0),
        Part::TreeCrown(kind, shade) => {
            let shade = f32::from(shade.min(2));
            let rgb = match kind {
                TreeKind::Broadleaved => [0.12 + 0.04 * shade, 0.30 + 0.05 * shade, 0.08],
                TreeKind::Needleleaved => [0.06 + 0.02 * shade, 0.20 + 0.04 * shade, 0.10],
            };
            ([rgb[0], rgb[1], rgb[2], 1.0], 0.9)
        }
    }
}
