//! Roads and railways drawn on the ground: the line a ground road runs along, the roads of a
//! tile joined into one network of surfaces with a surface per junction
//! ([`super::road_network`]), and railway beds. Ways on bridges, in tunnels, indoors or
//! underground are left to their own modules ([`super::structures::is_off_ground`]); what the
//! tags say of a road or a railway is [`super::roads`]' and [`super::railways`]' part.

use std::collections::HashMap;

use super::objects::{LitWay, ObjectKind, RoadSide};
use super::road_network::{self, RoadLine};
use super::roads::{self, Paving};
use super::structures::is_off_ground;
use super::{crossings, inference, markings, sidewalks, stop_lines, turn_arrows};
use super::{
    railways, widened_surface, FeatureClass, FeatureSet, FeatureSettings, Projection, Surface,
};
use crate::geometry::{Point, Polygon};
use crate::osm::units::parse_length_m;
use crate::osm::{ElementRef, ElementType, Node, Tags, Way};

/// The line a ground road way is drawn along, `None` for a way that is not a road on the
/// ground.
pub fn road_line(
    way: &Way,
    projection: &Projection,
    settings: &FeatureSettings,
) -> Option<RoadLine> {
    if is_off_ground(&way.tags) {
        return None;
    }
    let width = roads::width_m(&way.tags, settings)?;
    let first = way.positions.first()?;
    let mut line = RoadLine {
        nodes: Vec::with_capacity(way.nodes.len()),
        points: Vec::with_capacity(way.nodes.len()),
        half_width: projection.metres(width / 2.0, first.lat),
        metre: projection.metres(1.0, first.lat),
    };
    for (&node, &position) in way.nodes.iter().zip(&way.positions) {
        let point = projection.point(position);
        if line.points.last() != Some(&point) {
            line.nodes.push(node);
            line.points.push(point);
        }
    }
    if line.points.len() < 2 {
        tracing::debug!(way = way.id, "road of a single point; skipped");
        return None;
    }
    Some(line)
}

/// A flight of steps on the ground: its way's whole line (global tile units), its width and
/// the feature row its steps are drawn as (an object of the way's own).
#[derive(Debug, Clone)]
pub struct Stairs {
    pub feature: u32,
    pub line: Vec<Point>,
    pub width_m: f64,
    /// Tile units per metre along it.
    pub metre: f64,
}

/// What the roads leave to be placed once the rest of the tile's features are known.
pub(super) struct Carriageways {
    /// Where the signals and signs mapped on the roads stand.
    pub road_sides: Vec<RoadSide>,
    /// The bands beside the carriageways that may be sidewalks.
    pub bands: Vec<sidewalks::Candidate>,
    /// The lamps of the lit streets, where none are mapped.
    pub lit: Vec<LitWay>,
}

