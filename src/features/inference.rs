//! What a building's tags leave unsaid, inferred from what is known of it: its type, its
//! footprint (area, corners, right angles, how elongated), its levels and the region it stands
//! in. Almost no building in OSM carries `roof:shape`, and most carry no height either: what is
//! drawn for them is what a viewer sees nearly everywhere.
//!
//! Tagged values always win; only what is missing is inferred. Every choice is a pure
//! function of the building's own data, and where it varies (one house hipped, its neighbour
//! gabled) the variation is drawn from its OSM id: the same building gets the same roof in
//! every tile, on every machine.
//!
//! The shares follow what is built: small houses of one to five levels have pitched roofs far
//! more often than flat ones (osm2city counts about 80 % gabled, 10 % hipped, 10 % flat in
//! central Europe); Mediterranean houses have low hipped roofs or flat terraces; North
//! American houses are gabled or hipped; large, many-cornered, tall, industrial and commercial
//! buildings are flat.

use super::roof_shape::RoofShape;
use crate::osm::{ElementRef, ElementType, LonLat, Tags};

/// Where a building stands, as far as how roofs are built there goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Region {
    /// The Alps: gabled, moderately pitched roofs that hold the snow.
    Alpine,
    /// Europe north of the Alps and the Mediterranean: steep gables.
    CentralEurope,
    /// Around the Mediterranean: low hipped roofs, flat terraces in towns.
    Mediterranean,
    /// The United States and Canada: gabled and hipped houses, flat commercial buildings.
    NorthAmerica,
    /// Anywhere else.
    Other,
}

impl Region {
    /// The region of a point.
    pub fn of(at: LonLat) -> Region {
        let (lon, lat) = (at.lon, at.lat);
        if (-170.0..=-50.0).contains(&lon) && (15.0..=75.0).contains(&lat) {
            Region::NorthAmerica
        } else if (5.5..=16.5).contains(&lon) && (45.5..=48.0).contains(&lat) {
            Region::Alpine
        } else if (-10.0..=40.0).contains(&lon) && (30.0..45.5).contains(&lat) {
            Region::Mediterranean
        } else if (-11.0..=40.0).contains(&lon) && (45.5..=72.0).contains(&lat) {
            Region::CentralEurope
        } else {
            Region::Other
        }
    }

    /// The pitch of a house's roof here, degrees: the lowest, and the range above it.
    fn house_pitch_deg(self) -> (f64, f64) {
        match self {
            Region::Alpine => (28.0, 10.0),
            Region::CentralEurope => (38.0, 12.0),
            Region::Mediterranean => (18.0, 7.0),
            Region::NorthAmerica => (22.0, 12.0),
            Region::Other => (25.0, 10.0),
        }
    }

    /// How a house's roof is chosen here: the shares of each shape, summing to 100.
    fn house_roofs(self) -> &'static [(RoofShape, u32)] {
        match self {
            Region::Alpine => &[
                (RoofShape::Gabled, 84),
                (RoofShape::Hipped, 6),
                (RoofShape::HalfHipped, 5),
                (RoofShape::Flat, 5),
            ],
            Region::CentralEurope => &[
                (RoofShape::Gabled, 72),
                (RoofShape::Hipped, 12),
                (RoofShape::HalfHipped, 8),
                (RoofShape::Flat, 8),
            ],
            Region::Mediterranean => &[
                (RoofShape::Hipped, 50),
                (RoofShape::Gabled, 25),
                (RoofShape::Flat, 25),
            ],
            Region::NorthAmerica => &[
                (RoofShape::Gabled, 55),
                (RoofShape::Hipped, 38),
                (RoofShape::Flat, 7),
            ],
            Region::Other => &[
                (RoofShape::Gabled, 55),
                (RoofShape::Hipped, 25),
                (RoofShape::Flat, 20),
            ],
        }
    }

    /// The levels of a house here when none are tagged: the fewest, and how many may be added.
    fn house_levels(self) -> (u32, u32) {
        match self {
            Region::NorthAmerica => (1, 1),
            Region::Mediterranean => (2, 2),
            Region::Alpine => (2, 1),
            Region::CentralEurope | Region::Other => (1, 2),
        }
    }
}

