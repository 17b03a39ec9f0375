//! Water surfaces lie flat, no higher than their shore (thesis §4.2; its figure 4.8 shows a lake
//! above its banks), and waterways never flow uphill.
//!
//! The level of a water area is the lowest ground along its whole outline, sampled every
//! [`SHORE_STEP_M`] from its first vertex: a function of the whole OSM area and the terrain
//! alone, so every tile that shows the water computes the same level, and the shore (where the
//! outline's vertices take the level) is never below it. The sea lies at 0 m. A waterway drawn
//! at its width follows the lowest ground met so far along its whole way (sampled as often),
//! level across each station, so its water only ever runs down; a river's area likewise, on
//! the profile of the waterway in it (the thesis held river areas flat, a trench upstream of
//! their lowest shore).

use super::settled::{samples_along, Level, Rule, Stations};
use crate::features::water::WaterBody;
use crate::features::{FeatureClass, FeatureSet, Surface};
use crate::geometry::{Point, Polygon};
use crate::terrain::Elevation;

/// Spacing of the samples along a water area's outline, metres.
pub const SHORE_STEP_M: f64 = 5.0;

/// The water areas of a feature set with their levels; `metres_per_unit` is the tile's size.
pub fn levels(set: &FeatureSet, terrain: &dyn Elevation, metres_per_unit: f64) -> Vec<Level> {
    set.surfaces
        .iter()
        .enumerate()
        .filter(|(_, s)| s.class == FeatureClass::Water)
        .filter_map(|(index, surface)| {
            let rule = match surface.water {
                Some(WaterBody::Flowing) => {
                    downstream(&surface.centreline, terrain, metres_per_unit)?
                }
                // A river's area runs down as the waterway in it does, with the very same
                // profile: where the river leaves its area, the two meet without a step.
                Some(WaterBody::River) if surface.centreline.len() >= 2 => {
                    downstream(&surface.centreline, terrain, metres_per_unit)?
                }
                Some(WaterBody::Sea) => Rule::Level(0.0),
                Some(WaterBody::Still | WaterBody::River) | None => {
                    Rule::Level(shore_minimum(surface, terrain, metres_per_unit)?)
                }
            };
            Some(Level::new(
                index as u32,
                surface.pieces.clone(),
                surface.bounds,
                rule,
            ))
        })
        .collect()
}

/// The lowest ground met so far along a waterway's line, sampled every [`SHORE_STEP_M`].
fn downstream(line: &[Point], terrain: &dyn Elevation, metres_per_unit: f64) -> Option<Rule> {
    if line.len() < 2 {
        return None;
    }
    let step = SHORE_STEP_M / metres_per_unit;
    let mut lowest = f64::INFINITY;
    // Where the ground is unknown (no SRTM file), the lowest ground met before holds.
    let mut profile: Vec<(f64, f64)> = samples_along(line, step)
        .into_iter()
        .map(|(along, p)| {
            if let Some(h) = terrain.known_elevation_uv(p) {
                lowest = lowest.min(h);
            }
            (along, lowest)
        })
        .collect();
    // Stations before the first known ground lie at its level; a way over no known ground
    // at all, at sea level.
    let first = profile
        .iter()
        .map(|&(_, h)| h)
        .find(|h| h.is_finite())
        .unwrap_or(0.0);
    for (_, h) in &mut profile {
        if !h.is_finite() {
            *h = first;
        }
    }
    Some(Rule::Along {
        stations: Stations::new(line),
        profile,
    })
}

