//! Roads and paths (`highway=*`) as ground surfaces of their width (thesis §2.3.2).
//!
//! Width: the `width` tag, else `lanes` × the lane width, else a default per class. The paper's
//! default is 5 m for an ordinary road (seed 001 §4.4); the other defaults scale from it with the
//! usual lane counts of each class. Ways in tunnels are under the ground and not drawn on it.
//! Squares and plazas are drawn here; road ways are drawn by [`super::carriageways`], and how
//! they join into a network is [`super::road_network`]'s part.

use super::{Area, FeatureClass, FeatureSet, FeatureSettings, Projection};
use crate::osm::units::{parse_count, parse_length_m};
use crate::osm::Tags;

/// Width when nothing is tagged, by `highway` value; `None` for values that are not drawn as
/// carriageways (bus stops, proposed roads, indoor corridors…).
pub fn default_width_m(highway: &str) -> Option<f64> {
    let width = match highway {
        "motorway" | "trunk" => 10.0,
        "primary" => 8.0,
        "secondary" => 7.0,
        "tertiary" => 6.0,
        "unclassified" | "residential" | "living_street" | "road" | "pedestrian" | "raceway"
        | "busway" => 5.0,
        "motorway_link" | "trunk_link" | "primary_link" | "secondary_link" | "tertiary_link" => 5.0,
        "service" => 3.5,
        "track" => 3.0,
        "footway" | "cycleway" | "bridleway" | "steps" => 2.0,
        "path" => 1.5,
        _ => return None,
    };
    Some(width)
}

/// What a road's surface is made of, from its `surface` tag (asphalt when untagged).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Paving {
    Asphalt,
    Concrete,
    Stones,
    Unpaved,
    /// A sidewalk's paving: the bands beside a carriageway, and ways mapped as sidewalks.
    Sidewalk,
}

impl Paving {
    pub fn from_tags(tags: &Tags) -> Paving {
        if super::sidewalks::is_separate_sidewalk(tags)
            && !matches!(Paving::from_surface(tags), Paving::Unpaved)
        {
            return Paving::Sidewalk;
        }
        Paving::from_surface(tags)
    }

    /// The paving its `surface` tag (or, untagged, its class) says.
    fn from_surface(tags: &Tags) -> Paving {
        match tags.get("surface") {
            Some("concrete" | "concrete:plates" | "concrete:lanes") => Paving::Concrete,
            Some(
                "paving_stones" | "sett" | "cobblestone" | "unhewn_cobblestone" | "bricks"
                | "stone" | "marble",
            ) => Paving::Stones,
            Some(
                "unpaved" | "gravel" | "fine_gravel" | "compacted" | "dirt" | "earth" | "ground"
                | "grass" | "mud" | "sand" | "pebblestone" | "rock" | "woodchips",
            ) => Paving::Unpaved,
            // Tracks and paths are unpaved unless tagged otherwise.
            None if matches!(tags.get("highway"), Some("track" | "path" | "bridleway")) => {
                Paving::Unpaved
            }
            _ => Paving::Asphalt,
        }
    }

    pub fn as_str(self) -> &'static str {
        match self {
            Paving::Asphalt => "road_asphalt",
            Paving::Concrete => "road_concrete",
            Paving::Stones => "road_stones",
            Paving::Unpaved => "road_unpaved",
            Paving::Sidewalk => "sidewalk",
        }
    }

    /// Linear base colour and roughness.
    pub fn material(self) -> ([f32; 4], f32) {
        match self {
            Paving::Asphalt => ([0.32, 0.32, 0.34, 1.0], 0.9),
            Paving::Concrete => ([0.55, 0.55, 0.53, 1.0], 0.9),
            Paving::Stones => ([0.50, 0.44, 0.38, 1.0], 0.9),
            Paving::Unpaved => ([0.55, 0.46, 0.33, 1.0], 0.95),
            Paving::Sidewalk => ([0.62, 0.61, 0.58, 1.0], 0.9),
        }
    }
}

