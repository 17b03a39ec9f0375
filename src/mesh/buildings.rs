//! Extruded buildings: walls from below the lowest ground under the footprint up to the eaves,
//! and the roof: flat, or hipped and gabled roofs on the straight skeleton ([`super::roofs`]).
//!
//! The base follows thesis §4.1 in its simplest form: the lowest terrain point under the whole
//! footprint (vertices, points along the walls, raster samples inside), computed in global
//! coordinates so that a building cut by a tile edge has the same base and top in both tiles.
//! Walls start [`WALL_SKIRT_M`] below that, so no wall ends above the ground on a slope. An
//! untagged height is raised where needed so the roof clears the highest ground under it.

use std::collections::BTreeMap;

use super::roofs::{
    bend, centred_roof, long_axis, profile_roof, skeleton_roof, spread, CentredRoof, RoofEnd,
    RoofError, RoofMesh, SkeletonRoof,
};
use super::{facades, newell, passages, MeshBuffers, Part};
use crate::features::buildings::{RoofShape, RoofSpec};
use crate::features::BuildingShape;
use crate::geometry::constrained::triangulate_polygon;
use crate::geometry::{clip_to_rect, signed_area2, Point, Polygon};
use crate::terrain::{Elevation, TerrainModel};
use crate::tile::TileFrame;

/// How far walls reach below the lowest ground point, metres: hides the difference between the
/// sampled minimum and the triangulated ground between its vertices.
pub const WALL_SKIRT_M: f64 = 0.5;

/// Least height of a roof above the highest ground under a building whose height is a default.
const MIN_CLEARANCE_M: f64 = 2.5;

/// Footprints with more vertices than this get a flat roof: the skeleton's cost grows with the
/// cube of the count.
pub const MAX_ROOF_VERTICES: usize = 400;

/// The largest share of a building's height its roof may take.
const MAX_ROOF_SHARE: f64 = 0.6;

/// Points along each wall at which the ground is sampled, per SRTM sample spacing.
const WALL_SAMPLES_PER_CELL: f64 = 4.0;

/// The lowest and highest ground under a footprint, metres: the ground as settled (water at its
/// level), along the walls and at the terrain's raster samples inside.
pub fn ground_range(
    footprint: &Polygon,
    terrain: &TerrainModel<'_>,
    ground: &dyn Elevation,
    sample_step_uv: f64,
) -> (f64, f64) {
    let mut low = f64::INFINITY;
    let mut high = f64::NEG_INFINITY;
    let mut visit = |h: f64| {
        low = low.min(h);
        high = high.max(h);
    };
    for ring in footprint.rings() {
        for i in 0..ring.len() {
            let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
            let length = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
            let steps = (length / sample_step_uv * WALL_SAMPLES_PER_CELL)
                .ceil()
                .max(1.0) as usize;
            for s in 0..steps {
                let t = s as f64 / steps as f64;
                visit(ground.elevation_uv([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]));
            }
        }
    }
    let bounds = footprint.bounds();
    for p in terrain.sample_positions_uv(bounds.min, bounds.max) {
        if footprint.contains(p) {
            visit(ground.elevation_uv(p));
        }
    }
    (low, high)
}

/// A building's closed shell: plan coordinates in metres around its footprint's first vertex
/// (`x` and `y` growing with the tile coordinates `u` and `v`), the third coordinate its
/// elevation in metres. Every face is wound counter-clockwise seen from outside in that
/// `(x, y, elevation)` frame; together the faces close (every edge is shared by two of them,
/// running opposite ways), as long as the footprint does not cross itself.
#[derive(Debug, Clone, Default)]
pub struct Solid {
    /// The footprint's first vertex, tile units: `(0, 0)` of the plan.
    pub origin: Point,
    /// Metres per tile unit.
    pub size_m: f64,
    /// The lowest ground under the building's outline, metres: heights count from here.
    pub ground: f64,
    /// Vertical faces: the walls, and the gables and sides of the roof.
    pub walls: Vec<Vec<[f64; 3]>>,
    /// The roof's triangles.
    pub roof: Vec<[[f64; 3]; 3]>,
    /// True when the roof is flat (one normal for all its triangles).
    pub flat_roof: bool,
    /// The elevation of the eaves (the top of a flat roof), metres: the walls' levels end here.
    pub eaves: f64,
    /// The bottom, facing down: under a part that floats, underground otherwise.
    pub floor: Vec<[[f64; 3]; 3]>,
    /// True for a part above the ground (`min_height`).
    pub floating: bool,
    /// Why the roof is simpler than the tags asked for, if it is.
    pub fallback: Option<Fallback>,
}