/// Adds the roads among `ways` as one network: a surface per way, split and cut back where
/// ways meet, and a surface per junction (traced to its OSM node). A way of steps is a road
/// of the network (its ramp) and a flight of steps over it.
pub(super) fn add_roads(
    set: &mut FeatureSet,
    ways: &[&Way],
    nodes: &[&Node],
    projection: &Projection,
    settings: &FeatureSettings,
) -> Carriageways {
    let mut lines = Vec::new();
    let mut roads: Vec<(u32, Paving, f64)> = Vec::new();
    let mut plans = Vec::new();
    let mut traffic = Vec::new();
    let mut walks = Vec::new();
    let mut lit = Vec::new();
    let mut tags_of = Vec::new();
    for way in ways {
        let Some(line) = road_line(way, projection, settings) else {
            continue;
        };
        let Some(width) = roads::width_m(&way.tags, settings) else {
            continue;
        };
        let element = ElementRef {
            element_type: ElementType::Way,
            id: way.id,
        };
        let feature = set.add_feature(Some(element), FeatureClass::Road, &way.tags);
        roads.push((feature, Paving::from_tags(&way.tags), width));
        walks.push(sidewalks::plan(&way.tags));
        // The lines painted on it are a feature of their own, shown and hidden apart.
        plans.push(markings::lane_plan(&way.tags).map(|plan| {
            let painted = set.add_feature(
                Some(element),
                FeatureClass::Marking,
                &markings::painting_tags(&way.tags),
            );
            (painted, plan)
        }));
        if roads::is_steps(&way.tags) {
            let feature = set.add_feature(Some(element), FeatureClass::Object, &way.tags);
            set.stairs.push(Stairs {
                feature,
                line: line.points.clone(),
                width_m: width,
                metre: line.metre,
            });
        }
        if lamps_inferred(&way.tags) {
            lit.push(LitWay {
                way: element,
                places: lamps_along(&line, width),
                metre: line.metre,
            });
        }
        lines.push(line);
        traffic.push(crossings::is_painted_road(&way.tags));
        tags_of.push(&way.tags);
    }
    let network = road_network::build(&lines);
    let by_id: HashMap<i64, &Node> = nodes.iter().map(|n| (n.id, *n)).collect();
    let mut halts = Halts {
        nodes: &by_id,
        features: HashMap::new(),
    };
    let mut bands = Vec::new();
    for (r, ((((feature, paving, width), road), (painted, line)), walk)) in roads
        .iter()
        .zip(network.roads)
        .zip(plans.iter().zip(&lines))
        .zip(&walks)
        .enumerate()
    {
        if let Some((painted, plan)) = painted {
            set.markings
                .extend(markings::along(*painted, &road, plan, (*width, line.metre)));
            let length = crate::geometry::polyline_length(&line.points);
            set.markings.extend(turn_arrows::of_plan(
                *painted,
                &road,
                plan,
                (*width, length, line.metre),
            ));
        }
        if traffic[r] {
            let plan = painted.as_ref().map(|p| &p.1);
            halts.paint(set, (&road, line, *width), tags_of[r], plan);
        }
        if let Some(walk) = walk {
            bands.extend(sidewalks::candidates(
                *feature, &road, walk, *width, line.metre,
            ));
        }
        if let Some(mut surface) =
            Surface::from_parts(FeatureClass::Road, *feature, road.pieces, road.outline)
        {
            surface.paving = Some(*paving);
            surface.piece_lines = road.lines;
            set.surfaces.push(surface);
        }
    }
    let no_tags = Tags::default();
    for junction in network.junctions {
        let centre = network_centre(&lines, &junction);
        let element = ElementRef {
            element_type: ElementType::Node,
            id: junction.node,
        };
        let tags = by_id.get(&junction.node).map_or(&no_tags, |n| &n.tags);
        let feature = set.add_feature(Some(element), FeatureClass::Road, tags);
        // The junction is paved like the widest road that meets there.
        let paving = junction
            .roads
            .iter()
            .map(|&r| roads[r])
            .max_by(|a, b| a.2.total_cmp(&b.2))
            .map(|r| r.1);
        let polygon = Polygon {
            outer: junction.ring,
            holes: Vec::new(),
        };
        if let Some(mut surface) =
            Surface::from_polygons(FeatureClass::Road, feature, vec![polygon])
        {
            surface.paving = paving;
            surface.junction_at = centre;
            set.surfaces.push(surface);
        }
    }
    let widths: Vec<f64> = roads.iter().map(|r| r.2).collect();
    add_crossings(set, (&lines, &widths, &traffic), nodes);
    Carriageways {
        road_sides: road_sides(&lines, &widths, &traffic, nodes),
        bands,
        lit,
    }
}

/// The stop and give-way lines of the roads: the tags of the nodes, and the feature row of
/// each node that has lines (one however many ways pass it).
struct Halts<'a> {
    nodes: &'a HashMap<i64, &'a Node>,
    features: HashMap<i64, u32>,
}

impl Halts<'_> {
    /// Paints the lines before the halts on one road (its surface, line and width in metres)
    /// with these tags and lanes.
    fn paint(
        &mut self,
        set: &mut FeatureSet,
        (road, line, width): (&road_network::RoadSurface, &RoadLine, f64),
        tags: &Tags,
        plan: Option<&markings::LanePlan>,
    ) {
        let found: Vec<(usize, stop_lines::Halt, &Tags)> = line
            .nodes
            .iter()
            .enumerate()
            .filter_map(|(k, id)| {
                let tags = &self.nodes.get(id)?.tags;
                Some((k, stop_lines::Halt::from_tags(tags)?, tags))
            })
            .collect();
        if found.is_empty() {
            return;
        }
        let stations = crate::geometry::distances_along(&line.points);
        let crossings: Vec<_> = line
            .nodes
            .iter()
            .zip(&stations)
            .filter_map(|(id, &station)| {
                let node = self.nodes.get(id)?;
                let paint = crossings::paint(&node.tags, inference::Region::of(node.position))?;
                Some((station, paint))
            })
            .collect();
        let split = plan.map_or(0.5, |p| p.centre_share(width));
        let flow = stop_lines::Flow::of(tags, split);
        for (k, halt, node_tags) in found {
            let at = stop_lines::HaltAt {
                halt,
                tags: node_tags,
                k,
                count: line.nodes.len(),
                station: stations[k],
            };
            let ends = stop_lines::lines(road, flow, &at, &crossings, (width, line.metre));
            if ends.is_empty() {
                continue;
            }
            let feature = *self.features.entry(line.nodes[k]).or_insert_with(|| {
                let element = ElementRef {
                    element_type: ElementType::Node,
                    id: line.nodes[k],
                };
                set.add_feature(Some(element), FeatureClass::Marking, node_tags)
            });
            set.markings.extend(
                ends.into_iter()
                    .map(|e| stop_lines::marking(feature, halt, e, line.metre)),
            );
        }
    }
}

