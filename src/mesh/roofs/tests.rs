use super::*;

/// The corners of the roof's slopes at one height above the eaves.
fn corners_at(mesh: &RoofMesh, height: f64) -> Vec<[f64; 3]> {
    mesh.slopes
        .iter()
        .flatten()
        .copied()
        .filter(|c| (c[2] - height).abs() < 1e-9)
        .collect()
}

/// Twice the area of the roof's slopes seen from above, and the footprint's.
fn plan_areas(mesh: &RoofMesh, rings: &[Vec<Point>]) -> (f64, f64) {
    let roof: f64 = mesh
        .slopes
        .iter()
        .map(|t| signed_area2(&[[t[0][0], t[0][1]], [t[1][0], t[1][1]], [t[2][0], t[2][1]]]))
        .sum();
    let footprint: f64 = rings.iter().map(|r| signed_area2(r).abs()).sum::<f64>()
        - 2.0
            * rings[1..]
                .iter()
                .map(|r| signed_area2(r).abs())
                .sum::<f64>();
    (roof, footprint)
}

/// Every edge of the roof's faces runs the other way in exactly one other face once the
/// tops of the walls (the footprint's edges, at the eaves) are counted too: the roof closes
/// the walls, and every face is wound the same way round.
pub(crate) fn is_closed_over_the_walls(mesh: &RoofMesh, rings: &[Vec<Point>]) -> bool {
    let mut edges: std::collections::HashMap<([u64; 3], [u64; 3]), i32> = Default::default();
    let key = |c: [f64; 3]| c.map(|x| (x + 0.0).to_bits());
    let faces = mesh
        .slopes
        .iter()
        .map(|t| t.to_vec())
        .chain(mesh.sides.iter().cloned());
    for face in faces {
        for i in 0..face.len() {
            let (a, b) = (face[i], face[(i + 1) % face.len()]);
            *edges.entry((key(a), key(b))).or_default() += 1;
        }
    }
    for (r, ring) in rings.iter().enumerate() {
        for i in 0..ring.len() {
            // The wall's top runs from the edge's end back to its start.
            let mut top = vec![ring[(i + 1) % ring.len()]];
            top.extend(mesh.edge_points(r, i).iter().rev());
            top.push(ring[i]);
            for pair in top.windows(2) {
                let (b, a) = (pair[0], pair[1]);
                *edges
                    .entry((key([b[0], b[1], 0.0]), key([a[0], a[1], 0.0])))
                    .or_default() += 1;
            }
        }
    }
    edges
        .iter()
        .all(|((a, b), &n)| n == 1 && edges.get(&(*b, *a)) == Some(&1))
}

#[test]
fn a_gabled_rectangle_has_one_ridge_of_its_length() {
    let rings = vec![vec![[0.0, 0.0], [10.0, 0.0], [10.0, 6.0], [0.0, 6.0]]];
    let mesh = skeleton_roof(&rings, SkeletonRoof::GABLED, Some(4.0), 0.0).expect("a roof");
    assert_eq!(mesh.sides.len(), 2);
    // The ridge: the corners at full height, at the two ends of the long axis.
    let mut ridge: Vec<[f64; 3]> = corners_at(&mesh, 4.0);
    ridge.sort_by(|a, b| a[0].total_cmp(&b[0]));
    ridge.dedup();
    assert_eq!(ridge, vec![[0.0, 3.0, 4.0], [10.0, 3.0, 4.0]]);
    let (roof, footprint) = plan_areas(&mesh, &rings);
    assert!((roof - footprint).abs() < 1e-9);
    assert!(is_closed_over_the_walls(&mesh, &mesh.rings));
}

#[test]
fn a_hipped_rectangle_rises_at_its_pitch() {
    let rings = vec![vec![[0.0, 0.0], [10.0, 0.0], [10.0, 6.0], [0.0, 6.0]]];
    let mesh = skeleton_roof(&rings, SkeletonRoof::HIPPED, None, 0.5).expect("a roof");
    assert!(mesh.sides.is_empty());
    assert!((mesh.height - 1.5).abs() < 1e-9);
    assert!(is_closed_over_the_walls(&mesh, &mesh.rings));
}

