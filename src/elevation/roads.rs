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

use std::collections::HashMap;

use super::road_profiles::RoadProfiles;
use super::settled::{samples_along, Level, Rule, Sections, Stations};
use crate::features::road_network::StretchLine;
use crate::features::{FeatureClass, FeatureSet};
use crate::geometry::{Point, Polygon, Rect};
use crate::osm::ElementType;
use crate::terrain::Elevation;

/// Spacing of the terrain samples along a road's centre line, metres.
pub const PROFILE_STEP_M: f64 = 5.0;

/// Cells per tile unit of the grid that finds the levels under a point.
const CELLS_PER_UNIT: f64 = 64.0;

/// The levels of the roads and junctions of a tile, found by a grid.
#[derive(Debug, Default)]
pub struct RoadLevels {
    levels: Vec<Level>,
    /// Junction levels win over the roads that meet them.
    junction: Vec<bool>,
    grid: HashMap<(i64, i64), Vec<u32>>,
}

impl RoadLevels {
    /// The elevation of a road or junction at `p`, if one covers it: a junction's first, else
    /// the lowest of the road stretches there.
    pub fn elevation(&self, p: Point) -> Option<f64> {
        let cell = cell_of(p);
        let candidates = self.grid.get(&cell)?;
        let mut road: Option<f64> = None;
        for &i in candidates {
            let level = &self.levels[i as usize];
            if !level.covers(p) {
                continue;
            }
            let h = level.rule.elevation(p);
            if self.junction[i as usize] {
                return Some(h);
            }
            road = Some(road.map_or(h, |r: f64| r.min(h)));
        }
        road
    }

    /// The surfaces (indices into the feature set) whose vertices these levels settle.
    pub fn surfaces(&self) -> impl Iterator<Item = u32> + '_ {
        self.levels.iter().map(|l| l.surface)
    }

    pub fn len(&self) -> usize {
        self.levels.len()
    }

    pub fn is_empty(&self) -> bool {
        self.levels.is_empty()
    }

    fn push(&mut self, level: Level, junction: bool) {
        let index = self.levels.len() as u32;
        let Rect { min, max } = level.bounds;
        let (a, b) = (cell_of(min), cell_of(max));
        for x in a.0..=b.0 {
            for y in a.1..=b.1 {
                self.grid.entry((x, y)).or_default().push(index);
            }
        }
        self.levels.push(level);
        self.junction.push(junction);
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
                true,
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
            let Some(bounds) = pieces
                .iter()
                .map(Polygon::bounds)
                .reduce(|a, b| a.union(&b))
            else {
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
            out.push(Level::new(index as u32, pieces, bounds, rule), false);
        }
    }
    out
}

/// The terrain along a line: at its vertices and every `step` (tile units) between them.
fn terrain_profile(line: &[Point], terrain: &dyn Elevation, step: f64) -> Vec<(f64, f64)> {
    samples_along(line, step)
        .into_iter()
        .map(|(along, p)| (along, terrain.elevation_uv(p)))
        .collect()
}
