//! Rules of sidewalks on sloping land: the ground under a raised sidewalk is levelled with
//! its kerb, so the land beside a street cut into a hillside rises (or falls) beyond the
//! sidewalk's outer edge, never through it.

use super::*;

#[test]
fn the_ground_under_a_sidewalk_beside_a_street_across_a_slope_lies_at_its_kerb() {
    let mut fixture = Fixture::default();
    street_between_houses(&mut fixture);
    // The land rises northwards 30 m in every 100 m, across the street.
    let middle = at(0.5, 0.5).lat;
    let tile = drawn(
        &fixture,
        &terrain(move |_, lat| 100.0 + 0.3 * (lat - middle) * 111_195.0),
    );
    let size = tile.tile_size();
    let road = heights(&tile, "road", (0.5, 0.5))
        .into_iter()
        .fold(f64::MAX, f64::min);
    let ground = GroundLocator::of_ground(&tile);
    let mut checked = [0_usize; 2];
    for primitive in tile.primitives("roadside") {
        if primitive.material != "sidewalk" {
            continue;
        }
        for t in primitive.indices.chunks_exact(3) {
            let corners: Vec<[f64; 3]> = t
                .iter()
                .map(|&i| primitive.positions[i as usize].map(f64::from))
                .collect();
            // Points spread over the triangle.
            for (i, j) in (1..10).flat_map(|i| (1..10 - i).map(move |j| (i, j))) {
                let (a, b) = (f64::from(i) / 10.0, f64::from(j) / 10.0);
                let point = |axis: usize| {
                    corners[0][axis]
                        + a * (corners[1][axis] - corners[0][axis])
                        + b * (corners[2][axis] - corners[0][axis])
                };
                let (x, y, z) = (point(0), point(1), point(2));
                let off = z / size - 0.5;
                if off.abs() > 10.0 * metre() || (x / size - 0.5).abs() > 0.1 {
                    continue;
                }
                let under = ground
                    .heights_at(x, z, 1e-9)
                    .into_iter()
                    .fold(f64::MIN, f64::max);
                let over_road = under / scale() - road;
                // A residential street's kerb is 12 cm: the ground under the band lies between
                // the road's edge and the kerb's top, and the sidewalk's top above it.
                let side = if off < 0.0 { "north" } else { "south" };
                assert!(
                    (-0.02..=0.14).contains(&over_road),
                    "the ground under a sidewalk {side} of the street lies {over_road:.3} m over the road",
                );
                assert!(
                    y >= under,
                    "a sidewalk lies {:.3} m under the ground",
                    (under - y) / scale()
                );
                checked[usize::from(off > 0.0)] += 1;
            }
        }
    }
    assert!(
        checked.iter().all(|&n| n > 50),
        "sidewalk triangles on both sides: {checked:?}"
    );
}
