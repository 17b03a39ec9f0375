//! Water: areas (`natural=water`, `waterway=riverbank`, `landuse=reservoir|basin`) and
//! waterways as surfaces of their width (thesis §2.3.3). Where a waterway runs inside a water
//! area (a river with its riverbank mapped, a stream into the sea), the area alone is drawn,
//! and a river's area runs down along the waterway in it.

use super::{widened_surface, Area, FeatureClass, FeatureSet, Projection, Surface};
use crate::geometry::{Point, Polygon};
use crate::osm::units::parse_length_m;
use crate::osm::{ElementRef, ElementType, Tags, Way};

pub fn is_water_area(tags: &Tags) -> bool {
    tags.get("natural") == Some("water")
        || tags.get("waterway") == Some("riverbank")
        || matches!(tags.get("landuse"), Some("reservoir" | "basin"))
        || tags
            .get("water")
            .is_some_and(|_| tags.get("natural") == Some("water"))
}

/// Default width of a waterway in metres, `None` for values not drawn.
pub fn default_width_m(waterway: &str) -> Option<f64> {
    Some(match waterway {
        "river" => 10.0,
        "canal" => 8.0,
        "stream" => 2.0,
        "ditch" | "drain" => 1.0,
        _ => return None,
    })
}

/// How the water of a surface lies, as its tags say.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WaterBody {
    /// Tagged `waterway=*`: runs down along its centreline.
    Flowing,
    /// A river's area (`waterway=riverbank`, `natural=water` with `water=river|stream|rapids`):
    /// level across, running down along the waterway inside it.
    River,
    /// The sea, at sea level.
    Sea,
    /// Anything else: lies flat.
    Still,
}

impl WaterBody {
    pub fn of(tags: &Tags) -> WaterBody {
        let river_water = matches!(tags.get("water"), Some("river" | "stream" | "rapids"));
        if tags.get("waterway") == Some("riverbank")
            || (tags.get("natural") == Some("water") && river_water)
        {
            WaterBody::River
        } else if tags.is_set("waterway") {
            WaterBody::Flowing
        } else if tags.get("natural") == Some("sea") {
            WaterBody::Sea
        } else {
            WaterBody::Still
        }
    }
}

pub(super) fn add_area(set: &mut FeatureSet, area: &Area<'_>, projection: &Projection) {
    if !is_water_area(area.tags) || area.tags.is_set("tunnel") {
        return;
    }
    if let Some(surface) = set.add_area_surface(area, FeatureClass::Water, projection) {
        surface.water = Some(WaterBody::of(area.tags));
    }
}

pub(super) fn add_waterway(set: &mut FeatureSet, way: &Way, projection: &Projection) {
    let Some(default) = way.tags.get("waterway").and_then(default_width_m) else {
        return;
    };
    if way.tags.is_set("tunnel") {
        return;
    }
    let width = way
        .tags
        .get("width")
        .and_then(parse_length_m)
        .filter(|w| (0.3..=500.0).contains(w))
        .unwrap_or(default);
    let line = projection.points(&way.positions);
    let half_width = projection.metres(width / 2.0, way.positions[0].lat);
    let element = ElementRef {
        element_type: ElementType::Way,
        id: way.id,
    };
    let feature = set.add_feature(Some(element), FeatureClass::Water, &way.tags);
    match widened_surface(FeatureClass::Water, feature, &line, half_width) {
        Some(mut surface) => {
            surface.water = Some(WaterBody::of(&way.tags));
            set.surfaces.push(surface);
        }
        None => {
            set.features.pop();
        }
    }
}

/// True for the surface of a waterway drawn at its width (rather than a water area).
fn is_waterway(set: &FeatureSet, surface: &Surface) -> bool {
    surface.class == FeatureClass::Water
        && set.features[surface.feature as usize]
            .tags
            .get("waterway")
            .is_some_and(|w| default_width_m(w).is_some())
}