#[test]
fn an_l_house_gets_a_ridge_per_wing() {
    let rings = vec![vec![
        [0.0, 0.0],
        [12.0, 0.0],
        [12.0, 6.0],
        [6.0, 6.0],
        [6.0, 14.0],
        [0.0, 14.0],
    ]];
    let mesh = skeleton_roof(&rings, SkeletonRoof::GABLED, Some(3.0), 0.0).expect("a roof");
    // Both wing ends are gables; the ridges run along the wings at x = 3 and y = 3.
    assert_eq!(mesh.sides.len(), 2);
    let top: Vec<[f64; 3]> = corners_at(&mesh, 3.0);
    assert!(top
        .iter()
        .any(|c| c[0] == 12.0 && (c[1] - 3.0).abs() < 1e-9));
    assert!(top
        .iter()
        .any(|c| c[1] == 14.0 && (c[0] - 3.0).abs() < 1e-9));
    let (roof, footprint) = plan_areas(&mesh, &rings);
    assert!((roof - footprint).abs() < 1e-9, "{roof} {footprint}");
    assert!(is_closed_over_the_walls(&mesh, &mesh.rings));
}

#[test]
fn t_and_u_houses_get_a_ridge_per_wing_meeting_in_valleys() {
    let t = vec![vec![
        [0.0, 0.0],
        [18.0, 0.0],
        [18.0, 6.0],
        [12.0, 6.0],
        [12.0, 16.0],
        [6.0, 16.0],
        [6.0, 6.0],
        [0.0, 6.0],
    ]];
    let u = vec![vec![
        [0.0, 0.0],
        [18.0, 0.0],
        [18.0, 16.0],
        [12.0, 16.0],
        [12.0, 6.0],
        [6.0, 6.0],
        [6.0, 16.0],
        [0.0, 16.0],
    ]];
    // The ridge's corners: the ends of each wing and where the ridges meet.
    for (rings, ridge, gables) in [
        (t, vec![[0.0, 3.0], [9.0, 3.0], [9.0, 16.0], [18.0, 3.0]], 3),
        (
            u,
            vec![[3.0, 3.0], [3.0, 16.0], [15.0, 3.0], [15.0, 16.0]],
            2,
        ),
    ] {
        let mesh = skeleton_roof(&rings, SkeletonRoof::GABLED, Some(3.0), 0.0).expect("a roof");
        let mut top: Vec<Point> = corners_at(&mesh, 3.0)
            .iter()
            .map(|c| [c[0], c[1]])
            .collect();
        top.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
        top.dedup_by(|a, b| (a[0] - b[0]).hypot(a[1] - b[1]) < 1e-9);
        let near = |a: &Point, b: &Point| (a[0] - b[0]).hypot(a[1] - b[1]) < 1e-9;
        assert!(
            top.len() == ridge.len() && top.iter().zip(&ridge).all(|(a, b)| near(a, b)),
            "{top:?}"
        );
        assert_eq!(mesh.sides.len(), gables);
        // Valleys: the inner corners' arcs run down from the ridges to the eaves.
        let (roof, footprint) = plan_areas(&mesh, &rings);
        assert!((roof - footprint).abs() < 1e-9);
        assert!(is_closed_over_the_walls(&mesh, &mesh.rings));
    }
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(1000))]
    #[test]
    fn roofs_on_random_houses_cover_them_and_close_over_the_walls(
        columns in proptest::collection::vec((2u8..6, 2u8..7), 1..6),
        radii in proptest::collection::vec(5.0f64..15.0, 3..12),
        end in 0usize..4,
        bent in proptest::bool::ANY,
    ) {
        let ends = [RoofEnd::Hip, RoofEnd::Gable, RoofEnd::HalfHip, RoofEnd::Gablet];
        let shape = SkeletonRoof::ends(ends[end]);
        // A rectilinear house of wings side by side, and a random star-shaped one.
        let wings = crate::mesh::skeleton::tests::skyline(&columns);
        let star = crate::mesh::skeleton::tests::star(&radii);
        for ring in [wings, star] {
            let rings = vec![ring];
            let mut mesh = skeleton_roof(&rings, shape, Some(3.0), 0.0).expect("a roof");
            if bent {
                bend(&mut mesh);
            }
            let (roof, footprint) = plan_areas(&mesh, &rings);
            proptest::prop_assert!((roof - footprint).abs() < 1e-6 * footprint, "{} {}", roof, footprint);
            proptest::prop_assert!(mesh.slopes.iter().flatten().all(|c| c[2] >= -1e-9 && c[2] <= 3.0 + 1e-9));
            proptest::prop_assert!(is_closed_over_the_walls(&mesh, &mesh.rings));
        }
    }
}

