//! Rules of elevation, each on a hand-written fixture: a few ways on synthetic terrain (a plane
//! or a ramp), indexed and settled as the server settles a tile. Fast: no extract is read, no
//! tile is written.

use crate::common::fixture::{at, terrain, Fixture, TILE};

use terrastitch::elevation::settled::Rule;
use terrastitch::features::structures::{
    clearance_over_m, deck_thickness_m, foundation_depth_m, tunnel_height_m, TUNNEL_ROOF_M,
};
use terrastitch::osm::structures::StructureKind;
use terrastitch::osm::{LonLat, Tags};
use terrastitch::provider::inputs::{index_osm, QUERY_MARGIN_DEG};
use terrastitch::render::{settle_road_profiles, settle_structures, RenderSettings, Solutions};
use terrastitch::terrain::{Mosaic, TerrainModel};
use terrastitch::tile::lon_lat_to_uv;

/// A station of a settled profile: its point in global tile units, its elevation and the
/// terrain's there.
type Station = ([f64; 2], f64, f64);

/// The bridges and tunnels of `fixture` settled on `mosaic`, as the glb of [`TILE`] settles
/// them: each profile's stations as (point in global units, elevation, terrain).
fn settled(fixture: &Fixture, mosaic: &Mosaic) -> Vec<(StructureKind, Vec<Station>)> {
    let index = index_osm(fixture.data(), TILE.z);
    let selection = index.query(TILE, QUERY_MARGIN_DEG);
    settle_structures(
        TILE,
        &selection,
        mosaic,
        &RenderSettings::default(),
        &Solutions::default(),
    )
    .into_iter()
    .flat_map(|settled| settled.profiles)
    .map(|profile| {
        let stations = (0..profile.points.len())
            .map(|k| (profile.points[k], profile.elevations[k], profile.terrain[k]))
            .collect();
        (profile.kind, stations)
    })
    .collect()
}

/// The elevation of a profile where it passes closest to `place`, between its two nearest
/// stations.
fn elevation_near(stations: &[Station], place: LonLat) -> f64 {
    let n = f64::from(1u32 << TILE.z);
    let (u, v) = lon_lat_to_uv(place.lon, place.lat, n);
    let distance = |p: [f64; 2]| ((p[0] - u).powi(2) + (p[1] - v).powi(2)).sqrt();
    let nearest = (0..stations.len())
        .min_by(|&a, &b| distance(stations[a].0).total_cmp(&distance(stations[b].0)))
        .expect("a profile has stations");
    stations[nearest].1
}

fn tags(pairs: &[(&str, &str)]) -> Tags {
    Tags::from_pairs(pairs.iter().copied())
}

#[test]
fn a_bridge_over_a_road_clears_it_by_its_clearance() {
    let road = [("highway", "residential")];
    let bridge = [
        ("highway", "residential"),
        ("bridge", "yes"),
        ("layer", "1"),
    ];
    let mut fixture = Fixture::default();
    fixture
        .way(&road, &[(0.1, 0.5), (0.9, 0.5)])
        .way(&bridge, &[(0.5, 0.2), (0.5, 0.4), (0.5, 0.6), (0.5, 0.8)]);
    let settled = settled(&fixture, &terrain(|_, _| 10.0));
    let [(StructureKind::Bridge, stations)] = settled.as_slice() else {
        panic!("one bridge expected: {settled:?}");
    };
    let deck = elevation_near(stations, at(0.5, 0.5));
    let needed = clearance_over_m(&tags(&road)).expect("a road is cleared")
        + deck_thickness_m(&tags(&bridge));
    assert!(
        deck - 10.0 >= needed - 0.01,
        "deck {deck:.2} m over a road at 10 m: {needed:.2} m needed"
    );
}

