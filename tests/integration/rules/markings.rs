//! Rules of what is painted on the roads: lane, centre, edge and cycle-lane lines, crossings,
//! stop and give-way lines and turn arrows, and where the signs beside them stand.

use super::*;

/// The painted lines of a tile: for each line, its distance south of the tile's middle (metres
/// on the ground, rounded to decimetres) and the length it is painted over, east to west.
fn painted_lines(tile: &DecodedTile) -> Vec<(f64, f64)> {
    let size = tile.tile_size();
    let mut lines: std::collections::BTreeMap<i64, (f64, f64)> = Default::default();
    for primitive in tile.primitives("marking") {
        assert_eq!(primitive.material, "marking");
        for t in primitive.indices.chunks_exact(3) {
            let corners = [0, 1, 2].map(|k| primitive.positions[t[k] as usize]);
            let south = corners.iter().map(|c| f64::from(c[2])).sum::<f64>() / 3.0;
            let off_m = (south - size / 2.0) / scale();
            let (west, east) = corners.iter().fold((f64::MAX, f64::MIN), |(w, e), c| {
                (w.min(f64::from(c[0])), e.max(f64::from(c[0])))
            });
            let line = lines.entry((off_m * 2.0).round() as i64).or_default();
            // Two triangles a piece: half its length each.
            line.0 = off_m;
            line.1 += (east - west) / scale() / 2.0;
        }
    }
    lines.into_values().collect()
}

#[test]
fn a_four_lane_road_has_three_lines_and_a_solid_centre() {
    let mut fixture = Fixture::default();
    fixture.way(
        &[("highway", "primary"), ("lanes", "4")],
        &[(-0.2, 0.5), (1.2, 0.5)],
    );
    let tile = drawn(&fixture, &terrain(|_, _| 100.0));
    let lines = painted_lines(&tile);
    assert_eq!(lines.len(), 3, "{lines:?}");
    // 4 lanes of the configured 3.5 m: lines at a quarter, half and three quarters across.
    let width = 4.0 * 3.5;
    for ((off, _), expected) in lines.iter().zip([-width / 4.0, 0.0, width / 4.0]) {
        assert!((off - expected).abs() < 0.2, "{lines:?}");
    }
    let across_m = tile.tile_size() / scale();
    assert!(
        lines[1].1 > 0.99 * across_m,
        "the centre line is solid: {lines:?}"
    );
    for lane in [lines[0], lines[2]] {
        assert!(
            (lane.1 / across_m - 1.0 / 3.0).abs() < 0.05,
            "a lane line is a third paint: {lines:?}"
        );
    }
    // The paint lies just above the road.
    assert_paint_just_above_the_road(&tile, "marking");
}

#[test]
fn a_residential_street_without_lanes_and_a_service_road_are_not_painted() {
    let mut fixture = Fixture::default();
    fixture.way(&[("highway", "residential")], &[(-0.2, 0.3), (1.2, 0.3)]);
    fixture.way(
        &[("highway", "service"), ("lanes", "2")],
        &[(-0.2, 0.7), (1.2, 0.7)],
    );
    let tile = drawn(&fixture, &terrain(|_, _| 100.0));
    assert!(!tile.primitives("road").is_empty());
    assert!(painted_lines(&tile).is_empty());
}

