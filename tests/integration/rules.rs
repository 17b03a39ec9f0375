//! Rules of what a tile draws, each on a hand-written fixture rendered whole, as the server
//! renders a tile: the sea on its side of a coastline, a river's width, a roof's tagged height,
//! a passage through a building, the windows of its facade, sidewalks and lamps; what is painted on
//! the roads is in [`markings`], how the ground looks in [`ground`], where doors stand in [`doors`]. Fast: no extract is read.

use crate::common::fixture::{at, terrain, Fixture, TILE};
use crate::common::{along_side, corners, decode, DecodedTile, Feature, GroundLocator, Primitive};

use terrastitch::features::objects::ObjectKind;
use terrastitch::mesh::passages::HEADROOM_M;
use terrastitch::provider::inputs::{index_osm, QUERY_MARGIN_DEG};
use terrastitch::render::{render, RenderSettings};
use terrastitch::terrain::Mosaic;

mod doors;
mod ground;
mod markings;
mod sidewalks;

/// The glb of [`TILE`] made from `fixture` on `mosaic`, decoded.
fn drawn(fixture: &Fixture, mosaic: &Mosaic) -> DecodedTile {
    drawn_tile(fixture, mosaic, TILE)
}

/// The glb of `tile` made from `fixture` on `mosaic`, decoded.
fn drawn_tile(fixture: &Fixture, mosaic: &Mosaic, tile: terrastitch::TileId) -> DecodedTile {
    let index = index_osm(fixture.data(), tile.z);
    let selection = index.query(tile, QUERY_MARGIN_DEG);
    let rendered =
        render(tile, &selection, mosaic, &RenderSettings::default()).expect("the fixture renders");
    decode(&rendered.glb)
}

/// The features of [`TILE`] collected from `fixture`, before they are meshed.
fn collected(fixture: &Fixture) -> terrastitch::features::FeatureSet {
    let index = index_osm(fixture.data(), TILE.z);
    let selection = index.query(TILE, QUERY_MARGIN_DEG);
    terrastitch::features::collect(&selection, TILE, &Default::default())
}

/// The tile's vertical scale at the fixtures' latitude: a glb's heights are metres times the
/// Web Mercator scale factor (see the tile's `frame`), so differences of heights here are
/// divided by it.
fn scale() -> f64 {
    1.0 / at(0.5, 0.5).lat.to_radians().cos()
}

/// The heights of `node`'s surfaces over a place of the tile (fractions east and south), in
/// metres.
fn heights(tile: &DecodedTile, node: &str, (east, south): (f64, f64)) -> Vec<f64> {
    let size = tile.tile_size();
    GroundLocator::new(corners(tile.primitives(node)), size)
        .heights_at(east * size, south * size, 1e-9)
        .into_iter()
        .map(|h| h / scale())
        .collect()
}

/// The heights of the triangles of `node` drawn in `material`, lowest and highest, in metres.
fn height_range(tile: &DecodedTile, node: &str, material: &str) -> (f64, f64) {
    let heights: Vec<f64> = tile
        .primitives(node)
        .iter()
        .filter(|p| p.material == material)
        .flat_map(|p| p.positions.iter().map(|v| f64::from(v[1]) / scale()))
        .collect();
    assert!(!heights.is_empty(), "no {material} in {node}");
    (
        heights.iter().copied().fold(f64::MAX, f64::min),
        heights.iter().copied().fold(f64::MIN, f64::max),
    )
}

/// The ground's height at a place of the tile (the terrain, or what is drawn on it).
fn ground_at(tile: &DecodedTile, place: (f64, f64)) -> f64 {
    heights(tile, "terrain", place)
        .into_iter()
        .chain(heights(tile, "road", place))
        .fold(f64::MAX, f64::min)
}