impl Solid {
    /// A plan point in tile units.
    pub fn to_uv(&self, x: f64, y: f64) -> Point {
        [
            self.origin[0] + x / self.size_m,
            self.origin[1] + y / self.size_m,
        ]
    }

    /// Every face as a polygon: walls, roof, floor.
    pub fn faces(&self) -> impl Iterator<Item = Vec<[f64; 3]>> + '_ {
        self.walls
            .iter()
            .cloned()
            .chain(self.roof.iter().chain(&self.floor).map(|t| t.to_vec()))
    }
}

/// Why a building got a simpler roof than its tags ask for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Fallback {
    /// More than [`MAX_ROOF_VERTICES`] footprint vertices: flat.
    TooDetailed,
    /// A pyramid, dome or onion over a footprint with courtyards or not star-shaped around its
    /// centroid: hipped.
    NotStarShaped,
    /// The straight skeleton or the roof on it could not be built: gabled across the
    /// footprint's long axis, drawn by a profile on the outline as it is.
    Skeleton,
    /// Neither the straight skeleton nor a gabled profile could be built: flat.
    SkeletonAndProfile,
    /// The footprint has no width across the roof's direction: flat.
    Profile,
}

impl Fallback {
    pub fn describe(self) -> &'static str {
        match self {
            Fallback::TooDetailed => "footprint too detailed: flat",
            Fallback::NotStarShaped => "not star-shaped around its centroid: hipped",
            Fallback::Skeleton => "no straight skeleton: gabled by a profile",
            Fallback::SkeletonAndProfile => "no straight skeleton and no width across: flat",
            Fallback::Profile => "no width across the roof: flat",
        }
    }
}

/// The shell of a building whose lowest and highest ground (under its outline) are `low` and
/// `high`, metres, closed over the roads that pass through it.
pub fn solid(building: &BuildingShape, size_m: f64, low: f64, high: f64) -> Solid {
    solid_over_passages(building, size_m, low, high, None)
}

