//! Sidewalks beside the roads on the ground, raised by a kerb, and the verges in their place
//! where a road runs outside built-up land.
//!
//! A road's `sidewalk` tags (`sidewalk=both|left|right|no|separate`, `sidewalk:both`,
//! `sidewalk:left`, `sidewalk:right`, their `:width` and `:kerb`, `kerb:height`) say which sides
//! have one. Untagged, residential streets and roads of tertiary class and up (not trunk roads
//! or motorways) have one on each side where they run through built-up land. A sidewalk is a
//! band along the edge of the road's surface as drawn, outside it, so the road, its junctions
//! and its settled profile are the same whatever its sides show. Each stretch of a band, at
//! most [`PIECE_M`] long, decides for itself what it shows from what lies around it: a raised
//! sidewalk in built-up land (or where the tags map one), a flat verge outside it, nothing
//! where a separately mapped sidewalk (`footway=sidewalk`) runs beside it or where it would lie
//! on water, a railway or another road. A tile sees everything within the query margin around
//! it, so every tile that draws a stretch decides it alike.

use super::road_network::RoadSurface;
use super::{landcover::Cover, FeatureClass, FeatureSet};
use crate::geometry::{
    distance, distance_to_segment, lerp, ring_contains, segments_meet, Point, Rect,
};
use crate::osm::units::parse_length_m;
use crate::osm::{Tags, Way};

/// The longest stretch of a band that decides alone what it shows, metres.
pub const PIECE_M: f64 = 20.0;
/// Widths of a sidewalk outside this range (metres) are taken as tagging mistakes.
const PLAUSIBLE_WIDTH_M: std::ops::RangeInclusive<f64> = 0.5..=6.0;
/// Kerb heights outside this range (metres) are taken as tagging mistakes.
const PLAUSIBLE_KERB_M: std::ops::RangeInclusive<f64> = 0.0..=0.4;
/// How near a building's corners must be, metres, to count it as standing by a stretch.
const BUILT_UP_REACH_M: f64 = 40.0;
/// Buildings that make the land around a stretch built-up.
const BUILT_UP_BUILDINGS: usize = 3;
/// How far beside a band a separately mapped sidewalk is taken as the band's, metres.
const SEPARATE_REACH_M: f64 = 6.0;

/// What one side of a road has, by its tags.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    /// A sidewalk the tags map.
    Mapped,
    /// A sidewalk where the land is built-up: the tags say nothing.
    Untagged,
    /// Mapped as its own way, or mapped as absent: no band.
    None,
}

/// The sidewalks a road's tags allow: a side each, its width and its kerb.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SidewalkPlan {
    pub left: Side,
    pub right: Side,
    /// The width of the band on each side of the road, metres.
    pub width_m: f64,
    /// The kerb's height, metres.
    pub kerb_m: f64,
}

/// The sidewalks of a road from its tags; `None` for a road with no band on either side.
pub fn plan(tags: &Tags) -> Option<SidewalkPlan> {
    let highway = tags.get("highway")?;
    let major = matches!(highway, "primary" | "secondary" | "tertiary");
    let street = highway == "residential";
    let tagged = |key: &str| -> Option<Side> {
        match tags.get(key)? {
            "yes" => Some(Side::Mapped),
            "no" | "none" | "separate" => Some(Side::None),
            other => {
                tracing::debug!(key, value = other, "sidewalk value not understood");
                None
            }
        }
    };
    let (left, right) = match tags.get("sidewalk") {
        Some("both" | "yes") => (Side::Mapped, Side::Mapped),
        Some("left") => (Side::Mapped, Side::None),
        Some("right") => (Side::None, Side::Mapped),
        Some("no" | "none" | "separate") => (Side::None, Side::None),
        _ => {
            let both = tagged("sidewalk:both");
            let untagged = if (major || street)
                && tags.get("area") != Some("yes")
                && tags.get("foot") != Some("no")
            {
                Side::Untagged
            } else {
                Side::None
            };
            let side = |key| tagged(key).or(both).unwrap_or(untagged);
            (side("sidewalk:left"), side("sidewalk:right"))
        }
    };
    if left == Side::None && right == Side::None {
        return None;
    }
    let length = |keys: &[&str], plausible: &std::ops::RangeInclusive<f64>| {
        keys.iter()
            .filter_map(|k| tags.get(k).and_then(parse_length_m))
            .find(|w| plausible.contains(w))
    };
    let width_m = length(
        &[
            "sidewalk:both:width",
            "sidewalk:width",
            "sidewalk:left:width",
            "sidewalk:right:width",
        ],
        &PLAUSIBLE_WIDTH_M,
    )
    .unwrap_or(if street { 1.5 } else { 2.0 });
    let kerb_m = length(&["kerb:height", "sidewalk:kerb:height"], &PLAUSIBLE_KERB_M)
        .or_else(|| {
            let kerb = ["sidewalk:both:kerb", "sidewalk:kerb", "kerb"]
                .iter()
                .find_map(|k| tags.get(k))?;
            match kerb {
                "raised" => Some(0.15),
                "regular" => Some(0.12),
                "lowered" => Some(0.04),
                "flush" | "no" => Some(0.0),
                _ => None,
            }
        })
        .unwrap_or(if street { 0.12 } else { 0.15 });
    Some(SidewalkPlan {
        left,
        right,
        width_m,
        kerb_m,
    })
}