#[test]
fn the_sea_lies_right_of_a_coastline_and_the_land_left() {
    let land = terrain(|_, _| 3.0);
    // Drawn eastward: the land is on its left (north), the sea on its right (south).
    let mut eastward = Fixture::default();
    eastward.way(&[("natural", "coastline")], &[(-0.2, 0.5), (1.2, 0.5)]);
    let tile = drawn(&eastward, &land);
    assert!(!heights(&tile, "water", (0.5, 0.8)).is_empty(), "sea south");
    assert!(heights(&tile, "water", (0.5, 0.2)).is_empty(), "land north");
    // The sea at sea level, the land at its terrain's height above it.
    let sea = heights(&tile, "water", (0.5, 0.8))[0];
    let shore = ground_at(&tile, (0.5, 0.2));
    assert!(
        (shore - sea - 3.0).abs() < 0.5,
        "the land stands {} m above the sea",
        shore - sea
    );

    // Drawn westward, the same line has the sea on the other side.
    let mut westward = Fixture::default();
    westward.way(&[("natural", "coastline")], &[(1.2, 0.5), (-0.2, 0.5)]);
    let tile = drawn(&westward, &land);
    assert!(!heights(&tile, "water", (0.5, 0.2)).is_empty(), "sea north");
    assert!(heights(&tile, "water", (0.5, 0.8)).is_empty(), "land south");
}

#[test]
fn a_river_is_water_as_wide_as_its_tag_says() {
    let mut fixture = Fixture::default();
    fixture.way(
        &[("waterway", "river"), ("width", "30")],
        &[(0.5, -0.2), (0.5, 1.2)],
    );
    let tile = drawn(&fixture, &terrain(|_, _| 100.0));
    // Metres on the ground are Web Mercator metres divided by the scale factor.
    let metres = |east_m: f64| 0.5 + east_m * scale() / tile.tile_size();
    for (off_m, water) in [(0.0, true), (12.0, true), (-12.0, true), (18.0, false)] {
        assert_eq!(
            !heights(&tile, "water", (metres(off_m), 0.5)).is_empty(),
            water,
            "{off_m} m from the river's line"
        );
    }
}

#[test]
fn a_gabled_roof_rises_its_tagged_height_above_walls_of_the_tagged_height() {
    let mut fixture = Fixture::default();
    fixture.area(
        &[
            ("building", "house"),
            ("height", "9"),
            ("roof:shape", "gabled"),
            ("roof:height", "3"),
        ],
        (0.40, 0.40),
        (0.44, 0.42),
    );
    let tile = drawn(&fixture, &terrain(|_, _| 100.0));
    let ground = ground_at(&tile, (0.3, 0.3));
    let (eaves, ridge) = height_range(&tile, "building", "building_roofs");
    assert!(
        (ridge - ground - 9.0).abs() < 0.05,
        "ridge {} m up",
        ridge - ground
    );
    assert!(
        (ridge - eaves - 3.0).abs() < 0.05,
        "roof {} m high",
        ridge - eaves
    );
    // The gables, drawn blank above the windowed walls.
    let (_, wall_top) = height_range(&tile, "building", "building_walls");
    assert!(
        (wall_top - ridge).abs() < 1e-3,
        "the gables reach the ridge"
    );
}

/// The feature row of the one building whose `building` tag is `kind`.
fn building_row(tile: &DecodedTile, kind: &str) -> u32 {
    let rows: Vec<usize> = (0..tile.features.len())
        .filter(|&i| {
            tile.features[i]
                .tags
                .get("building")
                .and_then(|v| v.as_str())
                == Some(kind)
        })
        .collect();
    assert_eq!(rows.len(), 1, "one {kind}");
    rows[0] as u32
}

/// The texture coordinates of the wall triangles of one feature drawn in `material`.
fn wall_uvs(tile: &DecodedTile, material: &str, feature: u32) -> Vec<[[f32; 2]; 3]> {
    tile.primitives("building")
        .iter()
        .filter(|p| p.material == material)
        .flat_map(|p| {
            assert_eq!(p.uvs.len(), p.positions.len(), "{material} is textured");
            p.triangles()
                .filter(move |t| p.feature_ids[t[0]] == feature)
                .map(move |t| t.map(|i| p.uvs[i]))
        })
        .collect()
}

