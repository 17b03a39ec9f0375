//! Which coastline ways decide the side of the coast a tile lies on.
//!
//! A tile no coastline crosses is at sea when the coastline nearest to its centre has it on its
//! water side (the features' sea decides so). Only the ways that may hold that nearest point
//! matter: those whose box is no farther from the centre than the nearest way itself. They are
//! found best first, by the distance to their boxes, so a tile reads a handful of coastline
//! ways however long the coast of the data is, and a closure of the data that holds those ways
//! finds the same ones.

use super::{LonLat, Way};
use crate::tile::lon_lat_to_uv;

/// Relative room in distance comparisons: a way this close to tying with the nearest is kept,
/// whatever rounding the features' projection adds.
const TIE: f64 = 1e-9;

/// A coastline way's box in global tile units at the data's zoom.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CoastBox {
    pub id: i64,
    min: [f64; 2],
    max: [f64; 2],
}

impl CoastBox {
    /// The box of a way's positions at `n` tiles per axis; `None` for a way without any.
    pub fn of(id: i64, positions: &[LonLat], n: f64) -> Option<CoastBox> {
        let mut points = positions.iter().map(|p| uv(*p, n));
        let first = points.next()?;
        let (min, max) = points.fold((first, first), |(lo, hi), p| {
            (
                [lo[0].min(p[0]), lo[1].min(p[1])],
                [hi[0].max(p[0]), hi[1].max(p[1])],
            )
        });
        Some(CoastBox { id, min, max })
    }

    fn distance(&self, p: [f64; 2]) -> f64 {
        let dx = (self.min[0] - p[0]).max(p[0] - self.max[0]).max(0.0);
        let dy = (self.min[1] - p[1]).max(p[1] - self.max[1]).max(0.0);
        dx.hypot(dy)
    }
}

fn uv(p: LonLat, n: f64) -> [f64; 2] {
    let (u, v) = lon_lat_to_uv(p.lon, p.lat, n);
    [u, v]
}

/// The distance from `p` to a way's line, in global tile units at `n` tiles per axis.
pub fn distance_to_way(way: &Way, p: [f64; 2], n: f64) -> f64 {
    let points: Vec<[f64; 2]> = way.positions.iter().map(|&q| uv(q, n)).collect();
    match points.as_slice() {
        [] => f64::INFINITY,
        [only] => (only[0] - p[0]).hypot(only[1] - p[1]),
        _ => points
            .windows(2)
            .map(|s| crate::geometry::distance_to_segment(p, s[0], s[1]))
            .fold(f64::INFINITY, f64::min),
    }
}

/// The ways among `boxes` that may hold the point of the coast nearest to `p` (global tile
/// units at the boxes' zoom), by their positions in `boxes`, ascending. `distance` gives the
/// way at a position its own distance to `p` (`None`: the way is not to be had, and counts as
/// far).
pub fn nearest(
    boxes: &[CoastBox],
    p: [f64; 2],
    mut distance: impl FnMut(usize) -> Option<f64>,
) -> Vec<usize> {
    let mut order: Vec<(f64, usize)> = boxes
        .iter()
        .enumerate()
        .map(|(k, b)| (b.distance(p), k))
        .collect();
    order.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let mut nearest = f64::INFINITY;
    for &(bound, k) in &order {
        if bound > within(nearest) {
            break;
        }
        if let Some(d) = distance(k) {
            nearest = nearest.min(d);
        }
    }
    let mut kept: Vec<usize> = order
        .iter()
        .take_while(|&&(bound, _)| bound <= within(nearest))
        .map(|&(_, k)| k)
        .collect();
    kept.sort_unstable();
    kept
}

fn within(distance: f64) -> f64 {
    distance * (1.0 + TIE) + TIE * 1e-3
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn way(id: i64, points: &[(f64, f64)]) -> Way {
        Way {
            id,
            nodes: (0..points.len() as i64).collect(),
            positions: points
                .iter()
                .map(|&(lon, lat)| LonLat { lon, lat })
                .collect(),
            tags: Default::default(),
        }
    }

    proptest! {
        #[test]
        fn the_ways_kept_hold_every_way_as_near_as_the_nearest(
            lines in prop::collection::vec(
                prop::collection::vec((7.0..7.5f64, 43.5..44.0f64), 2..6), 1..30),
            at in (7.0..7.5f64, 43.5..44.0f64),
        ) {
            let n = 16384.0;
            let ways: Vec<Way> = lines.iter().enumerate().map(|(k, l)| way(k as i64 + 1, l)).collect();
            let boxes: Vec<CoastBox> =
                ways.iter().filter_map(|w| CoastBox::of(w.id, &w.positions, n)).collect();
            let p = uv(LonLat { lon: at.0, lat: at.1 }, n);
            let distance_of = |boxes: &[CoastBox]| {
                let ways = &ways;
                let boxes = boxes.to_vec();
                move |k: usize| {
                    let id = boxes[k].id;
                    ways.iter().find(|w| w.id == id).map(|w| distance_to_way(w, p, n))
                }
            };
            let kept: Vec<i64> =
                nearest(&boxes, p, distance_of(&boxes)).into_iter().map(|k| boxes[k].id).collect();
            let best = ways.iter().map(|w| distance_to_way(w, p, n)).fold(f64::INFINITY, f64::min);
            for w in &ways {
                if distance_to_way(w, p, n) <= best {
                    prop_assert!(kept.contains(&w.id), "way {} is nearest but not kept", w.id);
                }
            }
            // Ascending, and a closure that holds the kept ways finds them again.
            prop_assert!(kept.windows(2).all(|k| k[0] < k[1]));
            let closure: Vec<CoastBox> =
                boxes.iter().copied().filter(|b| kept.contains(&b.id)).collect();
            let again: Vec<i64> = nearest(&closure, p, distance_of(&closure))
                .into_iter()
                .map(|k| closure[k].id)
                .collect();
            prop_assert_eq!(again, kept);
        }
    }

    #[test]
    fn a_far_coast_is_left_out() {
        let n = 16384.0;
        let near = way(1, &[(7.40, 43.70), (7.41, 43.70)]);
        let far = way(2, &[(8.40, 43.70), (8.41, 43.70)]);
        let boxes: Vec<CoastBox> = [&near, &far]
            .iter()
            .filter_map(|w| CoastBox::of(w.id, &w.positions, n))
            .collect();
        let p = uv(
            LonLat {
                lon: 7.405,
                lat: 43.71,
            },
            n,
        );
        let mut read = Vec::new();
        let kept = nearest(&boxes, p, |k| {
            read.push(k);
            Some(distance_to_way([&near, &far][k], p, n))
        });
        assert_eq!(kept, vec![0]);
        assert_eq!(read, vec![0], "the far way is not even read");
    }
}