#[test]
fn centred_roofs_close_over_their_walls_and_reach_their_height() {
    let octagon: Vec<Point> = (0..8)
        .map(|i| {
            let a = std::f64::consts::TAU * i as f64 / 8.0;
            [5.0 * a.cos(), 5.0 * a.sin()]
        })
        .collect();
    for shape in [CentredRoof::Pyramid, CentredRoof::Dome, CentredRoof::Onion] {
        let mesh = centred_roof(&octagon, shape, 4.0).expect("a roof");
        assert!(is_closed_over_the_walls(&mesh, &mesh.rings), "{shape:?}");
        let top = mesh
            .slopes
            .iter()
            .flatten()
            .map(|c| c[2])
            .fold(0.0, f64::max);
        assert!((top - 4.0).abs() < 1e-12, "{shape:?} {top}");
    }
    // An onion bulges out past its walls; a dome stays within them.
    let reach = |shape| {
        centred_roof(&octagon, shape, 4.0)
            .expect("a roof")
            .slopes
            .iter()
            .flatten()
            .map(|c| c[0].hypot(c[1]))
            .fold(0.0, f64::max)
    };
    assert!(reach(CentredRoof::Onion) > 5.5);
    assert!(reach(CentredRoof::Dome) <= 5.0 + 1e-9);
    // An L is not star-shaped around its centroid: no centred roof.
    let l = [
        [0.0, 0.0],
        [10.0, 0.0],
        [10.0, 1.0],
        [1.0, 1.0],
        [1.0, 10.0],
        [0.0, 10.0],
    ];
    assert!(centred_roof(&l, CentredRoof::Pyramid, 3.0).is_none());
    let (inner, outer) = spread(&octagon).expect("star-shaped");
    assert!((inner - 5.0 * (std::f64::consts::PI / 8.0).cos()).abs() < 1e-9);
    assert!((outer - 5.0).abs() < 1e-9);
}

#[test]
fn mansard_and_gambrel_roofs_bend_and_stay_closed() {
    let rings = vec![vec![[0.0, 0.0], [12.0, 0.0], [12.0, 8.0], [0.0, 8.0]]];
    for shape in [SkeletonRoof::HIPPED, SkeletonRoof::GABLED] {
        let mut mesh = skeleton_roof(&rings, shape, Some(4.0), 0.0).expect("a roof");
        bend(&mut mesh);
        assert!(is_closed_over_the_walls(&mesh, &mesh.rings), "{shape:?}");
        let (roof, footprint) = plan_areas(&mesh, &rings);
        assert!((roof - footprint).abs() < 1e-9);
        // The knee: 30 % of the way in (1.2 m from the long sides), 70 % up (2.8 m).
        let knee: Vec<[f64; 3]> = corners_at(&mesh, 2.8);
        assert!(!knee.is_empty(), "{shape:?}");
        assert!(knee.iter().all(|c| (c[1] - 1.2).abs() < 1e-9
            || (c[1] - 6.8).abs() < 1e-9
            || c[0] < 1.3
            || c[0] > 10.7));
        let top = mesh
            .slopes
            .iter()
            .flatten()
            .map(|c| c[2])
            .fold(0.0, f64::max);
        assert!((top - 4.0).abs() < 1e-9);
    }
}

