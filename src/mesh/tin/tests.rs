use super::*;

fn grid(size: usize, f: impl Fn(f64, f64) -> f64) -> HeightGrid {
    let mut heights = Vec::with_capacity(size * size);
    for j in 0..size {
        for i in 0..size {
            heights.push(f(i as f64, j as f64));
        }
    }
    HeightGrid::unit(size, size, heights)
}

fn max_error(tin: &Tin, grid: &HeightGrid) -> f64 {
    let mut worst: f64 = 0.0;
    for t in &tin.triangles {
        let p = t.map(|i| tin.positions[i as usize]);
        let h = t.map(|i| tin.heights[i as usize]);
        let det = (p[1].x - p[0].x) * (p[2].y - p[0].y) - (p[2].x - p[0].x) * (p[1].y - p[0].y);
        for j in 0..grid.rows {
            for i in 0..grid.columns {
                let (x, z) = (i as f64 - p[0].x, j as f64 - p[0].y);
                let b1 = (x * (p[2].y - p[0].y) - z * (p[2].x - p[0].x)) / det;
                let b2 = (z * (p[1].x - p[0].x) - x * (p[1].y - p[0].y)) / det;
                let b0 = 1.0 - b1 - b2;
                if b0 >= -1e-9 && b1 >= -1e-9 && b2 >= -1e-9 {
                    let e = (b0 * h[0] + b1 * h[1] + b2 * h[2] - grid.height(i, j)).abs();
                    worst = worst.max(e);
                }
            }
        }
    }
    worst
}

fn limits(max_error: f64) -> RefineLimits {
    RefineLimits {
        max_error,
        keep_border: false,
        max_insertions: usize::MAX,
    }
}

#[test]
fn a_plane_needs_only_its_corners() {
    let g = grid(33, |x, z| 3.0 * x - 2.0 * z + 7.0);
    let (tin, report) = refine(&corner_seed(&g), &g, limits(0.01), &mut |_| unreachable!());
    assert_eq!(report.inserted, 0);
    assert_eq!(tin.triangles.len(), 2);
}

#[test]
fn every_sample_ends_within_the_bound() {
    let g = grid(65, |x, z| {
        20.0 * (x / 6.0).sin() * (z / 9.0).cos() + 0.01 * x * z
    });
    for bound in [0.5, 2.0, 5.0] {
        let (tin, report) = refine(&corner_seed(&g), &g, limits(bound), &mut |_| unreachable!());
        let measured = max_error(&tin, &g);
        assert!(
            measured <= bound + 1e-9,
            "bound {bound}: measured {measured}"
        );
        assert!(
            report.inserted < 65 * 65 / 2,
            "bound {bound}: {} insertions",
            report.inserted
        );
        assert_eq!(tin.heights.len(), tin.positions.len());
    }
}

#[test]
fn the_result_is_delaunay_and_counter_clockwise() {
    let g = grid(33, |x, z| ((x * 0.7).sin() + (z * 0.3).cos()) * 10.0);
    let (tin, _) = refine(&corner_seed(&g), &g, limits(0.2), &mut |_| unreachable!());
    let c = |i: u32| coord(tin.positions[i as usize]);
    for t in &tin.triangles {
        assert!(robust::orient2d(c(t[0]), c(t[1]), c(t[2])) > 0.0);
    }
    // No vertex lies strictly inside another triangle's circumcircle (sampled check).
    for t in tin.triangles.iter().step_by(7) {
        for v in (0..tin.positions.len() as u32).step_by(3) {
            if !t.contains(&v) {
                assert!(
                    robust::incircle(c(t[0]), c(t[1]), c(t[2]), c(v)) <= 1e-9,
                    "{t:?} {v}"
                );
            }
        }
    }
    // The triangles tile the square exactly.
    let area: f64 = tin
        .triangles
        .iter()
        .map(|t| robust::orient2d(c(t[0]), c(t[1]), c(t[2])) / 2.0)
        .sum();
    assert!((area - 32.0 * 32.0).abs() < 1e-9);
}

#[test]
fn constraint_edges_survive_refinement() {
    let g = grid(33, |x, z| 5.0 * (x / 3.0).sin() * (z / 4.0).cos());
    let mut seed = corner_seed(&g);
    let a = seed.insert(Point2::new(2.0, 3.5)).unwrap();
    let b = seed.insert(Point2::new(30.0, 29.5)).unwrap();
    seed.add_constraint_and_split(a, b, |p| p);
    let (tin, _) = refine(&seed, &g, limits(0.3), &mut |p| {
        5.0 * (p.x / 3.0).sin() * (p.y / 4.0).cos()
    });
    // Every point on the constraint line lies on an edge of the result: no triangle's
    // interior crosses it (check the segment's midpoints between consecutive vertices on it).
    let on_line: Vec<Point2<f64>> = {
        let mut v: Vec<Point2<f64>> = tin
            .positions
            .iter()
            .copied()
            .filter(|p| {
                robust::orient2d(
                    coord(Point2::new(2.0, 3.5)),
                    coord(Point2::new(30.0, 29.5)),
                    coord(*p),
                ) == 0.0
            })
            .filter(|p| p.x >= 2.0 && p.x <= 30.0)
            .collect();
        v.sort_by(|a, b| a.x.total_cmp(&b.x));
        v
    };
    assert!(on_line.len() >= 2);
    for pair in on_line.windows(2) {
        let (ia, ib) = [pair[0], pair[1]]
            .map(|p| tin.positions.iter().position(|q| *q == p).unwrap() as u32)
            .into();
        let has_edge = tin.triangles.iter().any(|t| {
            (0..3).any(|k| t[k] == ia && t[(k + 1) % 3] == ib || t[k] == ib && t[(k + 1) % 3] == ia)
        });
        assert!(has_edge, "no edge between {:?} and {:?}", pair[0], pair[1]);
    }
}

#[test]
fn weights_make_the_mesh_denser_where_they_are_high() {
    let mut g = grid(65, |x, z| 10.0 * (x / 5.0).sin() + 10.0 * (z / 7.0).cos());
    let count = |g: &HeightGrid| {
        let (tin, _) = refine(&corner_seed(g), g, limits(1.0), &mut |_| unreachable!());
        tin.positions.iter().filter(|p| p.x < 32.0).count()
    };
    let plain = count(&g);
    g.weights = Some(
        (0..65 * 65)
            .map(|k| if k % 65 < 32 { 4.0 } else { 1.0 })
            .collect(),
    );
    let weighted = count(&g);
    assert!(weighted > plain * 3 / 2, "{plain} → {weighted}");
}
