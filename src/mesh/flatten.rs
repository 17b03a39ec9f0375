//! The settled surfaces put on the ground's vertices: once the ground is triangulated, every
//! vertex of a water area, a tunnel's cut or a road takes the elevation its rule gives, so no
//! vertex the triangulation attached from just outside an outline is left at the terrain's.

use std::collections::{HashMap, HashSet};

use super::ground::Ground;
use crate::elevation::ground::Ground as SettledGround;
use crate::elevation::settled::{Bound, Rule};
use crate::geometry::Point;
use crate::tile::TileFrame;

/// Puts every vertex of a settled surface's triangles at its rule's elevation (the lowest,
/// where surfaces meet): the outline's vertices already are, and this catches a vertex the
/// triangulation attached to the surface from just outside its outline. Vertices on the tile's
/// edges stay as the ground model settled them (identically in both tiles). Floors and
/// ceilings ([`Bound`]) are left to the ground model (`model`, whose water areas, cuts and
/// roads these are), a vertex under a floor too.
pub fn flatten(ground: &mut Ground, model: &SettledGround<'_>, frame: &TileFrame) {
    let size_m = frame.size_m;
    let roads = model.roads;
    let rule_of: HashMap<u32, &Rule> = model
        .water
        .iter()
        .chain(model.cuts)
        .filter(|l| l.bound == Bound::Exact)
        .map(|l| (l.surface, &l.rule))
        .collect();
    let on_edge = |p: Point| p[0] == 0.0 || p[1] == 0.0 || p[0] == size_m || p[1] == size_m;
    let mut settled: Vec<Option<f64>> = vec![None; ground.vertices.len()];
    // Roads first: a vertex a road shares with water or a cut takes the water's or the cut's.
    let road_surfaces: HashSet<u32> = roads.surfaces().collect();
    let mut on_road: Vec<Option<f64>> = vec![None; ground.vertices.len()];
    for triangle in &ground.triangles {
        if !triangle.surface.is_some_and(|s| road_surfaces.contains(&s)) {
            continue;
        }
        for &vertex in &triangle.vertices {
            let slot = &mut on_road[vertex as usize];
            if slot.is_none() {
                let [x, z] = ground.vertices[vertex as usize];
                let (u, v) = frame.local_to_uv(x, z);
                // A vertex on water or in a cut (on its outline, say, next to a twin the
                // triangulation made a hair away) keeps what the ground model gave it.
                if !model.levels_at([u, v]).any(|l| l.bound == Bound::Exact) {
                    *slot = roads.elevation([u, v]);
                }
            }
        }
    }
    for triangle in &ground.triangles {
        let Some(rule) = triangle.surface.and_then(|s| rule_of.get(&s)) else {
            continue;
        };
        for &vertex in &triangle.vertices {
            let [x, z] = ground.vertices[vertex as usize];
            let (u, v) = frame.local_to_uv(x, z);
            let level = rule.elevation([u, v]);
            let slot = &mut settled[vertex as usize];
            *slot = Some(slot.map_or(level, |l: f64| l.min(level)));
        }
    }
    for (v, level) in settled.into_iter().enumerate() {
        if let Some(level) = level.or(on_road[v]) {
            let [x, z] = ground.vertices[v];
            let (u, w) = frame.local_to_uv(x, z);
            let raised = model.levels_at([u, w]).any(|l| l.bound == Bound::AtLeast);
            if !on_edge(ground.vertices[v]) && !raised {
                ground.elevations[v] = level;
            }
        }
    }
}
