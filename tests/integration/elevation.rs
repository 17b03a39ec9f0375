//! Elevations settled on real tiles: checked from the decoded glb and its feature table.

use crate::common;

use std::collections::HashMap;

use common::{decode, sample_osm, sample_srtm, GROUND_NODES, MONACO_TILES as TILES};
use terrastitch::elevation::settled::Stations;
use terrastitch::features;
use terrastitch::features::structures as tags;
use terrastitch::provider::Inputs;
use terrastitch::render::RenderSettings;
use terrastitch::TileId;

/// Every water area (not a waterway drawn at its width) is flat within 1 cm, and the ground
/// that meets it at its shore is at its level: the water never stands above its banks. Every
/// waterway drawn at its width runs down (or level) along its way and is level across.
#[test]
fn water_lies_flat_and_meets_its_shore_and_waterways_run_down() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let sources = Inputs::open(&[sample_osm()], &sample_srtm(), 14).expect("sample data");
    let (mut areas, mut waterways, mut shores) = (0, 0, 0);
    for (x, y) in TILES {
        let name = format!("14/{x}/{y}");
        let tile = decode(&common::render_in_process(&name, &[], dir.path()));
        let frame = TileId { z: 14, x, y }.frame();
        let elevation = |p: [f32; 3]| f64::from(p[1]) / frame.scale_at(f64::from(p[2]));
        // Elevations of each water area's vertices, and the level at each water position.
        let mut by_feature: HashMap<u32, Vec<f64>> = HashMap::new();
        for primitive in tile.primitives("water") {
            for (k, &p) in primitive.positions.iter().enumerate() {
                let feature = primitive.feature_ids[k];
                let tags = &tile.features[feature as usize].tags;
                if !tags.contains_key("waterway") {
                    by_feature.entry(feature).or_default().push(elevation(p));
                }
            }
        }
        let mut levels: HashMap<[u32; 2], f64> = HashMap::new();
        for (feature, heights) in &by_feature {
            let low = heights.iter().copied().fold(f64::INFINITY, f64::min);
            let high = heights.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            assert!(
                high - low < 0.01,
                "{name}: water feature {feature} (way {} {:?}) spans {low:.3}..{high:.3} m",
                tile.features[*feature as usize].osm_id,
                tile.features[*feature as usize].tags
            );
            areas += 1;
        }
        for primitive in tile.primitives("water") {
            for (k, &p) in primitive.positions.iter().enumerate() {
                if by_feature.contains_key(&primitive.feature_ids[k]) {
                    levels.insert([p[0].to_bits(), p[2].to_bits()], elevation(p));
                }
            }
        }
        // The shore: ground vertices of other surfaces where the water's vertices are (the
        // skirt under the tile's sides is no surface).
        let mut shore = 0;
        for node in GROUND_NODES.iter().filter(|n| **n != "water") {
            let surfaces = tile.primitives(node).iter();
            for primitive in surfaces.filter(|p| p.material != "terrain_skirt") {
                for &p in &primitive.positions {
                    if let Some(&level) = levels.get(&[p[0].to_bits(), p[2].to_bits()]) {
                        shore += 1;
                        assert!(
                            (elevation(p) - level).abs() < 0.01,
                            "{name}: {node} at {p:?} is {:.3} m, the water {level:.3} m",
                            elevation(p)
                        );
                    }
                }
            }
        }
        shores += shore;

        // Waterways: the elevation of each vertex against how far down the way it lies, where
        // no other water shares the vertex (where two meet, the lower takes the shared ones).
        let mut owners: HashMap<[u32; 2], std::collections::BTreeSet<u32>> = HashMap::new();
        for primitive in tile.primitives("water") {
            for (k, &p) in primitive.positions.iter().enumerate() {
                owners
                    .entry([p[0].to_bits(), p[2].to_bits()])
                    .or_default()
                    .insert(primitive.feature_ids[k]);
            }
        }
        let id = TileId { z: 14, x, y };
        let set = features::collect(&common::selection(&sources, id), id, &Default::default());
        for primitive in tile.primitives("water") {
            let mut by_feature: HashMap<u32, Vec<(f64, f64)>> = HashMap::new();
            for (k, &p) in primitive.positions.iter().enumerate() {
                let row = &tile.features[primitive.feature_ids[k] as usize];
                if !row.tags.contains_key("waterway")
                    || owners[&[p[0].to_bits(), p[2].to_bits()]].len() > 1
                {
                    continue;
                }
                let line = set
                    .surfaces
                    .iter()
                    .find(|s| {
                        set.features[s.feature as usize]
                            .element
                            .is_some_and(|e| e.id == row.osm_id)
                    })
                    .map(|s| Stations::new(&s.centreline))
                    .expect("the waterway's surface");
                let (u, v) = frame.local_to_uv(f64::from(p[0]), f64::from(p[2]));
                by_feature
                    .entry(primitive.feature_ids[k])
                    .or_default()
                    .push((line.at([u, v]), elevation(p)));
            }
            for (feature, mut points) in by_feature {
                waterways += 1;
                points.sort_by(|a, b| a.0.total_cmp(&b.0));
                for pair in points.windows(2) {
                    assert!(
                        pair[1].1 <= pair[0].1 + 0.01,
                        "{name}: waterway {feature} rises from {:.3} to {:.3} m",
                        pair[0].1,
                        pair[1].1
                    );
                }
            }
        }
    }
    assert!(areas >= 4, "{areas} water areas");
    assert!(shores > 100, "{shores} shore vertices");
    assert!(waterways >= 1, "{waterways} waterways");
}