/// Widths outside this range (metres) are taken as tagging mistakes.
const PLAUSIBLE_WIDTH_M: std::ops::RangeInclusive<f64> = 0.5..=80.0;

/// The width of a road way in metres, `None` if the way is not a drawn road.
pub fn width_m(tags: &Tags, settings: &FeatureSettings) -> Option<f64> {
    let class_default = default_width_m(tags.get("highway")?)?;
    if let Some(width) = tags.get("width").and_then(parse_length_m) {
        if PLAUSIBLE_WIDTH_M.contains(&width) {
            return Some(width);
        }
        tracing::debug!(width, "implausible road width ignored");
    }
    if let Some(lanes) = tags.get("lanes").and_then(parse_count) {
        if (1.0..=20.0).contains(&lanes) {
            return Some(lanes.round() * settings.lane_width_m);
        }
    }
    Some(class_default)
}

/// True for the ways whose shared nodes are joints of the road network's profiles: drawn
/// roads, on the ground or not, and railways (a level crossing holds both at one height).
pub fn joins(tags: &Tags) -> bool {
    tags.get("highway")
        .is_some_and(|h| default_width_m(h).is_some())
        || tags.is_set("railway")
}

/// Squares and plazas: `highway=* + area=yes` and `area:highway=*`.
pub(super) fn add_area(set: &mut FeatureSet, area: &Area<'_>, projection: &Projection) {
    // `highway=rest_area` or `services` with `area=yes` are facilities, not paved squares.
    let is_square = area.tags.get("area:highway").is_some()
        || (area
            .tags
            .get("highway")
            .is_some_and(|h| default_width_m(h).is_some())
            && area.tags.get("area") == Some("yes"));
    if !is_square || area.tags.is_set("tunnel") {
        return;
    }
    if let Some(surface) = set.add_area_surface(area, FeatureClass::Road, projection) {
        surface.paving = Some(Paving::from_tags(area.tags));
    }
}

/// A flight of steps (`highway=steps`).
pub fn is_steps(tags: &Tags) -> bool {
    tags.get("highway") == Some("steps")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn width_prefers_the_tag_then_lanes_then_the_class() {
        let settings = FeatureSettings::default();
        let tags = |pairs: &[(&str, &str)]| Tags::from_pairs(pairs.iter().copied());
        assert_eq!(
            width_m(&tags(&[("highway", "residential")]), &settings),
            Some(5.0)
        );
        assert_eq!(
            width_m(
                &tags(&[("highway", "residential"), ("lanes", "3")]),
                &settings
            ),
            Some(10.5)
        );
        assert_eq!(
            width_m(
                &tags(&[("highway", "residential"), ("lanes", "3"), ("width", "7 m")]),
                &settings
            ),
            Some(7.0)
        );
        assert_eq!(
            width_m(
                &tags(&[("highway", "residential"), ("width", "900")]),
                &settings
            ),
            Some(5.0)
        );
        assert_eq!(width_m(&tags(&[("highway", "bus_stop")]), &settings), None);
    }

    #[test]
    fn the_surface_tag_chooses_the_paving() {
        let paving = |pairs: &[(&str, &str)]| Paving::from_tags(&Tags::from_pairs(pairs.to_vec()));
        assert_eq!(paving(&[("highway", "residential")]), Paving::Asphalt);
        assert_eq!(paving(&[("highway", "track")]), Paving::Unpaved);
        assert_eq!(
            paving(&[("highway", "track"), ("surface", "asphalt")]),
            Paving::Asphalt
        );
        assert_eq!(
            paving(&[("highway", "pedestrian"), ("surface", "sett")]),
            Paving::Stones
        );
        assert_eq!(
            paving(&[("highway", "service"), ("surface", "concrete")]),
            Paving::Concrete
        );
    }
}