/// What a footprint says about the building on it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Footprint {
    /// Square metres.
    pub area_m2: f64,
    /// Corners, not counting those where the outline bends by less than 15°.
    pub corners: usize,
    /// Whether every corner is within 25° of a right angle.
    pub rectilinear: bool,
    /// The length of the footprint along its longest side over its width across it (≥ 1).
    pub elongation: f64,
}

impl Footprint {
    /// The footprint of an outline (its holes, courtyards, left aside).
    pub fn of(outer: &[LonLat]) -> Option<Footprint> {
        let points = local_metres(outer);
        if points.len() < 3 {
            return None;
        }
        let area_m2 = shoelace(&points).abs();
        let n = points.len();
        let mut corners = 0;
        let mut rectilinear = true;
        for i in 0..n {
            let (a, b, c) = (points[(i + n - 1) % n], points[i], points[(i + 1) % n]);
            let incoming = (b[0] - a[0], b[1] - a[1]);
            let outgoing = (c[0] - b[0], c[1] - b[1]);
            let turn = (incoming.0 * outgoing.1 - incoming.1 * outgoing.0)
                .atan2(incoming.0 * outgoing.0 + incoming.1 * outgoing.1)
                .abs()
                .to_degrees();
            if turn < 15.0 {
                continue;
            }
            corners += 1;
            if (turn - 90.0).abs() > 25.0 {
                rectilinear = false;
            }
        }
        Some(Footprint {
            area_m2,
            corners,
            rectilinear,
            elongation: elongation(&points),
        })
    }

    /// A plain four-cornered block.
    fn is_block(&self) -> bool {
        self.corners <= 4 && self.rectilinear
    }

    /// Square-cornered, with few enough corners for a gable on each wing (an L, T or U house:
    /// the skeleton gives one ridge per wing).
    fn takes_gables(&self) -> bool {
        self.corners <= 10 && self.rectilinear
    }
}

/// The points of a ring in metres east and north of its first point (the closing point, if
/// repeated, dropped).
fn local_metres(ring: &[LonLat]) -> Vec<[f64; 2]> {
    let Some(origin) = ring.first() else {
        return Vec::new();
    };
    let east = 111_320.0 * origin.lat.to_radians().cos();
    let north = 110_540.0;
    let mut points: Vec<[f64; 2]> = ring
        .iter()
        .map(|p| [(p.lon - origin.lon) * east, (p.lat - origin.lat) * north])
        .collect();
    if points.len() > 1 && points.first() == points.last() {
        points.pop();
    }
    points
}

fn shoelace(points: &[[f64; 2]]) -> f64 {
    let n = points.len();
    (0..n)
        .map(|i| {
            let (a, b) = (points[i], points[(i + 1) % n]);
            a[0] * b[1] - b[0] * a[1]
        })
        .sum::<f64>()
        / 2.0
}

/// Length over width of a footprint measured along its longest side.
fn elongation(points: &[[f64; 2]]) -> f64 {
    let n = points.len();
    let longest = (0..n)
        .map(|i| (points[i], points[(i + 1) % n]))
        .max_by(|(a, b), (c, d)| length(*a, *b).total_cmp(&length(*c, *d)));
    let Some((a, b)) = longest else {
        return 1.0;
    };
    let l = length(a, b).max(1e-9);
    let axis = [(b[0] - a[0]) / l, (b[1] - a[1]) / l];
    let (mut along, mut across) = ((f64::MAX, f64::MIN), (f64::MAX, f64::MIN));
    for p in points {
        let s = p[0] * axis[0] + p[1] * axis[1];
        let t = -p[0] * axis[1] + p[1] * axis[0];
        along = (along.0.min(s), along.1.max(s));
        across = (across.0.min(t), across.1.max(t));
    }
    let (length, width) = (along.1 - along.0, across.1 - across.0);
    if width <= 1e-9 {
        return f64::MAX;
    }
    (length / width).max(width / length)
}

fn length(a: [f64; 2], b: [f64; 2]) -> f64 {
    (b[0] - a[0]).hypot(b[1] - a[1])
}