/// Every cross-section of a road drawn by the network (the left and right corners of each
/// piece, where the mesh has vertices) is level within 1 cm, and every junction is level
/// within 1 cm — except where a corner is shared with water (the water's level wins there) or
/// lies on the tile's edge.
#[test]
fn roads_are_level_across_and_junctions_level() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let sources = Inputs::open(&[sample_osm()], &sample_srtm(), 14).expect("sample data");
    let (mut sections, mut junctions, mut tilted, mut tilted_junctions) = (0, 0, 0, 0);
    for (x, y) in TILES {
        let name = format!("14/{x}/{y}");
        let tile = decode(&common::render_in_process(&name, &[], dir.path()));
        let id = TileId { z: 14, x, y };
        let frame = id.frame();
        let size = tile.tile_size() as f32;
        let key = |x: f32, z: f32| [x.to_bits(), z.to_bits()];
        // Elevation of every road vertex, and the positions water holds.
        let mut road: HashMap<[u32; 2], f64> = HashMap::new();
        let mut owners: HashMap<[u32; 2], std::collections::BTreeSet<u32>> = HashMap::new();
        for primitive in tile.primitives("road") {
            for (&p, &feature) in primitive.positions.iter().zip(&primitive.feature_ids) {
                let e = f64::from(p[1]) / frame.scale_at(f64::from(p[2]));
                road.insert(key(p[0], p[2]), e);
                owners.entry(key(p[0], p[2])).or_default().insert(feature);
            }
        }
        let wet: std::collections::HashSet<[u32; 2]> = tile
            .primitives("water")
            .iter()
            .flat_map(|p| p.positions.iter().map(|q| key(q[0], q[2])))
            .collect();
        // Where a tunnel runs under a road too shallow for its roof, the ground over the tube
        // is raised and the road with it.
        let tunnels = common::TunnelFootprint::new(&tile);
        let over_tube = |x: f64, z: f64| tunnels.near(x, z);
        let at = |p: [f64; 2]| -> Option<f64> {
            let (lx, lz) = frame.uv_to_local(p[0], p[1]);
            if over_tube(lx, lz) {
                return None;
            }
            let (lx, lz) = (lx as f32, lz as f32);
            // A vertex two roads (or a road and its junction) share takes one of their levels.
            let shared = owners.get(&key(lx, lz)).is_some_and(|o| o.len() > 1);
            if lx <= 0.0
                || lz <= 0.0
                || lx >= size
                || lz >= size
                || wet.contains(&key(lx, lz))
                || shared
            {
                return None;
            }
            road.get(&key(lx, lz)).copied()
        };
        let at_junction = |p: [f64; 2]| -> Option<f64> {
            let (lx, lz) = frame.uv_to_local(p[0], p[1]);
            if over_tube(lx, lz) {
                return None;
            }
            let (lx, lz) = (lx as f32, lz as f32);
            if lx <= 0.0 || lz <= 0.0 || lx >= size || lz >= size || wet.contains(&key(lx, lz)) {
                return None;
            }
            road.get(&key(lx, lz)).copied()
        };
        let set = features::collect(&common::selection(&sources, id), id, &Default::default());
        for surface in &set.surfaces {
            if surface.junction_at.is_some() {
                // Corners another junction also holds (junctions close enough to touch) take
                // one of their levels.
                let shared = |c: [f64; 2]| {
                    set.surfaces
                        .iter()
                        .filter(|o| o.junction_at.is_some() && !std::ptr::eq(*o, surface))
                        .flat_map(|o| &o.pieces)
                        .any(|q| q.contains(c) || on_outline(q, c))
                };
                let corners = || surface.pieces.iter().flat_map(|p| p.outer.iter());
                let mut heights: Vec<f64> = corners().filter_map(|&c| at_junction(c)).collect();
                let spread = |h: &[f64]| {
                    let low = h.iter().copied().fold(f64::INFINITY, f64::min);
                    h.iter().copied().fold(f64::NEG_INFINITY, f64::max) - low
                };
                if heights.len() >= 2 && spread(&heights) >= 0.01 {
                    heights = corners()
                        .filter(|&&c| !shared(c))
                        .filter_map(|&c| at_junction(c))
                        .collect();
                }
                if heights.len() >= 2 {
                    let low = heights.iter().copied().fold(f64::INFINITY, f64::min);
                    let high = heights.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                    if high - low < 0.01 {
                        junctions += 1;
                    } else {
                        tilted_junctions += 1;
                    }
                }
                continue;
            }
            for (k, piece) in surface.pieces.iter().enumerate() {
                // Pieces of a way drawn by the network are quads: left[i], left[i + 1],
                // right[i + 1], right[i] (squares drawn as areas are not).
                let Some(stretch) = surface.piece_lines.iter().find(|(r, _)| r.contains(&k)) else {
                    continue;
                };
                let stretch = Some(stretch);
                let [l0, l1, r1, r0] = [0, 1, 2, 3].map(|k| piece.outer[k]);
                // Where another stretch of road overlaps this one (arms meeting at a sharp
                // angle), a point takes one of their levels.
                let overlapped = |c: [f64; 2]| {
                    set.surfaces
                        .iter()
                        .filter(|o| o.class == features::FeatureClass::Road)
                        .flat_map(|o| {
                            o.pieces.iter().enumerate().filter(move |(m, _)| {
                                !(std::ptr::eq(o, surface)
                                    && stretch.is_some_and(|(r, _)| r.contains(m)))
                            })
                        })
                        .any(|(_, q)| q.contains(c) || on_outline(q, c))
                };
                for (l, r) in [(l0, r0), (l1, r1)] {
                    if let (Some(a), Some(b)) = (at(l), at(r)) {
                        if (a - b).abs() >= 0.01 && (overlapped(l) || overlapped(r)) {
                            continue;
                        }
                        if (a - b).abs() >= 0.01 {
                            tilted += 1;
                            continue;
                        }
                        assert!(
                            (a - b).abs() < 0.01,
                            "{name}: a cross-section of way {:?} tilts {:.3} m",
                            set.features[surface.feature as usize].element,
                            a - b
                        );
                        sections += 1;
                    }
                }
            }
        }
    }
    eprintln!(
        "{sections} road cross-sections and {junctions} junctions level, {tilted} and {tilted_junctions} not"
    );
    assert!(sections > 1000, "{sections} cross-sections");
    assert!(junctions > 100, "{junctions} junctions");
    // Not quite all: on a bend folded so tightly that a cross-section touches another, its
    // corners take two stations, and a vertex the triangulation put a hair from the water's
    // outline keeps the water's level (a handful on these tiles).
    assert!(
        tilted * 1000 < sections,
        "{tilted} of {sections} cross-sections tilted"
    );
    assert!(
        tilted_junctions * 200 < junctions,
        "{tilted_junctions} of {junctions} junctions tilted"
    );
}