#[test]
fn a_zebra_crossing_draws_stripes_across_the_road_and_an_unmarked_one_none() {
    let mut fixture = Fixture::default();
    fixture
        .way(
            &[("highway", "residential"), ("width", "7")],
            &[(-0.2, 0.5), (0.5, 0.5), (1.2, 0.5)],
        )
        .tag_node(
            (0.5, 0.5),
            &[("highway", "crossing"), ("crossing", "zebra")],
        )
        .way(
            &[("highway", "residential"), ("width", "7")],
            &[(-0.2, 0.7), (0.5, 0.7), (1.2, 0.7)],
        )
        .tag_node(
            (0.5, 0.7),
            &[("highway", "crossing"), ("crossing", "unmarked")],
        );
    let tile = drawn(&fixture, &terrain(|_, _| 100.0));
    let crossings: Vec<&Feature> = tile
        .features
        .iter()
        .filter(|f| f.class == "marking" && f.osm_type == "node")
        .collect();
    assert_eq!(crossings.len(), 1, "{crossings:?}");
    let stripes: Vec<&Primitive> = tile
        .primitives("marking")
        .iter()
        .filter(|p| p.material == "crossing")
        .collect();
    let vertices: Vec<[f64; 3]> = stripes
        .iter()
        .flat_map(|p| p.positions.iter().map(|v| v.map(f64::from)))
        .collect();
    // Seven stripes of 0.5 m with 0.5 m between them fill the 7 m road: 6.5 m across, 4 m
    // along, at the crossing's node.
    assert_eq!(vertices.len(), 7 * 4, "{} vertices", vertices.len());
    let extent = |axis: usize| {
        let low = vertices.iter().map(|v| v[axis]).fold(f64::MAX, f64::min);
        let high = vertices.iter().map(|v| v[axis]).fold(f64::MIN, f64::max);
        (
            (high - low) / scale(),
            (high + low) / 2.0 / tile.tile_size(),
        )
    };
    let (along, east) = extent(0);
    let (across, south) = extent(2);
    assert!((along - 4.0).abs() < 0.05, "{along} m along the road");
    assert!((across - 6.5).abs() < 0.05, "{across} m across the road");
    assert!(
        (east - 0.5).abs() < 1e-3 && (south - 0.5).abs() < 1e-3,
        "at {east}, {south}"
    );
    assert_paint_just_above_the_road(&tile, "crossing");
}

#[test]
fn signals_on_a_road_stand_at_both_edges_a_stop_sign_and_a_bus_stop_at_one() {
    let mut fixture = Fixture::default();
    fixture
        .way(
            &[("highway", "residential"), ("width", "7")],
            &[(-0.2, 0.5), (0.3, 0.5), (0.5, 0.5), (0.7, 0.5), (1.2, 0.5)],
        )
        .tag_node((0.7, 0.5), &[("highway", "bus_stop")])
        .tag_node((0.5, 0.5), &[("highway", "traffic_signals")])
        .tag_node((0.3, 0.5), &[("highway", "stop"), ("direction", "forward")]);
    let set = collected(&fixture);
    let projection = terrastitch::features::Projection::new(TILE.z);
    let centre = projection.point(at(0.5, 0.5));
    let metre = projection.metres(1.0, at(0.5, 0.5).lat);
    // Metres east and south of the signals' node.
    let offsets = |kind: ObjectKind| -> Vec<(f64, f64)> {
        set.objects
            .iter()
            .filter(|o| o.kind == kind)
            .map(|o| ((o.at[0] - centre[0]) / metre, (o.at[1] - centre[1]) / metre))
            .collect()
    };
    let mut signals = offsets(ObjectKind::TrafficSignals);
    signals.sort_by(|a, b| a.1.total_cmp(&b.1));
    assert_eq!(signals.len(), 2, "{signals:?}");
    // Half the road's 7 m and half a metre clear of its edge, either side.
    for ((east, south), expected) in signals.iter().zip([-4.0, 4.0]) {
        assert!(
            east.abs() < 1e-6 && (south - expected).abs() < 1e-6,
            "{signals:?}"
        );
    }
    // Eastward traffic keeps right: the stop sign for it stands on the south edge.
    let stop = offsets(ObjectKind::StopSign);
    let expected_east = (projection.point(at(0.3, 0.5))[0] - centre[0]) / metre;
    assert_eq!(stop.len(), 1, "{stop:?}");
    assert!(
        (stop[0].0 - expected_east).abs() < 1e-6 && (stop[0].1 - 4.0).abs() < 1e-6,
        "{stop:?}"
    );
    // A bus stop on the road's line stands at the edge of the traffic along the way.
    let bus = offsets(ObjectKind::BusStop);
    assert!(bus.len() == 1 && (bus[0].1 - 4.0).abs() < 1e-6, "{bus:?}");
    // One feature for the two places of the signals' node.
    let features: std::collections::BTreeSet<u32> = set
        .objects
        .iter()
        .filter(|o| o.kind == ObjectKind::TrafficSignals)
        .map(|o| o.feature)
        .collect();
    assert_eq!(features.len(), 1);
}

