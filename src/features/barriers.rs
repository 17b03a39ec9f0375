//! Barriers and edges: walls, fences, hedges, retaining walls and city walls, drawn as thin
//! walls standing on the ground along their ways; cliffs and retaining walls are also recorded as
//! places where the ground changes height abruptly (thesis §2.3.5), for the elevation stage.

use super::{FeatureClass, FeatureSet, Projection};
use crate::geometry::{Point, Rect};
use crate::osm::units::parse_length_m;
use crate::osm::{ElementRef, ElementType, Tags, Way};

/// A kind of barrier, with its usual height and thickness.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum BarrierKind {
    Wall,
    Fence,
    Hedge,
    RetainingWall,
    CityWall,
}

impl BarrierKind {
    pub fn from_tags(tags: &Tags) -> Option<BarrierKind> {
        if tags.get("historic") == Some("city_walls") {
            return Some(BarrierKind::CityWall);
        }
        Some(match tags.get("barrier")? {
            "wall" => BarrierKind::Wall,
            "fence" | "guard_rail" | "railing" | "handrail" => BarrierKind::Fence,
            "hedge" => BarrierKind::Hedge,
            "retaining_wall" => BarrierKind::RetainingWall,
            "city_wall" => BarrierKind::CityWall,
            _ => return None,
        })
    }

    pub fn as_str(self) -> &'static str {
        match self {
            BarrierKind::Wall => "wall",
            BarrierKind::Fence => "fence",
            BarrierKind::Hedge => "hedge",
            BarrierKind::RetainingWall => "retaining_wall",
            BarrierKind::CityWall => "city_wall",
        }
    }

    /// Height and thickness in metres when untagged.
    pub fn size_m(self) -> (f64, f64) {
        match self {
            BarrierKind::Wall => (1.8, 0.3),
            BarrierKind::Fence => (1.2, 0.06),
            BarrierKind::Hedge => (1.5, 0.8),
            BarrierKind::RetainingWall => (1.5, 0.4),
            BarrierKind::CityWall => (6.0, 1.5),
        }
    }

    /// Linear base colour and roughness.
    pub fn material(self) -> ([f32; 4], f32) {
        match self {
            BarrierKind::Wall => ([0.55, 0.52, 0.47, 1.0], 0.9),
            BarrierKind::Fence => ([0.35, 0.27, 0.18, 1.0], 0.8),
            BarrierKind::Hedge => ([0.12, 0.28, 0.10, 1.0], 0.95),
            BarrierKind::RetainingWall => ([0.60, 0.59, 0.56, 1.0], 0.9),
            BarrierKind::CityWall => ([0.66, 0.58, 0.45, 1.0], 0.9),
        }
    }
}

/// A barrier to stand on the ground.
#[derive(Debug, Clone, PartialEq)]
pub struct Barrier {
    pub kind: BarrierKind,
    /// The way in global tile units.
    pub line: Vec<Point>,
    pub height_m: f64,
    pub thickness_m: f64,
    pub feature: u32,
}

/// Why the ground changes height abruptly along a line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EdgeKind {
    /// `natural=cliff`: the land is higher on the left of the way.
    Cliff,
    /// `barrier=retaining_wall`: the land is higher on the left of the way.
    RetainingWall,
}

/// A line where the ground steps, for the elevation stage.
#[derive(Debug, Clone, PartialEq)]
pub struct GroundStep {
    pub kind: EdgeKind,
    /// Global tile units, the high side on the left.
    pub line: Vec<Point>,
    /// How much higher the left side stands than the right, metres.
    pub height_m: f64,
    /// The width of the face between the two sides, metres (a wall's thickness).
    pub thickness_m: f64,
    /// One metre in tile units where the step is.
    pub metre: f64,
    /// The feature row of the way (a barrier's, or the cliff's own).
    pub feature: u32,
    /// The feature row of its face, drawn in the ground.
    pub face: u32,
}

impl GroundStep {
    /// How far from its line (and from its ends, along it) the step changes the ground,
    /// metres: twice its height, and at least 3 m.
    pub fn band_m(&self) -> f64 {
        (2.0 * self.height_m).max(3.0)
    }