/// Every ground road of the ten Monaco tiles keeps to its class's steepest grade unless the LP
/// reported that grade violated on that way nearby: along its settled profile in the tile
/// (every pair of stations, 10 m apart at most), and in the decoded glb between every two consecutive cross-sections
/// of its drawn strip that are level (the vertices the mesh holds it at; the mesh is linear
/// between them), measured along the strip's centre.
#[test]
fn road_grades_keep_to_the_class_maximum_unless_reported() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let sources = Inputs::open(&[sample_osm()], &sample_srtm(), 14).expect("sample data");
    let settings = RenderSettings::default();
    let (mut segments, mut steep, mut drawn, mut drawn_steep, mut settled_stretches) =
        (0, 0, 0, 0, 0);
    for (x, y) in TILES {
        let name = format!("14/{x}/{y}");
        let tile = decode(&common::render_in_process(&name, &[], dir.path()));
        let id = TileId { z: 14, x, y };
        let frame = id.frame();
        let size = tile.tile_size() as f32;
        let selection = common::selection(&sources, id);
        let mosaic = sources.mosaic(id).expect("srtm");
        let memo = terrastitch::render::Solutions::default();
        let roads =
            terrastitch::render::settle_road_profiles(id, &selection, &mosaic, &settings, &memo);
        settled_stretches += roads.settled;
        // A violation of the way's grade reported within 15 m of the segment from `a` to `b`.
        let reported = |way: i64, a: [f64; 2], b: [f64; 2], metre: f64| {
            roads.violations.iter().any(|r| {
                r.way == way
                    && r.violation > 0.0
                    && terrastitch::geometry::distance_to_segment(r.at, a, b) < 15.0 * metre
            })
        };
        let max_of = |way: i64| {
            let way = selection.ways.iter().find(|w| w.id == way)?;
            let mut max = tags::max_incline(&way.tags)?;
            if let Some(tags::Incline::Grade(g)) = tags::incline(&way.tags) {
                max = max.max(g.abs());
            }
            Some(max)
        };
        for (&way, profile) in &roads.profiles {
            let Some(max) = max_of(way) else {
                continue;
            };
            let in_tile = |p: [f64; 2]| {
                p[0] >= f64::from(x)
                    && p[0] <= f64::from(x + 1)
                    && p[1] >= f64::from(y)
                    && p[1] <= f64::from(y + 1)
            };
            for i in 0..profile.points.len() - 1 {
                if !in_tile(profile.points[i]) || !in_tile(profile.points[i + 1]) {
                    continue;
                }
                let run = (profile.along[i + 1] - profile.along[i]) / profile.metre;
                let rise = profile.elevations[i + 1] - profile.elevations[i];
                segments += 1;
                if run > 0.0 && rise.abs() > max * run + 1e-3 {
                    steep += 1;
                    assert!(
                        reported(way, profile.points[i], profile.points[i + 1], profile.metre),
                        "{name}: way {way}'s profile rises {:.3} per metre at station {i}, \
                         over its {max}, unreported",
                        rise.abs() / run
                    );
                }
            }
        }

        // The drawn strips: the elevation of every road vertex the way alone holds.
        let key = |x: f32, z: f32| [x.to_bits(), z.to_bits()];
        let mut road: HashMap<[u32; 2], (f64, u32)> = HashMap::new();
        let mut shared: std::collections::HashSet<[u32; 2]> = Default::default();
        for primitive in tile.primitives("road") {
            for (&p, &feature) in primitive.positions.iter().zip(&primitive.feature_ids) {
                let e = f64::from(p[1]) / frame.scale_at(f64::from(p[2]));
                if road
                    .insert(key(p[0], p[2]), (e, feature))
                    .is_some_and(|o| o.1 != feature)
                {
                    shared.insert(key(p[0], p[2]));
                }
            }
        }
        let wet: std::collections::HashSet<[u32; 2]> = tile
            .primitives("water")
            .iter()
            .flat_map(|p| p.positions.iter().map(|q| key(q[0], q[2])))
            .collect();
        let tunnels = common::TunnelFootprint::new(&tile);
        let at = |p: [f64; 2]| -> Option<(f64, [f64; 2])> {
            let (lx, lz) = frame.uv_to_local(p[0], p[1]);
            if tunnels.near(lx, lz) {
                return None;
            }
            let k = key(lx as f32, lz as f32);
            let inside = |c: f32| c > 0.0 && c < size;
            if !inside(lx as f32) || !inside(lz as f32) || wet.contains(&k) || shared.contains(&k) {
                return None;
            }
            road.get(&k).map(|&(h, _)| (h, [lx, lz]))
        };
        let set = features::collect(&selection, id, &Default::default());
        for surface in &set.surfaces {
            let Some(element) = set.features[surface.feature as usize].element else {
                continue;
            };
            let Some(max) = max_of(element.id) else {
                continue;
            };
            for (range, _) in &surface.piece_lines {
                for k in range.clone() {
                    let Some(piece) = surface.pieces.get(k) else {
                        continue;
                    };
                    let [l0, l1, r1, r0] = [0, 1, 2, 3].map(|c| piece.outer[c]);
                    let (Some(a), Some(b), Some(c), Some(d)) = (at(l0), at(r0), at(l1), at(r1))
                    else {
                        continue;
                    };
                    // A cross-section that is not level (a corner held by a cut or raised
                    // ground beside it) is the cross-section test's concern.
                    if (a.0 - b.0).abs() > 0.01 || (c.0 - d.0).abs() > 0.01 {
                        continue;
                    }
                    let mid = |p: [f64; 2], q: [f64; 2]| [(p[0] + q[0]) / 2.0, (p[1] + q[1]) / 2.0];
                    let (m0, m1) = (mid(a.1, b.1), mid(c.1, d.1));
                    // Local coordinates are Web Mercator metres: on the ground, shorter by
                    // the projection's scale.
                    let run = (m1[0] - m0[0]).hypot(m1[1] - m0[1])
                        / frame.scale_at((m0[1] + m1[1]) / 2.0);
                    if run < 0.5 {
                        continue;
                    }
                    drawn += 1;
                    let rise = (c.0 + d.0 - a.0 - b.0) / 2.0;
                    if rise.abs() > max * run + 0.005 {
                        drawn_steep += 1;
                        let metre = roads.profiles.get(&element.id).map_or(0.0, |p| p.metre);
                        assert!(
                            reported(element.id, l0, l1, metre),
                            "{name}: way {} is drawn rising {:.3} per metre over {run:.1} m, \
                             over its {max}, unreported",
                            element.id,
                            rise.abs() / run
                        );
                    }
                }
            }
        }
    }
    eprintln!(
        "{segments} profile segments, {steep} steeper than their class; {drawn} drawn \
         cross-section pairs, {drawn_steep} steeper; all reported; {settled_stretches} \
         stretches settled by the LP"
    );
    assert!(
        drawn > 10_000,
        "{drawn} cross-section pairs measured in the glb"
    );
}

