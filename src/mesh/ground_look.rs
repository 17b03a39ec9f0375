//! How the bare ground and the land cover look at each vertex: a colour from the cover's own
//! (a field's crop, a garden's lawn beside a house's paving), varied over the land by parcels
//! laid over the whole map in Web Mercator metres, so large areas are not one flat colour; a
//! slope too steep for deep soil shows it, and high ground turns alpine. A parcel's colour is
//! one over it (a tile's bytes stay few where vertices are many). Everything is drawn
//! from the vertex's place and the OSM element it belongs to: a vertex on a tile's edge has
//! the same colour in both tiles, and a tile the same bytes on every machine.

use crate::features::inference::{draw, unit};
use crate::features::landcover::Cover;
use crate::mesh::Part;
use crate::osm::ElementRef;
use crate::tile::TileFrame;

/// What a ground vertex's colour depends on besides its part.
#[derive(Debug, Clone, Copy)]
pub struct Site {
    /// Local `(x, z)`.
    pub at: [f64; 2],
    /// Elevation, metres.
    pub elevation_m: f64,
    /// The `y` of the vertex's unit normal: the cosine of the ground's slope there.
    pub up: f64,
    /// The OSM element of the surface (a field, a garden), if any.
    pub element: Option<ElementRef>,
    /// Whether the vertex lies on a building's outline.
    pub at_building: bool,
    /// Whether its surface spans more than a parcel or two: a smaller one (a field, a garden
    /// mapped on its own) is one parcel, a larger one (farmland mapped whole) shows the
    /// parcels it spans.
    pub large: bool,
}

/// The ground's look over one tile.
#[derive(Debug, Clone, Copy)]
pub struct GroundLook {
    frame: TileFrame,
}

/// Linear RGBA of the bare ground where nothing is mapped: grass and meadow.
pub const TERRAIN: [f32; 4] = [0.42, 0.52, 0.30, 1.0];

/// The spacing of the lattice the land's parcels are seeded on, map metres: about the size
/// of a meadow or a field in central Europe (North American fields run larger, and show as
/// several parcels).
const PARCEL_M: f64 = 220.0;
/// The longest side of a surface mapped as one parcel (a field on its own), map metres: a
/// larger one (farmland mapped whole) shows the parcels it spans, each its own crop.
pub const FIELD_M: f64 = 2.0 * PARCEL_M;
/// How much a parcel's brightness and its hue (towards dry or lush) vary.
const PARCEL_BRIGHTNESS: f64 = 0.09;
const PARCEL_DRYNESS: f64 = 0.7;

/// The crops a field shows, linear RGB: ripe grain, a green crop, ploughed soil, a ley,
/// stubble.
const CROPS: [[f64; 3]; 5] = [
    [0.60, 0.50, 0.24],
    [0.33, 0.47, 0.18],
    [0.36, 0.27, 0.17],
    [0.45, 0.53, 0.25],
    [0.64, 0.56, 0.34],
];
/// Linear RGB of a garden's lawn and of the paving round a house.
const LAWN: [f64; 3] = [0.31, 0.45, 0.19];
const PAVING: [f64; 3] = [0.58, 0.56, 0.52];
/// Linear RGB the grass takes where a slope thins the soil, and high above the tree line.
const THIN_SOIL: [f64; 3] = [0.42, 0.40, 0.27];
const ALPINE: [f64; 3] = [0.46, 0.44, 0.38];
/// Where alpine ground begins and where nothing but it is left, metres above the sea.
const ALPINE_FROM_M: f64 = 1900.0;
const ALPINE_FULL_M: f64 = 2700.0;
/// The steepest bare ground that keeps its soil and grass, as the cosine of its slope (40°,
/// about the angle of repose of soil): the terrain, an approximation of 30 m SRTM samples,
/// rounds cliffs off, so a face steeper than this is mostly rock in the land it stands for.
pub(super) const SOIL_HOLDS_COS: f64 = 0.766;

/// The slopes (cosines) over which soil thins: from 25° to 40°, where bare ground turns to
/// rock.
const THINNING_FROM_COS: f64 = 0.906;
const THINNING_FULL_COS: f64 = SOIL_HOLDS_COS;

const SALT_SEED_U: u64 = 0x51;
const SALT_SEED_V: u64 = 0x52;
const SALT_BRIGHT: u64 = 0x53;
const SALT_DRY: u64 = 0x54;
const SALT_CROP: u64 = 0x55;
const SALT_ELEMENT_U: u64 = 0x56;
const SALT_ELEMENT_V: u64 = 0x57;

impl GroundLook {
    pub fn new(frame: &TileFrame) -> GroundLook {
        GroundLook { frame: *frame }
    }

    /// Whether vertices of `part` take a colour of their own.
    pub fn varies(part: Part) -> bool {
        matches!(part, Part::Terrain | Part::Rock | Part::LandCover(_))
    }