/// What a stretch of band shows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Look {
    /// A sidewalk raised by a kerb of this height, metres.
    Sidewalk { kerb_m: f64 },
    /// A strip of grass along a road outside built-up land.
    Verge,
}

/// A run of stretches of one band that look alike: its edge along the road and its outer edge
/// (global tile units, point for point).
#[derive(Debug, Clone, PartialEq)]
pub struct Band {
    /// The road's row in the feature table.
    pub feature: u32,
    pub inner: Vec<Point>,
    pub outer: Vec<Point>,
    pub look: Look,
    /// One metre in tile units where it lies.
    pub metre: f64,
}

/// A band a road's tags allow, before what it shows is decided.
#[derive(Debug, Clone, PartialEq)]
pub struct Candidate {
    pub feature: u32,
    pub side: Side,
    pub inner: Vec<Point>,
    pub outer: Vec<Point>,
    /// For each point, true where it is a point of the road's own line (false where it was
    /// put in to make stretches short).
    pub own: Vec<bool>,
    pub kerb_m: f64,
    pub metre: f64,
}

/// The bands beside a road's surface `road_m` wide: for each run of its pieces and each side
/// with a band, the edges of the band (along the surface's edge and outside it), with a point
/// at least every [`PIECE_M`].
pub fn candidates(
    feature: u32,
    road: &RoadSurface,
    plan: &SidewalkPlan,
    road_m: f64,
    metre: f64,
) -> Vec<Candidate> {
    if road_m <= 0.0 {
        return Vec::new();
    }
    let share = plan.width_m / road_m;
    let mut found = Vec::new();
    for (range, _) in &road.lines {
        for (side, edge, beyond) in [(plan.left, 0.0, -share), (plan.right, 1.0, 1.0 + share)] {
            if side == Side::None {
                continue;
            }
            let (Some(inner), Some(outer)) = (
                road.line_at(range.clone(), edge),
                road.line_at(range.clone(), beyond),
            ) else {
                continue;
            };
            let (inner, outer, own) = densified(&inner, &outer, PIECE_M * metre);
            found.push(Candidate {
                feature,
                side,
                inner,
                outer,
                own,
                kerb_m: plan.kerb_m,
                metre,
            });
        }
    }
    found
}

/// Two edges walked in step, with points added so that no step is longer than `longest`, and
/// for each point whether it is one of the edges' own.
fn densified(
    inner: &[Point],
    outer: &[Point],
    longest: f64,
) -> (Vec<Point>, Vec<Point>, Vec<bool>) {
    let mut dense = (vec![inner[0]], vec![outer[0]], vec![true]);
    for k in 1..inner.len().min(outer.len()) {
        let length = distance(inner[k - 1], inner[k]).max(distance(outer[k - 1], outer[k]));
        let steps = (length / longest).ceil().max(1.0) as usize;
        for s in 1..=steps {
            let t = s as f64 / steps as f64;
            dense.0.push(lerp(inner[k - 1], inner[k], t));
            dense.1.push(lerp(outer[k - 1], outer[k], t));
            dense.2.push(s == steps);
        }
    }
    dense
}