#[test]
fn a_house_has_windows_by_level_and_bay_a_shop_has_shop_windows_and_a_garage_none() {
    let mut fixture = Fixture::default();
    fixture
        .area(
            &[
                ("building", "house"),
                ("building:levels", "2"),
                ("roof:shape", "flat"),
            ],
            (0.40, 0.40),
            (0.406, 0.405),
        )
        .area(
            &[
                ("building", "apartments"),
                ("building:levels", "4"),
                ("shop", "bakery"),
            ],
            (0.45, 0.40),
            (0.46, 0.41),
        )
        .area(&[("building", "garage")], (0.42, 0.40), (0.424, 0.403));
    let tile = drawn(&fixture, &terrain(|_, _| 100.0));
    let (house, shop, garage) = (
        building_row(&tile, "house"),
        building_row(&tile, "apartments"),
        building_row(&tile, "garage"),
    );
    // The house: its two levels of windows, the top of its walls two levels up, every wall a
    // whole number of bays wide.
    let triangles = wall_uvs(&tile, "facade_punched", house);
    assert!(triangles.len() >= 8, "{} wall triangles", triangles.len());
    let vs: Vec<f32> = triangles.iter().flatten().map(|uv| uv[1]).collect();
    let top = vs.iter().copied().fold(f32::MAX, f32::min);
    assert!((top + 2.0).abs() < 1e-4, "the walls end {} levels up", -top);
    for triangle in &triangles {
        let us = triangle.map(|uv| uv[0]);
        for u in us {
            let whole = u.round();
            assert!(
                (u - whole).abs() < 1e-4,
                "a wall's corners are at whole bays: {us:?}"
            );
        }
    }
    let widest = triangles
        .iter()
        .flat_map(|t| t.map(|uv| uv[0]))
        .fold(0.0f32, f32::max);
    assert!(widest >= 1.0, "{widest} bays");
    // The shop: shop windows on the ground floor, windows above, none of them crossing.
    let ground_floor = wall_uvs(&tile, "facade_shopfront", shop);
    assert!(!ground_floor.is_empty(), "shop windows");
    assert!(ground_floor.iter().flatten().all(|uv| uv[1] >= -1.0 - 1e-4));
    let upper = wall_uvs(&tile, "facade_punched", shop);
    let upper_v: Vec<f32> = upper.iter().flatten().map(|uv| uv[1]).collect();
    assert!(upper_v.iter().all(|&v| v <= -1.0 + 1e-4), "{upper_v:?}");
    assert!(
        upper_v.iter().any(|&v| (v + 4.0).abs() < 1e-4),
        "four levels"
    );
    // The garage: blank walls only.
    for primitive in tile.primitives("building") {
        let glazed = primitive.material.starts_with("facade");
        assert!(
            !(glazed && primitive.feature_ids.contains(&garage)),
            "a garage in {}",
            primitive.material
        );
    }
    let blank = tile
        .primitives("building")
        .iter()
        .any(|p| p.material == "building_walls" && p.feature_ids.contains(&garage));
    assert!(blank, "the garage's walls are drawn blank");
}

#[test]
fn a_passage_opens_its_building_over_the_road_and_nowhere_else() {
    let mut fixture = Fixture::default();
    fixture
        .area(
            &[("building", "apartments"), ("height", "15")],
            (0.40, 0.40),
            (0.50, 0.50),
        )
        .way(
            &[("highway", "service"), ("tunnel", "building_passage")],
            &[(0.45, 0.35), (0.45, 0.55)],
        );
    let tile = drawn(&fixture, &terrain(|_, _| 100.0));
    let ground = ground_at(&tile, (0.3, 0.3));
    let lowest = |place| {
        heights(&tile, "building", place)
            .into_iter()
            .fold(f64::MAX, f64::min)
            - ground
    };
    // Over the road: the ceiling, a headroom up; the road drawn on the ground beneath.
    let over_road = lowest((0.45, 0.45));
    assert!(
        (over_road - HEADROOM_M).abs() < 0.1,
        "the building's lowest surface over the road is {over_road} m up"
    );
    assert!(!heights(&tile, "road", (0.45, 0.45)).is_empty());
    // Beside the passage: the building's floor, on the ground.
    let beside = lowest((0.42, 0.45));
    assert!(beside < 0.5, "beside the road it starts {beside} m up");
}

/// The roof vertices of the only building drawn, in the tile's frame (x east, y up, z south).
fn roof_vertices(tile: &DecodedTile) -> Vec<[f32; 3]> {
    tile.primitives("building")
        .iter()
        .filter(|p| p.material == "building_roofs")
        .flat_map(|p| p.positions.iter().copied())
        .collect()
}

