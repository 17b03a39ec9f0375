//! A tile's settled elevations as GeoJSON, so a person can see why an elevation came out as it
//! did (the debug views of the thesis, appendix A.6): every bridge and tunnel that reaches the
//! tile as a line with its stations' elevations, its connectors (the ends on the ground or
//! joined to another chain, and every station in between), and every soft constraint of its
//! linear program with how far it is from holding; and every ground road whose profile left
//! the terrain, with the soft constraints of its grade that had to give way.

use serde_json::{json, Value};

use crate::elevation::road_profiles::RoadProfiles;
use crate::elevation::structures::{plan_tunnel, ConstraintReport, Profile, Settled};
use crate::geometry::Point;
use crate::osm::structures::StructureKind;
use crate::osm::Way;
use crate::tile::{u_to_lon, v_to_lat, TileId};

/// A constraint is drawn as violated beyond this much, metres.
pub const VIOLATION_TOLERANCE_M: f64 = 0.01;

/// The GeoJSON feature collection of the settled groups that reach `tile` and of its ground
/// roads.
pub fn elevations(
    tile: TileId,
    settled: &[Settled],
    roads: &RoadProfiles,
    ways: &[Way],
    surface_margin_m: f64,
) -> Value {
    let n = tile.tiles_per_axis();
    let mut features: Vec<Value> = Vec::new();
    let (mut variables, mut constraints, mut components, mut violated) = (0, 0, 0, 0);
    for (group, outcome) in settled.iter().enumerate() {
        variables += outcome.variables;
        constraints += outcome.constraints;
        components += outcome.components;
        for (chain, profile) in outcome.profiles.iter().enumerate() {
            let feature = structure_feature(group, chain, profile, ways, surface_margin_m, n);
            features.push(feature);
            push_connectors(&mut features, profile, ways, n);
        }
        for report in &outcome.reports {
            let holds = report.violation <= VIOLATION_TOLERANCE_M;
            if !holds {
                violated += 1;
            }
            features.push(constraint_feature(report, "constraint", holds, n));
        }
    }
    push_road_profiles(&mut features, roads, n);
    let mut road_violations = 0;
    for report in &roads.violations {
        if report.violation <= VIOLATION_TOLERANCE_M {
            continue;
        }
        road_violations += 1;
        features.push(constraint_feature(report, "road_constraint", false, n));
    }
    json!({
        "type": "FeatureCollection",
        "tile": format!("{}/{}/{}", tile.z, tile.x, tile.y),
        "lp": {
            "groups": settled.len(),
            "variables": variables,
            "constraints": constraints,
            "components": components,
            "violated": violated,
        },
        "roads": {
            "stretches": roads.stretches,
            "settled": roads.settled,
            "variables": roads.variables,
            "constraints": roads.constraints,
            "components": roads.components,
            "violated": road_violations,
        },
        "features": features,
    })
}

/// A bridge or tunnel chain as a line with its stations' elevations, and for a tunnel its plan.
fn structure_feature(
    group: usize,
    chain: usize,
    profile: &Profile,
    ways: &[Way],
    surface_margin_m: f64,
    n: f64,
) -> Value {
    let mut way_ids: Vec<i64> = profile.ways.iter().map(|&w| ways[w as usize].id).collect();
    way_ids.dedup();
    let mut properties = json!({
        "layer": "structure",
        "kind": kind_name(profile.kind),
        "group": group,
        "chain": chain,
        "osm_ways": way_ids,
        "structure_layer": profile.layer,
        "grounded": profile.grounded,
        "length_m": centimetres(profile.along_m.last().copied().unwrap_or(0.0)),
        "elevations_m": profile.elevations.iter().map(|&e| centimetres(e)).collect::<Vec<_>>(),
        "terrain_m": profile.terrain.iter().map(|&e| centimetres(e)).collect::<Vec<_>>(),
    });
    if profile.kind == StructureKind::Tunnel {
        let plan = plan_tunnel(profile, ways, surface_margin_m);
        properties["ramps_m"] = json!(plan.ramps);
        properties["tube_m"] = json!(plan.tube);
        properties["raised_m"] = json!(plan.raised);
        properties["portals_m"] = json!(plan.portals);
    }
    json!({
        "type": "Feature",
        "geometry": {
            "type": "LineString",
            "coordinates": line(&profile.points, n),
        },
        "properties": properties,
    })
}