/// Spacing of the lamps of a lit street where none are mapped, metres.
const LAMP_SPACING_M: f64 = 30.0;

/// True for a street whose lamps are drawn where none are mapped beside it: `lit=yes` on a
/// street of a town (not a motorway or a trunk road, whose lamps stand on the median).
fn lamps_inferred(tags: &Tags) -> bool {
    tags.get("lit") == Some("yes")
        && matches!(
            tags.get("highway"),
            Some(
                "primary"
                    | "secondary"
                    | "tertiary"
                    | "primary_link"
                    | "secondary_link"
                    | "tertiary_link"
                    | "residential"
                    | "living_street"
                    | "unclassified"
                    | "pedestrian"
            )
        )
}

/// The lamps along a lit way `width_m` wide: one every [`LAMP_SPACING_M`] along its line from
/// half a spacing past its first node, on the right of the way half a metre beyond its edge,
/// facing the road.
fn lamps_along(line: &RoadLine, width_m: f64) -> Vec<(Point, f64)> {
    let stations = crate::geometry::distances_along(&line.points);
    let Some(&length) = stations.last() else {
        return Vec::new();
    };
    let spacing = LAMP_SPACING_M * line.metre;
    let offset = (width_m / 2.0 + POLE_CLEARANCE_M) * line.metre;
    let mut places = Vec::new();
    let mut along = spacing / 2.0;
    while along < length && spacing > 0.0 {
        let (k, t) = crate::geometry::bracket(&stations, along);
        let (a, b) = (line.points[k - 1], line.points[k]);
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let run = dx.hypot(dy);
        along += spacing;
        if run <= 0.0 {
            continue;
        }
        let d = [dx / run, dy / run];
        let p = crate::geometry::lerp(a, b, t);
        // Right of the way (x east, y south): (-dy, dx); facing the road, left of that.
        let at = [p[0] - d[1] * offset, p[1] + d[0] * offset];
        let facing = [d[1], -d[0]];
        places.push((at, -facing[0].atan2(-facing[1])));
    }
    places
}

/// Clearance between a road's edge and a signal's pole, metres.
const POLE_CLEARANCE_M: f64 = 0.5;

/// The places of the signals, signs and bus stops mapped on the nodes of the roads for traffic
/// among `lines`: at the right edge for the traffic they serve (`direction` or
/// `traffic_signals:direction` `forward`/`backward`); signals without a direction on both
/// edges, a sign without one for the traffic towards the nearer end of its way, a bus stop
/// without one for the traffic along its way.
fn road_sides(
    lines: &[RoadLine],
    widths: &[f64],
    traffic: &[bool],
    nodes: &[&Node],
) -> Vec<RoadSide> {
    let kinds: HashMap<i64, (ObjectKind, &Tags)> = nodes
        .iter()
        .filter_map(|n| {
            let kind = ObjectKind::from_tags(&n.tags)?;
            kind.stands_beside_the_road()
                .then_some((n.id, (kind, &n.tags)))
        })
        .collect();
    let mut places = Vec::new();
    let mut placed = std::collections::HashSet::new();
    for ((line, &width), _) in lines.iter().zip(widths).zip(traffic).filter(|(_, &t)| t) {
        for (k, id) in line.nodes.iter().enumerate() {
            let Some(&(kind, tags)) = kinds.get(id) else {
                continue;
            };
            let Some(forward) = direction_at(line, k).filter(|_| placed.insert(*id)) else {
                continue;
            };
            let tagged = tags
                .get("traffic_signals:direction")
                .or_else(|| tags.get("direction"));
            let bus_stop = matches!(kind, ObjectKind::BusStop | ObjectKind::BusShelter);
            let ways: &[f64] = match tagged {
                Some("forward") => &[1.0],
                Some("backward") => &[-1.0],
                _ if kind == ObjectKind::TrafficSignals => &[1.0, -1.0],
                _ if bus_stop || 2 * k >= line.points.len() => &[1.0],
                _ => &[-1.0],
            };
            let offset = (width / 2.0 + POLE_CLEARANCE_M) * line.metre;
            for &sense in ways {
                let d = [forward[0] * sense, forward[1] * sense];
                // Right of the traffic (x east, y south): (-dy, dx).
                let at = [
                    line.points[k][0] - d[1] * offset,
                    line.points[k][1] + d[0] * offset,
                ];
                // A signal or sign faces the oncoming traffic (-d), a bus stop the road (left of
                // d); the rotation is the compass bearing of that facing, turned the other way.
                let facing = if bus_stop {
                    [d[1], -d[0]]
                } else {
                    [-d[0], -d[1]]
                };
                let bearing = facing[0].atan2(-facing[1]);
                places.push(RoadSide {
                    node: *id,
                    at,
                    rotation: -bearing,
                });
            }
        }
    }
    places
}