/// What lies around the bands: the buildings' corners, the built-up land's outlines and the
/// separately mapped sidewalks.
struct Surroundings {
    /// A point of each building, sorted by `u`.
    corners: Vec<Point>,
    built_up: Vec<(Rect, Vec<Point>)>,
    sidewalks: Vec<(Rect, Vec<Point>)>,
    /// Ground a sidewalk does not lie on: water, railways, roads (with their features).
    taken: Taken,
}

/// Areas indexed by the cells of a grid their bounds meet, for finding those a stretch meets.
struct Taken {
    areas: Vec<(Rect, Vec<Point>, u32)>,
    cells: std::collections::HashMap<(i64, i64), Vec<usize>>,
    /// Areas over too many cells to list in each: tried at every point.
    large: Vec<usize>,
}

/// Side of a cell of [`Taken`]'s grid, tile units.
const TAKEN_CELL: f64 = 1.0 / 128.0;
/// Most cells an area is listed in.
const TAKEN_MOST_CELLS: i64 = 256;

/// The row or column of [`Taken`]'s grid a coordinate falls in.
fn cell(v: f64) -> i64 {
    (v / TAKEN_CELL).floor() as i64
}

impl Taken {
    fn new(areas: Vec<(Rect, Vec<Point>, u32)>) -> Taken {
        let mut cells: std::collections::HashMap<(i64, i64), Vec<usize>> = Default::default();
        let mut large = Vec::new();
        for (i, (bounds, ..)) in areas.iter().enumerate() {
            let (u0, u1) = (cell(bounds.min[0]), cell(bounds.max[0]));
            let (v0, v1) = (cell(bounds.min[1]), cell(bounds.max[1]));
            if (u1 - u0 + 1) * (v1 - v0 + 1) > TAKEN_MOST_CELLS {
                large.push(i);
                continue;
            }
            for u in u0..=u1 {
                for v in v0..=v1 {
                    cells.entry((u, v)).or_default().push(i);
                }
            }
        }
        Taken {
            areas,
            cells,
            large,
        }
    }

    /// True where the quad `corners` meets an area of a feature other than `feature`: a corner
    /// of one inside the other, or their edges crossing (a stream narrower than the quad).
    fn meets(&self, corners: &[Point; 4], feature: u32) -> bool {
        let bounds = Rect::around(corners);
        let mut listed = std::collections::BTreeSet::new();
        for u in cell(bounds.min[0])..=cell(bounds.max[0]) {
            for v in cell(bounds.min[1])..=cell(bounds.max[1]) {
                if let Some(areas) = self.cells.get(&(u, v)) {
                    listed.extend(areas.iter().copied());
                }
            }
        }
        listed
            .into_iter()
            .chain(self.large.iter().copied())
            .any(|i| {
                let (area_bounds, ring, f) = &self.areas[i];
                *f != feature && area_bounds.intersects(&bounds) && overlaps(ring, corners)
            })
    }
}

/// True where a ring and a quad overlap.
fn overlaps(ring: &[Point], quad: &[Point; 4]) -> bool {
    quad.iter().any(|&p| ring_contains(ring, p))
        || ring.iter().any(|&p| ring_contains(quad, p))
        || edges(ring).any(|(a, b)| edges(quad).any(|(c, d)| segments_meet(a, b, c, d)))
}

/// The edges of a ring, the closing one included.
fn edges(points: &[Point]) -> impl Iterator<Item = (Point, Point)> + '_ {
    let n = points.len();
    (0..n).map(move |k| (points[k], points[(k + 1) % n]))
}

impl Surroundings {
    fn built_up_at(&self, p: Point, metre: f64) -> bool {
        if self
            .built_up
            .iter()
            .any(|(bounds, ring)| bounds.contains(p) && ring_contains(ring, p))
        {
            return true;
        }
        let reach = BUILT_UP_REACH_M * metre;
        let from = self.corners.partition_point(|c| c[0] <= p[0] - reach);
        let near = self.corners[from..]
            .iter()
            .take_while(|c| c[0] < p[0] + reach)
            .filter(|c| (c[1] - p[1]).abs() < reach)
            .take(BUILT_UP_BUILDINGS)
            .count();
        near >= BUILT_UP_BUILDINGS
    }