/// A number in `[0, 1)` drawn from an element and a salt (one per property), the same on every
/// machine.
pub fn draw(element: ElementRef, salt: u64) -> f64 {
    let kind = match element.element_type {
        ElementType::Node => 1u64,
        ElementType::Way => 2,
        ElementType::Relation => 3,
    };
    // splitmix64 over the id, the kind and the salt.
    unit(
        (element.id as u64)
            .wrapping_mul(0x9E37_79B9_7F4A_7C15)
            .wrapping_add(kind << 56)
            .wrapping_add(salt.wrapping_mul(0xD1B5_4A32_D192_ED03)),
    )
}

/// splitmix64's finalizer over `z` (a mix of what the number is drawn from), as a number in
/// `[0, 1)`, the same on every machine.
pub fn unit(mut z: u64) -> f64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 53) as f64
}

const SALT_SHAPE: u64 = 1;
const SALT_PITCH: u64 = 2;
const SALT_LEVELS: u64 = 3;

/// How a building is used, as far as its roof and height go.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    /// A house, or an untagged building as small as one.
    House,
    /// A block of flats.
    Apartments,
    /// A barn, a stable, a farm's outbuilding.
    Farm,
    /// A garage, a shed, a hut.
    Small,
    /// A church or a chapel: a steep gable.
    Church,
    /// Industry, trade, offices, parking: flat.
    Flat,
    /// Anything else: flat or hipped by size and region.
    Other,
}

fn kind_of(building: &str) -> Kind {
    match building {
        "house" | "detached" | "semidetached_house" | "terrace" | "bungalow" | "residential"
        | "farm" | "cabin" | "villa" | "dwelling_house" => Kind::House,
        "apartments" => Kind::Apartments,
        "barn" | "farm_auxiliary" | "stable" | "cowshed" | "sty" | "greenhouse_horticulture" => {
            Kind::Farm
        }
        "garage" | "shed" | "hut" | "allotment_house" | "boathouse" | "summer_house" => Kind::Small,
        "church" | "chapel" | "cathedral" => Kind::Church,
        "industrial" | "warehouse" | "retail" | "commercial" | "office" | "supermarket"
        | "garages" | "carport" | "parking" | "roof" | "hangar" | "manufacture" | "hospital"
        | "grandstand" | "transformer_tower" | "service" | "storage_tank" | "silo"
        | "train_station" | "stadium" | "construction" | "ruins" => Kind::Flat,
        "yes" => Kind::House,
        _ => Kind::Other,
    }
}

/// A roof inferred for a building whose `roof:shape` is missing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InferredRoof {
    pub shape: RoofShape,
    /// Degrees.
    pub pitch_deg: f64,
    /// The compass direction its faces look towards (degrees), where the roof follows a row
    /// rather than the footprint's long side.
    pub direction_deg: Option<f64>,
}

/// The roof a building most plausibly has when `roof:shape` is not tagged: from its `building`
/// value, its footprint, its height above the ground (`None` when nothing gives one), the
/// region and the element (for a deterministic variation).
pub fn roof(
    building: &str,
    footprint: &Footprint,
    height_m: Option<f64>,
    region: Region,
    element: ElementRef,
) -> InferredRoof {
    let flat = InferredRoof::FLAT;
    let kind = kind_of(building);
    if kind == Kind::Flat || flat_by_size(building, kind, footprint, height_m) {
        return flat;
    }
    let (low, range) = region.house_pitch_deg();
    let pitch = low + range * draw(element, SALT_PITCH);
    let pick = |shares: &[(RoofShape, u32)]| {
        let mut left = draw(element, SALT_SHAPE) * 100.0;
        for &(shape, share) in shares {
            left -= f64::from(share);
            if left < 0.0 {
                return shape;
            }
        }
        shares.last().map_or(RoofShape::Flat, |s| s.0)
    };
    let (shape, pitch_deg) = match kind {
        Kind::Church => (RoofShape::Gabled, 45.0),
        Kind::Farm => (
            pick(&[(RoofShape::Gabled, 85), (RoofShape::HalfHipped, 15)]),
            pitch.max(30.0),
        ),
        Kind::Small => (
            pick(&[
                (RoofShape::Gabled, 45),
                (RoofShape::Skillion, 20),
                (RoofShape::Flat, 35),
            ]),
            (pitch * 0.7).max(15.0),
        ),
        Kind::House => (pick(region.house_roofs()), pitch),
        Kind::Apartments | Kind::Other => match region {
            // Blocks of flats and public buildings: low hipped roofs or flat ones.
            Region::Mediterranean | Region::Other => (
                pick(&[(RoofShape::Hipped, 35), (RoofShape::Flat, 65)]),
                pitch.min(22.0),
            ),
            _ => (
                pick(&[
                    (RoofShape::Hipped, 40),
                    (RoofShape::Gabled, 30),
                    (RoofShape::Flat, 30),
                ]),
                pitch.min(35.0),
            ),
        },
        Kind::Flat => return flat,
    };
    // Gables need square-cornered wings; other outlines are hipped (every side slopes up to
    // the straight skeleton's ridges, whatever the outline).
    let shape = match shape {
        RoofShape::Gabled | RoofShape::HalfHipped if !footprint.takes_gables() => RoofShape::Hipped,
        // A long, thin building hipped at its ends looks wrong: gabled when it is a block.
        RoofShape::Hipped if footprint.is_block() && footprint.elongation > 3.0 => {
            RoofShape::Gabled
        }
        shape => shape,
    };
    if shape == RoofShape::Flat {
        return flat;
    }
    InferredRoof {
        shape,
        pitch_deg,
        direction_deg: None,
    }
}

