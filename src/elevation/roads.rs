//! Roads on the ground lie level across their width, and junctions lie level (thesis §4.2:
//! the left, centre and right connectors of a cross-section are equal; a junction area is
//! flat).
//!
//! Each stretch of a road between junctions follows its way's settled profile
//! ([`super::road_profiles`]: the terrain, held to the class's grade and level where it leaves a
//! junction) along its centre line, sampled every [`PROFILE_STEP_M`]; every point of the
//! stretch takes the profile's elevation at its station across the strip (the same for the
//! left and right corners of a cross-section). A junction lies at the terrain under its node,
//! which is where the profiles of the roads that meet there start. All of it is computed from
//! whole ways, so tiles that share a road draw it the same.
//!
//! The ground under a raised sidewalk lies level with its kerb's top across its band, at the
//! road's edge beside it: where the land beside the road rises or falls, it does so beyond the
//! sidewalk's outer edge (a cutting or an embankment up to the next vertex of the ground),
//! never under the sidewalk. The outer edges are stitched into the ground's mesh.

use rustc_hash::FxHashMap;

use super::road_profiles::RoadProfiles;
use super::settled::{samples_along, Level, Rule, Sections, Stations, ON_OUTLINE};
use crate::features::road_network::StretchLine;
use crate::features::sidewalks::{Band, Look};
use crate::features::{FeatureClass, FeatureSet};
use crate::geometry::{Point, Polygon, Rect};
use crate::osm::ElementType;
use crate::terrain::Elevation;

/// Spacing of the terrain samples along a road's centre line, metres.
pub const PROFILE_STEP_M: f64 = 5.0;

/// How far the terrain at a sidewalk's outer edge must lie above or below the sidewalk's top,
/// metres, somewhere along its band, for the ground under the band to be levelled: less, and
/// the sidewalk lies on the ground as it is.
const LEVEL_APART_M: f64 = 0.25;

/// Cells per tile unit of the grid that finds the levels under a point.
const CELLS_PER_UNIT: f64 = 64.0;

/// The levels of the roads and junctions of a tile, found by a grid.
#[derive(Debug, Default)]
pub struct RoadLevels {
    levels: Vec<Level>,
    /// What each level is: junction levels win over the roads that meet them, and roads over
    /// the sidewalks beside them.
    kinds: Vec<Kind>,
    /// For each cell, the pieces of levels that may cover a point of it, in the levels'
    /// order, so most are passed over on their box.
    grid: FxHashMap<(i64, i64), Vec<Piece>>,
    /// The lines the ground bends along: each sidewalk band's ends and outer edge.
    edges: Vec<Vec<Point>>,
}

/// A piece of a level in a cell of the grid: the level, the piece, and the piece's box widened
/// by [`ON_OUTLINE`].
type Piece = (u32, u32, Rect);

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Junction,
    Road,
    Sidewalk,
}

impl RoadLevels {
    /// The elevation of a road or junction at `p`, if one covers it: a junction's first, else
    /// the lowest of the road stretches there, else the lowest of the sidewalks' bands.
    pub fn elevation(&self, p: Point) -> Option<f64> {
        let cell = cell_of(p);
        let candidates = self.grid.get(&cell)?;
        let (mut road, mut side): (Option<f64>, Option<f64>) = (None, None);
        // The level found covering `p` last: its other pieces need not be read.
        let mut covering = None;
        for &(i, piece, bounds) in candidates {
            if covering == Some(i) || !bounds.contains(p) {
                continue;
            }
            let level = &self.levels[i as usize];
            if !level.piece_covers(piece as usize, p) {
                continue;
            }
            covering = Some(i);
            let h = level.rule.elevation(p);
            let lowest = |now: Option<f64>| Some(now.map_or(h, |r: f64| r.min(h)));
            match self.kinds[i as usize] {
                Kind::Junction => return Some(h),
                Kind::Road => road = lowest(road),
                Kind::Sidewalk => side = lowest(side),
            }
        }
        road.or(side)
    }

    /// The lines along which the ground these levels settle bends away from a level: the ends
    /// and outer edges of the sidewalks' bands (global tile units).
    pub fn edges(&self) -> &[Vec<Point>] {
        &self.edges
    }

    /// The surfaces (indices into the feature set) whose vertices these levels settle.
    pub fn surfaces(&self) -> impl Iterator<Item = u32> + '_ {
        self.levels
            .iter()
            .zip(&self.kinds)
            .filter(|(_, &kind)| kind != Kind::Sidewalk)
            .map(|(l, _)| l.surface)
    }

    pub fn len(&self) -> usize {
        self.levels.len()
    }

    pub fn is_empty(&self) -> bool {
        self.levels.is_empty()
    }

    fn push(&mut self, level: Level, kind: Kind) {
        let index = self.levels.len() as u32;
        // Each piece in its own cells: a long road's box holds many cells it does not touch,
        // and a piece's box holds little but the piece.
        for (k, piece) in level.pieces.iter().enumerate() {
            let near = piece.bounds().widened(ON_OUTLINE);
            let (a, b) = (cell_of(near.min), cell_of(near.max));
            for x in a.0..=b.0 {
                for y in a.1..=b.1 {
                    self.grid
                        .entry((x, y))
                        .or_default()
                        .push((index, k as u32, near));
                }
            }
        }
        self.levels.push(level);
        self.kinds.push(kind);
    }
}