/// Gives each river area the line of the waterway that runs furthest inside it (the longest
/// stretch; the smaller way id between equals), the line its water runs down along. An area
/// no waterway runs in keeps no line (and lies flat).
fn follow_waterways_in_river_areas(set: &mut FeatureSet) {
    let waterways: Vec<(i64, &[Point])> = set
        .surfaces
        .iter()
        .filter(|s| is_waterway(set, s) && s.centreline.len() >= 2)
        .map(|s| {
            let id = set.features[s.feature as usize]
                .element
                .map_or(i64::MAX, |e| e.id);
            (id, s.centreline.as_slice())
        })
        .collect();
    let mut lines: Vec<(usize, Vec<Point>)> = Vec::new();
    for (index, area) in set.surfaces.iter().enumerate() {
        if area.water != Some(WaterBody::River) || is_waterway(set, area) {
            continue;
        }
        // The length of a line's segments with both ends in the area (each point tested once).
        let inside = |line: &[Point]| -> f64 {
            let within: Vec<bool> = line.iter().map(|&p| area.contains(p)).collect();
            line.windows(2)
                .zip(within.windows(2))
                .filter(|(_, ends)| ends[0] && ends[1])
                .map(|(pair, _)| (pair[1][0] - pair[0][0]).hypot(pair[1][1] - pair[0][1]))
                .sum()
        };
        let best = waterways
            .iter()
            .map(|&(id, line)| (inside(line), id, line))
            .filter(|&(length, _, _)| length > 0.0)
            .max_by(|a, b| a.0.total_cmp(&b.0).then(b.1.cmp(&a.1)));
        if let Some((_, _, line)) = best {
            lines.push((index, line.to_vec()));
        }
    }
    for (index, line) in lines {
        set.surfaces[index].centreline = line;
    }
}

/// Removes the stretches of waterways that lie inside water areas, so the water is drawn once
/// and its ground is not cut by the waterway's edges; a waterway wholly inside loses its surface.
/// A river area takes first the line of the waterway that runs in it.
pub(super) fn drop_waterways_in_water_areas(set: &mut FeatureSet) {
    follow_waterways_in_river_areas(set);
    let areas: Vec<usize> = (0..set.surfaces.len())
        .filter(|&i| {
            set.surfaces[i].class == FeatureClass::Water && !is_waterway(set, &set.surfaces[i])
        })
        .collect();
    if areas.is_empty() {
        return;
    }
    let in_water = |p: Point, surfaces: &[Surface]| areas.iter().any(|&i| surfaces[i].contains(p));
    // The waterways that run into water areas, each with what is left of it outside them (none
    // when nothing is); the other surfaces stay as they are.
    let mut trimmed: std::collections::BTreeMap<usize, Option<Surface>> = Default::default();
    for (index, surface) in set.surfaces.iter().enumerate() {
        if areas.contains(&index)
            || !is_waterway(set, surface)
            || !areas
                .iter()
                .any(|&i| set.surfaces[i].bounds.intersects(&surface.bounds))
        {
            continue;
        }
        // The quads run along the waterway: [left i, left i+1, right i+1, right i].
        let outside: Vec<bool> = surface
            .pieces
            .iter()
            .map(|quad| !quad.outer.iter().all(|&p| in_water(p, &set.surfaces)))
            .collect();
        if outside.iter().all(|&o| o) {
            continue;
        }
        trimmed.insert(index, outside_water(surface, &outside));
    }
    if trimmed.is_empty() {
        return;
    }
    set.surfaces = std::mem::take(&mut set.surfaces)
        .into_iter()
        .enumerate()
        .filter_map(|(index, surface)| match trimmed.remove(&index) {
            Some(left) => left,
            None => Some(surface),
        })
        .collect();
}