/// Whether a building is flat-roofed by its size alone, whatever it is and where it stands:
/// large, many-cornered, tall, or too small for a roof of its own.
fn flat_by_size(building: &str, kind: Kind, footprint: &Footprint, height_m: Option<f64>) -> bool {
    let large = match kind {
        Kind::Farm | Kind::Church => footprint.area_m2 > 3000.0,
        Kind::House if building == "yes" => footprint.area_m2 > 300.0,
        _ => footprint.area_m2 > 1500.0,
    };
    let tall = height_m.is_some_and(|h| h > 20.0);
    large || tall || footprint.corners > 12 || footprint.area_m2 < 12.0
}

impl InferredRoof {
    const FLAT: InferredRoof = InferredRoof {
        shape: RoofShape::Flat,
        pitch_deg: 0.0,
        direction_deg: None,
    };
}

/// The roof of a building in a row ([`super::rows`]) whose shared wall runs along `wall_deg`
/// (a compass bearing): one style for the row, without the variation drawn per building, so
/// neighbours agree — flat where most of their kind are (or where size or height make them so),
/// else gabled with its ridge across the shared walls, along the row, at the region's middle
/// pitch (hipped where the outline does not take gables).
pub fn row_roof(
    building: &str,
    footprint: &Footprint,
    height_m: Option<f64>,
    region: Region,
    wall_deg: f64,
) -> InferredRoof {
    let kind = kind_of(building);
    let mostly_flat = match kind {
        Kind::Flat | Kind::Small => true,
        Kind::Apartments | Kind::Other => {
            matches!(region, Region::Mediterranean | Region::Other)
        }
        Kind::House | Kind::Farm | Kind::Church => false,
    };
    if mostly_flat || flat_by_size(building, kind, footprint, height_m) {
        return InferredRoof::FLAT;
    }
    let (low, range) = region.house_pitch_deg();
    let pitch_deg = low + range / 2.0;
    if !footprint.takes_gables() {
        // A gable across an irregular outline would stand out of it: hipped, on its own
        // outline.
        return InferredRoof {
            shape: RoofShape::Hipped,
            pitch_deg,
            direction_deg: None,
        };
    }
    InferredRoof {
        shape: RoofShape::Gabled,
        pitch_deg,
        // The faces look along the shared wall, to the street on either side.
        direction_deg: Some(wall_deg),
    }
}

