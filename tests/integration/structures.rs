//! Bridges and tunnels of Monaco (83 bridges, 181 tunnels in the OSRM extract) settled whole
//! and drawn: checked from the decoded glb against its own ground.

use crate::common;

use std::collections::{BTreeMap, HashMap};

use common::{decode, sample_osm, sample_srtm, GroundLocator, MONACO_TILES as TILES};
use terrastitch::elevation::solutions::Solutions;
use terrastitch::elevation::structures::{settle, ConstraintKind, Settled};
use terrastitch::features::structures as tags;
use terrastitch::features::{FeatureSettings, Projection};
use terrastitch::mesh::ground::MeshSettings;
use terrastitch::mesh::{dot, triangle_normal};
use terrastitch::osm::structures::{Crossed, StructureKind};
use terrastitch::provider::Inputs;
use terrastitch::terrain::{Interpolation, TerrainModel};
use terrastitch::TileId;

/// Every structure group of the sample settled as the renderer settles it.
fn settle_all(sources: &Inputs) -> Vec<Settled> {
    let tile = TileId {
        z: 14,
        x: 8529,
        y: 5973,
    };
    let mosaic = sources.mosaic(tile).expect("srtm");
    let terrain = TerrainModel::new(&mosaic, Interpolation::default(), 14);
    let margin = MeshSettings::default().max_error_m;
    let memo = Solutions::default();
    common::whole(sources)
        .structures()
        .iter()
        .map(|group| {
            settle(
                group,
                &common::whole(sources).data().ways,
                &terrain,
                &Projection::new(14),
                &FeatureSettings::default(),
                margin,
                &memo,
            )
        })
        .collect()
}

