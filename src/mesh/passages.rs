//! Passages through buildings (`tunnel=building_passage`): a road on the ground runs through the
//! building, whose walls open over it and whose floors stand over it at a ceiling.
//!
//! The shell stays closed. Its plan is triangulated with the passages' outlines stitched in;
//! the triangles outside the passages are the floor, those inside the ceiling. Walls run along
//! the passages' sides from the floor up to the ceiling, and each wall of the outline is drawn
//! in two bands: below the ceiling where no passage opens it, above the ceiling all along. Every
//! edge is then met by exactly one other running the other way.

use std::collections::HashMap;

use crate::geometry::constrained::{cut_polygon, CutPolygon};
use crate::geometry::{Point, Polygon};

/// Height of a passage's ceiling over the highest ground of the road under it, metres.
pub const HEADROOM_M: f64 = 4.0;

/// Least height of a building's walls above a passage's ceiling, metres: a lower building is
/// left closed.
pub const MIN_WALL_ABOVE_M: f64 = 1.0;

/// What a building of a guessed height keeps over a passage's ceiling, metres: a storey.
pub const STOREY_M: f64 = 3.0;

/// Least headroom a passage keeps under its ceiling where the walls above leave no more, metres:
/// a building too low for it is left closed.
pub const MIN_HEADROOM_M: f64 = 2.5;

/// A building's plan cut by the passages through it, and the ceiling over them.
pub struct Carving {
    cut: CutPolygon,
    /// Each directed edge of the triangles (corners counter-clockwise), with whether its
    /// triangle lies in a passage.
    edges: HashMap<[[u64; 2]; 2], bool>,
    /// The ceiling's height at each corner of the triangles.
    ceiling: HashMap<[u64; 2], f64>,
}

type Face = Vec<[f64; 3]>;

fn point_key(p: Point) -> [u64; 2] {
    p.map(|c| (c + 0.0).to_bits())
}

fn edge_key(a: Point, b: Point) -> [[u64; 2]; 2] {
    [point_key(a), point_key(b)]
}

fn at(p: Point, elevation: f64) -> [f64; 3] {
    [p[0], p[1], elevation]
}

impl Carving {
    /// `plan` cut by `passages` (both in the plan's metres), its ceiling not yet set; `None`
    /// when no passage reaches inside it.
    pub fn new(plan: &Polygon, passages: &[Polygon]) -> Option<Carving> {
        let cut = cut_polygon(plan, passages);
        if !cut.triangles.iter().any(|&(_, inside)| inside) {
            return None;
        }
        let mut edges = HashMap::new();
        for &(t, inside) in &cut.triangles {
            for k in 0..3 {
                edges.insert(edge_key(t[k], t[(k + 1) % 3]), inside);
            }
        }
        Some(Carving {
            cut,
            edges,
            ceiling: HashMap::new(),
        })
    }