/// A stop or give-way line: its node's id, the middle of the line and its two ends in metres
/// east and south of the node, and whether it is dashed.
type HaltLine = (i64, (f64, f64), [(f64, f64); 2], bool);

/// The stop and give-way lines of `set`.
fn halt_lines(set: &terrastitch::features::FeatureSet, fixture: &Fixture) -> Vec<HaltLine> {
    use terrastitch::features::markings::{Paint, Pattern};
    let projection = terrastitch::features::Projection::new(TILE.z);
    let positions: std::collections::HashMap<i64, terrastitch::osm::LonLat> = fixture
        .data()
        .nodes
        .iter()
        .map(|n| (n.id, n.position))
        .collect();
    set.markings
        .iter()
        .filter(|m| m.paint == Paint::Line && m.width_m == 0.5)
        .map(|m| {
            let id = set.features[m.feature as usize]
                .element
                .expect("a line's node")
                .id;
            let centre = projection.point(positions[&id]);
            let off = |p: [f64; 2]| ((p[0] - centre[0]) / m.metre, (p[1] - centre[1]) / m.metre);
            let (a, b) = (off(m.line[0]), off(m.line[1]));
            let middle = ((a.0 + b.0) / 2.0, (a.1 + b.1) / 2.0);
            (
                id,
                middle,
                [a, b],
                matches!(m.pattern, Pattern::Dashed { .. }),
            )
        })
        .collect()
}

#[test]
fn stop_lines_stand_before_signals_crossings_and_junctions_across_the_lanes_they_halt() {
    let mut fixture = Fixture::default();
    let street = [("highway", "residential"), ("width", "7")];
    fixture
        .way(
            &street,
            &[
                (-0.2, 0.5),
                (0.3, 0.5),
                (0.5, 0.5),
                (0.7, 0.5),
                (0.9, 0.5),
                (1.2, 0.5),
            ],
        )
        .way(&street, &[(0.9, 0.8), (0.9, 0.5)])
        .join((0.9, 0.5))
        .tag_node((0.3, 0.5), &[("highway", "traffic_signals")])
        .tag_node(
            (0.5, 0.5),
            &[
                ("highway", "crossing"),
                ("crossing", "traffic_signals"),
                ("crossing:markings", "zebra"),
            ],
        )
        .tag_node(
            (0.7, 0.5),
            &[("highway", "give_way"), ("direction", "backward")],
        )
        .tag_node((0.9, 0.5), &[("highway", "traffic_signals")]);
    let set = collected(&fixture);
    let lines = halt_lines(&set, &fixture);
    let node_at = |place: (f64, f64)| {
        let position = at(place.0, place.1);
        fixture
            .data()
            .nodes
            .iter()
            .find(|n| n.position == position)
            .expect("a tagged node")
            .id
    };
    let of = |place| -> Vec<_> { lines.iter().filter(|l| l.0 == node_at(place)).collect() };
    // A line spans the half of the 7 m road its traffic drives on, clear of the edge and the
    // centre by 0.15 m: eastward traffic keeps to the south half.
    let spans_half = |ends: &[(f64, f64); 2], south_half: bool| {
        let (low, high) = (ends[0].1.min(ends[1].1), ends[0].1.max(ends[1].1));
        let (near, far) = if south_half {
            (low, high)
        } else {
            (-high, -low)
        };
        (near - 0.15).abs() < 0.01 && (far - 3.35).abs() < 0.01
    };
    // Signals: a line each way, 1.25 m before the node (a metre clear, half the line's width).
    let signals = of((0.3, 0.5));
    assert_eq!(signals.len(), 2, "{lines:?}");
    for (_, (east, _), ends, dashed) in &signals {
        assert!(!dashed && (east.abs() - 1.25).abs() < 0.01, "{signals:?}");
        assert!(spans_half(ends, *east < 0.0), "{signals:?}");
    }
    // A signal crossing's zebra reaches 2 m either side: the lines stand a metre before it.
    let crossing = of((0.5, 0.5));
    assert_eq!(crossing.len(), 2, "{lines:?}");
    for (_, (east, _), ends, _) in &crossing {
        assert!((east.abs() - 3.25).abs() < 0.01, "{crossing:?}");
        assert!(spans_half(ends, *east < 0.0), "{crossing:?}");
    }
    // A give-way sign for the westward traffic: one dashed line east of it, on the north half.
    let give_way = of((0.7, 0.5));
    assert_eq!(give_way.len(), 1, "{lines:?}");
    let (_, (east, _), ends, dashed) = give_way[0];
    assert!(*dashed && (east - 1.25).abs() < 0.01 && spans_half(ends, false));
    // Signals at a junction: every road that comes to it halts where its surface is cut back,
    // outside the other road's 7 m and within 25 m.
    let junction = of((0.9, 0.5));
    assert_eq!(junction.len(), 3, "{lines:?}");
    for (_, (east, south), _, _) in &junction {
        let away = east.abs().max(south.abs());
        assert!((3.5..25.0).contains(&away), "{junction:?}");
    }
    assert!(
        junction
            .iter()
            .any(|(_, (east, south), ends, _)| *south > 3.5
                && east.abs() < 3.5
                && ends.iter().all(|e| e.0 > 0.0)),
        "the side road's northward traffic keeps to its east half: {junction:?}"
    );
}