/// A point per station of the chain: its grounded or joined ends and the stations between.
fn push_connectors(features: &mut Vec<Value>, profile: &Profile, ways: &[Way], n: f64) {
    let last = profile.points.len().saturating_sub(1);
    for (i, &p) in profile.points.iter().enumerate() {
        let connector = match (i, i == last) {
            (0, _) if profile.grounded[0] => "ground",
            (_, true) if profile.grounded[1] => "ground",
            (0, _) | (_, true) => "joined",
            _ => "station",
        };
        features.push(json!({
            "type": "Feature",
            "geometry": {"type": "Point", "coordinates": position(p, n)},
            "properties": {
                "layer": "connector",
                "connector": connector,
                "kind": kind_name(profile.kind),
                "osm_way": ways[profile.ways[i] as usize].id,
                "along_m": centimetres(profile.along_m[i]),
                "elevation_m": centimetres(profile.elevations[i]),
                "terrain_m": centimetres(profile.terrain[i]),
            },
        }));
    }
}

/// A soft constraint as a point in `layer`, with its bound and how far it is from holding.
fn constraint_feature(report: &ConstraintReport, layer: &str, satisfied: bool, n: f64) -> Value {
    json!({
        "type": "Feature",
        "geometry": {"type": "Point", "coordinates": position(report.at, n)},
        "properties": {
            "layer": layer,
            "constraint": report.kind.as_str(),
            "osm_way": report.way,
            "bound_m": centimetres(report.bound),
            "violation_m": centimetres(report.violation),
            "satisfied": satisfied,
        },
    })
}

/// The ground roads whose profiles left the terrain (at some station, to the centimetre they
/// are written to), in
/// order of way id.
fn push_road_profiles(features: &mut Vec<Value>, roads: &RoadProfiles, n: f64) {
    let mut road_ids: Vec<&i64> = roads.profiles.keys().collect();
    road_ids.sort_unstable();
    for id in road_ids {
        let profile = &roads.profiles[id];
        let left = profile
            .elevations
            .iter()
            .zip(&profile.terrain)
            .any(|(&e, &t)| centimetres(e) != centimetres(t));
        if !left {
            continue;
        }
        features.push(json!({
            "type": "Feature",
            "geometry": {
                "type": "LineString",
                "coordinates": line(&profile.points, n),
            },
            "properties": {
                "layer": "road_profile",
                "osm_way": id,
                "elevations_m": profile.elevations.iter().map(|&e| centimetres(e)).collect::<Vec<_>>(),
                "terrain_m": profile.terrain.iter().map(|&e| centimetres(e)).collect::<Vec<_>>(),
            },
        }));
    }
}

/// Longitude and latitude to 1e-7 degrees (about a centimetre), for a tile zoom of `n` tiles
/// along each axis.
fn position(p: Point, n: f64) -> Value {
    let round = |v: f64| (v * 1e7).round() / 1e7;
    json!([round(u_to_lon(p[0], n)), round(v_to_lat(p[1], n))])
}

/// The coordinates of a line string.
fn line(points: &[Point], n: f64) -> Vec<Value> {
    points.iter().map(|&p| position(p, n)).collect()
}

/// Metres rounded to the centimetre.
fn centimetres(v: f64) -> f64 {
    (v * 100.0).round() / 100.0
}

fn kind_name(kind: StructureKind) -> &'static str {
    match kind {
        StructureKind::Bridge => "bridge",
        StructureKind::Tunnel => "tunnel",
    }
}
