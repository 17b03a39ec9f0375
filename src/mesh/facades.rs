//! Texture coordinates of a building's walls: one repeat of its glazing's texture is one bay
//! wide and one level high.
//!
//! Each wall takes the whole number of bays nearest its width (so no window is cut at a
//! corner) and the walls the whole number of levels nearest their height from the lowest
//! ground to the eaves (so no row of windows is cut by the roof). Levels count from the lowest
//! ground under the building, so the levels of its parts and its walls line up. Gables and the
//! sides of a roof above the eaves are drawn blank; a wall that reaches above the eaves samples
//! the band of wall at the foot of a level there. A wall too narrow for a window shows wall
//! only too.
//!
//! Texture `v` grows downwards in glTF, so `v` is minus the levels counted up: each texture is
//! drawn as a level is seen, its top row at the top of the level.

use crate::features::facades::Facade;
use crate::geometry::clip_half_space;

/// Where, in a level of every facade texture, the wall under the windows is (share of a level
/// above its floor): gables sample it.
const WALL_BAND: f64 = 0.06;
/// Where, across a bay of every facade texture, a column of wall (or mullion) without glass
/// is: narrow walls sample it.
const WALL_COLUMN: f64 = 0.01;
/// A wall narrower than this share of a bay shows no window.
const NARROWEST_BAY: f64 = 0.6;

/// The levels of a building's walls.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Levels {
    /// The lowest ground under the building, metres: the floor of its first level.
    pub floor: f64,
    /// The height of a level, metres.
    pub level_m: f64,
    /// The levels from the floor to the eaves.
    pub count: f64,
}

impl Levels {
    /// The levels from `floor` to `eaves` (metres) nearest the facade's level height.
    pub fn new(facade: &Facade, floor: f64, eaves: f64) -> Levels {
        let height = eaves - floor;
        let nominal = facade.level_m.max(1.0);
        if height.is_nan() || height <= 0.0 {
            return Levels {
                floor,
                level_m: nominal,
                count: 1.0,
            };
        }
        let count = (height / nominal).round().max(1.0);
        Levels {
            floor,
            level_m: height / count,
            count,
        }
    }

    /// The elevation of the top of the ground floor, metres.
    pub fn ground_floor_top(&self) -> f64 {
        self.floor + self.level_m
    }

    /// Texture `v` at an elevation (metres): minus the levels up from the floor, held in the
    /// wall band over the eaves, and at the floor below it (the wall's foot is underground: one
    /// value there compresses best).
    fn v(&self, elevation: f64) -> f64 {
        let up = (elevation - self.floor) / self.level_m;
        -up.clamp(0.0, self.count + WALL_BAND)
    }
}

/// Across a vertical face: the horizontal direction it runs, where it starts and the width of
/// its bays.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Across {
    direction: [f64; 2],
    start: f64,
    /// Metres a bay; `None` when the face is too narrow for a window.
    bay_m: Option<f64>,
}

impl Across {
    /// The bays across a vertical face (plan metres and elevation, as the solids give them),
    /// fitted to its width; `None` for a face that is not vertical enough to have a width.
    pub fn of(face: &[[f64; 3]], bay_m: f64) -> Option<Across> {
        let normal = super::newell(face);
        let horizontal = normal[0].hypot(normal[1]);
        if horizontal.is_nan() || horizontal <= 1e-9 {
            return None;
        }
        let direction = [-normal[1] / horizontal, normal[0] / horizontal];
        let along = |p: &[f64; 3]| p[0] * direction[0] + p[1] * direction[1];
        let start = face.iter().map(along).fold(f64::INFINITY, f64::min);
        let end = face.iter().map(along).fold(f64::NEG_INFINITY, f64::max);
        let width = end - start;
        let bays = (width / bay_m).round();
        let bay_m = (bays >= 1.0 && width >= NARROWEST_BAY * bay_m).then(|| width / bays);
        Some(Across {
            direction,
            start,
            bay_m,
        })
    }

    /// Texture coordinates of corners of the face (or of a piece of it).
    pub fn uvs(&self, corners: &[[f64; 3]], levels: &Levels) -> Vec<[f64; 2]> {
        corners
            .iter()
            .map(|p| {
                let u = match self.bay_m {
                    Some(bay) => {
                        (p[0] * self.direction[0] + p[1] * self.direction[1] - self.start) / bay
                    }
                    None => WALL_COLUMN,
                };
                [u, levels.v(p[2])]
            })
            .collect()
    }
}

