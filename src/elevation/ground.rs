//! The ground model the mesher samples: the terrain, with water areas flat at their levels,
//! the ground reshaped around bridges and tunnels, roads on their profiles, and steps at cliffs
//! and retaining walls, each settled by its own module.

use super::roads::RoadLevels;
use super::settled::{Bound, Level, LevelGrid};
use super::steps::Steps;
use crate::terrain::Elevation;

/// The ground: the terrain, with water areas flat at their levels, the ground reshaped around
/// bridges and tunnels, roads on their profiles, and steps at cliffs and retaining walls.
pub struct Ground<'a> {
    pub terrain: &'a dyn Elevation,
    pub water: &'a [Level],
    /// Where tunnels cut into the ground or run under raised ground, and bridges over
    /// lowered ground.
    pub cuts: &'a [Level],
    /// Roads level across and junctions level.
    pub roads: &'a RoadLevels,
    /// Cliffs and retaining walls, stepping the terrain around them.
    pub steps: &'a Steps,
    index: &'a LevelIndex,
}

/// Where a tile's water areas and cuts lie, indexed once: every view of its ground (one a
/// thread, one for the glb) reads the same index.
#[derive(Debug, Clone, Default)]
pub struct LevelIndex {
    water: LevelGrid,
    cuts: LevelGrid,
}

impl LevelIndex {
    pub fn new(water: &[Level], cuts: &[Level]) -> LevelIndex {
        LevelIndex {
            water: LevelGrid::new(water),
            cuts: LevelGrid::new(cuts),
        }
    }

    /// The water areas and cuts of those this index was made of that cover `p`, water first.
    pub fn covering<'l>(
        &'l self,
        (water, cuts): (&'l [Level], &'l [Level]),
        p: [f64; 2],
    ) -> impl Iterator<Item = &'l Level> {
        self.water
            .covering(water, p)
            .chain(self.cuts.covering(cuts, p))
    }
}

impl<'a> Ground<'a> {
    /// The ground of these parts with the index made of `water` and `cuts` before.
    pub fn indexed(
        terrain: &'a dyn Elevation,
        (water, cuts): (&'a [Level], &'a [Level]),
        roads: &'a RoadLevels,
        steps: &'a Steps,
        index: &'a LevelIndex,
    ) -> Ground<'a> {
        Ground {
            terrain,
            water,
            cuts,
            roads,
            steps,
            index,
        }
    }

    /// The index of its water areas and cuts.
    pub fn index(&self) -> &'a LevelIndex {
        self.index
    }

    /// The water areas and cuts that cover `p` (floors among them), water first.
    pub fn levels_at(&self, p: [f64; 2]) -> impl Iterator<Item = &Level> {
        self.index.covering((self.water, self.cuts), p)
    }
}

impl Elevation for Ground<'_> {
    fn elevation_uv(&self, p: [f64; 2]) -> f64 {
        // Where water areas overlap, the lowest level wins.
        let water = self
            .index
            .water
            .covering(self.water, p)
            .map(|w| w.rule.elevation(p))
            .fold(None, |low: Option<f64>, l| {
                Some(low.map_or(l, |x| x.min(l)))
            });
        if let Some(level) = water {
            return level;
        }
        // Ground raised over a tunnel's roof wins over another way's cut beside it (two
        // carriageways whose portals are not abreast), so no tube shows through; the terrain
        // lowered under a bridge's deck leaves roads and cuts as they are.
        let mut cut: Option<f64> = None;
        let mut raised: Option<f64> = None;
        let mut lowered: Option<f64> = None;
        for level in self.index.cuts.covering(self.cuts, p) {
            let h = level.rule.elevation(p);
            match level.bound {
                Bound::AtLeast => raised = Some(raised.map_or(h, |r: f64| r.max(h))),
                Bound::AtMost => lowered = Some(lowered.map_or(h, |l: f64| l.min(h))),
                Bound::Exact if cut.is_none() => cut = Some(h),
                Bound::Exact => {}
            }
        }
        let ground = cut.or_else(|| self.roads.elevation(p)).unwrap_or_else(|| {
            let terrain = self.terrain.elevation_uv(p);
            let terrain = if self.steps.is_empty() {
                terrain
            } else {
                self.steps.ground(p, terrain, self.terrain)
            };
            lowered.map_or(terrain, |lowered| lowered.min(terrain))
        });
        raised.map_or(ground, |raised| raised.max(ground))
    }
}
