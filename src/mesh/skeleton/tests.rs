use super::*;
use proptest::prelude::*;

fn check(skeleton: &Skeleton) {
    if let Err(fault) = skeleton.verify() {
        panic!("{fault}");
    }
}

#[test]
fn a_rectangle_has_one_ridge_between_two_hips() {
    let skeleton =
        skeleton(&[vec![[0.0, 0.0], [10.0, 0.0], [10.0, 4.0], [0.0, 4.0]]]).expect("a skeleton");
    check(&skeleton);
    let inner: Vec<&SkeletonNode> = skeleton.nodes[4..]
        .iter()
        .filter(|n| n.time > 0.0)
        .collect();
    for node in &inner {
        assert!((node.time - 2.0).abs() < 1e-9);
        assert!((node.point[1] - 2.0).abs() < 1e-9);
    }
    let xs: Vec<f64> = inner.iter().map(|n| n.point[0]).collect();
    assert!(xs.iter().any(|x| (x - 2.0).abs() < 1e-9));
    assert!(xs.iter().any(|x| (x - 8.0).abs() < 1e-9));
    // The long sides are trapezoids, the short ones triangles.
    assert_eq!(skeleton.faces[0].len(), 4);
    assert_eq!(skeleton.faces[1].len(), 3);
}

#[test]
fn a_square_meets_in_its_centre() {
    let skeleton =
        skeleton(&[vec![[0.0, 0.0], [6.0, 0.0], [6.0, 6.0], [0.0, 6.0]]]).expect("a skeleton");
    check(&skeleton);
    let top = skeleton.nodes.iter().map(|n| n.time).fold(0.0, f64::max);
    assert!((top - 3.0).abs() < 1e-9);
}

#[test]
fn l_t_and_u_shapes_and_a_courtyard_have_valid_skeletons() {
    let l = vec![
        [0.0, 0.0],
        [12.0, 0.0],
        [12.0, 5.0],
        [5.0, 5.0],
        [5.0, 14.0],
        [0.0, 14.0],
    ];
    let t = vec![
        [0.0, 0.0],
        [18.0, 0.0],
        [18.0, 6.0],
        [11.0, 6.0],
        [11.0, 16.0],
        [7.0, 16.0],
        [7.0, 6.0],
        [0.0, 6.0],
    ];
    let u = vec![
        [0.0, 0.0],
        [16.0, 0.0],
        [16.0, 12.0],
        [11.0, 12.0],
        [11.0, 5.0],
        [5.0, 5.0],
        [5.0, 12.0],
        [0.0, 12.0],
    ];
    for ring in [l, t, u] {
        check(&skeleton(&[ring]).expect("a skeleton"));
    }
    let courtyard = skeleton(&[
        vec![[0.0, 0.0], [20.0, 0.0], [20.0, 16.0], [0.0, 16.0]],
        vec![[6.0, 5.0], [6.0, 11.0], [14.0, 11.0], [14.0, 5.0]],
    ])
    .expect("a skeleton");
    check(&courtyard);
    // The wings are 5 and 6 m wide: their ridges are 2.5 and 3 m in.
    let mut ridges: Vec<f64> = courtyard
        .nodes
        .iter()
        .map(|n| n.time)
        .filter(|&t| t > 0.0)
        .collect();
    ridges.sort_by(f64::total_cmp);
    ridges.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
    assert_eq!(ridges.len(), 2, "{ridges:?}");
    assert!(
        (ridges[0] - 2.5).abs() < 1e-9 && (ridges[1] - 3.0).abs() < 1e-9,
        "{ridges:?}"
    );
}

/// A random simple polygon: points at random radii around a centre, in angle order.
pub(crate) fn star(radii: &[f64]) -> Vec<Point> {
    let n = radii.len();
    radii
        .iter()
        .enumerate()
        .map(|(i, &r)| {
            let a = std::f64::consts::TAU * i as f64 / n as f64;
            [r * a.cos(), r * a.sin()]
        })
        .collect()
}

/// A rectilinear polygon: columns of the given widths and heights standing on one line, so
/// many edges are parallel and many events happen at once.
pub(crate) fn skyline(columns: &[(u8, u8)]) -> Vec<Point> {
    let mut ring = vec![[0.0, 0.0]];
    let width: f64 = columns.iter().map(|c| f64::from(c.0)).sum();
    ring.push([width, 0.0]);
    let mut x = width;
    for &(w, h) in columns.iter().rev() {
        ring.push([x, f64::from(h)]);
        x -= f64::from(w);
        ring.push([x, f64::from(h)]);
    }
    ring
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1000))]
    #[test]
    fn rectilinear_polygons_with_many_simultaneous_events_have_skeletons(
        columns in prop::collection::vec((1u8..4, 1u8..5), 1..9),
    ) {
        let ring: Vec<Point> = skyline(&columns)
            .iter()
            .map(|p| [p[0] * 2.0, p[1] * 2.0])
            .collect();
        let skeleton = skeleton(&[ring]).expect("a skeleton");
        check(&skeleton);
    }

    #[test]
    fn random_polygons_have_skeletons_whose_faces_tile_them(
        radii in prop::collection::vec(4.0f64..20.0, 3..24),
        hole in prop::option::of((0.3f64..1.2, 0.0f64..1.5)),
    ) {
        let mut rings = vec![star(&radii)];
        if let Some((half, turn)) = hole {
            // A small square hole inside the kernel of the star (every radius is at least 4).
            let (s, c) = turn.sin_cos();
            rings.push(
                [[-half, -half], [half, -half], [half, half], [-half, half]]
                    .iter()
                    .map(|p| [p[0] * c - p[1] * s, p[0] * s + p[1] * c])
                    .collect(),
            );
        }
        let skeleton = skeleton(&rings).expect("a skeleton");
        check(&skeleton);
    }
}