    fn passage_corners(&self) -> impl Iterator<Item = Point> + '_ {
        self.ceiling_triangles().flatten().copied()
    }

    /// The highest ground at the corners of the passages' triangles, by `ground` (the plan's
    /// points in metres).
    pub fn highest_ground(&self, ground: &dyn Fn(Point) -> f64) -> f64 {
        self.passage_corners()
            .map(ground)
            .fold(f64::NEG_INFINITY, f64::max)
    }

    /// Sets the ceiling [`HEADROOM_M`] over the ground at every corner, and no higher than
    /// [`MIN_WALL_ABOVE_M`] under `eaves`: it follows a road that climbs through the building.
    /// `None` when that leaves less than [`MIN_HEADROOM_M`] over a passage's ground.
    pub fn with_ceiling(mut self, ground: &dyn Fn(Point) -> f64, eaves: f64) -> Option<Carving> {
        let highest = eaves - MIN_WALL_ABOVE_M;
        let mut ceiling = HashMap::new();
        for &(t, inside) in &self.cut.triangles {
            for p in t {
                let under = ground(p);
                let height = (under + HEADROOM_M).min(highest);
                if inside && height < under + MIN_HEADROOM_M {
                    return None;
                }
                ceiling.insert(point_key(p), height);
            }
        }
        self.ceiling = ceiling;
        Some(self)
    }

    /// The ceiling's height at a corner of the triangles (the highest it may be elsewhere).
    fn ceiling_at(&self, p: Point) -> f64 {
        self.ceiling
            .get(&point_key(p))
            .copied()
            .unwrap_or(f64::NEG_INFINITY)
    }

    /// The triangles of the plan outside the passages (counter-clockwise).
    pub fn floor(&self) -> impl Iterator<Item = &[Point; 3]> {
        self.cut.triangles.iter().filter(|t| !t.1).map(|t| &t.0)
    }

    fn ceiling_triangles(&self) -> impl Iterator<Item = &[Point; 3]> {
        self.cut.triangles.iter().filter(|t| t.1).map(|t| &t.0)
    }

    /// The ceiling over the passages: triangles facing down.
    pub fn ceiling(&self) -> Vec<[[f64; 3]; 3]> {
        self.ceiling_triangles()
            .map(|&[a, b, c]| [a, c, b].map(|p| at(p, self.ceiling_at(p))))
            .collect()
    }

    /// The walls along the passages' sides inside the building, from `bottom` up to the
    /// ceiling, facing into the passage.
    pub fn side_walls(&self, bottom: f64) -> Vec<Face> {
        let mut walls = Vec::new();
        for t in self.floor() {
            for k in 0..3 {
                let (s, q) = (t[k], t[(k + 1) % 3]);
                // The building lies left of `s → q`, the passage right of it.
                if self.edges.get(&edge_key(q, s)) == Some(&true) {
                    walls.push(vec![
                        at(s, bottom),
                        at(q, bottom),
                        at(q, self.ceiling_at(q)),
                        at(s, self.ceiling_at(s)),
                    ]);
                }
            }
        }
        walls
    }

    /// The wall of the outline's ring `ring` from its point `index` to the next (the building
    /// on its left): from `bottom` up to the ceiling where no passage opens it, then from the
    /// ceiling up to `top`, the wall's top from the edge's end back to its start (the eaves,
    /// through the points where a roof bends).
    pub fn wall(&self, ring: usize, index: usize, bottom: f64, top: &[[f64; 3]]) -> Vec<Face> {
        let Some(points) = self.cut.edges.get(ring).and_then(|r| r.get(index)) else {
            return Vec::new();
        };
        if points.len() < 2 || top.len() < 2 {
            return Vec::new();
        }
        let mut faces = Vec::new();
        for pair in points.windows(2) {
            let open = self.edges.get(&edge_key(pair[0], pair[1])) == Some(&true);
            if !open {
                faces.push(vec![
                    at(pair[0], bottom),
                    at(pair[1], bottom),
                    at(pair[1], self.ceiling_at(pair[1])),
                    at(pair[0], self.ceiling_at(pair[0])),
                ]);
            }
        }
        let lower: Vec<[f64; 3]> = points.iter().map(|&p| at(p, self.ceiling_at(p))).collect();
        let upper: Vec<[f64; 3]> = top.iter().rev().copied().collect();
        faces.extend(zip(&lower, &upper));
        faces
    }
}