/// Texture coordinates held to sixteenths of a repeat (20 cm on a bay of 3.2 m, where only
/// a wall cut at a tile's edge lies between them): small whole numbers of steps compress to a
/// fraction of the size of finer ones.
pub fn snapped(uv: [f64; 2]) -> [f64; 2] {
    uv.map(|c| (c * STEPS).round() / STEPS)
}

/// Steps of a repeat texture coordinates are held to.
pub const STEPS: f64 = 16.0;

/// The pieces of a face below and above an elevation (either may be empty).
pub fn split_at(face: &[[f64; 3]], elevation: f64) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
    (
        keep_side(face, elevation, true),
        keep_side(face, elevation, false),
    )
}

/// The part of a convex polygon below (or above) an elevation, empty when it has no area.
fn keep_side(face: &[[f64; 3]], elevation: f64, below: bool) -> Vec<[f64; 3]> {
    let mut out = clip_half_space(face, 2, elevation, !below);
    out.dedup();
    while out.len() > 1 && out.first() == out.last() {
        out.pop();
    }
    if out.len() < 3 {
        out.clear();
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::features::facades::Glazing;

    fn facade(level_m: f64) -> Facade {
        Facade {
            upper: Some(Glazing::Punched),
            ground: None,
            level_m,
            bay_m: 3.2,
        }
    }

    /// A wall from (0, 0) to (`width`, 0), from elevation `low` to `high`.
    fn wall(width: f64, low: f64, high: f64) -> Vec<[f64; 3]> {
        vec![
            [0.0, 0.0, low],
            [width, 0.0, low],
            [width, 0.0, high],
            [0.0, 0.0, high],
        ]
    }

    #[test]
    fn a_wall_takes_whole_bays_and_the_walls_whole_levels() {
        let levels = Levels::new(&facade(3.0), 100.0, 109.6);
        assert_eq!(levels.count, 3.0);
        assert!((levels.level_m - 3.2).abs() < 1e-12);
        let face = wall(10.0, 99.5, 109.6);
        let across = Across::of(&face, 3.2).expect("a vertical wall");
        let uvs = across.uvs(&face, &levels);
        let us: Vec<f64> = uvs.iter().map(|uv| uv[0]).collect();
        let mut sorted = us.clone();
        sorted.sort_by(f64::total_cmp);
        // 10 m holds three bays of 3.33 m.
        assert!(
            (sorted[0] - 0.0).abs() < 1e-9 && (sorted[3] - 3.0).abs() < 1e-9,
            "{us:?}"
        );
        // The eaves are three levels up; the skirt under the floor is held at it.
        let vs: Vec<f64> = uvs.iter().map(|uv| uv[1]).collect();
        assert!(vs.iter().any(|v| (v + 3.0).abs() < 1e-9), "{vs:?}");
        assert!(vs.contains(&0.0) && vs.iter().all(|v| *v <= 0.0), "{vs:?}");
    }

    #[test]
    fn a_gable_and_a_narrow_wall_show_wall_only() {
        let levels = Levels::new(&facade(3.0), 0.0, 6.0);
        let gable = [[0.0, 0.0, 6.0], [8.0, 0.0, 6.0], [4.0, 0.0, 9.0]];
        let across = Across::of(&gable, 3.2).expect("a vertical gable");
        for [_, v] in across.uvs(&gable, &levels) {
            assert!((-(2.0 + WALL_BAND)..=-2.0).contains(&v), "{v}");
        }
        let narrow = wall(1.2, 0.0, 6.0);
        let across = Across::of(&narrow, 3.2).expect("a vertical wall");
        assert!(across
            .uvs(&narrow, &levels)
            .iter()
            .all(|uv| uv[0] == WALL_COLUMN));
        // A flat face has no width across.
        assert_eq!(
            Across::of(&[[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]], 3.2),
            None
        );
    }

    #[test]
    fn splitting_at_the_ground_floor_keeps_the_whole_wall() {
        let face = wall(6.0, -0.5, 9.0);
        let (below, above) = split_at(&face, 3.0);
        let area = |f: &[[f64; 3]]| {
            let n = crate::mesh::newell(f);
            (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt() / 2.0
        };
        assert!((area(&below) - 6.0 * 3.5).abs() < 1e-9);
        assert!((area(&above) - 6.0 * 6.0).abs() < 1e-9);
        assert!(below.iter().all(|p| p[2] <= 3.0) && above.iter().all(|p| p[2] >= 3.0));
        let (below, above) = split_at(&face, 20.0);
        assert_eq!((below.len(), above.len()), (4, 0));
    }
}
