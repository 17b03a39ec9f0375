//! Whether a point lies in an area, answered quickly: a grid over the area's bounds whose
//! cells are wholly inside, wholly outside, or crossed by its outline, so only a point in a
//! crossed cell is tested against the few segments and pieces there.

use super::{Point, Polygon, Rect};

/// Cells per side of an index, at most.
const CELLS: usize = 96;

/// The area's bounds in a grid of cells, each wholly inside, wholly outside, or crossed by
/// the outline (with the segments that cross it). A cell is one byte and its lists are runs of
/// two flat arrays, so the grid of an area read once in a while stays small enough to be
/// found in the cache, and is made without a list per cell.
#[derive(Debug, Clone)]
pub struct CellIndex {
    bounds: Rect,
    /// Cells per side: more for outlines of more segments, at most [`CELLS`].
    side: usize,
    /// Per cell: [`OUTSIDE`], [`INSIDE`] or [`CROSSED`].
    codes: Vec<u8>,
    /// Where each cell's run starts in `segments` and in `near`, and a last entry for the end.
    starts: Vec<(u32, u32)>,
    /// The outline's segments near each cell, cell after cell.
    segments: Vec<(Point, Point)>,
    /// The pieces whose bounds meet each cell, cell after cell.
    near: Vec<u32>,
}

const OUTSIDE: u8 = 0;
const INSIDE: u8 = 1;
const CROSSED: u8 = 2;

/// What a cell of a [`CellIndex`] holds.
#[derive(Debug, Clone, Copy)]
pub enum Cell<'a> {
    Inside,
    Outside,
    /// Segments of the outline near the cell (`(a, b)` pairs) and the pieces whose bounds
    /// meet it.
    Crossed(&'a [(Point, Point)], &'a [u32]),
}

/// Calls its argument with every (cell, item) of a list per cell, in order.
type EachItem<'a, T> = &'a dyn Fn(&mut dyn FnMut(usize, T));

/// Lists per cell in one array: counted in a first pass, placed in a second, each cell's in
/// the order given.
struct Runs<T> {
    starts: Vec<u32>,
    items: Vec<T>,
}

impl<T: Copy + Default> Runs<T> {
    /// `each` calls its argument with every (cell, item), in order, twice over.
    fn new(cells: usize, each: EachItem<'_, T>) -> Runs<T> {
        let mut starts = vec![0u32; cells + 1];
        each(&mut |cell, _| starts[cell + 1] += 1);
        for k in 0..cells {
            starts[k + 1] += starts[k];
        }
        let mut items = vec![T::default(); starts[cells] as usize];
        let mut next = starts.clone();
        each(&mut |cell, item| {
            items[next[cell] as usize] = item;
            next[cell] += 1;
        });
        Runs { starts, items }
    }

    fn run(&self, cell: usize) -> &[T] {
        &self.items[self.starts[cell] as usize..self.starts[cell + 1] as usize]
    }
}

impl CellIndex {
    /// The index of `pieces` over `bounds` widened by `margin`: a cell nearer than `margin`
    /// to a segment of their outlines is crossed by it.
    pub fn new(pieces: &[Polygon], bounds: Rect, margin: f64) -> CellIndex {
        let bounds = bounds.widened(margin);
        let segments: usize = pieces.iter().flat_map(Polygon::rings).map(Vec::len).sum();
        let side = ((segments as f64).sqrt().ceil() as usize * 2).clamp(4, CELLS);
        let size = [
            (bounds.max[0] - bounds.min[0]) / side as f64,
            (bounds.max[1] - bounds.min[1]) / side as f64,
        ];
        let cell_span = |lo: f64, hi: f64, axis: usize| {
            let cell = |v: f64| {
                (((v - bounds.min[axis]) / size[axis]).floor().max(0.0) as usize).min(side - 1)
            };
            cell(lo)..=cell(hi)
        };
        let touching = Runs::new(side * side, &|put| {
            for (k, piece) in pieces.iter().enumerate() {
                let b = piece.bounds();
                for row in cell_span(b.min[1], b.max[1], 1) {
                    for column in cell_span(b.min[0], b.max[0], 0) {
                        put(row * side + column, k as u32);
                    }
                }
            }
        });
        let crossed = Runs::new(side * side, &|put| {
            for ring in pieces.iter().flat_map(Polygon::rings) {
                for i in 0..ring.len() {
                    let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
                    let span = |axis: usize| {
                        cell_span(
                            a[axis].min(b[axis]) - margin,
                            a[axis].max(b[axis]) + margin,
                            axis,
                        )
                    };
                    for row in span(1) {
                        for column in span(0) {
                            put(row * side + column, (a, b));
                        }
                    }
                }
            }
        });
        let codes = (0..side * side)
            .map(|k| {
                if !crossed.run(k).is_empty() {
                    return CROSSED;
                }
                // No outline in the cell: its centre tells for all of it.
                let centre = [
                    bounds.min[0] + ((k % side) as f64 + 0.5) * size[0],
                    bounds.min[1] + ((k / side) as f64 + 0.5) * size[1],
                ];
                let near = touching.run(k);
                if near.iter().any(|&i| pieces[i as usize].contains(centre)) {
                    INSIDE
                } else {
                    OUTSIDE
                }
            })
            .collect();
        CellIndex {
            bounds,
            side,
            codes,
            starts: crossed.starts.into_iter().zip(touching.starts).collect(),
            segments: crossed.items,
            near: touching.items,
        }
    }