#[test]
fn a_courtyard_roof_is_closed() {
    let rings = vec![
        vec![[0.0, 0.0], [20.0, 0.0], [20.0, 16.0], [0.0, 16.0]],
        vec![[6.0, 5.0], [6.0, 11.0], [14.0, 11.0], [14.0, 5.0]],
    ];
    let mesh = skeleton_roof(&rings, SkeletonRoof::HIPPED, Some(3.0), 0.0).expect("a roof");
    let (roof, footprint) = plan_areas(&mesh, &rings);
    assert!((roof - footprint).abs() < 1e-9, "{roof} {footprint}");
    assert!(is_closed_over_the_walls(&mesh, &mesh.rings));
}

/// The corners of the roof's sides (gables) at one height above the eaves.
fn side_corners_at(mesh: &RoofMesh, height: f64) -> Vec<[f64; 3]> {
    mesh.sides
        .iter()
        .flatten()
        .copied()
        .filter(|c| (c[2] - height).abs() < 1e-9)
        .collect()
}

#[test]
fn half_hips_gablets_and_one_hipped_end_shape_the_ends_of_a_rectangle() {
    let rings = vec![vec![[0.0, 0.0], [10.0, 0.0], [10.0, 6.0], [0.0, 6.0]]];
    let ridge_ends = |mesh: &RoofMesh| {
        let mut xs: Vec<f64> = corners_at(mesh, 4.0).iter().map(|c| c[0]).collect();
        xs.sort_by(f64::total_cmp);
        xs.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
        xs
    };
    let close = |a: &[f64], b: &[f64]| {
        a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-9)
    };
    // Half hip: gables up to 65 % of the height, the ridge shortened by 35 % of the hip.
    let half = skeleton_roof(&rings, SkeletonRoof::ends(RoofEnd::HalfHip), Some(4.0), 0.0)
        .expect("a roof");
    assert_eq!(half.sides.len(), 2);
    assert!(
        close(&ridge_ends(&half), &[1.05, 8.95]),
        "{:?}",
        ridge_ends(&half)
    );
    assert_eq!(side_corners_at(&half, 2.6).len(), 4);
    assert!(half.sides.iter().flatten().all(|c| c[2] <= 2.6 + 1e-9));
    // Gablet: hips up to half the height, a small gable above reaching the ridge.
    let gablet =
        skeleton_roof(&rings, SkeletonRoof::ends(RoofEnd::Gablet), Some(4.0), 0.0).expect("a roof");
    assert!(
        close(&ridge_ends(&gablet), &[1.5, 8.5]),
        "{:?}",
        ridge_ends(&gablet)
    );
    assert!(gablet.sides.iter().flatten().all(|c| c[2] >= 2.0 - 1e-9));
    assert_eq!(side_corners_at(&gablet, 4.0).len(), 2);
    // Side hipped towards the east: gabled at the west end only.
    let side = SkeletonRoof {
        ends: RoofEnd::Gable,
        one_end: Some(([1.0, 0.0], RoofEnd::Hip)),
    };
    let side = skeleton_roof(&rings, side, Some(4.0), 0.0).expect("a roof");
    assert_eq!(side.sides.len(), 1);
    assert!(
        close(&ridge_ends(&side), &[0.0, 7.0]),
        "{:?}",
        ridge_ends(&side)
    );
    for mesh in [&half, &gablet, &side] {
        assert!(is_closed_over_the_walls(mesh, &mesh.rings));
        let (roof, footprint) = plan_areas(mesh, &rings);
        assert!((roof - footprint).abs() < 1e-9, "{roof} {footprint}");
    }
}

