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
    let roads = model.roads;
    // The levels covering a point, read on any thread (the model's terrain is one thread's).
    let (water, cuts, index) = (model.water, model.cuts, model.index());
    let levels_at = |p: Point| index.covering((water, cuts), p);
    let uv_of = |vertex: u32| {
        let [x, z] = ground.vertices[vertex as usize];
        let (u, v) = frame.local_to_uv(x, z);
        [u, v]
    };
    let rule_of: HashMap<u32, &Rule> = water
        .iter()
        .chain(cuts)
        .filter(|l| l.bound == Bound::Exact)
        .map(|l| (l.surface, &l.rule))
        .collect();
    let threads =
        |items: usize| crate::parallel::threads_for(items, VERTICES_PER_THREAD, MAX_THREADS);

    // Roads first: a vertex a road shares with water or a cut takes the water's or the cut's.
    let road_surfaces: HashSet<u32> = roads.surfaces().collect();
    let road_vertices = vertices_of(ground, |s| road_surfaces.contains(&s));
    let road_levels =
        crate::parallel::map_chunks(&road_vertices, threads(road_vertices.len()), &|chunk| {
            chunk
                .iter()
                .map(|&vertex| {
                    let p = uv_of(vertex);
                    // A vertex on water or in a cut (on its outline, say, next to a twin the
                    // triangulation made a hair away) keeps what the ground model gave it.
                    if levels_at(p).any(|l| l.bound == Bound::Exact) {
                        None
                    } else {
                        roads.elevation(p)
                    }
                })
                .collect()
        });
    let mut on_road: Vec<Option<f64>> = vec![None; ground.vertices.len()];
    for (&vertex, level) in road_vertices.iter().zip(road_levels) {
        on_road[vertex as usize] = level;
    }

    // The lowest level each vertex of a water area or a cut is given by the rules of its
    // triangles, taken in the triangles' order.
    let ruled: Vec<(u32, &Rule)> = ground
        .triangles
        .iter()
        .filter_map(|t| {
            t.surface
                .and_then(|s| rule_of.get(&s))
                .map(|&rule| (t, rule))
        })
        .flat_map(|(t, rule)| t.vertices.map(|vertex| (vertex, rule)))
        .collect();
    let rule_levels = crate::parallel::map_chunks(&ruled, threads(ruled.len()), &|chunk| {
        chunk
            .iter()
            .map(|&(vertex, rule)| rule.elevation(uv_of(vertex)))
            .collect()
    });
    let mut settled: Vec<Option<f64>> = vec![None; ground.vertices.len()];
    for (&(vertex, _), level) in ruled.iter().zip(rule_levels) {
        let slot = &mut settled[vertex as usize];
        *slot = Some(slot.map_or(level, |l: f64| l.min(level)));
    }

    for (v, level) in settled.into_iter().enumerate() {
        if let Some(level) = level.or(on_road[v]) {
            let raised = levels_at(uv_of(v as u32)).any(|l| l.bound == Bound::AtLeast);
            if !frame.on_edge(ground.vertices[v]) && !raised {
                ground.elevations[v] = level;
            }
        }
    }
}

/// Vertices below this many are flattened on one thread.
const VERTICES_PER_THREAD: usize = 4_096;
/// Most threads the vertices' levels are read on.
const MAX_THREADS: usize = 4;

/// The vertices of the triangles whose surface `of` selects, each once, in the order the
/// triangles first name them.
fn vertices_of(ground: &Ground, of: impl Fn(u32) -> bool) -> Vec<u32> {
    let mut seen = vec![false; ground.vertices.len()];
    let mut vertices = Vec::new();
    for triangle in &ground.triangles {
        if !triangle.surface.is_some_and(&of) {
            continue;
        }
        for &vertex in &triangle.vertices {
            if !std::mem::replace(&mut seen[vertex as usize], true) {
                vertices.push(vertex);
            }
        }
    }
    vertices
}
