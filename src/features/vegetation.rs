//! Trees (paper 001 §4.3): `natural=tree` nodes, `natural=tree_row` ways, and trees scattered
//! through forests and woods.
//!
//! Forest trees stand on a jittered grid laid over the whole map in global tile units, so a
//! forest that spans two tiles is planted once, each tree in the tile that holds it; the jitter
//! keeps trees at least a fifth of the spacing apart. Every random choice (position in the cell,
//! height, rotation, shade) comes from a hash of the OSM id and the cell, so a tile renders the
//! same bytes every time. `leaf_type` chooses needle-leaved or broad-leaved trees (a mixed
//! forest has both).

use super::{FeatureClass, FeatureSet, Projection};
use crate::geometry::{Point, Rect};
use crate::osm::index::Selection;
use crate::osm::units::parse_length_m;
use crate::osm::{ElementRef, ElementType, Tags};

/// The shape of a tree.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum TreeKind {
    Broadleaved,
    Needleleaved,
}

impl TreeKind {
    pub fn as_str(self) -> &'static str {
        match self {
            TreeKind::Broadleaved => "broadleaved",
            TreeKind::Needleleaved => "needleleaved",
        }
    }
}

/// Shades of crown colour a tree may take.
pub const SHADES: u8 = 3;

/// A tree to plant, if the ground at its foot allows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tree {
    /// Foot of the tree in global tile units.
    pub at: Point,
    pub kind: TreeKind,
    pub height_m: f64,
    /// Rotation about the vertical, radians.
    pub rotation: f64,
    pub shade: u8,
    /// Row in the feature table.
    pub feature: u32,
    /// For a forest tree, the surface that must be the ground at its foot.
    pub forest: Option<u32>,
}

/// How trees are planted.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct VegetationSettings {
    /// Distance between forest trees before jitter, metres.
    pub forest_spacing_m: f64,
    /// Distance between the trees of a `natural=tree_row`, metres.
    pub row_spacing_m: f64,
    /// Most trees in one tile; forests are thinned evenly to stay under it.
    pub max_trees_per_tile: usize,
}

impl Default for VegetationSettings {
    fn default() -> Self {
        VegetationSettings {
            forest_spacing_m: 8.0,
            row_spacing_m: 8.0,
            max_trees_per_tile: 6000,
        }
    }
}

/// A 64-bit mix (SplitMix64's finaliser): the deterministic source of every random choice.
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Uniform numbers in `[0, 1)` drawn from a seed.
struct Draws(u64);

impl Draws {
    fn new(seed: &[u64]) -> Draws {
        Draws(seed.iter().fold(0x2545_f491_4f6c_dd1d, |h, &s| mix(h ^ s)))
    }