#[test]
fn an_untagged_house_gets_a_pitched_roof_with_its_ridge_along_its_long_side() {
    // A 16 m × 8 m house, its long side east–west; ground metres as fractions of the tile.
    let metre = metre();
    let mut pitched = 0;
    for padding in 0..6 {
        // Ways before it change the house's id, and so the variation drawn from it.
        let mut fixture = Fixture::default();
        for _ in 0..padding {
            fixture.way(&[("note", "padding")], &[(0.1, 0.1), (0.11, 0.1)]);
        }
        let far_corner = (0.5 + 16.0 * metre, 0.5 + 8.0 * metre);
        fixture.area(&[("building", "house")], (0.5, 0.5), far_corner);
        let tile = drawn(&fixture, &terrain(|_, _| 100.0));
        let roof = roof_vertices(&tile);
        let top = roof.iter().map(|v| v[1]).fold(f32::MIN, f32::max);
        let bottom = roof.iter().map(|v| v[1]).fold(f32::MAX, f32::min);
        if f64::from(top - bottom) / scale() < 1.0 {
            continue;
        }
        pitched += 1;
        let house = &tile.features[building_row(&tile, "house") as usize];
        assert!(
            ["gabled", "hipped"].contains(&house.inferred_roof_shape.as_str()),
            "the roof drawn is marked as inferred: {:?}",
            house.inferred_roof_shape
        );
        let ridge: Vec<&[f32; 3]> = roof.iter().filter(|v| v[1] > top - 0.05).collect();
        let spread = |axis: usize| {
            let values = ridge.iter().map(|v| v[axis]);
            values.clone().fold(f32::MIN, f32::max) - values.fold(f32::MAX, f32::min)
        };
        assert!(
            spread(0) > 2.0 * spread(2),
            "the ridge runs east–west: {} along, {} across",
            spread(0),
            spread(2)
        );
    }
    // Around the Mediterranean a quarter of houses are flat-roofed terraces.
    assert!(pitched >= 4, "{pitched} of 6 houses pitched");
}

#[test]
fn a_tagged_flat_roof_stays_flat() {
    let mut fixture = Fixture::default();
    fixture.area(
        &[("building", "house"), ("roof:shape", "flat")],
        (0.5, 0.5),
        (0.51, 0.505),
    );
    let tile = drawn(&fixture, &terrain(|_, _| 100.0));
    let roof = roof_vertices(&tile);
    let top = roof.iter().map(|v| v[1]).fold(f32::MIN, f32::max);
    let bottom = roof.iter().map(|v| v[1]).fold(f32::MAX, f32::min);
    assert!(!roof.is_empty() && top - bottom < 1e-3, "{bottom}..{top}");
    let house = &tile.features[building_row(&tile, "house") as usize];
    assert_eq!(
        house.inferred_roof_shape, "",
        "a mapped roof is not marked inferred"
    );
}

#[test]
fn a_terrace_of_touching_houses_shares_one_roof_style_with_its_ridges_along_the_row() {
    // Three houses 6 m wide and 10 m deep side by side east–west, sharing their walls: alone,
    // each would have its ridge along its long side, north–south.
    let metre = metre();
    let south = 0.5 + 10.0 * metre;
    for padding in 0..4 {
        let mut fixture = Fixture::default();
        for _ in 0..padding {
            fixture.way(&[("note", "padding")], &[(0.1, 0.1), (0.11, 0.1)]);
        }
        let walls: Vec<f64> = (0..4).map(|k| 0.5 + 6.0 * metre * f64::from(k)).collect();
        for pair in walls.windows(2) {
            fixture.area(&[("building", "house")], (pair[0], 0.5), (pair[1], south));
        }
        let tile = drawn(&fixture, &terrain(|_, _| 100.0));
        let roofs: Vec<&Feature> = tile
            .features
            .iter()
            .filter(|f| f.class == "building")
            .collect();
        assert_eq!(roofs.len(), 3);
        let roof = roof_vertices(&tile);
        let top = roof.iter().map(|v| v[1]).fold(f32::MIN, f32::max);
        let bottom = roof.iter().map(|v| v[1]).fold(f32::MAX, f32::min);
        assert!(
            f64::from(top - bottom) / scale() > 1.0,
            "the row is pitched"
        );
        // One ridge line through the row: the highest vertices spread east–west over all
        // three houses, at one height.
        let ridge: Vec<&[f32; 3]> = roof.iter().filter(|v| v[1] > top - 0.05).collect();
        let spread = |axis: usize| {
            let values = ridge.iter().map(|v| v[axis]);
            values.clone().fold(f32::MIN, f32::max) - values.fold(f32::MAX, f32::min)
        };
        let row_m = f64::from(spread(0)) / scale();
        assert!(row_m > 17.0, "the ridges run {row_m} m east–west");
        assert!(f64::from(spread(2)) / scale() < 0.1, "one ridge line");
    }
}