/// Where a bridge crosses a way, the underside of its deck in the tile is above the ground
/// drawn there by at least the clearance (`maxheight` of the way below, else the default
/// for what it carries), unless the LP reported that clearance violated. No vertex of a
/// tunnel's floor or lining is above the ground over it.
#[test]
fn bridges_clear_what_they_cross_and_tunnels_stay_under_the_ground() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let sources = Inputs::open(&[sample_osm()], &sample_srtm(), 14).expect("sample data");
    let ways = &common::whole(&sources).data().ways;
    let groups = common::whole(&sources).structures();
    let settled = settle_all(&sources);
    let projection = Projection::new(14);
    let (mut crossings, mut reported, mut tunnel_vertices) = (0, 0, 0);
    let mut closest = f64::INFINITY;
    for (x, y) in TILES {
        let name = format!("14/{x}/{y}");
        let tile = decode(&common::render_in_process(&name, &[], dir.path()));
        let id = TileId { z: 14, x, y };
        let frame = id.frame();
        let size = tile.tile_size();
        let elevation = |y: f64, z: f64| y / frame.scale_at(z);
        let ground = GroundLocator::of_ground(&tile);
        // Deck triangles by OSM way.
        let mut decks: HashMap<i64, Vec<[[f64; 3]; 3]>> = HashMap::new();
        for primitive in tile.primitives("bridge") {
            if !primitive.material.starts_with("bridge_deck") {
                continue;
            }
            for t in primitive.triangles() {
                let way = tile.features[primitive.feature_ids[t[0]] as usize].osm_id;
                decks
                    .entry(way)
                    .or_default()
                    .push(t.map(|i| primitive.positions[i].map(f64::from)));
            }
        }
        let margin = 2.0 / size;
        for (group, settled) in groups.iter().zip(&settled) {
            for crossing in &group.crossings {
                let chain = &group.chains[crossing.chain as usize];
                let Crossed::Way(below) = crossing.other else {
                    continue;
                };
                if chain.kind != StructureKind::Bridge {
                    continue;
                }
                let below = &ways[below as usize];
                let Some(clearance) = tags::clearance_over_m(&below.tags) else {
                    continue;
                };
                let below_layer = tags::layer(&below.tags).unwrap_or(0);
                if below_layer >= chain.layer {
                    continue;
                }
                let k = crossing.segment as usize;
                let (a, b) = (
                    projection.point(chain.positions[k]),
                    projection.point(chain.positions[k + 1]),
                );
                let t = crossing.t;
                let at = [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
                let inside = |c: f64, lo: u32| {
                    c > f64::from(lo) + margin && c < f64::from(lo) + 1.0 - margin
                };
                if !inside(at[0], x) || !inside(at[1], y) {
                    continue;
                }
                let upper = &ways[chain.ways[chain.segment_way[k] as usize].way as usize];
                let (lx, lz) = frame.uv_to_local(at[0], at[1]);
                let Some(deck) = decks.get(&upper.id) else {
                    panic!(
                        "{name}: bridge way {} crosses way {} here but has no deck",
                        upper.id, below.id
                    );
                };
                let top = GroundLocator::new(deck.clone(), size)
                    .heights_at(lx, lz, 1e-6)
                    .into_iter()
                    .fold(f64::NEG_INFINITY, f64::max);
                let under = ground
                    .heights_at(lx, lz, 1e-6)
                    .into_iter()
                    .fold(f64::NEG_INFINITY, f64::max);
                if !top.is_finite() || !under.is_finite() {
                    continue; // the ground is cut out under a building here
                }
                let free =
                    elevation(top, lz) - tags::deck_thickness_m(&upper.tags) - elevation(under, lz);
                let violated = settled.violations(0.01).any(|v| {
                    v.kind == ConstraintKind::Clearance
                        && v.way == upper.id
                        && (v.at[0] - at[0]).hypot(v.at[1] - at[1]) * size < 1.0
                });
                if violated {
                    reported += 1;
                    continue;
                }
                assert!(
                    free >= clearance - 0.01,
                    "{name}: bridge way {} leaves {free:.2} m over way {} ({:?}), {clearance} m asked",
                    upper.id,
                    below.id,
                    below.tags
                );
                closest = closest.min(free - clearance);
                crossings += 1;
            }
        }
        for primitive in tile.primitives("tunnel") {
            if primitive.material == "tunnel_portal" {
                continue;
            }
            for (k, p) in primitive.positions.iter().enumerate() {
                let (px, py, pz) = (f64::from(p[0]), f64::from(p[1]), f64::from(p[2]));
                let over = ground
                    .heights_at(px, pz, 1e-6)
                    .into_iter()
                    .fold(f64::INFINITY, f64::min);
                if !over.is_finite() {
                    continue;
                }
                let feature = &tile.features[primitive.feature_ids[k] as usize];
                assert!(
                    elevation(py, pz) <= elevation(over, pz) + 0.01,
                    "{name}: tunnel way {} ({}) at {p:?} is {:.2} m above the ground",
                    feature.osm_id,
                    primitive.material,
                    elevation(py, pz) - elevation(over, pz)
                );
                tunnel_vertices += 1;
            }
        }
    }
    eprintln!(
        "{crossings} crossings cleared (closest {closest:.2} m beyond the clearance), {reported} reported violated; {tunnel_vertices} tunnel vertices under the ground"
    );
    assert!(crossings >= 20, "only {crossings} crossings checked");
    assert!(
        tunnel_vertices >= 1000,
        "only {tunnel_vertices} tunnel vertices checked"
    );
}

/// Along every settled bridge and tunnel, no grade is steeper than its class allows unless
/// a violation of that bound was reported for the way; a summary of what was reported.
#[test]
fn grades_keep_to_the_class_maximum_unless_reported() {
    let sources = Inputs::open(&[sample_osm()], &sample_srtm(), 14).expect("sample data");
    let ways = &common::whole(&sources).data().ways;
    let settled = settle_all(&sources);
    let mut by_kind: BTreeMap<ConstraintKind, usize> = BTreeMap::new();
    let (mut segments, mut steep) = (0, 0);
    for group in &settled {
        assert_eq!(group.failed, 0);
        for report in group.violations(0.01) {
            *by_kind.entry(report.kind).or_default() += 1;
        }
        for profile in &group.profiles {
            for i in 0..profile.points.len() - 1 {
                let way = &ways[profile.ways[i] as usize];
                let run = profile.along_m[i + 1] - profile.along_m[i];
                let Some(max) = tags::max_incline(&way.tags) else {
                    continue;
                };
                if run <= 0.0 {
                    continue;
                }
                segments += 1;
                let grade = (profile.elevations[i + 1] - profile.elevations[i]).abs() / run;
                if grade <= max + 1e-3 {
                    continue;
                }
                steep += 1;
                let reported = group.violations(0.001).any(|v| {
                    matches!(
                        v.kind,
                        ConstraintKind::MaxIncline | ConstraintKind::TaggedIncline
                    ) && v.way == way.id
                });
                assert!(
                    reported,
                    "way {} rises {grade:.3} per metre, over its {max}, unreported",
                    way.id
                );
            }
        }
    }
    eprintln!("{segments} segments, {steep} steeper than their class allows (all reported); violations by kind: {by_kind:?}");
    assert!(segments > 1000);
}