/// The shell of a building (see [`solid`]) whose walls open over the roads that pass through
/// it ([`BuildingShape::passages`]), under a ceiling [`passages::HEADROOM_M`] over `ground`
/// (the ground as settled, by tile units) where the walls above leave room for it.
pub fn solid_over_passages(
    building: &BuildingShape,
    size_m: f64,
    low: f64,
    high: f64,
    ground: Option<&dyn Elevation>,
) -> Solid {
    let footprint = &building.footprint;
    let Some(&origin) = footprint
        .outer
        .first()
        .filter(|_| footprint.outer.len() >= 3)
    else {
        return Solid::default();
    };
    let mut rings: Vec<Vec<Point>> = footprint
        .rings()
        .map(|r| plan_ring(r, origin, size_m))
        .collect();
    for (index, ring) in rings.iter_mut().enumerate() {
        if (index == 0) == (signed_area2(ring) < 0.0) {
            ring.reverse();
        }
    }
    let mut top = low + building.height_m + building.basement_m.min(high - low);
    if !building.height_tagged {
        top = top.max(high + MIN_CLEARANCE_M);
    }
    let floating = building.min_height_m > 0.0;
    let bottom = if floating {
        low + building.min_height_m
    } else {
        low - WALL_SKIRT_M
    };
    let (pitched, fallback) = pitched_roof(building, &rings);
    if let Some(roof) = &pitched {
        rings.clone_from(&roof.rings);
    }
    let plan = Polygon {
        outer: rings[0].clone(),
        holes: rings[1..].to_vec(),
    };
    // Roads through the building, the ground under them by plan metres.
    let ground_at = |p: Point| {
        ground.map_or(low, |g| {
            g.elevation_uv([origin[0] + p[0] / size_m, origin[1] + p[1] / size_m])
        })
    };
    let carving = ground
        .filter(|_| !floating)
        .and_then(|_| carving_of(building, &plan, origin, size_m));
    if let Some(carving) = carving.as_ref().filter(|_| !building.height_tagged) {
        // A guessed height leaves a storey over a road through the building.
        let ceiling = carving.highest_ground(&ground_at) + passages::HEADROOM_M;
        top = top.max(ceiling + passages::STOREY_M);
    }
    let mut solid = Solid {
        origin,
        size_m,
        ground: low,
        floating,
        fallback,
        ..Solid::default()
    };
    let at = |p: Point, elevation: f64| [p[0], p[1], elevation];
    // A pitched roof takes its height from the top, or stands on it when the height counts
    // the levels under the roof only; the walls stop at its eaves, on the rings the roof stands
    // on, so the two meet edge for edge.
    let eaves = match &pitched {
        Some(roof) => {
            let eaves = if building.roof.over_levels {
                top
            } else {
                top - roof.height
            };
            let raise = |c: [f64; 3]| [c[0], c[1], eaves + c[2]];
            solid.roof = roof.slopes.iter().map(|t| t.map(raise)).collect();
            // A side whose top rounds onto the eaves is none.
            for side in &roof.sides {
                let mut face: Vec<[f64; 3]> = side.iter().copied().map(raise).collect();
                face.dedup();
                if face.len() >= 3 {
                    solid.walls.push(face);
                }
            }
            eaves
        }
        None => top,
    };
    solid.eaves = eaves;
    let carving = carving.and_then(|c| c.with_ceiling(&ground_at, eaves));
    // Walls: the building lies left of every edge (outer ring counter-clockwise, holes
    // clockwise), so `a, b` at the bottom then `b, a` at the eaves faces outwards.
    // Their tops pass through the points where the roof above them bends.
    for (r, ring) in rings.iter().enumerate() {
        for i in 0..ring.len() {
            let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
            if a == b {
                continue;
            }
            let mut top = vec![at(b, eaves)];
            if let Some(roof) = &pitched {
                top.extend(roof.edge_points(r, i).iter().rev().map(|&p| at(p, eaves)));
            }
            top.push(at(a, eaves));
            match &carving {
                Some(carving) => solid.walls.extend(carving.wall(r, i, bottom, &top)),
                None => {
                    let mut wall = vec![at(a, bottom), at(b, bottom)];
                    wall.extend(top);
                    solid.walls.push(wall);
                }
            }
        }
    }
    let cap = triangulate_polygon(&plan);
    let oriented = |t: &[Point], up: bool, elevation: f64| {
        let [a, b, c] = [t[0], t[1], t[2]];
        let (b, c) = if (signed_area2(&[a, b, c]) > 0.0) == up {
            (b, c)
        } else {
            (c, b)
        };
        [at(a, elevation), at(b, elevation), at(c, elevation)]
    };
    match &carving {
        Some(carving) => {
            solid.walls.extend(carving.side_walls(bottom));
            solid.floor = carving
                .floor()
                .map(|t| oriented(t, false, bottom))
                .chain(carving.ceiling())
                .collect();
        }
        None => solid.floor = cap.iter().map(|t| oriented(t, false, bottom)).collect(),
    }
    if pitched.is_none() {
        solid.flat_roof = true;
        solid.roof = cap.iter().map(|t| oriented(t, true, top)).collect();
    }
    solid
}

/// The roads through a building cut into its plan (metres around `origin`); `None` when no
/// road reaches under it.
fn carving_of(
    building: &BuildingShape,
    plan: &Polygon,
    origin: Point,
    size_m: f64,
) -> Option<passages::Carving> {
    if building.passages.is_empty() {
        return None;
    }
    let plan_of = |p: &Polygon| Polygon {
        outer: plan_ring(&p.outer, origin, size_m),
        holes: p
            .holes
            .iter()
            .map(|h| plan_ring(h, origin, size_m))
            .collect(),
    };
    let cuts: Vec<Polygon> = building.passages.iter().map(plan_of).collect();
    passages::Carving::new(plan, &cuts)
}

