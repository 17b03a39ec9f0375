//! Instances of the models on the ground: trees and street-level objects, each standing where
//! the ground triangulation says it may — a forest tree only on its forest's own ground (not on a
//! road or a path through it), anything else anywhere but under a building or in water. A foot is
//! placed on the ground mesh itself, and sunk a little so it never floats; a thing whose node lies
//! on a bridge's way (a lamp on a bridge, a tree in a planter on it) stands on the deck instead.

use std::collections::BTreeMap;

use super::drawn_ground::DrawnGround;
use super::models::Model;
use crate::elevation::structures::Profile;
use crate::features::objects::PointObject;
use crate::features::vegetation::{Tree, TreeKind};
use crate::features::{FeatureClass, FeatureSet};
use crate::geometry::{Point, Rect};

/// The instances of one model.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Instances {
    pub translations: Vec<[f32; 3]>,
    /// Unit quaternions `(x, y, z, w)`.
    pub rotations: Vec<[f32; 4]>,
    pub scales: Vec<[f32; 3]>,
    pub feature_ids: Vec<u32>,
}

impl Instances {
    pub fn len(&self) -> usize {
        self.translations.len()
    }

    pub fn is_empty(&self) -> bool {
        self.translations.is_empty()
    }

    /// Drops every instance placed, turned or scaled by a number that is not finite; returns
    /// how many went.
    pub fn drop_non_finite(&mut self) -> usize {
        let kept: Vec<bool> = (0..self.len())
            .map(|i| {
                self.translations[i]
                    .iter()
                    .chain(&self.rotations[i])
                    .chain(&self.scales[i])
                    .all(|c| c.is_finite())
            })
            .collect();
        let before = self.len();
        super::retain_marked(&mut self.translations, &kept);
        super::retain_marked(&mut self.rotations, &kept);
        super::retain_marked(&mut self.scales, &kept);
        super::retain_marked(&mut self.feature_ids, &kept);
        before - self.len()
    }
}

/// Depth a foot reaches below the ground, metres.
const SINK_M: f64 = 0.3;

/// One thing to stand on the ground.
struct Placement {
    at: Point,
    model: Model,
    /// Scale of the model in true metres (x, y, z).
    scale_m: [f64; 3],
    rotation: f64,
    feature: u32,
    /// The surface that must be the ground at the foot (a forest tree's own forest).
    on: Option<u32>,
}

/// How far from a bridge's line a point still lies on it, tile units (a fraction of a
/// millimetre: a node of the way itself).
const ON_DECK_UV: f64 = 1e-7;

/// The deck's top where `at` lies on the line of one of `decks` (bridges' settled profiles).
fn deck_at(decks: &[(Rect, &Profile)], at: Point) -> Option<f64> {
    let probe = Rect {
        min: [at[0] - ON_DECK_UV, at[1] - ON_DECK_UV],
        max: [at[0] + ON_DECK_UV, at[1] + ON_DECK_UV],
    };
    decks
        .iter()
        .filter(|(b, _)| b.intersects(&probe))
        .find_map(|(_, profile)| {
            profile.points.windows(2).enumerate().find_map(|(k, pair)| {
                let (a, b) = (pair[0], pair[1]);
                let inside = |i: usize| {
                    at[i] >= a[i].min(b[i]) - ON_DECK_UV && at[i] <= a[i].max(b[i]) + ON_DECK_UV
                };
                if !inside(0) || !inside(1) {
                    return None;
                }
                let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
                let length2 = dx * dx + dy * dy;
                let t = if length2 > 0.0 {
                    (((at[0] - a[0]) * dx + (at[1] - a[1]) * dy) / length2).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                let near = [a[0] + t * dx - at[0], a[1] + t * dy - at[1]];
                (near[0].hypot(near[1]) <= ON_DECK_UV).then(|| {
                    let e = &profile.elevations;
                    e[k] + t * (e[k + 1] - e[k])
                })
            })
        })
}

/// Places the trees and objects of a tile on its ground, or on a bridge's deck where their
/// node lies on the bridge (`decks`: the settled profiles of the bridges that reach the tile):
/// the instances of each model.
pub fn place(
    (trees, objects): (&[Tree], &[PointObject]),
    feature_set: &FeatureSet,
    ground: &DrawnGround<'_>,
    decks: &[&Profile],
) -> BTreeMap<Model, Instances> {
    let frame = ground.frame;
    let placements = trees
        .iter()
        .map(|tree| {
            let width = match tree.kind {
                TreeKind::Broadleaved => 1.0,
                TreeKind::Needleleaved => 0.9,
            } * tree.height_m;
            Placement {
                at: tree.at,
                model: Model::Tree(tree.kind, tree.shade),
                scale_m: [width, tree.height_m, width],
                rotation: tree.rotation,
                feature: tree.feature,
                on: tree.forest,
            }
        })
        .chain(objects.iter().map(|object| Placement {
            at: object.at,
            model: Model::Object(object.kind),
            scale_m: [1.0; 3],
            rotation: object.rotation,
            feature: object.feature,
            on: None,
        }));
    let decks: Vec<(Rect, &Profile)> = decks
        .iter()
        .map(|profile| (Rect::around(&profile.points), *profile))
        .collect();
    let mut models: BTreeMap<Model, Instances> = BTreeMap::new();
    for placement in placements {
        let (x, z) = frame.uv_to_local(placement.at[0], placement.at[1]);
        // Only a mapped node may lie on a bridge's way: a forest's trees stand on its ground.
        let on_deck = placement
            .on
            .is_none()
            .then(|| deck_at(&decks, placement.at))
            .flatten();
        if let Some(deck) = on_deck {
            // On the deck, resting on it.
            let y = frame.elevation_to_y(deck, z);
            push(&mut models, &placement, [x, y, z], frame.scale_at(z));
            continue;
        }
        let Some((triangle, y)) = ground.under(x, z) else {
            continue;
        };
        let surface = triangle.surface;
        let allowed = match placement.on {
            Some(required) => surface == Some(required),
            None => surface.is_none_or(|s| {
                !matches!(
                    feature_set.surfaces[s as usize].class,
                    FeatureClass::Building | FeatureClass::Water
                )
            }),
        };
        if !allowed {
            continue;
        }
        let scale = frame.scale_at(z);
        push(&mut models, &placement, [x, y - SINK_M * scale, z], scale);
    }
    models
}

/// Adds one instance with its foot at `foot` (local frame), `scale` being the frame's scale
/// there.
fn push(
    models: &mut BTreeMap<Model, Instances>,
    placement: &Placement,
    foot: [f64; 3],
    scale: f64,
) {
    let half = placement.rotation / 2.0;
    let instances = models.entry(placement.model).or_default();
    instances.translations.push(foot.map(|c| c as f32));
    instances
        .rotations
        .push([0.0, half.sin() as f32, 0.0, half.cos() as f32]);
    instances
        .scales
        .push(placement.scale_m.map(|m| (m * scale) as f32));
    instances.feature_ids.push(placement.feature);
}