/// One metre on the ground as a fraction of the tile, at the fixtures' latitude.
fn metre() -> f64 {
    1.0 / (40_075_016.686 * at(0.5, 0.5).lat.to_radians().cos() / 16384.0)
}

/// A residential street east–west across the tile's middle with houses along both sides of
/// its middle stretch.
fn street_between_houses(fixture: &mut Fixture) {
    fixture.way(&[("highway", "residential")], &[(-0.2, 0.5), (1.2, 0.5)]);
    let m = metre();
    for k in 0..10 {
        let east = 0.5 + (f64::from(k) - 5.0) * 20.0 * m;
        for (near, far) in [(-8.0_f64, -18.0_f64), (8.0, 18.0)] {
            fixture.area(
                &[("building", "house")],
                (east, 0.5 + near.min(far) * m),
                (east + 12.0 * m, 0.5 + near.max(far) * m),
            );
        }
    }
}

/// The heights over the road's middle (metres) of the vertices of `material` in the
/// `roadside` node (or, for a way mapped as a sidewalk, the `road` node) within 10 m of the line `south` (a fraction of the tile), on its north and on its
/// south side.
fn beside(tile: &DecodedTile, material: &str, south: f64) -> (Vec<f64>, Vec<f64>) {
    let size = tile.tile_size();
    let road = heights(tile, "road", (0.5, south))
        .into_iter()
        .fold(f64::MAX, f64::min);
    let (mut north, mut southern) = (Vec::new(), Vec::new());
    let drawn = tile
        .primitives("roadside")
        .iter()
        .chain(tile.primitives("road"));
    for primitive in drawn {
        if primitive.material != material {
            continue;
        }
        for v in &primitive.positions {
            let off = f64::from(v[2]) / size - south;
            if off.abs() > 10.0 * metre() {
                continue;
            }
            let over = f64::from(v[1]) / scale() - road;
            if off < 0.0 {
                north.push(over);
            } else {
                southern.push(over);
            }
        }
    }
    (north, southern)
}

fn highest(heights: &[f64]) -> f64 {
    heights.iter().copied().fold(f64::MIN, f64::max)
}

#[test]
fn a_street_between_houses_has_raised_sidewalks_and_a_road_in_open_country_verges() {
    let mut fixture = Fixture::default();
    street_between_houses(&mut fixture);
    fixture.way(&[("highway", "tertiary")], &[(-0.2, 0.8), (1.2, 0.8)]);
    let tile = drawn(&fixture, &terrain(|_, _| 100.0));
    let (north, south) = beside(&tile, "sidewalk", 0.5);
    for side in [&north, &south] {
        // A residential street's kerb is 12 cm.
        assert!(
            (highest(side) - 0.12).abs() < 0.02,
            "sidewalk tops at {:.3} m over the road",
            highest(side)
        );
    }
    assert!(tile
        .primitives("roadside")
        .iter()
        .any(|p| p.material == "kerb" && !p.indices.is_empty()));
    let (north, south) = beside(&tile, "sidewalk", 0.8);
    assert!(
        north.is_empty() && south.is_empty(),
        "no sidewalk in the fields"
    );
    let (north, south) = beside(&tile, "verge", 0.8);
    assert!(
        !north.is_empty() && !south.is_empty(),
        "verges on both sides"
    );
    assert!(highest(&north) < 0.05 && highest(&south) < 0.05);
}