/// What is left of a waterway's surface of quads outside water areas (`outside`: each quad's),
/// with the outline of each run of quads left.
fn outside_water(surface: &Surface, outside: &[bool]) -> Option<Surface> {
    let mut pieces: Vec<Polygon> = Vec::new();
    let mut outline: Vec<Vec<Point>> = Vec::new();
    let mut run: Vec<&Polygon> = Vec::new();
    let close = |run: &mut Vec<&Polygon>, outline: &mut Vec<Vec<Point>>| {
        if let (Some(first), Some(last)) = (run.first(), run.last()) {
            let mut left = vec![first.outer[0]];
            let mut right = vec![first.outer[3]];
            left.extend(run.iter().map(|q| q.outer[1]));
            right.extend(run.iter().map(|q| q.outer[2]));
            outline.push(left);
            outline.push(right);
            outline.push(vec![first.outer[0], first.outer[3]]);
            outline.push(vec![last.outer[1], last.outer[2]]);
        }
        run.clear();
    };
    for (quad, &keep) in surface.pieces.iter().zip(outside) {
        if keep {
            run.push(quad);
            pieces.push(quad.clone());
        } else {
            close(&mut run, &mut outline);
        }
    }
    close(&mut run, &mut outline);
    let mut trimmed = Surface::from_parts(FeatureClass::Water, surface.feature, pieces, outline)?;
    // The water still runs down the whole way.
    trimmed.centreline.clone_from(&surface.centreline);
    trimmed.water = surface.water;
    Some(trimmed)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::osm::Tags;

    #[test]
    fn a_river_area_follows_the_waterway_that_runs_furthest_in_it() {
        let mut set = FeatureSet::default();
        let tags = Tags::from_pairs([("waterway", "riverbank")]);
        let bank = set.add_feature(None, FeatureClass::Water, &tags);
        let square = Polygon {
            outer: vec![[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]],
            holes: Vec::new(),
        };
        let mut area =
            Surface::from_polygons(FeatureClass::Water, bank, vec![square]).expect("a surface");
        area.water = Some(WaterBody::of(&tags));
        set.surfaces.push(area);
        let stream = [[1.0, 1.0], [3.0, 1.0]];
        let river = [[12.0, 5.0], [8.0, 5.0], [2.0, 5.0], [-3.0, 5.0]];
        for (kind, line) in [("stream", &stream[..]), ("river", &river[..])] {
            let feature = set.add_feature(
                None,
                FeatureClass::Water,
                &Tags::from_pairs([("waterway", kind)]),
            );
            let mut surface =
                widened_surface(FeatureClass::Water, feature, line, 0.5).expect("a surface");
            surface.centreline = line.to_vec();
            set.surfaces.push(surface);
        }
        drop_waterways_in_water_areas(&mut set);
        assert_eq!(set.surfaces[0].water, Some(WaterBody::River));
        assert_eq!(set.surfaces[0].centreline, river.to_vec());
    }

    #[test]
    fn a_river_inside_its_riverbank_is_drawn_once() {
        let mut set = FeatureSet::default();
        set.add_feature(None, FeatureClass::Terrain, &Tags::default());
        let bank = set.add_feature(
            None,
            FeatureClass::Water,
            &Tags::from_pairs([("waterway", "riverbank")]),
        );
        let river = set.add_feature(
            None,
            FeatureClass::Water,
            &Tags::from_pairs([("waterway", "river")]),
        );
        let square = Polygon {
            outer: vec![[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]],
            holes: Vec::new(),
        };
        set.surfaces.push(
            Surface::from_polygons(FeatureClass::Water, bank, vec![square]).expect("a surface"),
        );
        // A river from inside the bank area out past its east side, in three stretches.
        let line = [[2.0, 5.0], [6.0, 5.0], [9.0, 5.0], [14.0, 5.0]];
        set.surfaces
            .push(widened_surface(FeatureClass::Water, river, &line, 0.5).expect("a surface"));
        drop_waterways_in_water_areas(&mut set);
        assert_eq!(set.surfaces.len(), 2);
        let trimmed = &set.surfaces[1];
        // Only the stretch that leaves the area is left, with its own outline.
        assert_eq!(trimmed.pieces.len(), 1);
        assert_eq!(trimmed.pieces[0].outer[0], [9.0, 4.5]);
        assert_eq!(trimmed.outline.len(), 4);
        assert!(!trimmed.contains([4.0, 5.0]));
        assert!(trimmed.contains([12.0, 5.0]));
    }
}