    /// The linear RGBA colour of a vertex of `part` at `site`.
    pub fn colour(&self, part: Part, site: &Site) -> [u8; 4] {
        // A surface smaller than a parcel or two is one parcel of its own.
        let parcel = match site.element {
            Some(element) if !site.large => element_parcel(element),
            _ => parcel(self.world(site.at)),
        };
        let (base, amplitude) = base(part, site, parcel);
        let shade = |salt: u64| 2.0 * lattice(parcel, salt) - 1.0;
        let bright = 1.0 + amplitude * PARCEL_BRIGHTNESS * shade(SALT_BRIGHT);
        let dry = amplitude * PARCEL_DRYNESS * shade(SALT_DRY);
        let tint = [1.0 + 0.12 * dry, 1.0 + 0.02 * dry, 1.0 - 0.12 * dry];
        let rgb: [f64; 3] = std::array::from_fn(|i| base[i] * bright * tint[i]);
        let byte = |v: f64| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
        [byte(rgb[0]), byte(rgb[1]), byte(rgb[2]), 255]
    }

    /// Local `(x, z)` to map metres east and south of the map's north-west corner (the
    /// local frame's units are the map's metres).
    fn world(&self, at: [f64; 2]) -> [f64; 2] {
        let (u, v) = self.frame.local_to_uv(at[0], at[1]);
        [u * self.frame.size_m, v * self.frame.size_m]
    }
}

/// The colour of a part before its parcel's variation, and how strongly that varies.
fn base(part: Part, site: &Site, parcel: (i64, i64)) -> ([f64; 3], f64) {
    let material = |rgba: [f32; 4]| [rgba[0], rgba[1], rgba[2]].map(f64::from);
    match part {
        Part::Rock => (material(Cover::BareRock.material().0), 0.8),
        Part::LandCover(Cover::Farmland) => {
            let crop = lattice(parcel, SALT_CROP);
            let pick = ((crop * CROPS.len() as f64) as usize).min(CROPS.len() - 1);
            (CROPS[pick], 0.5)
        }
        // Paved round the houses, gardens between.
        Part::LandCover(Cover::Residential) if site.at_building => (PAVING, 0.4),
        Part::LandCover(Cover::Residential) => (natural(LAWN, site), 0.6),
        Part::LandCover(cover @ (Cover::Commercial | Cover::Industrial | Cover::Parking)) => {
            (material(cover.material().0), 0.4)
        }
        Part::LandCover(cover @ (Cover::Pitch | Cover::Park | Cover::Grass)) => {
            (natural(material(cover.material().0), site), 0.6)
        }
        Part::LandCover(cover) => (natural(material(cover.material().0), site), 1.0),
        _ => (natural(material(TERRAIN), site), 1.0),
    }
}

/// A natural cover's colour where the slope thins the soil, and high up.
fn natural(rgb: [f64; 3], site: &Site) -> [f64; 3] {
    let thinning =
        ((THINNING_FROM_COS - site.up) / (THINNING_FROM_COS - THINNING_FULL_COS)).clamp(0.0, 1.0);
    let rgb = mix(rgb, THIN_SOIL, 0.5 * thinning);
    let alpine =
        ((site.elevation_m - ALPINE_FROM_M) / (ALPINE_FULL_M - ALPINE_FROM_M)).clamp(0.0, 1.0);
    mix(rgb, ALPINE, 0.8 * alpine)
}

/// The parcel of a surface drawn as one: a key drawn from its OSM element, apart from every
/// lattice cell's.
fn element_parcel(element: ElementRef) -> (i64, i64) {
    let key = |salt: u64| (draw(element, salt) * (1u64 << 52) as f64) as i64;
    (key(SALT_ELEMENT_U) | 1 << 60, key(SALT_ELEMENT_V))
}

/// The parcel a point of the map (metres) lies in: the lattice cell whose seed, placed at
/// random in the cell's middle part, is the nearest. Parcels are irregular polygons of
/// about `PARCEL_M` a side, the same whichever tile asks.
fn parcel(p: [f64; 2]) -> (i64, i64) {
    let (i, j) = (
        (p[0] / PARCEL_M).floor() as i64,
        (p[1] / PARCEL_M).floor() as i64,
    );
    let mut best = ((i, j), f64::INFINITY);
    for dj in -1..=1 {
        for di in -1..=1 {
            let cell = (i + di, j + dj);
            let seed = [
                (cell.0 as f64 + 0.15 + 0.7 * lattice(cell, SALT_SEED_U)) * PARCEL_M,
                (cell.1 as f64 + 0.15 + 0.7 * lattice(cell, SALT_SEED_V)) * PARCEL_M,
            ];
            let distance = (seed[0] - p[0]).powi(2) + (seed[1] - p[1]).powi(2);
            if distance < best.1 {
                best = (cell, distance);
            }
        }
    }
    best.0
}