/// A ring in tile units in a building's plan: metres around `origin`.
fn plan_ring(ring: &[Point], origin: Point, size_m: f64) -> Vec<Point> {
    ring.iter()
        .map(|p| [(p[0] - origin[0]) * size_m, (p[1] - origin[1]) * size_m])
        .collect()
}

/// The buildings drawn in the tile as parts: one primitive per finish of blank walls and of
/// roofs, and per glazing of walls with windows; `sample_step_uv` is how finely the ground
/// under them is sampled.
pub fn build(
    buildings: &[BuildingShape],
    frame: &TileFrame,
    terrain: &TerrainModel<'_>,
    ground: &dyn Elevation,
    sample_step_uv: f64,
) -> BTreeMap<Part, MeshBuffers> {
    let mut parts: BTreeMap<Part, MeshBuffers> = BTreeMap::new();
    let solids = solids(buildings, frame, terrain, ground, sample_step_uv);
    for (building, solid) in buildings.iter().zip(&solids) {
        if let Some(solid) = solid {
            extrude(building, solid, frame, &mut parts);
        }
    }
    parts
}

/// The shells of the buildings drawn in the tile (`None` for the others), each on the ground
/// under its outline: the parts of one building share the ground range of their outline,
/// sampled once.
pub fn solids(
    buildings: &[BuildingShape],
    frame: &TileFrame,
    terrain: &TerrainModel<'_>,
    ground: &dyn Elevation,
    sample_step_uv: f64,
) -> Vec<Option<Solid>> {
    let rect = crate::features::tile_rect(frame.tile);
    let mut ranges: std::collections::HashMap<usize, (f64, f64)> = Default::default();
    buildings
        .iter()
        .enumerate()
        .map(|(index, building)| {
            if !building.drawn || !building.footprint.bounds().intersects(&rect) {
                return None;
            }
            let base = building
                .base
                .filter(|&b| b < buildings.len())
                .unwrap_or(index);
            let (low, high) = *ranges.entry(base).or_insert_with(|| {
                ground_range(&buildings[base].footprint, terrain, ground, sample_step_uv)
            });
            Some(solid_over_passages(
                building,
                frame.size_m,
                low,
                high,
                Some(ground),
            ))
        })
        .collect()
}