/// Under a building or a tree, a settled tunnel's roof stays below its foundations (3 m,
/// a storey more per underground level) or roots (1.5 m) and the mesh's error bound, unless
/// the LP reported that bound violated there.
#[test]
fn tunnels_keep_clear_of_the_foundations_over_them() {
    let sources = Inputs::open(&[sample_osm()], &sample_srtm(), 14).expect("sample data");
    let ways = &common::whole(&sources).data().ways;
    let groups = common::whole(&sources).structures();
    let settled = settle_all(&sources);
    let projection = Projection::new(14);
    let margin = MeshSettings::default().max_error_m;
    let (mut under, mut reported, mut buildings) = (0, 0, 0);
    for (group, outcome) in groups.iter().zip(&settled) {
        let outlines: Vec<(terrastitch::geometry::Polygon, f64)> = group
            .above
            .iter()
            .filter(|a| a.positions.len() > 1)
            .map(|a| {
                let outline = terrastitch::geometry::Polygon {
                    outer: projection.points(&a.positions),
                    holes: Vec::new(),
                };
                (outline, a.depth_m)
            })
            .collect();
        buildings += outlines.len();
        for profile in &outcome.profiles {
            if profile.kind != StructureKind::Tunnel {
                continue;
            }
            let last = profile.points.len() - 1;
            for i in 1..last {
                let p = profile.points[i];
                let Some(depth) = outlines
                    .iter()
                    .filter(|(o, _)| o.contains(p))
                    .map(|&(_, d)| d)
                    .reduce(f64::max)
                else {
                    continue;
                };
                under += 1;
                let way = &ways[profile.ways[i] as usize];
                let roof =
                    profile.elevations[i] + tags::tunnel_height_m(&way.tags) + tags::TUNNEL_ROOF_M;
                if roof <= profile.terrain[i] - depth - margin + 0.01 {
                    continue;
                }
                let violated = outcome.violations(0.001).any(|v| {
                    v.kind == ConstraintKind::Foundations
                        && v.way == way.id
                        && (v.at[0] - p[0]).hypot(v.at[1] - p[1]) < 1e-9
                });
                assert!(
                    violated,
                    "tunnel way {} at station {i}: roof {roof:.2} m, ground {:.2} m, \
                     foundations {depth} m deep, unreported",
                    way.id, profile.terrain[i]
                );
                reported += 1;
            }
        }
    }
    eprintln!(
        "{buildings} buildings over tunnels; {under} tunnel stations under them, {reported} \
         too shallow and reported"
    );
    assert!(under > 100, "{under} tunnel stations under buildings");
}