#[test]
fn a_tunnel_under_a_building_stays_below_its_foundations() {
    let tunnel = [("highway", "primary"), ("tunnel", "yes"), ("layer", "-1")];
    let building = [("building", "yes"), ("building:levels:underground", "2")];
    let mut fixture = Fixture::default();
    fixture
        .way(
            &tunnel,
            &[(0.1, 0.5), (0.3, 0.5), (0.5, 0.5), (0.7, 0.5), (0.9, 0.5)],
        )
        .area(&building, (0.45, 0.47), (0.55, 0.53));
    let ground = 50.0;
    let settled = settled(&fixture, &terrain(|_, _| ground));
    let [(StructureKind::Tunnel, stations)] = settled.as_slice() else {
        panic!("one tunnel expected: {settled:?}");
    };
    let floor = elevation_near(stations, at(0.5, 0.5));
    let roof = floor + tunnel_height_m(&tags(&tunnel)) + TUNNEL_ROOF_M;
    let foundations = ground - foundation_depth_m(&tags(&building)).expect("a building has them");
    assert!(
        roof <= foundations + 0.01,
        "tunnel roof at {roof:.2} m under foundations reaching down to {foundations:.2} m"
    );
}

#[test]
fn a_tunnel_rises_to_meet_the_ground_at_its_portals() {
    let tunnel = [("highway", "primary"), ("tunnel", "yes"), ("layer", "-1")];
    let mut fixture = Fixture::default();
    fixture.way(&tunnel, &[(0.2, 0.5), (0.5, 0.5), (0.8, 0.5)]);
    // A ramp rising to the east, 100 m over the tile.
    let b = TILE.bounds();
    let ramp = move |lon: f64, _: f64| 200.0 + 100.0 * (lon - b.west) / (b.east - b.west);
    let settled = settled(&fixture, &terrain(ramp));
    let [(StructureKind::Tunnel, stations)] = settled.as_slice() else {
        panic!("one tunnel expected: {settled:?}");
    };
    for end in [stations.first(), stations.last()] {
        let (_, floor, ground) = end.expect("a profile has stations");
        assert!(
            (floor - ground).abs() < 0.05,
            "portal floor {floor:.2} m, ground {ground:.2} m"
        );
    }
}

#[test]
fn a_lake_on_a_slope_lies_flat_at_its_lowest_shore() {
    let mut fixture = Fixture::default();
    fixture.area(&[("natural", "water")], (0.3, 0.3), (0.6, 0.5));
    // A ramp rising 100 m to the east across the tile.
    let b = TILE.bounds();
    let ramp = move |lon: f64| 200.0 + 100.0 * (lon - b.west) / (b.east - b.west);
    let mosaic = terrain(move |lon, _| ramp(lon));
    let index = index_osm(fixture.data(), TILE.z);
    let selection = index.query(TILE, QUERY_MARGIN_DEG);
    let settings = RenderSettings::default();
    let set = terrastitch::features::collect(&selection, TILE, &settings.features);
    let model = TerrainModel::new(&mosaic, settings.interpolation, TILE.z);
    let levels = terrastitch::elevation::water::levels(&set, &model, TILE.frame().size_m);
    let [level] = levels.as_slice() else {
        panic!("one water level expected, found {}", levels.len());
    };
    let Rule::Level(height) = level.rule else {
        panic!("a lake lies flat: {:?}", level.rule);
    };
    // The west shore is the lowest: 30 % of the way up the ramp.
    let west_shore = ramp(at(0.3, 0.4).lon);
    assert!(
        (height - west_shore).abs() < 0.05,
        "lake at {height:.3} m, its west shore at {west_shore:.3} m"
    );
}

/// Three roads meeting at one node on a slope steeper than a primary may climb: a primary
/// through the node, two residentials from it.
struct Junction {
    profiles: terrastitch::elevation::road_profiles::RoadProfiles,
    drawn: terrastitch::elevation::roads::RoadLevels,
    /// The node, in global tile units.
    node: (f64, f64),
    /// A place along each arm.
    arms: [(f64, f64); 4],
}