/// Paints the crossings on the roads for traffic among `lines` (each with its width, metres,
/// and whether it carries traffic): one feature a crossing node, however many ways share it.
fn add_crossings(
    set: &mut FeatureSet,
    (lines, widths, traffic): (&[RoadLine], &[f64], &[bool]),
    nodes: &[&Node],
) {
    let crossing_nodes: HashMap<i64, &Node> = nodes
        .iter()
        .filter(|n| n.tags.is_set("crossing") || n.tags.get("highway") == Some("crossing"))
        .map(|n| (n.id, *n))
        .collect();
    if crossing_nodes.is_empty() {
        return;
    }
    let mut painted = std::collections::HashSet::new();
    for ((line, &width), _) in lines.iter().zip(widths).zip(traffic).filter(|(_, &t)| t) {
        for (k, id) in line.nodes.iter().enumerate() {
            let Some(node) = crossing_nodes.get(id) else {
                continue;
            };
            let region = inference::Region::of(node.position);
            let Some(paint) = crossings::paint(&node.tags, region) else {
                continue;
            };
            let Some(direction) = direction_at(line, k).filter(|_| painted.insert(*id)) else {
                continue;
            };
            let element = ElementRef {
                element_type: ElementType::Node,
                id: *id,
            };
            let feature = set.add_feature(Some(element), FeatureClass::Marking, &node.tags);
            set.markings.extend(crossings::strips(
                feature,
                paint,
                line.points[k],
                direction,
                width,
                line.metre,
            ));
        }
    }
}

/// The unit direction of a road's line at its `k`-th point (from the point before to the one
/// after); `None` where the line has no length there.
fn direction_at(line: &RoadLine, k: usize) -> Option<[f64; 2]> {
    let (before, after) = (
        line.points[k.saturating_sub(1)],
        line.points[(k + 1).min(line.points.len() - 1)],
    );
    let (dx, dy) = (after[0] - before[0], after[1] - before[1]);
    let length = dx.hypot(dy);
    (length > 0.0).then(|| [dx / length, dy / length])
}

/// The point of a junction's node.
fn network_centre(lines: &[RoadLine], junction: &road_network::Junction) -> Option<Point> {
    junction.roads.iter().find_map(|&r| {
        let line = &lines[r];
        let k = line.nodes.iter().position(|&n| n == junction.node)?;
        Some(line.points[k])
    })
}

pub(super) fn add_railway(set: &mut FeatureSet, way: &Way, projection: &Projection) {
    let Some(railway) = way.tags.get("railway") else {
        return;
    };
    if !railways::drawn(railway) || is_off_ground(&way.tags) {
        return;
    }
    let width = way
        .tags
        .get("width")
        .and_then(parse_length_m)
        .filter(|w| (0.5..=30.0).contains(w))
        .unwrap_or_else(|| {
            railways::width_m(way.tags.get("gauge"), railways::is_embedded(&way.tags))
        });
    let line = projection.points(&way.positions);
    let half_width = projection.metres(width / 2.0, way.positions[0].lat);
    let element = ElementRef {
        element_type: ElementType::Way,
        id: way.id,
    };
    let feature = set.add_feature(Some(element), FeatureClass::Railway, &way.tags);
    match widened_surface(FeatureClass::Railway, feature, &line, half_width) {
        Some(mut surface) => {
            surface.embedded = railways::is_embedded(&way.tags);
            set.surfaces.push(surface);
        }
        None => {
            set.features.pop();
        }
    }
}