/// The lowest known ground along the rings of a surface's pieces.
fn shore_minimum(surface: &Surface, terrain: &dyn Elevation, metres_per_unit: f64) -> Option<f64> {
    let step = SHORE_STEP_M / metres_per_unit;
    // Where the ground is unknown (no SRTM file), the shore is not counted; a shore over no
    // known ground at all lies at sea level.
    let lowest = surface
        .pieces
        .iter()
        .flat_map(Polygon::rings)
        .flat_map(|ring| {
            let mut closed = ring.clone();
            closed.extend(ring.first());
            samples_along(&closed, step)
        })
        .filter_map(|(_, p)| terrain.known_elevation_uv(p))
        .reduce(f64::min);
    lowest.or(Some(0.0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::elevation::ground::Ground;

    /// Ground rising eastwards: one metre per hundredth of a unit.
    struct Slope;
    impl Elevation for Slope {
        fn elevation_uv(&self, p: [f64; 2]) -> f64 {
            p[0] * 100.0
        }
    }

    #[test]
    fn a_river_area_is_level_across_and_runs_down_along_its_waterway() {
        let bank = Polygon {
            outer: vec![[0.10, 0.10], [0.30, 0.10], [0.30, 0.12], [0.10, 0.12]],
            holes: Vec::new(),
        };
        let mut set = FeatureSet::default();
        let tags = crate::osm::Tags::from_pairs([("waterway", "riverbank")]);
        let feature = set.add_feature(None, FeatureClass::Water, &tags);
        let mut surface =
            Surface::from_polygons(FeatureClass::Water, feature, vec![bank]).expect("a surface");
        surface.water = Some(WaterBody::of(&tags));
        // The river flows west, down the slope.
        surface.centreline = vec![[0.29, 0.11], [0.2, 0.11], [0.11, 0.11]];
        set.surfaces.push(surface);
        let water = levels(&set, &Slope, 1000.0);
        assert_eq!(water.len(), 1);
        let at = |p: [f64; 2]| water[0].rule.elevation(p);
        let mut upstream = f64::INFINITY;
        for k in 0..=40 {
            let x = 0.30 - 0.2 * f64::from(k) / 40.0;
            let (south, north) = (at([x, 0.1]), at([x, 0.12]));
            assert!(
                (south - north).abs() < 0.01,
                "across at {x}: {south} {north}"
            );
            assert!(south <= upstream + 1e-9, "rises downstream at {x}");
            if (0.11..=0.29).contains(&x) {
                assert!(
                    south <= Slope.elevation_uv([x, 0.1]) + 1e-9,
                    "above its bank at {x}"
                );
            }
            upstream = south;
        }
        // Not held flat at its lowest shore.
        assert!(at([0.25, 0.11]) > 20.0);
    }

    #[test]
    fn a_pond_on_a_slope_lies_flat_at_its_lowest_shore() {
        let pond = Polygon {
            outer: vec![[0.10, 0.10], [0.20, 0.10], [0.20, 0.20], [0.10, 0.20]],
            holes: Vec::new(),
        };
        let mut set = FeatureSet::default();
        let tags = crate::osm::Tags::from_pairs([("natural", "water")]);
        let feature = set.add_feature(None, FeatureClass::Water, &tags);
        set.surfaces.push(
            Surface::from_polygons(FeatureClass::Water, feature, vec![pond]).expect("a surface"),
        );
        let water = levels(&set, &Slope, 1000.0);
        assert_eq!(water.len(), 1);
        assert_eq!(water[0].rule, Rule::Level(10.0));
        let (roads, steps) = (Default::default(), Default::default());
        let index = crate::elevation::ground::LevelIndex::new(&water, &[]);
        let ground = Ground::indexed(&Slope, (&water, &[]), &roads, &steps, &index);
        // Flat inside and on the outline (the high side too), the terrain outside.
        for p in [[0.15, 0.15], [0.2, 0.15], [0.1, 0.1], [0.2, 0.2]] {
            assert!((ground.elevation_uv(p) - 10.0).abs() < 1e-9, "{p:?}");
        }
        assert!((ground.elevation_uv([0.3, 0.15]) - 30.0).abs() < 1e-9);
        // The terrain along the shore is nowhere below the water; beyond it, the ground is the
        // terrain's.
        for k in 0..=40 {
            let t = 0.1 + 0.1 * f64::from(k) / 40.0;
            for p in [[t, 0.1], [t, 0.2], [0.1, t], [0.2, t]] {
                assert!(Slope.elevation_uv(p) >= 10.0 - 1e-9, "{p:?}");
            }
        }
        assert_eq!(
            ground.elevation_uv([0.095, 0.15]),
            Slope.elevation_uv([0.095, 0.15])
        );
    }

    /// The slope where `u` ≥ 0.2; no file west of it.
    struct CutSlope;
    impl Elevation for CutSlope {
        fn elevation_uv(&self, p: [f64; 2]) -> f64 {
            self.known_elevation_uv(p).unwrap_or(0.0)
        }
        fn known_elevation_uv(&self, p: [f64; 2]) -> Option<f64> {
            (p[0] >= 0.2).then(|| Slope.elevation_uv(p))
        }
    }

    #[test]
    fn a_waterway_over_unknown_ground_holds_the_known_level_instead_of_dropping_to_sea_level() {
        // From where no file covers the ground, east into it and back west out of it.
        let line = vec![[0.10, 0.5], [0.40, 0.5], [0.40, 0.6], [0.05, 0.6]];
        let rule = downstream(&line, &CutSlope, 1000.0).expect("a profile");
        let Rule::Along { profile, .. } = &rule else {
            panic!("{rule:?}");
        };
        let lowest = profile
            .iter()
            .map(|&(_, h)| h)
            .fold(f64::INFINITY, f64::min);
        assert!((lowest - 20.0).abs() < 0.1, "lowest station {lowest}");
        assert!(profile.windows(2).all(|w| w[1].1 <= w[0].1));
        // A lake half over unknown ground lies at its lowest known shore.
        let lake = Polygon {
            outer: vec![[0.10, 0.10], [0.30, 0.10], [0.30, 0.20], [0.10, 0.20]],
            holes: Vec::new(),
        };
        let surface =
            Surface::from_polygons(FeatureClass::Water, 0, vec![lake]).expect("a surface");
        let level = shore_minimum(&surface, &CutSlope, 1000.0).expect("a level");
        assert!((level - 20.0).abs() < 1e-9, "{level}");
    }

    #[test]
    fn a_waterway_never_runs_uphill() {
        // A stream drawn eastwards up the slope, round two right-angle bends, then back west
        // down it.
        let line = vec![[0.10, 0.5], [0.30, 0.5], [0.30, 0.7], [0.05, 0.7]];
        let rule = downstream(&line, &Slope, 1000.0).expect("a profile");
        let Rule::Along { profile, .. } = &rule else {
            panic!("{rule:?}");
        };
        assert!(profile
            .windows(2)
            .all(|w| w[1].1 <= w[0].1 && w[1].0 >= w[0].0));
        // Level at its source's height up the slope, then down with the ground.
        assert!((rule.elevation([0.25, 0.5]) - 10.0).abs() < 1e-9);
        let back = rule.elevation([0.06, 0.7]);
        assert!((back - 6.0).abs() < 0.5, "{back}");
        // Along the water, never up: on both banks, and round the bends' insides.
        for bank in [-0.01, 0.01] {
            let mut last = f64::INFINITY;
            for k in 0..=100 {
                let t = f64::from(k) / 100.0 * 0.65;
                let p = if t < 0.2 {
                    [0.1 + t, 0.5 + bank]
                } else if t < 0.4 {
                    [0.3 - bank, 0.5 + (t - 0.2)]
                } else {
                    [0.3 - (t - 0.4), 0.7 - bank]
                };
                let h = rule.elevation(p);
                assert!(h <= last + 1e-9, "{p:?}: {h} after {last}");
                last = h;
            }
        }
        // The station runs on without a step through the inside of a bend.
        let inside = [0.29, 0.51];
        let stations = Stations::new(&line);
        let (a, b) = (stations.at([0.29, 0.509]), stations.at(inside));
        assert!((a - b).abs() < 0.005, "{a} {b}");
    }
}