#[test]
fn cycle_lanes_are_marked_off_inside_the_edges_and_a_motorway_has_edge_lines() {
    let mut fixture = Fixture::default();
    fixture.way(
        &[
            ("highway", "secondary"),
            ("width", "10"),
            ("cycleway", "lane"),
        ],
        &[(-0.2, 0.3), (1.2, 0.3)],
    );
    fixture.way(
        &[("highway", "motorway"), ("width", "8"), ("lanes", "2")],
        &[(-0.2, 0.7), (1.2, 0.7)],
    );
    let tile = drawn(&fixture, &terrain(|_, _| 100.0));
    let lines = painted_lines(&tile);
    // The lines' distances (metres) from the middle of the road `south` of the tile's middle,
    // triangles of one line within 0.3 m taken together.
    let across = |south: f64| {
        let mut offsets: Vec<f64> = lines
            .iter()
            .map(|l| l.0 - (south - 0.5) * tile.tile_size() / scale())
            .filter(|o| o.abs() < 6.0)
            .collect();
        offsets.dedup_by(|b, a| (*b - *a).abs() < 0.3);
        offsets
    };
    let street = across(0.3);
    // The cycle lanes' lines 1.5 m inside each edge of the 10 m street, the centre line
    // between them.
    assert_eq!(street.len(), 3, "{lines:?}");
    for (off, expected) in street.iter().zip([-3.5, 0.0, 3.5]) {
        assert!((off - expected).abs() < 0.15, "{street:?}");
    }
    // The motorway: a lane line in the middle and an edge line 0.3 m inside each edge.
    let motorway = across(0.7);
    assert_eq!(motorway.len(), 3, "{lines:?}");
    for (off, expected) in motorway.iter().zip([-3.7, 0.0, 3.7]) {
        assert!((off - expected).abs() < 0.15, "{motorway:?}");
    }
}