/// Adds the part of a building's shell inside the tile to `parts`: walls (with windows where
/// its facade has them), roof and floor.
pub fn extrude(
    building: &BuildingShape,
    solid: &Solid,
    frame: &TileFrame,
    parts: &mut BTreeMap<Part, MeshBuffers>,
) {
    let rect = crate::features::tile_rect(frame.tile);
    let look = &building.appearance;
    // Each face clipped to the tile in the plan, its height (and texture coordinates) carried
    // along.
    let place = |face: &[[f64; 3]], uvs: Option<&[[f64; 2]]>| {
        let lifted: Vec<[f64; 5]> = face
            .iter()
            .enumerate()
            .map(|(i, c)| {
                let [u, v] = solid.to_uv(c[0], c[1]);
                let [s, t] = uvs.map_or([0.0; 2], |uvs| uvs[i]);
                [u, v, c[2], s, t]
            })
            .collect();
        let clipped = clip_to_rect(&lifted, &rect);
        let corners: Vec<[f64; 3]> = clipped
            .iter()
            .map(|&[u, v, elevation, ..]| {
                let (x, z) = frame.uv_to_local(u, v);
                [x, frame.elevation_to_y(elevation, z), z]
            })
            .collect();
        let uvs: Vec<[f64; 2]> = clipped
            .iter()
            .map(|&[.., s, t]| facades::snapped([s, t]))
            .collect();
        (corners, uvs)
    };
    // The plan's (x, y, elevation) is the local frame's (x, z, y).
    let facing = |face: &[[f64; 3]]| {
        let n = newell(face);
        [n[0], n[2], n[1]]
    };
    let facade = &building.facade;
    let levels = facades::Levels::new(facade, solid.ground, solid.eaves);
    for face in &solid.walls {
        // A gable or a side of the roof, above the eaves, is wall only: drawn blank, it needs no
        // texture coordinates.
        let gable = face.iter().all(|c| c[2] >= solid.eaves);
        let pieces = match (facade.ground, facade.upper) {
            _ if gable => [(face.clone(), None), (Vec::new(), None)],
            (Some(ground), upper) => {
                let (below, above) = facades::split_at(face, levels.ground_floor_top());
                [(below, Some(ground)), (above, upper)]
            }
            (None, upper) => [(face.clone(), upper), (Vec::new(), None)],
        };
        for (piece, glazing) in pieces.iter().filter(|(p, _)| p.len() >= 3) {
            let across = glazing.and_then(|g| {
                let bay = if Some(g) == facade.upper {
                    facade.bay_m
                } else {
                    g.bay_m()
                };
                facades::Across::of(face, bay).map(|a| (g, a))
            });
            match across {
                Some((glazing, across)) => {
                    let (corners, uvs) = place(piece, Some(&across.uvs(piece, &levels)));
                    painted(parts, Part::Facade(glazing), look.walls).push_textured_polygon(
                        &corners,
                        &uvs,
                        facing(face),
                        building.feature,
                    );
                }
                None => {
                    let (corners, _) = place(piece, None);
                    painted(parts, Part::BuildingWalls(look.wall_finish), look.walls)
                        .push_flat_polygon(&corners, facing(face), building.feature);
                }
            }
        }
    }
    let fan = |triangles: &[[[f64; 3]; 3]]| -> Vec<[[f64; 3]; 3]> {
        let mut out = Vec::with_capacity(triangles.len());
        for t in triangles {
            let (corners, _) = place(t, None);
            for i in 1..corners.len().saturating_sub(1) {
                out.push([corners[0], corners[i], corners[i + 1]]);
            }
        }
        out
    };
    // The floor closes the shell (under the ground where the building stands on it), so a
    // building is a closed solid in the tile for printing, volumes and shadow volumes.
    painted(parts, Part::BuildingWalls(look.wall_finish), look.walls).push_flat_triangles(
        &fan(&solid.floor),
        [0.0, -1.0, 0.0],
        building.feature,
    );
    let roofs = painted(parts, Part::BuildingRoofs(look.roof_finish), look.roof);
    if solid.flat_roof {
        roofs.push_flat_triangles(&fan(&solid.roof), [0.0, 1.0, 0.0], building.feature);
    } else {
        for triangle in &solid.roof {
            let (corners, _) = place(triangle, None);
            roofs.push_flat_polygon(&corners, facing(triangle), building.feature);
        }
    }
}

/// The buffers of a part, painted from now on in `colour`.
fn painted(
    parts: &mut BTreeMap<Part, MeshBuffers>,
    part: Part,
    colour: [u8; 4],
) -> &mut MeshBuffers {
    let buffers = parts.entry(part).or_default();
    buffers.paint(colour);
    buffers
}

/// Untagged roof heights are rise per run times these shares of the footprint's width across
/// the roof.
const SKILLION_RUN: f64 = 1.0;
const GABLE_RUN: f64 = 0.5;
const SALTBOX_RIDGE: f64 = 2.0 / 3.0;

/// Teeth of a sawtooth roof: one per this many metres of width.
const SAWTOOTH_PERIOD_M: f64 = 8.0;
/// Share of each tooth its long slope takes; the steep glazed face takes the rest.
const SAWTOOTH_SLOPE: f64 = 0.85;
/// Segments of a round roof's arc.
const ROUND_STEPS: usize = 8;