    fn mapped_apart_at(&self, p: Point, metre: f64) -> bool {
        let reach = SEPARATE_REACH_M * metre;
        self.sidewalks.iter().any(|(bounds, line)| {
            bounds.contains(p)
                && line
                    .windows(2)
                    .any(|s| distance_to_segment(p, s[0], s[1]) < reach)
        })
    }
}

/// True for a way mapped as a sidewalk of its own.
pub fn is_separate_sidewalk(tags: &Tags) -> bool {
    matches!(tags.get("highway"), Some("footway" | "path" | "cycleway"))
        && tags.get("footway") == Some("sidewalk")
}

/// Decides what each stretch of the `candidates` shows, from the buildings and land cover of
/// `set` (before it is cut down to the tile) and the separately mapped sidewalks among `ways`,
/// and puts the runs into `set.sidewalks`.
pub(super) fn place(
    set: &mut FeatureSet,
    candidates: Vec<Candidate>,
    ways: &[&Way],
    projection: &super::Projection,
) {
    // A building's first corner stands for it.
    let mut corners: Vec<Point> = set
        .buildings
        .iter()
        .filter_map(|b| b.footprint.outer.first().copied())
        .collect();
    corners.sort_by(|a, b| a[0].total_cmp(&b[0]));
    let reach = |line: Vec<Point>, metre: f64| {
        let bounds = Rect::around(&line).widened(SEPARATE_REACH_M * metre);
        (bounds, line)
    };
    let surroundings = Surroundings {
        corners,
        built_up: set
            .surfaces
            .iter()
            .filter(|s| {
                s.class == FeatureClass::LandCover
                    && matches!(
                        s.cover,
                        Some(Cover::Residential | Cover::Commercial | Cover::Industrial)
                    )
            })
            .flat_map(|s| s.pieces.iter().map(|p| (p.bounds(), p.outer.clone())))
            .collect(),
        taken: Taken::new(
            set.surfaces
                .iter()
                .filter(|s| {
                    matches!(
                        s.class,
                        FeatureClass::Water | FeatureClass::Railway | FeatureClass::Road
                    )
                })
                .flat_map(|s| {
                    s.pieces
                        .iter()
                        .map(|p| (p.bounds(), p.outer.clone(), s.feature))
                })
                .collect(),
        ),
        sidewalks: ways
            .iter()
            .filter(|w| is_separate_sidewalk(&w.tags) && !w.positions.is_empty())
            .map(|w| {
                let metre = projection.metres(1.0, w.positions[0].lat);
                reach(projection.points(&w.positions), metre)
            })
            .collect(),
    };
    for candidate in candidates {
        runs(&candidate, &surroundings, &mut set.sidewalks);
    }
}