/// The debug view shows the settled structures and ground roads of a tile with their
/// connectors and constraints; rendering a tile counts its LP in `/metrics`; bad debug paths are JSON errors.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_debug_view_shows_connectors_and_constraints() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let server = common::TestServer::start(&dir.path().join("cache.sqlite")).await;
    let response = reqwest::get(server.url("/debug/tiles/14/8530/5973.geojson"))
        .await
        .expect("request reaches the server");
    assert_eq!(response.status(), 200);
    assert_eq!(response.headers()["content-type"], "application/geo+json");
    let view: serde_json::Value = response.json().await.expect("GeoJSON");
    assert_eq!(view["type"], "FeatureCollection");
    assert!(
        view["lp"]["variables"].as_u64().unwrap_or(0) > 100,
        "{}",
        view["lp"]
    );
    let features = view["features"].as_array().expect("features");
    let count = |layer: &str| {
        features
            .iter()
            .filter(|f| f["properties"]["layer"] == layer)
            .count()
    };
    assert!(count("structure") > 10);
    assert!(count("connector") > count("structure"));
    assert!(count("constraint") > 100);
    // Every constraint tells whether it holds, and the count of those that do not matches.
    let violated = features
        .iter()
        .filter(|f| f["properties"]["layer"] == "constraint")
        .filter(|f| f["properties"]["satisfied"] == false)
        .count();
    assert_eq!(Some(violated as u64), view["lp"]["violated"].as_u64());
    // The ground roads: profiles that left the terrain, each with both profiles, and the
    // constraints that gave way, as many as the summary says.
    assert!(
        view["roads"]["settled"].as_u64().unwrap_or(0) > 10,
        "{}",
        view["roads"]
    );
    assert!(count("road_profile") > 10);
    for f in features
        .iter()
        .filter(|f| f["properties"]["layer"] == "road_profile")
    {
        let p = &f["properties"];
        let n = f["geometry"]["coordinates"].as_array().map(Vec::len);
        assert_eq!(p["elevations_m"].as_array().map(Vec::len), n, "{p}");
        assert_eq!(p["terrain_m"].as_array().map(Vec::len), n, "{p}");
        assert_ne!(p["elevations_m"], p["terrain_m"], "{p}");
    }
    assert_eq!(
        Some(count("road_constraint") as u64),
        view["roads"]["violated"].as_u64()
    );
    // Grounded ends sit at the terrain.
    for f in features
        .iter()
        .filter(|f| f["properties"]["connector"] == "ground")
    {
        let p = &f["properties"];
        assert_eq!(p["elevation_m"], p["terrain_m"], "{p}");
    }

    for (path, status) in [
        ("/debug/tiles/14/8530/5973.json", 400),
        ("/debug/tiles/14/abc/5973.geojson", 400),
        ("/debug/tiles/13/4265/2986.geojson", 404),
    ] {
        let response = reqwest::get(server.url(path)).await.expect("request");
        assert_eq!(response.status(), status, "{path}");
        let body: serde_json::Value = response.json().await.expect("a JSON error");
        assert!(body["error"].is_string(), "{body}");
    }

    let response = reqwest::get(server.url("/tiles/14/8530/5973.glb"))
        .await
        .expect("request");
    assert_eq!(response.status(), 200);
    // (The body read, so the connection is free and the server can stop.)
    assert!(!response.bytes().await.expect("body").is_empty());
    assert!(server.metric("terrastitch_lp_components_total").await > 10.0);
    server.stop().await;
}