#[test]
fn turn_lanes_paint_an_arrow_in_each_lane_before_the_junction() {
    let mut fixture = Fixture::default();
    fixture
        .way(
            &[
                ("highway", "primary"),
                ("oneway", "yes"),
                ("turn:lanes", "left|through|through;right"),
            ],
            &[(-0.2, 0.5), (0.5, 0.5)],
        )
        .way(
            &[("highway", "primary"), ("width", "7")],
            &[(0.5, 0.3), (0.5, 0.5), (0.5, 0.7)],
        )
        .join((0.5, 0.5));
    let set = collected(&fixture);
    let projection = terrastitch::features::Projection::new(TILE.z);
    let centre = projection.point(at(0.5, 0.5));
    let metre = projection.metres(1.0, at(0.5, 0.5).lat);
    // The heads' tips, metres east and south of the junction's node.
    let mut tips: Vec<(f64, f64)> = set
        .markings
        .iter()
        .filter(|m| m.tip)
        .map(|m| {
            let tip = m.line[m.line.len() - 1];
            ((tip[0] - centre[0]) / metre, (tip[1] - centre[1]) / metre)
        })
        .collect();
    tips.sort_by(|a, b| a.1.total_cmp(&b.1));
    assert_eq!(tips.len(), 4, "{tips:?}");
    // Three lanes of 3.5 m (taken from the turns' count): their middles 3.5 m apart. The
    // left lane's head bends north, the right one's south of its lane, the others run east.
    let lane_of = |south: f64| ((south + 5.25) / 3.5).floor() as i32;
    assert!(
        tips[0].1 < -3.5 - 0.5,
        "the left turn bends north: {tips:?}"
    );
    assert_eq!(lane_of(tips[1].1), 1, "{tips:?}");
    assert_eq!(lane_of(tips[2].1), 2, "{tips:?}");
    assert!(
        tips[3].1 > 3.5 + 0.5,
        "the right turn bends south: {tips:?}"
    );
    // All before the junction: past the other road's half width and within 25 m.
    for (east, _) in &tips {
        assert!((-25.0..-3.5).contains(east), "{tips:?}");
    }
    // Lane lines between the three lanes come with them.
    let lines = set
        .markings
        .iter()
        .filter(|m| !m.tip && m.width_m == 0.12)
        .count();
    assert!(lines >= 2, "{lines} lane lines");
}

/// The paint drawn in `material` lies just above the road (its surface at a place west of the
/// middle, on the tile's east–west centre line): over it, less than 10 cm up.
fn assert_paint_just_above_the_road(tile: &DecodedTile, material: &str) {
    let road = ground_at(tile, (0.3, 0.5));
    let (low, high) = height_range(tile, "marking", material);
    assert!(
        low > road && high < road + 0.1,
        "{material} paint at {low}..{high} over {road}"
    );
}

#[test]
fn paint_lies_just_above_the_road_as_drawn_over_rolling_ground() {
    // A four-lane road with a zebra crossing over ground that rises and falls 20 m every
    // 340 m or so: the road as drawn leaves its settled profile by up to the mesh's error bound.
    let mut fixture = Fixture::default();
    fixture
        .way(
            &[("highway", "primary"), ("lanes", "4")],
            &[(-0.2, 0.5), (0.45, 0.5), (1.2, 0.5)],
        )
        .tag_node(
            (0.45, 0.5),
            &[("highway", "crossing"), ("crossing", "zebra")],
        );
    let tile = drawn(
        &fixture,
        &terrain(|lon, _| 100.0 + 20.0 * (lon * 1500.0).sin()),
    );
    let size = tile.tile_size();
    let road = GroundLocator::new(corners(tile.primitives("road")), size);
    let (mut checked, mut off) = (0, Vec::new());
    for primitive in tile.primitives("marking") {
        for t in primitive.indices.chunks_exact(3) {
            let corners = [0, 1, 2].map(|k| primitive.positions[t[k] as usize].map(f64::from));
            let middle = |axis: usize| corners.iter().map(|c| c[axis]).sum::<f64>() / 3.0;
            let (x, y, z) = (middle(0), middle(1), middle(2));
            let Some(lift) = road
                .heights_at(x, z, 1e-9)
                .into_iter()
                .map(|h| (y - h) / scale())
                .min_by(|a, b| a.abs().total_cmp(&b.abs()))
            else {
                continue;
            };
            checked += 1;
            if !(0.005..0.06).contains(&lift) {
                off.push((primitive.material.clone(), x / size, lift));
            }
        }
    }
    assert!(checked > 500, "{checked} painted triangles over the road");
    assert!(
        off.is_empty(),
        "{} of {checked} painted triangles off the road: {:?}",
        off.len(),
        &off[..off.len().min(8)]
    );
}

/// A painted triangle: its middle (fractions of the tile east and south), its distance south
/// of a place (metres) and its middle's height (metres).
struct Painted {
    middle: (f64, f64),
    south_m: f64,
    height: f64,
}