/// The levels a building most plausibly has when neither `height` nor `building:levels` is
/// tagged, by its `building` value, its footprint and the region; `None` where the type's own
/// default height serves (garages, sheds, industry).
pub fn levels(
    building: &str,
    footprint: &Footprint,
    region: Region,
    variation: Option<ElementRef>,
) -> Option<u32> {
    // Drawn from the element; a building in a row (no variation) takes the middle, as its
    // neighbours do.
    let extra = |most: u32| -> u32 {
        match variation {
            Some(element) => {
                let drawn = draw(element, SALT_LEVELS) * f64::from(most + 1);
                (drawn as u32).min(most)
            }
            None => most.div_ceil(2),
        }
    };
    match kind_of(building) {
        Kind::House if footprint.area_m2 <= 300.0 => {
            let (fewest, more) = region.house_levels();
            // Very small footprints are sheds and annexes, not two-storey houses.
            if footprint.area_m2 < SMALLEST_TWO_STOREYS_M2 {
                return Some(1);
            }
            Some(fewest + extra(more))
        }
        Kind::House => Some(if region == Region::Mediterranean {
            4 + extra(3)
        } else {
            3 + extra(2)
        }),
        Kind::Apartments => Some(if region == Region::Mediterranean {
            5 + extra(3)
        } else {
            4 + extra(2)
        }),
        // A field barn or a hut of a few square metres is one storey; farm buildings are
        // one or two.
        Kind::Farm if footprint.area_m2 < SMALLEST_TWO_STOREYS_M2 => Some(1),
        Kind::Farm => Some(1 + extra(1)),
        _ => None,
    }
}

/// The least footprint, square metres, of a house or farm building inferred to have a second
/// storey: smaller ones are sheds, annexes and field barns.
const SMALLEST_TWO_STOREYS_M2: f64 = 40.0;

const SALT_ROOF_COLOUR: u64 = 4;
const SALT_WALL_COLOUR: u64 = 5;

/// Roof colours (sRGB) by region: clay tiles, concrete tiles and slate where roofs are
/// pitched, asphalt shingles in North America.
fn pitched_roof_palette(region: Region) -> &'static [[u8; 3]] {
    match region {
        Region::Alpine | Region::CentralEurope => &[
            [0x9c, 0x4a, 0x35],
            [0xa8, 0x55, 0x3a],
            [0x8a, 0x3f, 0x2e],
            [0x6e, 0x3b, 0x2e],
            [0x4a, 0x4a, 0x4e],
            [0x5b, 0x4a, 0x42],
            [0xb0, 0x62, 0x45],
        ],
        Region::Mediterranean => &[
            [0xb8, 0x5e, 0x3c],
            [0xc4, 0x6d, 0x45],
            [0xa8, 0x52, 0x36],
            [0xcc, 0x7a, 0x50],
            [0x9e, 0x4f, 0x38],
        ],
        Region::NorthAmerica => &[
            [0x55, 0x55, 0x58],
            [0x6b, 0x63, 0x5b],
            [0x3f, 0x3f, 0x44],
            [0x7a, 0x6e, 0x62],
            [0x4e, 0x45, 0x3e],
            [0x5e, 0x66, 0x6e],
        ],
        Region::Other => &[
            [0x8a, 0x4a, 0x3a],
            [0x5a, 0x58, 0x5a],
            [0x9e, 0x5a, 0x40],
            [0x6e, 0x60, 0x58],
        ],
    }
}

/// Flat roofs: gravel, bitumen, membranes.
const FLAT_ROOF_PALETTE: [[u8; 3]; 5] = [
    [0x8e, 0x8c, 0x88],
    [0x9e, 0x9a, 0x92],
    [0x74, 0x74, 0x72],
    [0xa8, 0xa4, 0x9c],
    [0x82, 0x7e, 0x78],
];