fn mix(a: [f64; 3], b: [f64; 3], t: f64) -> [f64; 3] {
    std::array::from_fn(|i| a[i] + (b[i] - a[i]) * t)
}

/// A number in `[0, 1)` for a lattice point: splitmix64 over its coordinates and the salt.
fn lattice((i, j): (i64, i64), salt: u64) -> f64 {
    unit(
        (i as u64)
            .wrapping_mul(0x9E37_79B9_7F4A_7C15)
            .wrapping_add((j as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F))
            .wrapping_add(salt.wrapping_mul(0xD1B5_4A32_D192_ED03)),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::osm::ElementType;
    use crate::tile::TileId;

    fn frame(x: u32) -> TileFrame {
        TileId { z: 14, x, y: 5750 }.frame()
    }

    fn site(at: [f64; 2]) -> Site {
        Site {
            at,
            elevation_m: 450.0,
            up: 1.0,
            element: None,
            at_building: false,
            large: true,
        }
    }

    fn way(id: i64) -> Option<ElementRef> {
        Some(ElementRef {
            element_type: ElementType::Way,
            id,
        })
    }

    /// Green over red: how lush a colour looks.
    fn lushness(c: [u8; 4]) -> f64 {
        f64::from(c[1]) / f64::from(c[0])
    }

    #[test]
    fn a_vertex_on_a_tile_edge_has_one_colour_in_both_tiles() {
        let (west, east) = (GroundLook::new(&frame(8626)), GroundLook::new(&frame(8627)));
        let size = frame(8626).size_m;
        for k in 0..50 {
            let z = size * f64::from(k) / 50.0;
            for part in [Part::Terrain, Part::LandCover(Cover::Farmland)] {
                assert_eq!(
                    west.colour(part, &site([size, z])),
                    east.colour(part, &site([0.0, z]))
                );
            }
        }
    }

    #[test]
    fn bare_ground_varies_by_parcels_and_is_even_within_one() {
        let look = GroundLook::new(&frame(8626));
        let size = frame(8626).size_m;
        let mut colours = std::collections::BTreeSet::new();
        let (mut pairs, mut even) = (0, 0);
        for i in 0..100 {
            for j in 0..100 {
                let at = [size * f64::from(i) / 100.0, size * f64::from(j) / 100.0];
                let here = look.colour(Part::Terrain, &site(at));
                let beside = look.colour(Part::Terrain, &site([at[0] + 5.0, at[1]]));
                colours.insert(here);
                pairs += 1;
                even += usize::from(here == beside);
            }
        }
        assert!(colours.len() >= 20, "{} colours over a tile", colours.len());
        assert!(
            even * 100 >= pairs * 90,
            "{even} of {pairs} 5 m apart alike"
        );
    }

    #[test]
    fn a_field_mapped_alone_is_one_crop_and_farmland_mapped_whole_a_patchwork() {
        let look = GroundLook::new(&frame(8626));
        let field = |at: [f64; 2], large: bool| {
            let site = Site {
                element: way(42),
                large,
                ..site(at)
            };
            look.colour(Part::LandCover(Cover::Farmland), &site)
        };
        let places: Vec<[f64; 2]> = (0..40).map(|k| [60.0 * f64::from(k), 900.0]).collect();
        let alone: std::collections::BTreeSet<_> =
            places.iter().map(|&p| field(p, false)).collect();
        let whole: std::collections::BTreeSet<_> = places.iter().map(|&p| field(p, true)).collect();
        assert_eq!(alone.len(), 1);
        assert!(whole.len() >= 4, "{whole:?}");
    }

    #[test]
    fn steep_ground_thins_its_grass_and_high_ground_turns_alpine() {
        let look = GroundLook::new(&frame(8626));
        let at = [300.0, 300.0];
        let level = look.colour(Part::Terrain, &site(at));
        let steep = look.colour(
            Part::Terrain,
            &Site {
                up: 0.8,
                ..site(at)
            },
        );
        let high = look.colour(
            Part::Terrain,
            &Site {
                elevation_m: 2600.0,
                ..site(at)
            },
        );
        assert!(
            lushness(steep) < lushness(level) - 0.05,
            "{steep:?} {level:?}"
        );
        assert!(lushness(high) < lushness(steep), "{high:?} {steep:?}");
    }

    #[test]
    fn residential_land_is_paved_round_its_houses_and_gardened_between() {
        let look = GroundLook::new(&frame(8626));
        let garden = Site {
            element: way(7),
            large: false,
            ..site([500.0, 500.0])
        };
        let paved = Site {
            at_building: true,
            ..garden
        };
        let part = Part::LandCover(Cover::Residential);
        let (garden, paved) = (look.colour(part, &garden), look.colour(part, &paved));
        assert!(lushness(garden) > 1.2, "{garden:?}");
        assert!(lushness(paved) < 1.05, "{paved:?}");
    }
}