#[test]
fn a_separately_mapped_sidewalk_is_not_drawn_twice() {
    let mut fixture = Fixture::default();
    street_between_houses(&mut fixture);
    // The north sidewalk, mapped as its own way 4.5 m from the street's middle.
    let north = 0.5 - 4.5 * metre();
    fixture.way(
        &[("highway", "footway"), ("footway", "sidewalk")],
        &[(0.3, north), (0.7, north)],
    );
    let tile = drawn(&fixture, &terrain(|_, _| 100.0));
    let (north, south) = beside(&tile, "sidewalk", 0.5);
    assert!(
        highest(&south) > 0.1,
        "the south sidewalk is raised: {:.3}",
        highest(&south)
    );
    // On the north, only the mapped footway, drawn as sidewalk on the ground.
    assert!(
        !north.is_empty(),
        "the mapped sidewalk is drawn as a sidewalk"
    );
    assert!(
        highest(&north) < 0.05,
        "no raised sidewalk beside the mapped one: {:.3}",
        highest(&north)
    );
}

#[test]
fn a_lit_street_without_mapped_lamps_gets_them_along_one_side_and_a_mapped_one_stands_alone() {
    let mut fixture = Fixture::default();
    // Two lit streets 600 m long, one with a lamp mapped beside its middle; an unlit one.
    let m = metre();
    let (west, east) = (0.5 - 300.0 * m, 0.5 + 300.0 * m);
    fixture.way(
        &[("highway", "residential"), ("lit", "yes")],
        &[(west, 0.3), (east, 0.3)],
    );
    fixture.way(
        &[("highway", "residential"), ("lit", "yes")],
        &[(west, 0.5), (east, 0.5)],
    );
    fixture.node(&[("highway", "street_lamp")], (0.5, 0.5 + 4.0 * m));
    fixture.way(&[("highway", "residential")], &[(west, 0.7), (east, 0.7)]);
    let set = collected(&fixture);
    let projection = terrastitch::features::Projection::new(TILE.z);
    let metre = projection.metres(1.0, at(0.5, 0.5).lat);
    let lamps_near = |south: f64| -> Vec<(f64, f64)> {
        let line = projection.point(at(0.5, south));
        set.objects
            .iter()
            .filter(|o| o.kind == ObjectKind::StreetLamp)
            .map(|o| ((o.at[0] - line[0]) / metre, (o.at[1] - line[1]) / metre))
            .filter(|(_, off)| off.abs() < 20.0)
            .collect()
    };
    let first = lamps_near(0.3);
    // Every 30 m from 15 m in: 20 lamps, all 3 m south (half the 5 m street and half a metre).
    assert_eq!(first.len(), 20, "{first:?}");
    assert!(
        first.iter().all(|(_, off)| (off - 3.0).abs() < 0.01),
        "{first:?}"
    );
    let mut along: Vec<f64> = first.iter().map(|(e, _)| *e).collect();
    along.sort_by(f64::total_cmp);
    assert!(along.windows(2).all(|w| (w[1] - w[0] - 30.0).abs() < 0.01));
    // The mapped lamp stands where it is mapped, and no drawn one within 25 m of it.
    let second = lamps_near(0.5);
    let mapped: Vec<_> = second.iter().filter(|(e, _)| e.abs() < 1e-6).collect();
    assert_eq!(mapped.len(), 1, "{second:?}");
    assert!(
        second
            .iter()
            .all(|(e, _)| e.abs() < 1e-6 || e.abs() >= 25.0),
        "{second:?}"
    );
    assert_eq!(second.len(), 1 + 20 - 2, "{second:?}");
    assert!(lamps_near(0.7).is_empty(), "an unlit street has none");
}

#[test]
fn a_sidewalk_keeps_clear_of_a_narrow_stream_crossing_its_street() {
    // A stream 2 m wide across the street between the houses, at one place after another
    // along a stretch of the band: wherever it crosses, no sidewalk lies over the water.
    let m = metre();
    for d in 0..12 {
        let east = 0.5 + (f64::from(d) * 1.7 - 10.0) * m;
        let mut fixture = Fixture::default();
        street_between_houses(&mut fixture);
        fixture.way(
            &[("waterway", "stream"), ("width", "2")],
            &[(east, 0.45), (east, 0.55)],
        );
        let tile = drawn(&fixture, &terrain(|_, _| 100.0));
        assert!(
            !tile.primitives("roadside").is_empty(),
            "the street has its sidewalks"
        );
        for k in 4..=16 {
            let off = f64::from(k) * 0.5 * m;
            for south in [0.5 - off, 0.5 + off] {
                let over = heights(&tile, "roadside", (east, south));
                assert!(
                    over.is_empty(),
                    "roadside over the stream {:.1} m east of the middle: {over:?}",
                    (east - 0.5) / m
                );
            }
        }
    }
}