/// Triangles between two rows of points along one line in the plan, both from the line's start
/// to its end, `upper` above `lower`: each triangle takes points of both rows, wound as a wall
/// whose bottom runs from start to end.
fn zip(lower: &[[f64; 3]], upper: &[[f64; 3]]) -> Vec<Face> {
    let (start, end) = (lower[0], lower[lower.len() - 1]);
    let direction = [end[0] - start[0], end[1] - start[1]];
    let along = |p: [f64; 3]| (p[0] - start[0]) * direction[0] + (p[1] - start[1]) * direction[1];
    let (mut i, mut j) = (0, 0);
    let mut faces = Vec::with_capacity(lower.len() + upper.len());
    while i + 1 < lower.len() || j + 1 < upper.len() {
        let lower_next = j + 1 == upper.len()
            || (i + 1 < lower.len() && along(lower[i + 1]) <= along(upper[j + 1]));
        if lower_next {
            faces.push(vec![lower[i], lower[i + 1], upper[j]]);
            i += 1;
        } else {
            faces.push(vec![lower[i], upper[j + 1], upper[j]]);
            j += 1;
        }
    }
    faces
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(x0: f64, y0: f64, x1: f64, y1: f64) -> Polygon {
        Polygon {
            outer: vec![[x0, y0], [x1, y0], [x1, y1], [x0, y1]],
            holes: Vec::new(),
        }
    }

    #[test]
    fn a_passage_across_a_building_splits_its_plan_into_floor_and_ceiling() {
        let plan = square(0.0, 0.0, 20.0, 10.0);
        let road = square(8.0, -5.0, 12.0, 15.0);
        let carving = Carving::new(&plan, &[road]).expect("the road passes through");
        let area = |t: &[Point; 3]| crate::geometry::signed_area2(t) / 2.0;
        let floor: f64 = carving.floor().map(area).sum();
        let ceiling: f64 = carving.ceiling_triangles().map(area).sum();
        assert!((floor - 160.0).abs() < 1e-9, "floor {floor}");
        assert!((ceiling - 40.0).abs() < 1e-9, "ceiling {ceiling}");
        // Two sides of the passage, each one wall (or more) from the floor to the ceiling.
        let carving = carving
            .with_ceiling(&|_| 0.0, 10.0)
            .expect("room for the ceiling");
        let sides = carving.side_walls(0.0);
        let length: f64 = sides
            .iter()
            .map(|w| ((w[1][0] - w[0][0]).powi(2) + (w[1][1] - w[0][1]).powi(2)).sqrt())
            .sum();
        assert!((length - 20.0).abs() < 1e-9, "sides {length} m long");
    }

    #[test]
    fn the_ceiling_follows_a_climbing_road_below_the_eaves() {
        let plan = square(0.0, 0.0, 20.0, 10.0);
        let road = square(8.0, -5.0, 12.0, 15.0);
        // The road climbs 0.3 m a metre northwards (y); eaves at 10 m.
        let ground = |p: Point| 0.3 * p[1];
        let carving = Carving::new(&plan, std::slice::from_ref(&road))
            .and_then(|c| c.with_ceiling(&ground, 10.0))
            .expect("room for the ceiling");
        for t in carving.ceiling() {
            for c in t {
                let expected = (ground([c[0], c[1]]) + HEADROOM_M).min(9.0);
                assert!((c[2] - expected).abs() < 1e-12, "{c:?}");
            }
        }
        // Eaves at 5 m leave less than the least headroom over the road's high end.
        let low = Carving::new(&plan, &[road]).and_then(|c| c.with_ceiling(&ground, 5.0));
        assert!(low.is_none());
    }

    #[test]
    fn a_road_beside_a_building_carves_nothing() {
        let plan = square(0.0, 0.0, 20.0, 10.0);
        assert!(Carving::new(&plan, &[square(25.0, -5.0, 30.0, 15.0)]).is_none());
    }

    #[test]
    fn a_wall_over_a_passage_stands_on_its_ceiling_there() {
        let plan = square(0.0, 0.0, 20.0, 10.0);
        let carving = Carving::new(&plan, &[square(8.0, -5.0, 12.0, 15.0)])
            .and_then(|c| c.with_ceiling(&|_| 0.0, 10.0))
            .expect("carved");
        // The south wall, from (0, 0) to (20, 0), its top at 10 m.
        let faces = carving.wall(0, 0, -0.5, &[[20.0, 0.0, 10.0], [0.0, 0.0, 10.0]]);
        let below: Vec<&Face> = faces.iter().filter(|f| f[0][2] == -0.5).collect();
        assert_eq!(below.len(), 2, "two bands below the ceiling: {faces:?}");
        assert!(below.iter().all(|f| f[1][0] <= 8.0 || f[0][0] >= 12.0));
        // Above the ceiling the wall is whole: its triangles cover 20 m × 6 m.
        let area: f64 = faces
            .iter()
            .filter(|f| f.len() == 3)
            .map(|f| {
                let n = crate::mesh::newell(f);
                (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt() / 2.0
            })
            .sum();
        assert!((area - 120.0).abs() < 1e-9, "upper wall {area} m²");
    }
}
