//! Cliffs and retaining walls: the ground on their high side stands above the ground on their
//! low side (thesis §4.2, minimum difference across a line).
//!
//! SRTM's 30 m cells smooth a wall's step into a slope (or, where the tag and the surface
//! model disagree, even a rise the wrong way). At a step's line the ground is half the step's
//! height above the terrain under the line on the high side (the way's left) and as much below
//! it on the low side, so the two sides differ by the step's height whatever the terrain does
//! there; away from the line it blends back into the terrain, reaching it
//! [`GroundStep::band_m`] away and
//! over as much from the line's ends. The step's face (its thickness wide, drawn as its own
//! surface) holds the triangulation's edges on both sides, so the drop is drawn where the wall
//! is. A point on the line itself, or inside the face, is on the low side: a wall stands at the
//! foot of its step, and its top meets the high side's ground. Everything comes from the whole
//! way and the global terrain, so tiles agree.

use crate::features::barriers::GroundStep;
use crate::geometry::{distances_along, Point, Rect};
use crate::terrain::Elevation;

/// The steps of a tile's ground, ready to be read.
#[derive(Debug, Clone, Default)]
pub struct Steps {
    steps: Vec<Step>,
}

#[derive(Debug, Clone)]
struct Step {
    line: Vec<Point>,
    /// Distance along the line of each vertex, tile units.
    along: Vec<f64>,
    half_height_m: f64,
    /// Half the face's width, and the band each side, tile units.
    half_face: f64,
    band: f64,
    bounds: Rect,
}

impl Steps {
    pub fn new(steps: &[GroundStep]) -> Steps {
        let steps = steps
            .iter()
            .filter(|s| s.line.len() >= 2 && s.height_m > 0.0)
            .map(|s| {
                let band = s.band_m() * s.metre;
                Step {
                    line: s.line.clone(),
                    along: distances_along(&s.line),
                    half_height_m: s.height_m / 2.0,
                    half_face: s.thickness_m / 2.0 * s.metre,
                    band,
                    bounds: s.reach(),
                }
            })
            .collect();
        Steps { steps }
    }

    pub fn is_empty(&self) -> bool {
        self.steps.is_empty()
    }

    /// The ground at `p` where the terrain there is `ground`, blended towards the level of
    /// the side of the step that decides it most (walls in terraces, each the nearest one's).
    pub fn ground(&self, p: Point, ground: f64, terrain: &dyn Elevation) -> f64 {
        let mut strongest: Option<(f64, Point, f64)> = None;
        for step in self.steps.iter().filter(|s| s.bounds.contains(p)) {
            if let Some((q, weight, side)) = step.influence(p) {
                if strongest.is_none_or(|(w, _, _)| weight > w) {
                    strongest = Some((weight, q, side * step.half_height_m));
                }
            }
        }
        match strongest {
            Some((weight, q, offset)) => {
                ground + weight * (terrain.elevation_uv(q) + offset - ground)
            }
            None => ground,
        }
    }
}

impl Step {
    /// The point of the line nearest `p`, how much the step decides the ground at `p` (1 at
    /// the face, 0 from the band's edge and at the line's ends) and its side (+1 high, −1 low).
    fn influence(&self, p: Point) -> Option<(Point, f64, f64)> {
        // The nearest point of the line, its distance along the line and which side `p` is on.
        let mut best: Option<(f64, Point, f64, bool)> = None;
        for i in 0..self.line.len() - 1 {
            let (a, b) = (self.line[i], self.line[i + 1]);
            let d = [b[0] - a[0], b[1] - a[1]];
            let len2 = d[0] * d[0] + d[1] * d[1];
            if len2 <= 0.0 {
                continue;
            }
            let t = (((p[0] - a[0]) * d[0] + (p[1] - a[1]) * d[1]) / len2).clamp(0.0, 1.0);
            let q = [a[0] + t * d[0], a[1] + t * d[1]];
            let distance = (p[0] - q[0]).hypot(p[1] - q[1]);
            if best.is_some_and(|(bd, _, _, _)| bd <= distance) {
                continue;
            }
            // Tile units run east and south: the way's left (north of a way going east) is
            // where this cross product is positive.
            let left = (p[0] - a[0]) * d[1] - (p[1] - a[1]) * d[0] > 0.0;
            let along = self.along[i] + t * (self.along[i + 1] - self.along[i]);
            best = Some((distance, q, along, left));
        }
        let (distance, q, along, left) = best?;
        if distance >= self.band {
            return None;
        }
        let total = self.along.last().copied().unwrap_or(0.0);
        let ends = (along.min(total - along) / self.band).clamp(0.0, 1.0);
        let across = if distance <= self.half_face {
            1.0
        } else {
            1.0 - (distance - self.half_face) / (self.band - self.half_face).max(1e-12)
        };
        // The face's own edges (a hair either way of its half width) belong to the sides.
        let in_face = distance < self.half_face * (1.0 - 1e-6);
        let side = if left && !in_face { 1.0 } else { -1.0 };
        Some((q, across * ends, side))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::features::barriers::EdgeKind;

    /// A wall 2 m high running east along v = 0.5, in units of 100 m.
    fn wall() -> Steps {
        Steps::new(&[GroundStep {
            kind: EdgeKind::RetainingWall,
            line: vec![[0.0, 0.5], [1.0, 0.5]],
            height_m: 2.0,
            thickness_m: 0.4,
            metre: 0.01,
            feature: 1,
            face: 2,
        }])
    }

    /// Terrain rising 50 % towards the south: the way's right, its low side.
    struct Wrong;
    impl Elevation for Wrong {
        fn elevation_uv(&self, p: [f64; 2]) -> f64 {
            50.0 * p[1]
        }
    }

    #[test]
    fn the_left_side_stands_above_the_right_side_by_the_height() {
        let steps = wall();
        let terrain = Wrong;
        let ground = |p: Point| steps.ground(p, terrain.elevation_uv(p), &terrain);
        // North (smaller v) is the left of a way going east; at the face's edges the sides
        // differ by the height, though the terrain rises the other way.
        let edge = 0.002 * (1.0 - 1e-9);
        let (high, low) = (ground([0.5, 0.5 - edge]), ground([0.5, 0.5 + edge]));
        assert!((high - low - 2.0).abs() < 1e-6, "{high} {low}");
        assert!((high - 26.0).abs() < 1e-6, "{high}");
        // On the line and inside the face: the foot of the wall.
        assert!((ground([0.5, 0.5]) - 24.0).abs() < 1e-9);
        assert!((ground([0.5, 0.5 - 0.001]) - 24.0).abs() < 1e-9);
        // Beyond the band and past the ends, the terrain.
        for p in [[0.5, 0.45], [1.1, 0.5 - 0.003]] {
            assert_eq!(ground(p), terrain.elevation_uv(p), "{p:?}");
        }
        // Halfway across the band, halfway back to the terrain.
        let p = [0.5, 0.5 - 0.021];
        let expected = 0.5 * 26.0 + 0.5 * terrain.elevation_uv(p);
        assert!(
            (ground(p) - expected).abs() < 1e-9,
            "{} {expected}",
            ground(p)
        );
        // It fades towards the ends.
        let near_end = ground([0.99, 0.5 - 0.002]) - terrain.elevation_uv([0.99, 0.5 - 0.002]);
        assert!(near_end > 0.0 && near_end < 1.0, "{near_end}");
    }
}