    /// The bounds the index covers, its margin included.
    pub fn bounds(&self) -> Rect {
        self.bounds
    }

    /// The cell of `p`; `None` outside the bounds.
    pub fn cell(&self, p: Point) -> Option<Cell<'_>> {
        if !self.bounds.contains(p) {
            return None;
        }
        let side = self.side;
        let index = |axis: usize| {
            let size = (self.bounds.max[axis] - self.bounds.min[axis]) / side as f64;
            (((p[axis] - self.bounds.min[axis]) / size).floor().max(0.0) as usize).min(side - 1)
        };
        let k = index(1) * side + index(0);
        Some(match *self.codes.get(k)? {
            OUTSIDE => Cell::Outside,
            INSIDE => Cell::Inside,
            _ => {
                let ((s0, n0), (s1, n1)) = (self.starts[k], self.starts[k + 1]);
                Cell::Crossed(
                    &self.segments[s0 as usize..s1 as usize],
                    &self.near[n0 as usize..n1 as usize],
                )
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A comb: a square with a square hole and teeth, many cells of each kind.
    fn comb() -> Polygon {
        let mut outer = vec![[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]];
        for tooth in (0..5).rev() {
            let x = f64::from(tooth) * 2.0;
            outer.extend([
                [x + 1.5, 10.0],
                [x + 1.5, 6.0],
                [x + 0.5, 6.0],
                [x + 0.5, 10.0],
            ]);
        }
        outer.push([0.0, 10.0]);
        let hole = vec![[3.0, 2.0], [7.0, 2.0], [7.0, 4.0], [3.0, 4.0]];
        Polygon {
            outer,
            holes: vec![hole],
        }
    }

    #[test]
    fn a_cell_inside_or_outside_answers_as_the_polygon_does_and_a_crossed_one_lists_its_segments() {
        let comb = comb();
        let index = CellIndex::new(std::slice::from_ref(&comb), comb.bounds(), 1e-9);
        let (mut inside, mut outside, mut crossed) = (0, 0, 0);
        for i in 0..=200 {
            for j in 0..=200 {
                let p = [f64::from(i) * 0.05 + 0.001, f64::from(j) * 0.05 + 0.002];
                match index.cell(p) {
                    Some(Cell::Inside) => {
                        inside += 1;
                        assert!(comb.contains(p), "{p:?} is not inside");
                    }
                    Some(Cell::Outside) => {
                        outside += 1;
                        assert!(!comb.contains(p), "{p:?} is not outside");
                    }
                    Some(Cell::Crossed(segments, near)) => {
                        crossed += 1;
                        assert!(!segments.is_empty());
                        assert_eq!(near, &[0]);
                    }
                    None => assert!(!comb.bounds().contains(p)),
                }
            }
        }
        assert!(inside > 1000 && outside > 1000 && crossed > 1000);
    }

    #[test]
    fn a_point_beyond_the_bounds_and_margin_has_no_cell() {
        let comb = comb();
        let index = CellIndex::new(std::slice::from_ref(&comb), comb.bounds(), 0.5);
        assert!(index.cell([-0.4, 5.0]).is_some());
        assert!(index.cell([-0.6, 5.0]).is_none());
        assert!(index.cell([5.0, 10.6]).is_none());
    }
}