    fn next(&mut self) -> f64 {
        self.0 = mix(self.0);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// The kinds a `leaf_type` allows: one, or both for mixed or untagged forests.
fn kinds_of(tags: &Tags) -> &'static [TreeKind] {
    match tags.get("leaf_type") {
        Some("needleleaved") => &[TreeKind::Needleleaved],
        Some("broadleaved") => &[TreeKind::Broadleaved],
        _ => &[TreeKind::Broadleaved, TreeKind::Needleleaved],
    }
}

/// A tree with its random traits drawn from `draws`; `height_m` overrides the drawn height.
fn tree(
    at: Point,
    kinds: &[TreeKind],
    height_m: Option<f64>,
    feature: u32,
    forest: Option<u32>,
    draws: &mut Draws,
) -> Tree {
    let kind = kinds[((draws.next() * kinds.len() as f64) as usize).min(kinds.len() - 1)];
    let drawn = match kind {
        TreeKind::Broadleaved => 8.0 + 8.0 * draws.next(),
        TreeKind::Needleleaved => 10.0 + 12.0 * draws.next(),
    };
    Tree {
        at,
        kind,
        height_m: height_m.unwrap_or(drawn),
        rotation: draws.next() * std::f64::consts::TAU,
        shade: ((draws.next() * f64::from(SHADES)) as u8).min(SHADES - 1),
        feature,
        forest,
    }
}

/// The trees of a tile: mapped trees and tree rows first, then forests, within the cap.
pub(super) fn collect(
    set: &mut FeatureSet,
    selection: &Selection<'_>,
    projection: &Projection,
    rect: &Rect,
    settings: &VegetationSettings,
) {
    let mut trees = mapped_trees(set, selection, projection, rect);
    trees.extend(tree_rows(set, selection, projection, rect, settings));
    let mut forest_trees = forest_trees(set, projection, rect, settings);
    let room = settings.max_trees_per_tile.saturating_sub(trees.len());
    trees.truncate(settings.max_trees_per_tile);
    if forest_trees.len() > room && room > 0 {
        thin_evenly(&mut forest_trees, room);
    } else if room == 0 {
        forest_trees.clear();
    }
    trees.extend(forest_trees);
    set.trees = trees;
}

/// The tile's `natural=tree` nodes, each a feature of its own, with a tagged height when it is
/// a plausible one.
fn mapped_trees(
    set: &mut FeatureSet,
    selection: &Selection<'_>,
    projection: &Projection,
    rect: &Rect,
) -> Vec<Tree> {
    let mut trees = Vec::new();
    for node in &selection.nodes {
        if node.tags.get("natural") != Some("tree") {
            continue;
        }
        let at = projection.point(node.position);
        if !rect.owns(at) {
            continue;
        }
        let height = node
            .tags
            .get("height")
            .and_then(parse_length_m)
            .filter(|h| (1.0..=120.0).contains(h));
        let element = ElementRef {
            element_type: ElementType::Node,
            id: node.id,
        };
        let feature = set.add_feature(Some(element), FeatureClass::Vegetation, &node.tags);
        let mut draws = Draws::new(&[node.id as u64]);
        trees.push(tree(
            at,
            kinds_of(&node.tags),
            height,
            feature,
            None,
            &mut draws,
        ));
    }
    trees
}

/// The trees of the `natural=tree_row` ways, planted along each at the row spacing; a row with
/// a tree in the tile is one feature.
fn tree_rows(
    set: &mut FeatureSet,
    selection: &Selection<'_>,
    projection: &Projection,
    rect: &Rect,
    settings: &VegetationSettings,
) -> Vec<Tree> {
    let mut trees = Vec::new();
    for way in &selection.ways {
        if way.tags.get("natural") != Some("tree_row") {
            continue;
        }
        let line = projection.points(&way.positions);
        let spacing = projection.metres(settings.row_spacing_m, way.positions[0].lat);
        if spacing <= 0.0 {
            continue;
        }
        let planted: Vec<Point> = planted_along(&line, spacing)
            .into_iter()
            .filter(|&at| rect.owns(at))
            .collect();
        if planted.is_empty() {
            continue;
        }
        let element = ElementRef {
            element_type: ElementType::Way,
            id: way.id,
        };
        let feature = set.add_feature(Some(element), FeatureClass::Vegetation, &way.tags);
        for (index, at) in planted.into_iter().enumerate() {
            let mut draws = Draws::new(&[way.id as u64, index as u64]);
            trees.push(tree(
                at,
                kinds_of(&way.tags),
                None,
                feature,
                None,
                &mut draws,
            ));
        }
    }
    trees
}

/// Points every `spacing` along the line from its start, the spacing carried over its bends.
fn planted_along(line: &[Point], spacing: f64) -> Vec<Point> {
    let mut planted = Vec::new();
    let mut carried = 0.0;
    for pair in line.windows(2) {
        let (a, b) = (pair[0], pair[1]);
        let length = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
        let mut s = carried;
        while s < length {
            let t = s / length;
            let at = [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
            planted.push(at);
            s += spacing;
        }
        carried = s - length;
    }
    planted
}

/// The trees of the forest surfaces, on the global jittered grid (so a forest cut by a tile
/// edge has the same trees in both tiles), in grid order.
fn forest_trees(
    set: &FeatureSet,
    projection: &Projection,
    rect: &Rect,
    settings: &VegetationSettings,
) -> Vec<Tree> {
    let centre_lat = crate::tile::v_to_lat(
        (rect.min[1] + rect.max[1]) / 2.0,
        projection.tiles_per_axis(),
    );
    let step = projection.metres(settings.forest_spacing_m, centre_lat);
    let mut forest_trees = Vec::new();
    if step <= 0.0 {
        return forest_trees;
    }
    for (index, surface) in set.surfaces.iter().enumerate() {
        if surface.cover != Some(super::landcover::Cover::Forest) {
            continue;
        }
        let info = &set.features[surface.feature as usize];
        let id = info.element.map_or(0, |e| e.id as u64);
        let kinds = kinds_of(&info.tags);
        let b = surface.bounds;
        let (i0, i1) = (
            (b.min[0].max(rect.min[0]) / step).floor() as i64,
            (b.max[0].min(rect.max[0]) / step).ceil() as i64,
        );
        let (j0, j1) = (
            (b.min[1].max(rect.min[1]) / step).floor() as i64,
            (b.max[1].min(rect.max[1]) / step).ceil() as i64,
        );
        for j in j0..j1 {
            for i in i0..i1 {
                let mut draws = Draws::new(&[id, i as u64, j as u64]);
                let at = [
                    (i as f64 + 0.1 + 0.8 * draws.next()) * step,
                    (j as f64 + 0.1 + 0.8 * draws.next()) * step,
                ];
                if rect.owns(at) && surface.contains(at) {
                    forest_trees.push(tree(
                        at,
                        kinds,
                        None,
                        surface.feature,
                        Some(index as u32),
                        &mut draws,
                    ));
                }
            }
        }
    }
    forest_trees
}

/// Keeps `room` of the trees, an even selection: every k-th tree in grid order.
fn thin_evenly(trees: &mut Vec<Tree>, room: usize) {
    let keep = room as f64 / trees.len() as f64;
    let mut credit = 0.0;
    trees.retain(|_| {
        credit += keep;
        if credit >= 1.0 {
            credit -= 1.0;
            true
        } else {
            false
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn draws_are_uniform_and_repeatable() {
        let a: Vec<f64> = {
            let mut d = Draws::new(&[42, 7]);
            (0..1000).map(|_| d.next()).collect()
        };
        let mut d = Draws::new(&[42, 7]);
        assert!(a.iter().all(|&x| x == d.next()));
        assert!(a.iter().all(|&x| (0.0..1.0).contains(&x)));
        let mean = a.iter().sum::<f64>() / a.len() as f64;
        assert!((mean - 0.5).abs() < 0.05, "{mean}");
        let mut other = Draws::new(&[42, 8]);
        assert_ne!(a[0], other.next());
    }

    #[test]
    fn leaf_type_chooses_the_kind() {
        let tags = |v: &str| Tags::from_pairs([("leaf_type", v)]);
        assert_eq!(kinds_of(&tags("needleleaved")), &[TreeKind::Needleleaved]);
        assert_eq!(kinds_of(&tags("broadleaved")), &[TreeKind::Broadleaved]);
        assert_eq!(kinds_of(&tags("mixed")).len(), 2);
    }
}