/// The building's pitched roof in the plan's metres, `None` for a flat one; and why it is
/// simpler than tagged, if it is (logged at debug level). Pyramids, domes and onions rise
/// over the centroid of a footprint without courtyards that is star-shaped around it; other
/// footprints get a hipped roof instead.
fn pitched_roof(
    building: &BuildingShape,
    rings: &[Vec<Point>],
) -> (Option<RoofMesh>, Option<Fallback>) {
    let spec = &building.roof;
    if spec.shape == RoofShape::Flat {
        return (None, None);
    }
    let fall_back = |fallback: Fallback, error: Option<RoofError>| {
        tracing::debug!(
            feature = building.feature,
            ?error,
            "{}",
            fallback.describe()
        );
        Some(fallback)
    };
    if rings.iter().map(Vec::len).sum::<usize>() > MAX_ROOF_VERTICES {
        return (None, fall_back(Fallback::TooDetailed, None));
    }
    let most = building.height_m * MAX_ROOF_SHARE;
    let tagged = spec.height_m.map(|h| h.min(most));
    let mut fallback = None;
    if let Some(centred) = centred_shape(spec.shape) {
        let built = centred_roof_over(spec, rings, centred, tagged, most);
        if built.is_some() {
            return (built, None);
        }
        fallback = fall_back(Fallback::NotStarShaped, None);
    }
    let direction = main_face_direction(spec);
    let profile = roof_profile(spec, direction);
    if profile.is_some() || spec.shape == RoofShape::Sawtooth {
        return match profiled_roof(spec, rings, direction, profile, tagged, most) {
            Ok(mesh) => (Some(mesh), fallback),
            Err(error) => (None, fall_back(Fallback::Profile, error)),
        };
    }
    let shape = skeleton_shape(spec, direction);
    match skeleton_roof_within(rings, shape, tagged, spec.pitch, most) {
        Ok(mut mesh) => {
            if matches!(spec.shape, RoofShape::Mansard | RoofShape::Gambrel) {
                bend(&mut mesh);
            }
            (Some(mesh), fallback)
        }
        // The outline stays as drawn (the ground is cut by it): a profile needs no skeleton.
        Err(error) => {
            let gable = Some((vec![(0.0, 0.0), (0.5, 1.0), (1.0, 0.0)], GABLE_RUN));
            match profiled_roof(spec, rings, None, gable, tagged, most) {
                Ok(mesh) => (Some(mesh), fall_back(Fallback::Skeleton, Some(error))),
                Err(_) => (None, fall_back(Fallback::SkeletonAndProfile, Some(error))),
            }
        }
    }
}

/// The shapes that rise to one point over the centroid rather than along a ridge.
fn centred_shape(shape: RoofShape) -> Option<CentredRoof> {
    match shape {
        RoofShape::Pyramidal => Some(CentredRoof::Pyramid),
        RoofShape::Dome => Some(CentredRoof::Dome),
        RoofShape::Onion => Some(CentredRoof::Onion),
        _ => None,
    }
}

/// A pyramid, dome or onion over a footprint without courtyards, if it is star-shaped around
/// its centroid. Untagged, a pyramid rises at the roof's pitch over the least distance from the
/// centroid to a side, a dome as high as the mean distance to a corner, an onion half as high
/// again.
fn centred_roof_over(
    spec: &RoofSpec,
    rings: &[Vec<Point>],
    centred: CentredRoof,
    tagged: Option<f64>,
    most: f64,
) -> Option<RoofMesh> {
    match rings {
        [outer] => spread(outer).and_then(|(inner, radius)| {
            let untagged = match centred {
                CentredRoof::Pyramid => spec.pitch * inner,
                CentredRoof::Dome => radius,
                CentredRoof::Onion => 1.5 * radius,
            };
            centred_roof(outer, centred, tagged.unwrap_or(untagged).min(most))
        }),
        _ => None,
    }
}

/// The plan direction the roof's main face looks towards (`roof:direction`: 0° north, 90°
/// east; the plan's y grows southwards), when tagged.
fn main_face_direction(spec: &RoofSpec) -> Option<Point> {
    spec.direction_deg.map(|d| {
        let d = d.to_radians();
        [d.sin(), -d.cos()]
    })
}

/// The section of a roof drawn along a profile, as (share of the width, share of the height)
/// points, with the run its untagged height is reckoned on; `None` for the other shapes
/// (a sawtooth's profile depends on the footprint's width, see [`sawtooth_profile`]).
fn roof_profile(spec: &RoofSpec, direction: Option<Point>) -> Option<(Vec<(f64, f64)>, f64)> {
    match spec.shape {
        RoofShape::Skillion => Some((vec![(0.0, 0.0), (1.0, 1.0)], SKILLION_RUN)),
        RoofShape::Saltbox => Some((
            vec![(0.0, 0.0), (SALTBOX_RIDGE, 1.0), (1.0, 0.0)],
            SALTBOX_RIDGE,
        )),
        RoofShape::Butterfly => Some((vec![(0.0, 1.0), (0.5, 0.0), (1.0, 1.0)], GABLE_RUN)),
        RoofShape::Round => Some((
            (0..=ROUND_STEPS)
                .map(|i| {
                    let angle = std::f64::consts::PI * i as f64 / ROUND_STEPS as f64;
                    ((1.0 - angle.cos()) / 2.0, angle.sin())
                })
                .collect(),
            GABLE_RUN,
        )),
        RoofShape::Gabled if spec.across || direction.is_some() => {
            Some((vec![(0.0, 0.0), (0.5, 1.0), (1.0, 0.0)], GABLE_RUN))
        }
        _ => None,
    }
}