    /// The box around the ground the step changes, tile units.
    pub fn reach(&self) -> Rect {
        let around = Rect::around(&self.line);
        let band = self.band_m() * self.metre;
        Rect {
            min: [around.min[0] - band, around.min[1] - band],
            max: [around.max[0] + band, around.max[1] + band],
        }
    }
}

/// A cliff's height when untagged, metres (the SRTM surface already falls across a large one).
const DEFAULT_CLIFF_HEIGHT_M: f64 = 3.0;
/// The width of a cliff's face, metres.
const CLIFF_FACE_M: f64 = 0.5;

/// The `height` tag, if plausible (metres).
fn height_tag(tags: &crate::osm::Tags) -> Option<f64> {
    tags.get("height")
        .and_then(parse_length_m)
        .filter(|h| (0.2..=50.0).contains(h))
}

/// A step's face, drawn as bare rock in the ground between its two sides (a land-cover row of
/// the way in the feature table), so the ground's triangulation has an edge on each side.
fn add_face(set: &mut FeatureSet, step: &mut GroundStep, way: &Way) {
    let element = ElementRef {
        element_type: ElementType::Way,
        id: way.id,
    };
    step.face = set.add_feature(Some(element), FeatureClass::LandCover, &way.tags);
    let half = step.thickness_m / 2.0 * step.metre;
    if let Some(mut surface) =
        super::widened_surface(FeatureClass::LandCover, step.face, &step.line, half)
    {
        surface.cover = Some(super::landcover::Cover::BareRock);
        set.surfaces.push(surface);
    }
}

pub(super) fn add_way(set: &mut FeatureSet, way: &Way, projection: &Projection) {
    let element = ElementRef {
        element_type: ElementType::Way,
        id: way.id,
    };
    let line = projection.points(&way.positions);
    let Some(lat) = way.positions.first().map(|p| p.lat) else {
        return;
    };
    if way.tags.get("natural") == Some("cliff") {
        let mut step = GroundStep {
            kind: EdgeKind::Cliff,
            line,
            height_m: height_tag(&way.tags).unwrap_or(DEFAULT_CLIFF_HEIGHT_M),
            thickness_m: CLIFF_FACE_M,
            metre: projection.metres(1.0, lat),
            feature: 0,
            face: 0,
        };
        add_face(set, &mut step, way);
        step.feature = step.face;
        set.steps.push(step);
        return;
    }
    let Some(kind) = BarrierKind::from_tags(&way.tags) else {
        return;
    };
    if way.tags.get("location") == Some("underground") || way.tags.is_set("tunnel") {
        return;
    }
    let (default_height, default_thickness) = kind.size_m();
    let height_m = height_tag(&way.tags)
        .filter(|h| *h <= 30.0)
        .unwrap_or(default_height);
    let thickness_m = way
        .tags
        .get("width")
        .and_then(parse_length_m)
        .filter(|w| (0.02..=10.0).contains(w))
        .unwrap_or(default_thickness);
    let feature = set.add_feature(Some(element), FeatureClass::Barrier, &way.tags);
    if kind == BarrierKind::RetainingWall {
        // The wall stands on the low side and its top is the high side's ground.
        let mut step = GroundStep {
            kind: EdgeKind::RetainingWall,
            line: line.clone(),
            height_m,
            thickness_m,
            metre: projection.metres(1.0, lat),
            feature,
            face: 0,
        };
        add_face(set, &mut step, way);
        set.steps.push(step);
    }
    set.barriers.push(Barrier {
        kind,
        line,
        height_m,
        thickness_m,
        feature,
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tags_choose_the_barrier() {
        let kind =
            |pairs: &[(&str, &str)]| BarrierKind::from_tags(&Tags::from_pairs(pairs.to_vec()));
        assert_eq!(kind(&[("barrier", "fence")]), Some(BarrierKind::Fence));
        assert_eq!(kind(&[("barrier", "hedge")]), Some(BarrierKind::Hedge));
        assert_eq!(
            kind(&[("historic", "city_walls"), ("barrier", "wall")]),
            Some(BarrierKind::CityWall)
        );
        assert_eq!(kind(&[("barrier", "gate")]), None);
        assert_eq!(kind(&[("highway", "residential")]), None);
    }
}