/// The tops of the bridge decks of the ten Monaco tiles, away from the ramps where a deck
/// meets the ground (15 m from each end of a bridge and from each node another way joins),
/// stand clear of the ground: at most 1 % of their vertices lie under the ground beneath them
/// or a metre beside them; and where a deck passes over a road, a railway or water, its
/// underside clears it by 2 m at 99 % of its vertices, or falls short where the LP reported
/// the clearance violated.
#[test]
fn bridge_decks_stand_clear_of_the_ground_under_and_beside_them() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let sources = Inputs::open(&[sample_osm()], &sample_srtm(), 14).expect("sample data");
    let groups = common::whole(&sources).structures();
    let projection = Projection::new(14);
    // Where a bridge comes down to the ground: the ends of its chains, and each of its nodes
    // a way off the bridges joins (a road meeting it, a tunnel's portal).
    let ways = &common::whole(&sources).data().ways;
    let bridge_chains: Vec<_> = groups
        .iter()
        .flat_map(|g| &g.chains)
        .filter(|c| c.kind == StructureKind::Bridge)
        .collect();
    let on_bridges: std::collections::HashSet<u32> = bridge_chains
        .iter()
        .flat_map(|c| c.ways.iter().map(|w| w.way))
        .collect();
    let joined: std::collections::HashSet<i64> = ways
        .iter()
        .enumerate()
        .filter(|(i, _)| !on_bridges.contains(&(*i as u32)))
        .flat_map(|(_, w)| w.nodes.iter().copied())
        .collect();
    let passed_over: std::collections::HashSet<i64> = groups
        .iter()
        .flat_map(|g| g.crossings.iter().map(move |c| (g, c)))
        .filter(|(g, c)| g.chains[c.chain as usize].kind == StructureKind::Bridge)
        .filter_map(|(_, c)| match c.other {
            Crossed::Way(way) => Some(ways[way as usize].id),
            Crossed::Chain { .. } => None,
        })
        .collect();
    let ends: Vec<[f64; 2]> = bridge_chains
        .iter()
        .flat_map(|c| {
            let joined = &joined;
            let last = c.nodes.len() - 1;
            (0..=last)
                .filter(move |&k| k == 0 || k == last || joined.contains(&c.nodes[k]))
                .map(move |k| c.positions[k])
        })
        .map(|p| projection.point(p))
        .collect();
    // Bridge ways whose clearance the LP reported it could not give (against a grade bound).
    let short: std::collections::HashSet<i64> = settle_all(&sources)
        .iter()
        .flat_map(|s| s.violations(0.01))
        .filter(|v| v.kind == ConstraintKind::Clearance)
        .map(|v| v.way)
        .collect();
    let (mut mid_span, mut buried, mut over, mut clear, mut reported) = (0, 0, 0, 0, 0);
    let mut deepest: f64 = 0.0;
    for (x, y) in TILES {
        let name = format!("14/{x}/{y}");
        let tile = decode(&common::render_in_process(&name, &[], dir.path()));
        let frame = TileId { z: 14, x, y }.frame();
        let size = tile.tile_size();
        let ground = GroundLocator::of_ground(&tile);
        // The ways the bridges pass over (not those that join them at a ramp), and water.
        let crossed = GroundLocator::new(
            ["road", "railway", "water"]
                .iter()
                .flat_map(|n| tile.primitives(n))
                .flat_map(|primitive| {
                    primitive.triangles().filter_map(|t| {
                        let feature = &tile.features[primitive.feature_ids[t[0]] as usize];
                        (feature.class == "water" || passed_over.contains(&feature.osm_id))
                            .then(|| t.map(|i| primitive.positions[i].map(f64::from)))
                    })
                })
                .collect(),
            size,
        );
        let ends: Vec<(f64, f64)> = ends.iter().map(|p| frame.uv_to_local(p[0], p[1])).collect();
        let highest = |locator: &GroundLocator, x: f64, z: f64| {
            locator
                .heights_at(x, z, 1e-6)
                .into_iter()
                .fold(f64::NEG_INFINITY, f64::max)
        };
        for primitive in tile.primitives("bridge") {
            if !primitive.material.starts_with("bridge_deck") {
                continue;
            }
            let mut tops = std::collections::BTreeSet::new();
            for t in primitive.triangles() {
                let n = triangle_normal(t.map(|i| primitive.positions[i].map(f64::from)));
                if n[1] > 0.5 * dot(n, n).sqrt() {
                    tops.extend(t);
                }
            }
            for i in tops {
                let p = primitive.positions[i].map(f64::from);
                let metre = frame.scale_at(p[2]);
                if ends
                    .iter()
                    .any(|e| (e.0 - p[0]).hypot(e.1 - p[2]) < 15.0 * metre)
                {
                    continue;
                }
                mid_span += 1;
                let top = p[1] / metre;
                let beneath = highest(&ground, p[0], p[2]) / metre;
                let beside = [[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]]
                    .iter()
                    .map(|d| highest(&ground, p[0] + d[0] * metre, p[2] + d[1] * metre) / metre)
                    .fold(beneath, f64::max);
                if beside > top + 0.01 {
                    buried += 1;
                    deepest = deepest.max(beside - top);
                }
                let below = highest(&crossed, p[0], p[2]) / metre;
                if below.is_finite() && below < top {
                    over += 1;
                    let feature = &tile.features[primitive.feature_ids[i] as usize];
                    let tags = terrastitch::osm::Tags::from_pairs(
                        feature
                            .tags
                            .iter()
                            .map(|(k, v)| (k.clone(), v.as_str().unwrap_or("").to_string())),
                    );
                    if top - tags::deck_thickness_m(&tags) - below >= 2.0 {
                        clear += 1;
                    } else if short.contains(&feature.osm_id) {
                        reported += 1;
                    }
                }
            }
        }
    }
    let buried_share = buried as f64 / mid_span.max(1) as f64;
    let clear_share = (clear + reported) as f64 / over.max(1) as f64;
    eprintln!(
        "{mid_span} mid-span deck vertices: {buried} ({:.1} %) under the ground (deepest {deepest:.2} m); {over} over roads, railways and water, {clear} clear by 2 m and {reported} short where the LP reported it ({:.1} %)",
        buried_share * 100.0,
        clear_share * 100.0
    );
    // A deck's top is a strip: consecutive quads share their vertices.
    assert!(mid_span > 500, "only {mid_span} deck vertices");
    assert!(buried_share <= 0.01);
    assert!(clear_share >= 0.99);
}