fn cell_of(p: Point) -> (i64, i64) {
    (
        (p[0] * CELLS_PER_UNIT).floor() as i64,
        (p[1] * CELLS_PER_UNIT).floor() as i64,
    )
}

/// The levels of the road surfaces of `set` drawn by the road network (surfaces listed in
/// `skip` are settled otherwise), along the profiles of their ways (the terrain for a way
/// without one); `metres_per_unit` is the tile's size.
pub fn levels(
    set: &FeatureSet,
    profiles: &RoadProfiles,
    terrain: &dyn Elevation,
    metres_per_unit: f64,
    skip: &[u32],
) -> RoadLevels {
    let mut out = RoadLevels::default();
    let step = PROFILE_STEP_M / metres_per_unit;
    for (index, surface) in set.surfaces.iter().enumerate() {
        if surface.class != FeatureClass::Road || skip.contains(&(index as u32)) {
            continue;
        }
        if let Some(node) = surface.junction_at {
            out.push(
                Level::new(
                    index as u32,
                    surface.pieces.clone(),
                    surface.bounds,
                    Rule::Level(terrain.elevation_uv(node)),
                ),
                Kind::Junction,
            );
            continue;
        }
        let way = set
            .features
            .get(surface.feature as usize)
            .and_then(|f| f.element)
            .filter(|e| e.element_type == ElementType::Way)
            .and_then(|e| profiles.profiles.get(&e.id));
        let profile = |line: &StretchLine, centre: &[Point]| match way {
            Some(way) => way.along_stretch(line, centre, step),
            None => terrain_profile(centre, terrain, step),
        };
        for (range, line) in &surface.piece_lines {
            let Some(pieces) = surface.pieces.get(range.clone()) else {
                continue;
            };
            let pieces: Vec<Polygon> = pieces.to_vec();
            let Some(bounds) = Rect::around_all(&pieces) else {
                continue;
            };
            // Stations by cross-section; where the strip is not a row of quads (it always
            // is, as the network draws it), along the line.
            let rule = match Sections::from_quads(&pieces) {
                Some(sections) => {
                    let centre = sections.centre_line();
                    Rule::Across {
                        profile: profile(line, &centre),
                        sections,
                    }
                }
                None => Rule::Along {
                    stations: Stations::new(&line.points),
                    profile: profile(line, &line.points),
                },
            };
            out.push(Level::new(index as u32, pieces, bounds, rule), Kind::Road);
        }
    }
    let sidewalks: Vec<(Level, Vec<Point>)> = set
        .sidewalks
        .iter()
        .filter_map(|band| sidewalk_level(band, &out, terrain))
        .collect();
    for (level, edge) in sidewalks {
        out.push(level, Kind::Sidewalk);
        out.edges.push(edge);
    }
    out
}

/// The level of a raised sidewalk's band: across it, the road's elevation at the inner point
/// of its cross-section and the kerb's height; with the line of its ends and outer edge. The
/// band is no surface of the feature set: its level carries its road's feature row, and
/// [`RoadLevels::surfaces`] leaves it out.
fn sidewalk_level(
    band: &Band,
    roads: &RoadLevels,
    terrain: &dyn Elevation,
) -> Option<(Level, Vec<Point>)> {
    let Look::Sidewalk { kerb_m } = band.look else {
        return None;
    };
    let n = band.inner.len().min(band.outer.len());
    if n < 2 {
        return None;
    }
    let (inner, outer) = (&band.inner[..n], &band.outer[..n]);
    let pieces: Vec<Polygon> = (1..n)
        .map(|k| Polygon {
            outer: vec![inner[k - 1], inner[k], outer[k], outer[k - 1]],
            holes: Vec::new(),
        })
        .collect();
    let sections = Sections::from_quads(&pieces)?;
    let bounds = Rect::around_all(&pieces)?;
    let profile: Vec<(f64, f64)> = sections
        .starts()
        .iter()
        .zip(inner)
        .map(|(&along, &p)| {
            let road = roads
                .elevation(p)
                .unwrap_or_else(|| terrain.elevation_uv(p));
            (along, road + kerb_m.max(0.0))
        })
        .collect();
    // Where the land beside it lies at the sidewalk's level anyway, the ground is left alone.
    let apart = |(&(_, level), &p): (&(f64, f64), &Point)| {
        (terrain.elevation_uv(p) - level).abs() > LEVEL_APART_M
    };
    if !profile.iter().zip(outer).any(apart) {
        return None;
    }
    let rule = Rule::Across { sections, profile };
    let mut edge = Vec::with_capacity(n + 2);
    edge.push(inner[0]);
    edge.extend_from_slice(outer);
    edge.push(inner[n - 1]);
    Some((Level::new(band.feature, pieces, bounds, rule), edge))
}

/// The terrain along a line: at its vertices and every `step` (tile units) between them.
fn terrain_profile(line: &[Point], terrain: &dyn Elevation, step: f64) -> Vec<(f64, f64)> {
    samples_along(line, step)
        .into_iter()
        .map(|(along, p)| (along, terrain.elevation_uv(p)))
        .collect()
}