/// The runs of one candidate band: each stretch looks as its middle decides (unless it would
/// lie on ground that is taken), and neighbouring
/// stretches that look alike make one run, which keeps only the road's own points inside it.
fn runs(candidate: &Candidate, around: &Surroundings, out: &mut Vec<Band>) {
    let metre = candidate.metre;
    let mut current: Option<Band> = None;
    let end = |run: Option<Band>, out: &mut Vec<Band>, k: usize| {
        if let Some(mut run) = run {
            // The run's last point, if it was put in, ends it.
            if run.inner.last() != Some(&candidate.inner[k]) {
                run.inner.push(candidate.inner[k]);
                run.outer.push(candidate.outer[k]);
            }
            out.push(run);
        }
    };
    for k in 1..candidate.inner.len() {
        let middle = lerp(
            lerp(candidate.inner[k - 1], candidate.inner[k], 0.5),
            lerp(candidate.outer[k - 1], candidate.outer[k], 0.5),
            0.5,
        );
        // All of it but the quarter along the road's edge (where the road's own junctions
        // touch it) must lie on free ground.
        let near = |k: usize| lerp(candidate.inner[k], candidate.outer[k], 0.25);
        let far = [
            near(k - 1),
            near(k),
            candidate.outer[k],
            candidate.outer[k - 1],
        ];
        let taken = around.taken.meets(&far, candidate.feature);
        let look = if taken || around.mapped_apart_at(middle, metre) {
            None
        } else if candidate.side == Side::Mapped || around.built_up_at(middle, metre) {
            Some(Look::Sidewalk {
                kerb_m: candidate.kerb_m,
            })
        } else {
            Some(Look::Verge)
        };
        match (&mut current, look) {
            (Some(run), Some(look)) if run.look == look => {
                if candidate.own[k] {
                    run.inner.push(candidate.inner[k]);
                    run.outer.push(candidate.outer[k]);
                }
            }
            (_, look) => {
                end(current.take(), out, k - 1);
                current = look.map(|look| Band {
                    feature: candidate.feature,
                    inner: vec![candidate.inner[k - 1]],
                    outer: vec![candidate.outer[k - 1]],
                    look,
                    metre,
                });
                if let Some(run) = current.as_mut().filter(|_| candidate.own[k]) {
                    run.inner.push(candidate.inner[k]);
                    run.outer.push(candidate.outer[k]);
                }
            }
        }
    }
    end(current, out, candidate.inner.len() - 1);
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::osm::tags;

    fn sides(pairs: &[(&str, &str)]) -> Option<(Side, Side)> {
        plan(&tags(pairs)).map(|p| (p.left, p.right))
    }

    #[test]
    fn tagged_sides_win_and_untagged_streets_may_have_both() {
        use Side::*;
        assert_eq!(
            sides(&[("highway", "residential"), ("sidewalk", "both")]),
            Some((Mapped, Mapped))
        );
        assert_eq!(
            sides(&[("highway", "primary"), ("sidewalk", "right")]),
            Some((None, Mapped))
        );
        assert_eq!(
            sides(&[("highway", "residential"), ("sidewalk:left", "separate")]),
            Some((None, Untagged))
        );
        assert_eq!(
            sides(&[("highway", "tertiary"), ("sidewalk:both", "yes")]),
            Some((Mapped, Mapped))
        );
        assert_eq!(
            sides(&[("highway", "secondary")]),
            Some((Untagged, Untagged))
        );
        for none in ["no", "none", "separate"] {
            assert_eq!(
                sides(&[("highway", "residential"), ("sidewalk", none)]),
                Option::None
            );
        }
    }

    #[test]
    fn motorways_tracks_service_and_rural_roads_get_no_band_unless_tagged() {
        for highway in [
            "motorway",
            "trunk",
            "track",
            "service",
            "unclassified",
            "footway",
        ] {
            assert_eq!(sides(&[("highway", highway)]), Option::None, "{highway}");
        }
        assert_eq!(
            sides(&[("highway", "service"), ("sidewalk", "left")]),
            Some((Side::Mapped, Side::None))
        );
    }

    #[test]
    fn widths_and_kerbs_come_from_tags_within_reason() {
        let plan_of = |pairs: &[(&str, &str)]| plan(&tags(pairs)).unwrap();
        let street = plan_of(&[("highway", "residential")]);
        assert_eq!((street.width_m, street.kerb_m), (1.5, 0.12));
        let main = plan_of(&[("highway", "primary")]);
        assert_eq!((main.width_m, main.kerb_m), (2.0, 0.15));
        let tagged = plan_of(&[
            ("highway", "residential"),
            ("sidewalk:both:width", "3"),
            ("sidewalk:both:kerb", "lowered"),
        ]);
        assert_eq!((tagged.width_m, tagged.kerb_m), (3.0, 0.04));
        // Odd values fall back to the defaults, with no panic.
        let odd = plan_of(&[
            ("highway", "residential"),
            ("sidewalk:width", "-3"),
            ("kerb:height", "a lot"),
            ("sidewalk:both:kerb", "gigantic"),
            ("sidewalk:left", "perhaps"),
        ]);
        assert_eq!((odd.width_m, odd.kerb_m), (1.5, 0.12));
        assert_eq!(odd.left, Side::Untagged);
    }
}