#[test]
fn the_ground_under_a_deck_stays_below_it_beside_a_road_held_higher() {
    // A bridge east–west on a slope rising 50 % to the north, level along its line; a street
    // on the ground beside it, 7 m uphill and held level across at its centre line's
    // terrain, its edge a metre from the deck's. The ground under the deck is lowered, and
    // where it climbs to the street it starts climbing at the deck's edge, not under it.
    let m = metre();
    let middle = at(0.5, 0.5).lat;
    let mosaic = terrain(move |_, lat| 100.0 + 0.5 * (lat - middle) * 111_195.0);
    let mut fixture = Fixture::default();
    fixture
        .way(
            &[
                ("highway", "tertiary"),
                ("bridge", "yes"),
                ("layer", "1"),
                ("width", "7"),
            ],
            &[(0.5 - 40.0 * m, 0.5), (0.5 + 40.0 * m, 0.5)],
        )
        .way(
            &[("highway", "residential"), ("width", "5")],
            &[
                (0.5 - 80.0 * m, 0.5 - 7.0 * m),
                (0.5 + 80.0 * m, 0.5 - 7.0 * m),
            ],
        );
    let tile = drawn(&fixture, &mosaic);
    let street = heights(&tile, "road", (0.5, 0.5 - 7.0 * m));
    assert!(
        street.iter().any(|h| (h - 103.5).abs() < 0.5),
        "the street on its terrain: {street:?}"
    );
    for east in [-20.0, -10.0, 0.0, 10.0, 20.0] {
        for north in [-3.4, -2.0, 0.0, 2.0, 3.0, 3.4] {
            let place = (0.5 + east * m, 0.5 - north * m);
            let deck = heights(&tile, "bridge", place)
                .into_iter()
                .fold(f64::MIN, f64::max);
            let ground = heights(&tile, "terrain", place)
                .into_iter()
                .fold(f64::MIN, f64::max);
            assert!(
                deck > 99.0,
                "the deck over {east} m east, {north} m north: {deck}"
            );
            assert!(
                ground < deck - 1.0,
                "{east} m east, {north} m north: the ground at {ground:.2} m under a deck at {deck:.2} m"
            );
        }
    }
}

/// Whether the ground at a place of the tile (fractions east and south) is drawn in
/// `material`.
fn ground_material_at(tile: &DecodedTile, material: &str, (east, south): (f64, f64)) -> bool {
    let size = tile.tile_size();
    let drawn: Vec<Primitive> = tile
        .primitives("terrain")
        .iter()
        .filter(|p| p.material == material)
        .cloned()
        .collect();
    !GroundLocator::new(corners(&drawn), size)
        .heights_at(east * size, south * size, 1e-9)
        .is_empty()
}

#[test]
fn bare_ground_too_steep_for_soil_is_rock_and_gentler_ground_and_mapped_cover_are_not() {
    // Flat in the west, a 25 % slope, then a 150 % one (56°) rising east, 300 m of each; a
    // meadow mapped over part of the steep slope.
    let m = metre();
    let middle = at(0.5, 0.5).lon;
    let east_m = move |lon: f64| (lon - middle) * 111_195.0 * at(0.5, 0.5).lat.to_radians().cos();
    let mosaic = terrain(move |lon, _| {
        let x = east_m(lon);
        100.0 + 0.25 * x.clamp(0.0, 300.0) + 1.5 * (x - 300.0).clamp(0.0, 300.0)
    });
    let mut fixture = Fixture::default();
    fixture.area(
        &[("landuse", "meadow")],
        (0.5 + 400.0 * m, 0.3),
        (0.5 + 500.0 * m, 0.4),
    );
    let tile = drawn(&fixture, &mosaic);
    for south in [0.45, 0.55, 0.6] {
        let steep = (0.5 + 450.0 * m, south);
        assert!(
            ground_material_at(&tile, "terrain_rock", steep),
            "rock at {steep:?}"
        );
        for gentle in [(0.5 - 100.0 * m, south), (0.5 + 150.0 * m, south)] {
            assert!(
                ground_material_at(&tile, "terrain", gentle),
                "soil at {gentle:?}"
            );
            assert!(
                !ground_material_at(&tile, "terrain_rock", gentle),
                "rock at {gentle:?}"
            );
        }
    }
    // The meadow mapped on the steep slope stays meadow.
    let mapped = (0.5 + 450.0 * m, 0.35);
    assert!(!ground_material_at(&tile, "terrain_rock", mapped));
    assert!(!heights(&tile, "landcover", mapped).is_empty());
}