/// Wall colours (sRGB) by region and use: plaster in Europe (warmer around the Mediterranean),
/// siding and brick in North America, grey cladding for industry.
fn wall_palette(region: Region, building: &str) -> &'static [[u8; 3]] {
    if kind_of(building) == Kind::Flat {
        return &[
            [0xb4, 0xb4, 0xb0],
            [0xc8, 0xc4, 0xbc],
            [0x9c, 0xa0, 0xa4],
            [0xd0, 0xcc, 0xc0],
        ];
    }
    match region {
        Region::Alpine | Region::CentralEurope => &[
            [0xf0, 0xeb, 0xe0],
            [0xe8, 0xde, 0xc8],
            [0xf2, 0xe6, 0xc4],
            [0xe6, 0xe2, 0xda],
            [0xdc, 0xd0, 0xb8],
            [0xee, 0xdc, 0xc0],
        ],
        Region::Mediterranean => &[
            [0xf0, 0xe0, 0xc0],
            [0xe8, 0xc8, 0xa0],
            [0xf2, 0xd8, 0xc8],
            [0xe0, 0xb8, 0x90],
            [0xf4, 0xec, 0xdc],
            [0xe8, 0xd4, 0xa8],
        ],
        Region::NorthAmerica => &[
            [0xf2, 0xf0, 0xea],
            [0xd8, 0xd4, 0xc8],
            [0xc8, 0xcc, 0xcc],
            [0xb8, 0x7a, 0x62],
            [0xe4, 0xd8, 0xc0],
            [0xc4, 0xcc, 0xd4],
        ],
        Region::Other => &[[0xe8, 0xe2, 0xd6], [0xd8, 0xd0, 0xc0], [0xe0, 0xd8, 0xcc]],
    }
}

/// The colours (sRGB, 0..1) of a building's walls and roof when none are tagged, by region,
/// type and whether its roof is flat, drawn from its element.
pub fn colours(
    building: &str,
    flat_roof: bool,
    region: Region,
    element: ElementRef,
) -> ([f64; 3], [f64; 3]) {
    let choose = |palette: &[[u8; 3]], salt| {
        let i = (draw(element, salt) * palette.len() as f64) as usize;
        palette[i.min(palette.len() - 1)].map(|c| f64::from(c) / 255.0)
    };
    let roofs: &[[u8; 3]] = if flat_roof {
        &FLAT_ROOF_PALETTE
    } else {
        pitched_roof_palette(region)
    };
    (
        choose(wall_palette(region, building), SALT_WALL_COLOUR),
        choose(roofs, SALT_ROOF_COLOUR),
    )
}

/// What was inferred for one building.
#[derive(Debug, Clone, PartialEq)]
pub struct Inferred {
    pub region: Region,
    /// Levels, when neither `height` nor `building:levels` is tagged and its type has no
    /// height of its own.
    pub levels: Option<u32>,
    /// The roof, when `roof:shape` is not tagged.
    pub roof: Option<InferredRoof>,
    /// Walls and roof (sRGB, 0..1), for what neither a colour nor a material is tagged for.
    pub colours: ([f64; 3], [f64; 3]),
}

/// The largest of a building's outlines that can be measured, with its footprint; `None` when
/// every one is too small or degenerate to measure.
pub fn largest<'a>(
    outlines: impl Iterator<Item = &'a [LonLat]>,
) -> Option<(&'a [LonLat], Footprint)> {
    outlines
        .filter_map(|outline| Some((outline, Footprint::of(outline)?)))
        .max_by(|a, b| a.1.area_m2.total_cmp(&b.1.area_m2))
}

/// Infers what a building's tags leave unsaid from its `building` value, its outline (the
/// largest, when it has several: see [`largest`]) and its footprint, the height tagged (if any), its element and, for a building
/// in a row, the bearing of its shared wall; `None` for an empty outline.
pub fn building(
    tags: &Tags,
    (outline, footprint): (&[LonLat], &Footprint),
    tagged_height_m: Option<f64>,
    element: ElementRef,
    row: Option<f64>,
) -> Option<Inferred> {
    let region = Region::of(*outline.first()?);
    let kind = tags.get("building").unwrap_or("yes");
    let shape_tagged = tags.is_set("roof:shape") || tags.is_set("building:roof:shape");
    let levels_tagged = tags.is_set("building:levels");
    let levels = (tagged_height_m.is_none() && !levels_tagged)
        .then(|| levels(kind, footprint, region, row.is_none().then_some(element)))
        .flatten();
    let roof = (!shape_tagged).then(|| match row {
        Some(wall_deg) => row_roof(kind, footprint, tagged_height_m, region, wall_deg),
        None => roof(kind, footprint, tagged_height_m, region, element),
    });
    let flat = roof.map_or(tags.get("roof:shape") == Some("flat"), |r| {
        r.shape == RoofShape::Flat
    });
    Some(Inferred {
        region,
        levels,
        roof,
        colours: colours(kind, flat, region, element),
    })
}

#[cfg(test)]
mod tests;