/// Along every cliff and retaining wall of the ten Monaco tiles, the ground on the edge of its
/// face on the high side (the way's left) stands above the edge on the low side by the step's
/// height (within 5 %: at a bend the two edges are nearest to different points of the line),
/// away from its ends (where the step fades), from sharp bends and from vertices a road, water
/// or another surface holds.
#[test]
fn cliffs_and_retaining_walls_step_the_ground() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let sources = Inputs::open(&[sample_osm()], &sample_srtm(), 14).expect("sample data");
    let (mut steps, mut pairs) = (0, 0);
    for (x, y) in TILES {
        let name = format!("14/{x}/{y}");
        let id = TileId { z: 14, x, y };
        let set = features::collect(&common::selection(&sources, id), id, &Default::default());
        if set.steps.is_empty() {
            continue;
        }
        let tile = decode(&common::render_in_process(&name, &[], dir.path()));
        let frame = id.frame();
        let size = tile.tile_size() as f32;
        let key = |x: f32, z: f32| [x.to_bits(), z.to_bits()];
        // Ground vertex elevations, and the vertices any other surface's triangles hold too.
        let mut heights: HashMap<[u32; 2], f64> = HashMap::new();
        let mut owners: HashMap<[u32; 2], std::collections::BTreeSet<u32>> = HashMap::new();
        for node in GROUND_NODES {
            for primitive in tile.primitives(node) {
                for (&p, &feature) in primitive.positions.iter().zip(&primitive.feature_ids) {
                    let e = f64::from(p[1]) / frame.scale_at(f64::from(p[2]));
                    heights.entry(key(p[0], p[2])).or_insert(e);
                    owners.entry(key(p[0], p[2])).or_default().insert(feature);
                }
            }
        }
        let at = |p: [f64; 2], feature: u32| -> Option<f64> {
            let (lx, lz) = frame.uv_to_local(p[0], p[1]);
            let (lx, lz) = (lx as f32, lz as f32);
            if lx <= 0.0 || lz <= 0.0 || lx >= size || lz >= size {
                return None;
            }
            let k = key(lx, lz);
            // Held by the face and the terrain or land cover around it, nothing else.
            let foreign = owners.get(&k)?.iter().any(|&f| {
                f != feature
                    && !matches!(
                        tile.features[f as usize].class.as_str(),
                        "terrain" | "landcover"
                    )
            });
            (!foreign).then(|| heights.get(&k).copied()).flatten()
        };
        for step in &set.steps {
            steps += 1;
            let band = step.band_m() * step.metre;
            let mut along = 0.0;
            let total: f64 = step
                .line
                .windows(2)
                .map(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]))
                .sum();
            let Some(face) = set.surfaces.iter().find(|s| s.feature == step.face) else {
                panic!("{name}: a step without its face");
            };
            for (k, piece) in face.pieces.iter().enumerate() {
                if k > 0 {
                    let (a, b) = (step.line[k - 1], step.line[k]);
                    along += (b[0] - a[0]).hypot(b[1] - a[1]);
                }
                if along < band || total - along < band {
                    continue;
                }
                let (left, right) = (piece.outer[0], piece.outer[3]);
                // At a sharp bend the face's mitred corners lie far apart, each nearest to
                // another stretch of the line.
                let width = (left[0] - right[0]).hypot(left[1] - right[1]) / step.metre;
                if width > 1.2 * step.thickness_m {
                    continue;
                }
                let (Some(high), Some(low)) = (at(left, step.face), at(right, step.face)) else {
                    continue;
                };
                pairs += 1;
                assert!(
                    high - low >= 0.95 * step.height_m,
                    "{name}: the {:?} of feature {} steps {:.2} m, {} m asked",
                    step.kind,
                    step.feature,
                    high - low,
                    step.height_m
                );
            }
        }
    }
    eprintln!("{steps} cliffs and retaining walls; {pairs} cross-sections of their faces stepped");
    assert!(pairs > 20, "{pairs} cross-sections checked");
}

/// True when `c` lies on a polygon's outline (within a few micrometres).
fn on_outline(polygon: &terrastitch::geometry::Polygon, c: [f64; 2]) -> bool {
    polygon.rings().any(|ring| {
        (0..ring.len()).any(|i| {
            let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
            terrastitch::geometry::distance_to_segment(c, a, b) < 1e-9
        })
    })
}