#[test]
fn the_ground_hangs_a_skirt_along_its_sides_as_its_neighbour_does_facing_out() {
    // Rolling ground and a road across the shared side of two tiles.
    let mosaic = terrain(|lon, lat| 100.0 + 30.0 * (lon * 900.0).sin() * (lat * 700.0).cos());
    let mut fixture = Fixture::default();
    fixture.way(&[("highway", "primary")], &[(0.5, 0.4), (1.5, 0.6)]);
    let west = drawn(&fixture, &mosaic);
    let east_tile = terrastitch::TileId {
        x: TILE.x + 1,
        ..TILE
    };
    let east = drawn_tile(&fixture, &mosaic, east_tile);
    let size = west.tile_size() as f32;
    // 6 error bounds of 1 m, in the local frame's units.
    let depth = 6.0;
    let skirt_along = |tile: &DecodedTile, side: &str| {
        let skirt: Vec<&Primitive> = tile
            .primitives("terrain")
            .iter()
            .filter(|p| p.material == "terrain_skirt")
            .collect();
        assert_eq!(skirt.len(), 1, "one skirt");
        let mut strips = std::collections::BTreeSet::new();
        for t in skirt[0].triangles() {
            let corners = t.map(|k| skirt[0].positions[k]);
            if !corners.iter().all(|c| along_side(c, side, size).is_some()) {
                continue;
            }
            // Facing out: its normal points away from the tile's middle.
            let (u, v) = (
                [0, 1, 2].map(|a| corners[1][a] - corners[0][a]),
                [0, 1, 2].map(|a| corners[2][a] - corners[0][a]),
            );
            let normal = [
                u[1] * v[2] - u[2] * v[1],
                u[2] * v[0] - u[0] * v[2],
                u[0] * v[1] - u[1] * v[0],
            ];
            let outwards = match side {
                "west" => -normal[0],
                "east" => normal[0],
                "north" => -normal[2],
                _ => normal[2],
            };
            assert!(outwards > 0.0, "{side}: {corners:?} faces in");
            for c in corners {
                strips.insert((c[1].to_bits(), c[2].to_bits()));
            }
        }
        strips
    };
    for side in ["west", "east", "north", "south"] {
        assert!(!skirt_along(&west, side).is_empty(), "no skirt {side}");
    }
    // The shared side's skirt is the same from both tiles, and hangs `depth` under the edge.
    let shared = skirt_along(&west, "east");
    assert_eq!(shared, skirt_along(&east, "west"));
    let edge = crate::common::ground_edge(&west, "east");
    let tops: std::collections::BTreeSet<(u32, u32)> =
        edge.iter().map(|&(y, along, _)| (y, along)).collect();
    for &(y, along) in &shared {
        let y = f32::from_bits(y);
        let top = (y + depth).to_bits();
        assert!(
            tops.contains(&(y.to_bits(), along)) || tops.contains(&(top, along)),
            "a skirt vertex at {y} neither on the edge nor {depth} under it"
        );
    }
}

#[test]
fn the_sea_is_lit_as_level_water_whatever_slopes_its_coast() {
    // A coast rising 50 % from the shore: the sea's vertices along it are the land's too.
    let middle = at(0.5, 0.5).lat;
    let mosaic = terrain(move |_, lat| (2.0 + 0.5 * (lat - middle) * 111_195.0).max(0.0));
    let mut fixture = Fixture::default();
    fixture.way(&[("natural", "coastline")], &[(-0.2, 0.5), (1.2, 0.5)]);
    let tile = drawn(&fixture, &mosaic);
    let water = tile.primitives("water");
    assert!(!water.is_empty(), "the sea is drawn");
    for primitive in water {
        for normal in &primitive.normals {
            assert_eq!(*normal, [0.0, 1.0, 0.0], "a sea vertex leans");
        }
    }
}