/// Every corner and the centroid of every triangle lie on the profile: no triangle spans
/// a bend.
fn follows_profile(mesh: &RoofMesh, across: Point, profile: &[(f64, f64)], height: f64) -> bool {
    let s = |p: [f64; 3]| p[0] * across[0] + p[1] * across[1];
    let (low, high) =
        mesh.rings[0]
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                let v = p[0] * across[0] + p[1] * across[1];
                (lo.min(v), hi.max(v))
            });
    let on = |c: [f64; 3]| {
        (c[2] - height * profile_at(profile, (s(c) - low) / (high - low))).abs() < 1e-6
    };
    mesh.slopes.iter().all(|t| {
        let centroid = [0, 1, 2].map(|k| (t[0][k] + t[1][k] + t[2][k]) / 3.0);
        t.iter().all(|&c| on(c)) && on(centroid)
    })
}

#[test]
fn a_skillion_slopes_as_one_plane_with_a_high_wall() {
    let rings = vec![vec![[0.0, 0.0], [10.0, 0.0], [10.0, 6.0], [0.0, 6.0]]];
    let profile = [(0.0, 0.0), (1.0, 1.0)];
    let mesh = profile_roof(&rings, [0.0, 1.0], &profile, 3.0).expect("a roof");
    assert!(follows_profile(&mesh, [0.0, 1.0], &profile, 3.0));
    // The high side is a full quad, the two ends triangles, the low side none.
    let mut corners: Vec<usize> = mesh.sides.iter().map(Vec::len).collect();
    corners.sort_unstable();
    assert_eq!(corners, vec![3, 3, 4]);
    assert!((mesh.height - 3.0).abs() < 1e-12);
    assert!(is_closed_over_the_walls(&mesh, &mesh.rings));
    let (roof, footprint) = plan_areas(&mesh, &rings);
    assert!((roof - footprint).abs() < 1e-9);
}

#[test]
fn long_axis_follows_the_longer_side() {
    let angle: f64 = 0.4;
    let (c, s) = (angle.cos(), angle.sin());
    let ring: Vec<Point> = [[0.0, 0.0], [10.0, 0.0], [10.0, 4.0], [0.0, 4.0]]
        .iter()
        .map(|p| [p[0] * c - p[1] * s, p[0] * s + p[1] * c])
        .collect();
    let axis = long_axis(&ring).expect("an axis");
    assert!((axis[0] * c + axis[1] * s).abs() > 1.0 - 1e-9, "{axis:?}");
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(500))]
    #[test]
    fn profile_roofs_on_random_footprints_follow_their_profile_and_close(
        radii in proptest::collection::vec(5.0f64..15.0, 3..12),
        hole in proptest::bool::ANY,
        turn in 0.0f64..std::f64::consts::TAU,
        teeth in 1usize..5,
        shape in 0usize..3,
    ) {
        let mut rings = vec![crate::mesh::skeleton::tests::star(&radii)];
        let inner = radii.iter().copied().fold(f64::INFINITY, f64::min);
        if hole {
            let r = inner * 0.3;
            rings.push(vec![[-r, -r], [-r, r], [r, r], [r, -r]]);
        }
        let profile: Vec<(f64, f64)> = match shape {
            0 => vec![(0.0, 0.0), (1.0, 1.0)],
            1 => vec![(0.0, 0.0), (0.4, 1.0), (1.0, 0.0)],
            _ => {
                let mut p = vec![(0.0, 0.0)];
                for k in 0..teeth {
                    p.push(((k as f64 + 0.8) / teeth as f64, 1.0));
                    p.push(((k + 1) as f64 / teeth as f64, 0.0));
                }
                p
            }
        };
        let across = [turn.cos(), turn.sin()];
        let mesh = profile_roof(&rings, across, &profile, 3.0).expect("a roof");
        proptest::prop_assert!(follows_profile(&mesh, across, &profile, 3.0));
        let (roof, footprint) = plan_areas(&mesh, &rings);
        proptest::prop_assert!((roof - footprint).abs() < 1e-6 * footprint, "{} {}", roof, footprint);
        proptest::prop_assert!(is_closed_over_the_walls(&mesh, &mesh.rings));
    }
}