/// A sawtooth's section across `width` metres: a tooth per [`SAWTOOTH_PERIOD_M`], each a long
/// slope and a steep face, with the run of one slope.
fn sawtooth_profile(width: f64) -> (Vec<(f64, f64)>, f64) {
    let teeth = (width / SAWTOOTH_PERIOD_M).round().max(1.0) as usize;
    let mut profile = vec![(0.0, 0.0)];
    for k in 0..teeth {
        let start = k as f64 / teeth as f64;
        profile.push((start + SAWTOOTH_SLOPE / teeth as f64, 1.0));
        profile.push(((k + 1) as f64 / teeth as f64, 0.0));
    }
    (profile, SAWTOOTH_SLOPE / teeth as f64)
}

/// A roof drawn along `profile` (a sawtooth's when `None`), rising away from the main face, else
/// across the ridge, which runs along the longer side unless `roof:orientation=across`. The
/// error is `None` when the footprint has no long axis to rise along.
fn profiled_roof(
    spec: &RoofSpec,
    rings: &[Vec<Point>],
    direction: Option<Point>,
    profile: Option<(Vec<(f64, f64)>, f64)>,
    tagged: Option<f64>,
    most: f64,
) -> Result<RoofMesh, Option<RoofError>> {
    let across = || {
        let long = long_axis(&rings[0])?;
        Some(if spec.across {
            long
        } else {
            [-long[1], long[0]]
        })
    };
    // Rising away from the main face: it looks down the slope.
    let axis = direction.map(|d| [-d[0], -d[1]]).or_else(across);
    let Some(axis) = axis else {
        return Err(None);
    };
    let values = rings[0].iter().map(|p| p[0] * axis[0] + p[1] * axis[1]);
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
        (lo.min(x), hi.max(x))
    });
    let width = hi - lo;
    let (profile, run) = profile.unwrap_or_else(|| sawtooth_profile(width));
    let height = tagged.unwrap_or(spec.pitch * run * width).min(most);
    profile_roof(rings, axis, &profile, height).map_err(Some)
}

/// How the skeleton finishes the ends of the roof's wings for the tagged shape; hipped unless
/// the shape says otherwise.
fn skeleton_shape(spec: &RoofSpec, direction: Option<Point>) -> SkeletonRoof {
    match spec.shape {
        RoofShape::Gabled | RoofShape::Gambrel => SkeletonRoof::GABLED,
        RoofShape::HalfHipped => SkeletonRoof::ends(RoofEnd::HalfHip),
        RoofShape::HippedAndGabled => SkeletonRoof::ends(RoofEnd::Gablet),
        RoofShape::SideHipped | RoofShape::SideHalfHipped => SkeletonRoof {
            ends: RoofEnd::Gable,
            one_end: Some((
                direction.unwrap_or([1.0, 0.0]),
                if spec.shape == RoofShape::SideHipped {
                    RoofEnd::Hip
                } else {
                    RoofEnd::HalfHip
                },
            )),
        },
        _ => SkeletonRoof::HIPPED,
    }
}

/// The skeleton's roof, built again at `most` when it rises higher.
fn skeleton_roof_within(
    rings: &[Vec<Point>],
    shape: SkeletonRoof,
    tagged: Option<f64>,
    pitch: f64,
    most: f64,
) -> Result<RoofMesh, RoofError> {
    skeleton_roof(rings, shape, tagged, pitch).and_then(|mesh| {
        if mesh.height > most {
            skeleton_roof(rings, shape, Some(most), pitch)
        } else {
            Ok(mesh)
        }
    })
}

#[cfg(test)]
mod tests;
