//! OSM features on the real Monaco extract, as the served tiles show them: the sea from the
//! coastline.

use crate::common;

use common::{corners, decode, DecodedTile, GroundLocator, TestServer, GROUND_NODES};

async fn tile(server: &TestServer, x: u32, y: u32) -> DecodedTile {
    let response = reqwest::get(server.url(&format!("/tiles/14/{x}/{y}.glb")))
        .await
        .expect("request reaches the server");
    assert_eq!(response.status(), 200, "{x}/{y}");
    decode(&response.bytes().await.expect("body"))
}

/// Plan area of a node's triangles as a fraction of the tile.
fn area_fraction(tile: &DecodedTile, node: &str) -> f64 {
    let size = tile.tile_size();
    corners(tile.primitives(node))
        .iter()
        .map(|[a, b, c]| {
            ((b[0] - a[0]) * (c[2] - a[2]) - (c[0] - a[0]) * (b[2] - a[2])).abs() / 2.0
        })
        .sum::<f64>()
        / (size * size)
}

/// True when the point at fractions `(fx, fz)` of the tile (east, south) is in a water triangle.
fn is_water(tile: &DecodedTile, fx: f64, fz: f64) -> bool {
    let size = tile.tile_size();
    let water = GroundLocator::new(corners(tile.primitives("water")), size);
    !water.heights_at(fx * size, fz * size, 1e-9).is_empty()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_sea_lies_beyond_the_coastline() {
    let dir = tempfile::tempdir().unwrap();
    let server = TestServer::start(&dir.path().join("cache.sqlite")).await;

    // Larvotto: the coast runs from the west edge to the north-east; the sea is south-east.
    let larvotto = tile(&server, 8530, 5973).await;
    let sea = area_fraction(&larvotto, "water");
    assert!(
        (0.25..0.75).contains(&sea),
        "water covers {sea} of 8530/5973"
    );
    assert!(is_water(&larvotto, 0.9, 0.9));
    assert!(!is_water(&larvotto, 0.1, 0.1));
    let sea_rows: Vec<_> = larvotto
        .features
        .iter()
        .filter(|f| f.tags.get("natural").and_then(|v| v.as_str()) == Some("sea"))
        .collect();
    assert_eq!(sea_rows.len(), 1, "one sea feature");
    assert_eq!(sea_rows[0].class, "water");

    // Open sea: no coastline crosses the tile; the nearest one has it on its water side.
    let open_sea = tile(&server, 8531, 5974).await;
    let sea = area_fraction(&open_sea, "water");
    assert!((sea - 1.0).abs() < 1e-6, "water covers {sea} of 8531/5974");

    // Inland above La Turbie: no sea at all.
    let inland = tile(&server, 8528, 5973).await;
    assert_eq!(area_fraction(&inland, "water"), 0.0);

    // Monaco-Ville, Fontvieille and the port: the sea reaches the south-east corner, and the
    // ground of the tile still adds up to the whole square.
    let monaco = tile(&server, 8529, 5974).await;
    assert!(is_water(&monaco, 0.95, 0.95));
    // Port Hercule's basin, between its pontoons, is sea behind the harbour walls.
    assert!(is_water(&monaco, 0.867, 0.233), "Port Hercule");
    let ground: f64 = GROUND_NODES.iter().map(|n| area_fraction(&monaco, n)).sum();
    assert!(ground < 1.0 + 1e-6, "ground covers {ground} of 8529/5974");
    // Roads are drawn in the material their `surface` tag (or their class) says.
    let pavings: Vec<&str> = monaco
        .primitives("road")
        .iter()
        .map(|p| p.material.as_str())
        .collect();
    for expected in ["road_asphalt", "road_unpaved"] {
        assert!(pavings.contains(&expected), "{pavings:?}");
    }
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn land_cover_is_drawn_with_its_own_materials() {
    let dir = tempfile::tempdir().unwrap();
    let server = TestServer::start(&dir.path().join("cache.sqlite")).await;
    // Above La Turbie: woods, the village and its pitches.
    let turbie = tile(&server, 8528, 5973).await;
    let materials: Vec<&str> = turbie
        .primitives("landcover")
        .iter()
        .map(|p| p.material.as_str())
        .collect();
    for expected in ["forest", "residential", "pitch"] {
        assert!(materials.contains(&expected), "{materials:?}");
    }
    let cover = area_fraction(&turbie, "landcover");
    assert!((0.2..0.95).contains(&cover), "land cover covers {cover}");
    let rows: Vec<_> = turbie
        .features
        .iter()
        .filter(|f| f.class == "landcover")
        .collect();
    assert!(!rows.is_empty());
    for row in rows {
        assert_eq!(row.osm_type, "way", "{row:?}");
        assert!(
            ["landuse", "natural", "leisure", "amenity"]
                .iter()
                .any(|k| row.tags.contains_key(*k)),
            "{row:?}"
        );
    }
    // Roads, water and land cover share one ground: nothing is counted twice.
    let ground: f64 = GROUND_NODES.iter().map(|n| area_fraction(&turbie, n)).sum();
    assert!(ground < 1.0 + 1e-6, "ground covers {ground}");
    server.stop().await;
}

/// The JSON chunk of a glb.
fn gltf_json(bytes: &[u8]) -> serde_json::Value {
    let length = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    serde_json::from_slice(&bytes[20..20 + length]).expect("JSON chunk")
}

/// The float components of an accessor (tightly packed, as the writer lays them out).
fn accessor_floats(gltf: &gltf::Gltf, blob: &[u8], accessor: u64) -> Vec<f32> {
    let accessor = gltf.document.accessors().nth(accessor as usize).unwrap();
    let start = accessor.view().unwrap().offset() + accessor.offset();
    let n = accessor.count() * accessor.dimensions().multiplicity();
    blob[start..start + 4 * n]
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes(b.try_into().unwrap()))
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn forests_are_planted_with_instanced_trees() {
    let dir = tempfile::tempdir().unwrap();
    let server = TestServer::start(&dir.path().join("cache.sqlite")).await;
    let bytes = reqwest::get(server.url("/tiles/14/8528/5973.glb"))
        .await
        .unwrap()
        .bytes()
        .await
        .unwrap();
    let root = gltf_json(&bytes);
    let used: Vec<&str> = root["extensionsUsed"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|v| v.as_str())
        .collect();
    assert!(used.contains(&"EXT_mesh_gpu_instancing"), "{used:?}");
    let decoded = decode(&bytes);
    let size = decoded.tile_size();
    let tree_nodes: Vec<&serde_json::Value> = root["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|n| n["extensions"]["EXT_mesh_gpu_instancing"].is_object())
        .filter(|n| n["name"].as_str().unwrap_or("").contains("leaved_crown"))
        .collect();
    assert!(!tree_nodes.is_empty());

    // Read every instance's translation and feature id.
    let gltf = gltf::Gltf::from_slice(&bytes).unwrap();
    let blob = gltf.blob.clone().unwrap();
    let floats = |accessor: u64| accessor_floats(&gltf, &blob, accessor);
    let mut trees = 0;
    for node in tree_nodes {
        let attributes = &node["extensions"]["EXT_mesh_gpu_instancing"]["attributes"];
        let translations = floats(attributes["TRANSLATION"].as_u64().unwrap());
        let ids = floats(attributes["_FEATURE_ID_0"].as_u64().unwrap());
        assert_eq!(translations.len(), 3 * ids.len());
        for (t, id) in translations.chunks_exact(3).zip(&ids) {
            // Inside the tile, and on the ground of a forest or a mapped tree.
            assert!((0.0..=size as f32).contains(&t[0]) && (0.0..=size as f32).contains(&t[2]));
            let feature = &decoded.features[*id as usize];
            assert!(
                feature.class == "vegetation"
                    || feature.tags.get("landuse").and_then(|v| v.as_str()) == Some("forest")
                    || feature.tags.get("natural").and_then(|v| v.as_str()) == Some("wood"),
                "{feature:?}"
            );
        }
        trees += ids.len();
    }
    assert!((500..=6000).contains(&trees), "{trees} trees");

    // Street lamps, benches and the like: instanced models of their own, features of class
    // `object` traced to their nodes.
    let bytes = reqwest::get(server.url("/tiles/14/8529/5973.glb"))
        .await
        .unwrap()
        .bytes()
        .await
        .unwrap();
    let root = gltf_json(&bytes);
    let decoded = decode(&bytes);
    let objects: Vec<&serde_json::Value> = root["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|n| {
            [
                "street_lamp",
                "bench",
                "bollard",
                "power_pole",
                "power_tower",
                "wind_turbine",
            ]
            .contains(&n["name"].as_str().unwrap_or(""))
        })
        .collect();
    assert!(!objects.is_empty(), "no street-level objects");
    let gltf = gltf::Gltf::from_slice(&bytes).unwrap();
    let blob = gltf.blob.clone().unwrap();
    for node in objects {
        let accessor = node["extensions"]["EXT_mesh_gpu_instancing"]["attributes"]["_FEATURE_ID_0"]
            .as_u64()
            .unwrap();
        for id in accessor_floats(&gltf, &blob, accessor) {
            let feature = &decoded.features[id as usize];
            assert_eq!(
                (feature.class.as_str(), feature.osm_type.as_str()),
                ("object", "node")
            );
        }
    }
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn barriers_stand_on_the_ground() {
    let dir = tempfile::tempdir().unwrap();
    let server = TestServer::start(&dir.path().join("cache.sqlite")).await;
    let monaco = tile(&server, 8529, 5974).await;
    let size = monaco.tile_size();
    let barriers = monaco.primitives("barrier");
    assert!(!barriers.is_empty(), "no barrier drawn");
    let ground: Vec<_> = GROUND_NODES
        .iter()
        .flat_map(|n| corners(monaco.primitives(n)))
        .collect();
    let locator = GroundLocator::new(ground, size);
    let (mut below, mut above) = (0, 0);
    for primitive in barriers {
        assert!(
            ["wall", "fence", "hedge", "retaining_wall", "city_wall"]
                .contains(&primitive.material.as_str()),
            "{}",
            primitive.material
        );
        for (p, &id) in primitive.positions.iter().zip(&primitive.feature_ids) {
            let feature = &monaco.features[id as usize];
            assert_eq!(feature.class, "barrier");
            let heights = locator.heights_at(f64::from(p[0]), f64::from(p[2]), 1e-6);
            let Some(&ground) = heights.first() else {
                continue; // under a building: the ground is cut out there
            };
            let y = f64::from(p[1]);
            // Feet a little below the ground, tops at most a city wall's height above it (in
            // local units, 1/cos(latitude) ≈ 1.38 per metre here). A retaining wall stands at
            // the foot of its step: its high side's ground is as high above its feet as it is.
            let step_m = if primitive.material == "retaining_wall" {
                feature
                    .tags
                    .get("height")
                    .and_then(|h| h.as_str()?.trim_end_matches(" m").parse::<f64>().ok())
                    .unwrap_or(1.5)
            } else {
                0.0
            };
            assert!(
                y > ground - 3.0 - 1.38 * step_m && y < ground + 12.0,
                "{y} over ground {ground}"
            );
            if y < ground {
                below += 1;
            } else {
                above += 1;
            }
        }
    }
    assert!(below > 0 && above > 0, "{below} feet, {above} tops");
    server.stop().await;
}

/// The centre of Monaco from the tag-rich 2021 extract, rendered by the command line.
#[test]
fn the_tag_rich_extract_gives_every_family() {
    let dir = tempfile::tempdir().unwrap();
    let bytes = common::render_in_process(
        "14/8529/5974",
        &[
            "--osm".as_ref(),
            "tests/data/monaco-planetiler-2021.osm.pbf".as_ref(),
        ],
        dir.path(),
    );
    let out = dir.path().join("14_8529_5974.glb");
    common::validate(&[out.as_path()])[0].assert_clean();
    let tile = decode(&bytes);
    let count = |class: &str| tile.features.iter().filter(|f| f.class == class).count();
    for (class, at_least) in [
        ("building", 300),
        ("road", 500),
        ("water", 1),
        ("landcover", 10),
        ("barrier", 10),
        ("object", 20),
        ("vegetation", 20),
    ] {
        assert!(count(class) >= at_least, "{} {class} rows", count(class));
    }
    // The sea and the port, from coastlines the extract carries.
    assert!(is_water(&tile, 0.95, 0.95));
    let instanced: Vec<&String> = tile.instanced.iter().collect();
    assert!(
        instanced.iter().any(|n| n.contains("crown"))
            && instanced.iter().any(|n| !n.contains("crown")),
        "{instanced:?}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn power_lines_hang_above_the_ground() {
    let dir = tempfile::tempdir().unwrap();
    let server = TestServer::start(&dir.path().join("cache.sqlite")).await;
    let monaco = tile(&server, 8529, 5973).await;
    let size = monaco.tile_size();
    let ground: Vec<_> = GROUND_NODES
        .iter()
        .flat_map(|n| corners(monaco.primitives(n)))
        .collect();
    let locator = GroundLocator::new(ground, size);
    let lines: Vec<_> = monaco
        .primitives("object")
        .iter()
        .filter(|p| p.material == "power_line")
        .collect();
    assert!(!lines.is_empty(), "no power line drawn");
    let (mut above, mut total, mut vertices) = (0, 0, 0);
    for primitive in lines {
        for (p, &id) in primitive.positions.iter().zip(&primitive.feature_ids) {
            vertices += 1;
            let feature = &monaco.features[id as usize];
            assert_eq!(
                (feature.osm_type.as_str(), feature.class.as_str()),
                ("way", "object")
            );
            assert!(feature.tags.contains_key("power"), "{feature:?}");
            let Some(&ground) = locator
                .heights_at(f64::from(p[0]), f64::from(p[2]), 1e-6)
                .first()
            else {
                continue;
            };
            total += 1;
            // Several metres up (local units: about 1.38 per metre at this latitude).
            if f64::from(p[1]) > ground + 3.0 {
                above += 1;
            }
        }
    }
    // Most conductors are over the tile's ground: the measure is taken on them.
    assert!(
        total * 2 >= vertices && total > 0,
        "only {total} of {vertices} conductor vertices over the ground"
    );
    assert!(
        above * 10 >= total * 9,
        "{above} of {total} conductor vertices well above the ground"
    );
    server.stop().await;
}

/// A road through a building (`tunnel=building_passage`) is a road on the ground that runs on
/// under the building, whose walls open over it: Monaco's 14/8529/5974 has four. Every passage
/// is drawn; where a building stands over a passage's paving, no face of it lies within 2.5 m
/// over the road and no wall across it comes lower, and each such building is still a closed
/// shell in the glb.
#[test]
fn roads_through_buildings_run_on_under_their_raised_floors() {
    use std::collections::{BTreeMap, BTreeSet};
    let dir = tempfile::tempdir().unwrap();
    let tile = decode(&common::render_in_process("14/8529/5974", &[], dir.path()));
    let passages: BTreeSet<usize> = tile
        .features
        .iter()
        .enumerate()
        .filter(|(_, f)| f.class == "road")
        .filter(|(_, f)| f.tags.get("tunnel").and_then(|v| v.as_str()) == Some("building_passage"))
        .map(|(index, _)| index)
        .collect();
    assert!(passages.len() >= 4, "passages with a row: {passages:?}");
    // The passages' paving triangles.
    let mut paving: Vec<[[f32; 3]; 3]> = Vec::new();
    let mut drawn: BTreeSet<usize> = BTreeSet::new();
    for p in tile.primitives("road") {
        for t in p.indices.chunks_exact(3) {
            let feature = p.feature_ids[t[0] as usize] as usize;
            if passages.contains(&feature) {
                drawn.insert(feature);
                paving.push([0, 1, 2].map(|k| p.positions[t[k] as usize]));
            }
        }
    }
    assert_eq!(drawn, passages, "every passage drawn");
    // Building faces over the paving (at its centroid) and walls standing across it (points
    // along their foot strictly inside it), compared with the road's height at that point.
    let mut covered = 0;
    let mut low = Vec::new();
    let mut carved: BTreeSet<u32> = BTreeSet::new();
    // Directed edges (by their ends' bits) of each building's triangles.
    type Edges = BTreeMap<([u32; 3], [u32; 3]), i32>;
    let mut edges: BTreeMap<u32, Edges> = BTreeMap::new();
    for p in tile.primitives("building") {
        for t in p.indices.chunks_exact(3) {
            let feature = p.feature_ids[t[0] as usize];
            let c = [0, 1, 2].map(|k| p.positions[t[k] as usize]);
            let key = |q: [f32; 3]| q.map(f32::to_bits);
            let building = edges.entry(feature).or_default();
            for k in 0..3 {
                *building
                    .entry((key(c[k]), key(c[(k + 1) % 3])))
                    .or_default() += 1;
            }
            for road in &paving {
                let plan = road.map(|q| [q[0], q[2]]);
                // (point, height, whether it is a wall's foot)
                let mut points: Vec<([f32; 2], f32, bool)> = Vec::new();
                let middle = centroid(plan);
                if let Some(y) = height_in_plan(c, middle) {
                    covered += 1;
                    points.push((middle, y, false));
                }
                for k in 1..8 {
                    let s = k as f32 / 8.0;
                    for (i, j) in [(0, 1), (1, 2), (2, 0)] {
                        let q = [
                            c[i][0] + s * (c[j][0] - c[i][0]),
                            c[i][2] + s * (c[j][2] - c[i][2]),
                        ];
                        if strictly_inside(plan, q) {
                            points.extend(wall_bottom(c, q).map(|y| (q, y, true)));
                        }
                    }
                }
                for (q, y, foot) in points {
                    carved.insert(feature);
                    let under = height_in_plan(*road, q).unwrap_or(f32::NAN);
                    // A face under the road is a floor in the ground; a wall reaching below
                    // the headroom stands in the way.
                    if y < under + 2.5 && (foot || y > under - 0.25) {
                        low.push((feature, under, y));
                    }
                }
            }
        }
    }
    assert!(covered >= 20, "{covered} building faces over passages");
    assert!(
        low.is_empty(),
        "{} building faces within 2.5 m over a passage (way, tags, road, face), e.g. {:?}",
        low.len(),
        low.iter()
            .take(5)
            .map(|l| (
                tile.features[l.0 as usize].osm_id,
                &tile.features[l.0 as usize].tags,
                l.1,
                l.2
            ))
            .collect::<Vec<_>>()
    );
    let open: Vec<u32> = carved
        .iter()
        .copied()
        .filter(|f| {
            let building = &edges[f];
            building
                .iter()
                .any(|(&(a, b), &n)| building.get(&(b, a)).copied().unwrap_or(0) != n)
        })
        .collect();
    assert!(
        open.is_empty(),
        "buildings over passages not closed: {open:?} of {carved:?}"
    );
}

fn centroid(t: [[f32; 2]; 3]) -> [f32; 2] {
    [
        (t[0][0] + t[1][0] + t[2][0]) / 3.0,
        (t[0][1] + t[1][1] + t[2][1]) / 3.0,
    ]
}

/// Whether `p` lies inside the plan triangle `t` and 2 cm or more from its sides.
fn strictly_inside(t: [[f32; 2]; 3], p: [f32; 2]) -> bool {
    (0..3).all(|k| {
        let (a, b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
        let side = |q: [f32; 2]| (b[0] - a[0]) * (q[1] - a[1]) - (b[1] - a[1]) * (q[0] - a[0]);
        let length = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
        length > 0.0 && side(p) * side(c).signum() > 0.02 * length
    })
}

/// The lowest point at `p` (x, z) of an upright triangle whose foot passes through it in plan.
fn wall_bottom(c: [[f32; 3]; 3], p: [f32; 2]) -> Option<f32> {
    let (i, j) = [(0, 1), (1, 2), (0, 2)]
        .into_iter()
        .max_by(|&(a, b), &(x, y)| {
            let length = |m: usize, n: usize| (c[n][0] - c[m][0]).hypot(c[n][2] - c[m][2]);
            length(a, b).total_cmp(&length(x, y))
        })?;
    let d = [c[j][0] - c[i][0], c[j][2] - c[i][2]];
    let along = |q: [f32; 2]| {
        ((q[0] - c[i][0]) * d[0] + (q[1] - c[i][2]) * d[1]) / (d[0] * d[0] + d[1] * d[1])
    };
    let at = along(p);
    let mut lowest: Option<f32> = None;
    for (m, n) in [(0, 1), (1, 2), (2, 0)] {
        let (a, b) = (along([c[m][0], c[m][2]]), along([c[n][0], c[n][2]]));
        if a == b || at < a.min(b) || at > a.max(b) {
            continue;
        }
        let y = c[m][1] + (at - a) / (b - a) * (c[n][1] - c[m][1]);
        lowest = Some(lowest.map_or(y, |l| l.min(y)));
    }
    lowest
}

/// The height at `p` (x, z) of a triangle that covers it in plan.
fn height_in_plan(c: [[f32; 3]; 3], p: [f32; 2]) -> Option<f32> {
    let [a, b, d] = c.map(|q| [f64::from(q[0]), f64::from(q[2]), f64::from(q[1])]);
    let (x, z) = (f64::from(p[0]), f64::from(p[1]));
    let det = (b[0] - a[0]) * (d[1] - a[1]) - (d[0] - a[0]) * (b[1] - a[1]);
    if det.abs() < 1e-9 {
        return None;
    }
    let u = ((x - a[0]) * (d[1] - a[1]) - (d[0] - a[0]) * (z - a[1])) / det;
    let v = ((b[0] - a[0]) * (z - a[1]) - (x - a[0]) * (b[1] - a[1])) / det;
    if u < 0.0 || v < 0.0 || u + v > 1.0 {
        return None;
    }
    Some((a[2] + u * (b[2] - a[2]) + v * (d[2] - a[2])) as f32)
}

/// A street lamp on a bridge's way stands on the deck, not on the ground under it.
#[test]
fn a_lamp_on_a_bridge_stands_on_its_deck() {
    let dir = tempfile::tempdir().unwrap();
    let extract = dir.path().join("bridge.osm.pbf");
    // A bridge over a primary road in 14/8529/5974, a lamp on it right over the road.
    let ways = serde_json::json!([
        {
            "tags": {"highway": "residential", "bridge": "yes", "layer": "1"},
            "nodes": [[7.4195, 43.735], [7.4205, 43.735, {"highway": "street_lamp"}], [7.4215, 43.735]],
        },
        {
            "tags": {"highway": "primary"},
            "nodes": [[7.4205, 43.734], [7.4205, 43.736]],
        },
    ]);
    common::write_extract(&ways, &extract);
    let bytes = common::render_in_process(
        "14/8529/5974",
        &["--osm".as_ref(), extract.as_os_str()],
        dir.path(),
    );
    let root = gltf_json(&bytes);
    let decoded = decode(&bytes);
    let gltf = gltf::Gltf::from_slice(&bytes).unwrap();
    let blob = gltf.blob.clone().unwrap();
    let lamp = root["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .find(|n| n["name"] == "street_lamp")
        .expect("the lamp is drawn");
    let attributes = &lamp["extensions"]["EXT_mesh_gpu_instancing"]["attributes"];
    let foot = accessor_floats(&gltf, &blob, attributes["TRANSLATION"].as_u64().unwrap());
    assert_eq!(foot.len(), 3, "one lamp");
    // The deck's top right there: the highest up-facing bridge triangle over the lamp; the
    // road under it, the lowest road triangle there.
    let (x, z) = (f64::from(foot[0]), f64::from(foot[2]));
    let heights_at = |node: &str| -> Vec<f32> {
        decoded
            .primitives(node)
            .iter()
            .flat_map(|p| {
                p.triangles()
                    .filter(|t| p.normals[t[0]][1] > 0.9)
                    .map(|t| t.map(|k| p.positions[k].map(f64::from)))
                    .collect::<Vec<_>>()
            })
            .filter_map(|[a, b, c]| {
                let d = (b[2] - c[2]) * (a[0] - c[0]) + (c[0] - b[0]) * (a[2] - c[2]);
                let wa = ((b[2] - c[2]) * (x - c[0]) + (c[0] - b[0]) * (z - c[2])) / d;
                let wb = ((c[2] - a[2]) * (x - c[0]) + (a[0] - c[0]) * (z - c[2])) / d;
                let wc = 1.0 - wa - wb;
                (d.abs() > 1e-12 && wa >= -1e-6 && wb >= -1e-6 && wc >= -1e-6)
                    .then(|| (wa * a[1] + wb * b[1] + wc * c[1]) as f32)
            })
            .collect()
    };
    let deck = heights_at("bridge")
        .into_iter()
        .fold(f32::NEG_INFINITY, f32::max);
    assert!(deck.is_finite(), "the deck is drawn over the lamp");
    assert!(
        (foot[1] - deck).abs() < 0.05,
        "the lamp's foot at {} m, the deck's top at {deck} m",
        foot[1]
    );
    // And the deck clears the road: the lamp is well above the road under it.
    let ground = heights_at("road").into_iter().fold(f32::INFINITY, f32::min);
    assert!(ground.is_finite(), "the road is drawn under the lamp");
    assert!(
        foot[1] > ground + 4.0,
        "lamp {} over a road at {ground}",
        foot[1]
    );
}

/// A way of steps is drawn as steps over its ramp: level treads, not sunk into the ground
/// (but for 1 %, where another way's surface overlaps the steps) and, but for 1 %, within
/// half a metre over it, drawn as objects of their way.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn steps_are_drawn_as_level_treads_over_their_ramp() {
    let dir = tempfile::tempdir().unwrap();
    let server = TestServer::start(&dir.path().join("cache.sqlite")).await;
    let monaco = tile(&server, 8529, 5974).await;
    let locator = GroundLocator::of_ground(&monaco);
    let stairs: Vec<_> = monaco
        .primitives("object")
        .iter()
        .filter(|p| p.material == "stairs")
        .collect();
    assert_eq!(stairs.len(), 1, "no steps drawn");
    let (mut treads, mut over_ground, mut sunk, mut tall, mut highest) = (0, 0, 0, 0, 0.0f64);
    for primitive in stairs {
        for t in primitive.triangles() {
            let feature = &monaco.features[primitive.feature_ids[t[0]] as usize];
            assert_eq!(
                (feature.class.as_str(), feature.tags.get("highway")),
                ("object", Some(&serde_json::json!("steps")))
            );
            let [a, b, c] = t.map(|i| primitive.positions[i].map(f64::from));
            let up = (b[2] - a[2]) * (c[0] - a[0]) - (b[0] - a[0]) * (c[2] - a[2]);
            if up <= 1e-9 {
                continue;
            }
            treads += 1;
            assert!(
                (a[1] - b[1]).abs() < 1e-3 && (a[1] - c[1]).abs() < 1e-3,
                "a tread is not level: {a:?} {b:?} {c:?}"
            );
            let centre = [(a[0] + b[0] + c[0]) / 3.0, (a[2] + b[2] + c[2]) / 3.0];
            let Some(&ground) = locator.heights_at(centre[0], centre[1], 1e-6).first() else {
                continue;
            };
            over_ground += 1;
            // Local units: about 1.38 to the metre here.
            let above = (a[1] - ground) / 1.38;
            if above < -0.05 {
                sunk += 1;
            }
            if above > 0.5 {
                tall += 1;
            }
            highest = highest.max(above);
        }
    }
    eprintln!(
        "{treads} tread triangles, {over_ground} over the ground: {sunk} sunk into it (where a \
         way beside overlaps the steps), {tall} more than 0.5 m above it (where the ground \
         steps within a tread), at most {highest:.2} m"
    );
    assert!(treads > 1000, "only {treads} tread triangles");
    assert!(
        over_ground * 2 >= treads,
        "only {over_ground} of {treads} treads over the ground"
    );
    assert!(
        sunk * 100 <= over_ground,
        "{sunk} of {over_ground} treads sunk"
    );
    assert!(
        tall * 100 <= over_ground,
        "{tall} of {over_ground} treads stand tall"
    );
}