/// The marking triangles of a tile whose middles lie within `reach_m` of a place (fractions
/// east and south).
fn marking_near(tile: &DecodedTile, (east, south): (f64, f64), reach_m: f64) -> Vec<Painted> {
    let size = tile.tile_size();
    let mut found = Vec::new();
    for primitive in tile.primitives("marking") {
        for t in primitive.indices.chunks_exact(3) {
            let corners = [0, 1, 2].map(|k| primitive.positions[t[k] as usize]);
            let middle =
                |axis: usize| corners.iter().map(|c| f64::from(c[axis])).sum::<f64>() / 3.0;
            let (x_m, z_m) = (
                (middle(0) - east * size) / scale(),
                (middle(2) - south * size) / scale(),
            );
            if x_m.hypot(z_m) <= reach_m {
                found.push(Painted {
                    middle: (middle(0) / size, middle(2) / size),
                    south_m: z_m,
                    height: middle(1) / scale(),
                });
            }
        }
    }
    found
}

/// The distinct lines among painted triangles (by their distance south, to 0.5 m).
fn lines_of(painted: &[Painted]) -> std::collections::BTreeSet<i64> {
    painted
        .iter()
        .map(|p| (p.south_m * 2.0).round() as i64)
        .collect()
}

#[test]
fn a_bridge_deck_and_a_tunnel_floor_carry_their_roads_lines_just_above_them() {
    // A four-lane bridge 120 m long over a river, and a four-lane tunnel 600 m long under a
    // hill 60 m high, each between roads on the ground.
    let m = metre();
    let hill = at(0.5, 0.7);
    let mosaic = terrain(move |lon, lat| {
        let east = 111_195.0 * hill.lat.to_radians().cos();
        let (dx, dy) = ((lon - hill.lon) * east, (lat - hill.lat) * 111_195.0);
        100.0 + 60.0 * (-(dx * dx + dy * dy) / (2.0 * 150.0 * 150.0)).exp()
    });
    let road = [("highway", "primary"), ("lanes", "4")];
    let mut fixture = Fixture::default();
    for (south, structure, layer, half_m) in [
        (0.3, ("bridge", "yes"), "1", 60.0),
        (0.7, ("tunnel", "yes"), "-1", 300.0),
    ] {
        let (west, east) = (0.5 - half_m * m, 0.5 + half_m * m);
        fixture
            .way(&road, &[(west - 300.0 * m, south), (west, south)])
            .way(
                &[road[0], road[1], structure, ("layer", layer)],
                &[(west, south), (east, south)],
            )
            .way(&road, &[(east, south), (east + 300.0 * m, south)]);
    }
    fixture.way(
        &[("waterway", "river"), ("width", "20")],
        &[(0.5, 0.2), (0.5, 0.4)],
    );
    let tile = drawn(&fixture, &mosaic);
    for (south, node) in [(0.3, "bridge"), (0.7, "tunnel")] {
        for east_m in [-40.0, 0.0, 40.0] {
            let place = (0.5 + east_m * m, south);
            let paint = marking_near(&tile, place, 12.0);
            // Three lines, but a lane line's dash may miss the place.
            let lines = lines_of(&paint);
            assert!(
                lines.len() >= 2 && lines.iter().all(|l| (l.abs() as f64) / 2.0 < 7.0),
                "{node} {east_m} m east: lines {lines:?}"
            );
            for painted in &paint {
                // The deck's top is its highest face there, the tunnel's floor its lowest.
                let faces = heights(&tile, node, painted.middle).into_iter();
                let top = if node == "bridge" {
                    faces.fold(f64::MIN, f64::max)
                } else {
                    faces.fold(f64::MAX, f64::min)
                };
                assert!(
                    painted.height > top && painted.height < top + 0.1,
                    "{node} {east_m} m east: paint at {:.2} over {top:.2}",
                    painted.height
                );
            }
        }
        let along = marking_near(&tile, (0.5, south), 60.0);
        assert_eq!(lines_of(&along).len(), 3, "{node}: {:?}", lines_of(&along));
    }
}