fn junction_on_a_slope() -> Junction {
    let primary = [("highway", "primary")];
    let residential = [("highway", "residential")];
    let junction = (0.5, 0.5);
    let arms = [(0.3, 0.5), (0.7, 0.5), (0.5, 0.3), (0.65, 0.7)];
    let mut fixture = Fixture::default();
    fixture
        .way(&primary, &[arms[0], junction, arms[1]])
        .way(&residential, &[junction, arms[2]])
        .way(&residential, &[junction, arms[3]])
        .join(junction);
    // A slope rising 200 m to the east (steeper than a primary may climb) and 100 m to the
    // north across the tile.
    let b = TILE.bounds();
    let mosaic = terrain(move |lon, lat| {
        let (east, north) = (
            (lon - b.west) / (b.east - b.west),
            (lat - b.south) / (b.north - b.south),
        );
        200.0 + 200.0 * east + 100.0 * north
    });
    let index = index_osm(fixture.data(), TILE.z);
    let selection = index.query(TILE, QUERY_MARGIN_DEG);
    let settings = RenderSettings::default();
    let profiles =
        settle_road_profiles(TILE, &selection, &mosaic, &settings, &Solutions::default());
    let set = terrastitch::features::collect(&selection, TILE, &settings.features);
    let model = TerrainModel::new(&mosaic, settings.interpolation, TILE.z);
    let drawn =
        terrastitch::elevation::roads::levels(&set, &profiles, &model, TILE.frame().size_m, &[]);
    Junction {
        profiles,
        drawn,
        node: uv(junction),
        arms: arms.map(uv),
    }
}

/// A place in [`TILE`] in global tile units.
fn uv((east, south): (f64, f64)) -> (f64, f64) {
    let place = at(east, south);
    lon_lat_to_uv(place.lon, place.lat, f64::from(1u32 << TILE.z))
}

#[test]
fn roads_meeting_at_a_junction_share_its_level() {
    let Junction {
        profiles,
        drawn,
        node,
        ..
    } = junction_on_a_slope();
    let level = drawn
        .elevation([node.0, node.1])
        .expect("the junction is drawn");
    assert_eq!(profiles.profiles.len(), 3, "{:?}", profiles.profiles.keys());
    for (way, profile) in &profiles.profiles {
        let k = (profile.points.iter())
            .position(|p| (p[0] - node.0).hypot(p[1] - node.1) < 1e-9)
            .expect("a station at the node");
        let h = profile.elevations[k];
        assert!(
            (h - level).abs() < 0.01,
            "way {way} at {h:.3} m, junction at {level:.3} m"
        );
    }
}

#[test]
fn a_road_leaves_its_junction_without_a_step() {
    let Junction {
        profiles,
        drawn,
        node,
        arms,
    } = junction_on_a_slope();
    // A metre on the ground, in tile units.
    let metre = profiles.profiles[&1].metre;
    // Walking out along each road 10 cm at a time, the drawn surface rises or falls no more
    // than a road's grade allows (15 %: 1.5 cm).
    for to in arms {
        let length = (to.0 - node.0).hypot(to.1 - node.1);
        let heights: Vec<f64> = (0..=100)
            .map(|k| {
                let t = k as f64 * 0.1 * metre / length;
                let p = [node.0 + t * (to.0 - node.0), node.1 + t * (to.1 - node.1)];
                drawn.elevation(p).expect("the road is drawn along its way")
            })
            .collect();
        let (k, step) = (1..heights.len())
            .map(|k| (k, (heights[k] - heights[k - 1]).abs()))
            .fold((0, 0.0), |a, b| if b.1 > a.1 { b } else { a });
        assert!(
            step < 0.02,
            "towards {to:?} the road steps {step:.3} m at {:.1} m from the node",
            k as f64 * 0.1
        );
    }
}
