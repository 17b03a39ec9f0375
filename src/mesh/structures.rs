//! Bridges and tunnels drawn from their settled profiles.
//!
//! A bridge is a deck of its way's width: the paved top at the settled elevation, sides and an
//! underside [`deck_thickness_m`](crate::features::structures::deck_thickness_m) below it, and
//! piers down into the ground every [`PIER_SPACING_M`] where the deck stands high enough,
//! kept clear of what it crosses. A tunnel is a tube along its covered stretch: the floor, its
//! walls and ceiling, and a dark opening at each portal, where the approach cut in the ground
//! ends. Every face is built in global tile units from the whole structure and clipped to the
//! tile, so a structure that crosses tiles is drawn the same on both sides.

use std::collections::{BTreeMap, HashMap};

use super::drawn_ground::DrawnGround;
use super::{markings, structure_lines, MeshBuffers, Part};
use crate::elevation::structures::{plan_tunnel, tube_heights, Profile, Settled, Station};
use crate::features::markings::LanePlan;
use crate::features::structures::{WayTraits, TUNNEL_ROOF_M};
use crate::features::{FeatureSettings, Projection};
use crate::geometry::{clip_to_rect, offset_polyline, Point, Rect};
use crate::osm::structures::StructureKind;
use crate::osm::Way;
use crate::tile::TileFrame;

/// Distance between a bridge's piers, metres.
pub const PIER_SPACING_M: f64 = 30.0;
/// A deck's underside stands at least this high above the ground where a pier is built, metres.
const PIER_MIN_HEIGHT_M: f64 = 2.0;
/// Piers keep this far from what the bridge crosses and from its ends, metres.
const PIER_CLEAR_M: f64 = 8.0;
/// A pier's length along the bridge, metres, and its width as a share of the deck's (at most
/// [`PIER_MAX_WIDTH_M`]).
const PIER_LENGTH_M: f64 = 1.5;
const PIER_WIDTH_SHARE: f64 = 0.5;
const PIER_MAX_WIDTH_M: f64 = 4.0;
/// How far a pier reaches below the terrain, metres: into the ground whatever the mesh does.
const PIER_FOOTING_M: f64 = 2.0;

/// What drawing needs besides the profiles.
pub struct Context<'a> {
    pub ways: &'a [Way],
    /// Feature row of each structure way drawn in this tile (by index into `ways`).
    pub features: &'a HashMap<u32, u32>,
    pub frame: &'a TileFrame,
    pub projection: &'a Projection,
    pub settings: &'a FeatureSettings,
    /// The mesh's error bound, metres.
    pub surface_margin_m: f64,
    /// The feature row and plan of the lines painted on each structure way that has any (by
    /// index into `ways`).
    pub lines: &'a HashMap<u32, (u32, LanePlan)>,
    /// The ground as drawn, into which a tunnel's ramps are cut.
    pub ground: &'a DrawnGround<'a>,
}

/// Draws every bridge and tunnel of the settled groups that reaches into the tile into
/// `parts` (the lines on their tops after those on the ground).
pub fn build(settled: &[Settled], context: &Context<'_>, parts: &mut BTreeMap<Part, MeshBuffers>) {
    let rect = crate::features::tile_rect(context.frame.tile);
    let mut drawer = Drawer {
        context,
        rect,
        parts,
    };
    for profile in settled.iter().flat_map(|s| &s.profiles) {
        match profile.kind {
            StructureKind::Bridge => drawer.bridge(profile),
            StructureKind::Tunnel => drawer.tunnel(profile),
        }
    }
}

struct Drawer<'a, 'b> {
    context: &'a Context<'b>,
    rect: Rect,
    parts: &'a mut BTreeMap<Part, MeshBuffers>,
}

/// A quad of a strip along a structure, in (u, v, elevation): from one cross-section's edge
/// to the next (the corners of each edge in the same order), with the normal at each
/// (in the same axes).
struct Quad {
    from: [[f64; 3]; 2],
    to: [[f64; 3]; 2],
    normals: [[f64; 3]; 2],
}

/// A box section drawn along a run: a surface facing up at the stations' elevation (a deck's
/// top, a tunnel's floor), one facing down `down_m` metres from it (the deck's underside, the
/// tunnel's ceiling) and the sides between, facing out of the box or into it.
struct Section {
    /// The parts of the surface facing up, the one facing down and the sides.
    parts: [Part; 3],
    down_m: f64,
    sides_out: bool,
}

/// A run of stations on one way, widened.
struct Run {
    feature: u32,
    way: u32,
    stations: Vec<Station>,
    left: Vec<Point>,
    right: Vec<Point>,
}

impl Drawer<'_, '_> {
    /// What the tags say of a structure's way.
    fn traits(&self, way: &Way) -> WayTraits {
        WayTraits::of(way, self.context.settings)
    }

    /// `metres` in global tile units where `way` is.
    fn in_units(&self, way: &Way, metres: f64) -> f64 {
        let lat = way.positions.first().map_or(0.0, |p| p.lat);
        self.context.projection.metres(metres, lat)
    }

    /// The stations split where the way changes (the station at a change in both runs), each
    /// run widened to its way's width; runs on ways without a feature row here are skipped.
    fn runs(&self, stations: &[Station]) -> Vec<Run> {
        let mut runs = Vec::new();
        let mut start = 0;
        for k in 1..=stations.len() {
            if k < stations.len() && stations[k].way == stations[start].way {
                continue;
            }
            let end = k.min(stations.len() - 1);
            let way = stations[start].way;
            let mut run: Vec<Station> = Vec::with_capacity(end - start + 1);
            for s in &stations[start..=end] {
                if run.last().is_none_or(|l| l.point != s.point) {
                    run.push(*s);
                }
            }
            start = end;
            let Some(&feature) = self.context.features.get(&way) else {
                continue;
            };
            let w = &self.context.ways[way as usize];
            let half = self.in_units(w, self.traits(w).width_m / 2.0);
            let line: Vec<Point> = run.iter().map(|s| s.point).collect();
            if let Some((left, right)) = offset_polyline(&line, half) {
                runs.push(Run {
                    feature,
                    way,
                    stations: run,
                    left,
                    right,
                });
            }
        }
        runs
    }

    /// Adds a flat face given in (u, v, elevation), clipped to the tile; `facing` in the same
    /// axes.
    fn face(&mut self, part: Part, corners: &[[f64; 3]], facing: [f64; 3], feature: u32) {
        let frame = self.context.frame;
        let local: Vec<[f64; 3]> = clip_to_rect(corners, &self.rect)
            .into_iter()
            .map(|[u, v, elevation]| {
                let (x, z) = frame.uv_to_local(u, v);
                [x, frame.elevation_to_y(elevation, z), z]
            })
            .collect();
        if local.len() >= 3 {
            let facing = [facing[0], facing[2], facing[1]];
            self.parts
                .entry(part)
                .or_default()
                .push_flat_polygon(&local, facing, feature);
        }
    }

    /// Draws a run's box section (see [`Section`]) as four strips along its stations: the
    /// surface facing up, the one facing down and each side; quads inside the tile share
    /// their cross-sections, lit as one smooth surface along the way.
    fn strips(&mut self, run: &Run, section: &Section) {
        let s = &run.stations;
        let at = |p: Point, e: f64| [p[0], p[1], e];
        let [up, down, sides] = section.parts.map(|part| (part, run.feature));
        let facing = |k: usize, side: &[Point]| {
            let (c, p) = (s[k].point, side[k]);
            let (from, to) = if section.sides_out { (c, p) } else { (p, c) };
            [to[0] - from[0], to[1] - from[1], 0.0]
        };
        let mut strips = [None; 4];
        for k in 0..s.len() - 1 {
            let (e0, e1) = (s[k].elevation, s[k + 1].elevation);
            let (d0, d1) = (e0 + section.down_m, e1 + section.down_m);
            let (l0, l1, r0, r1) = (run.left[k], run.left[k + 1], run.right[k], run.right[k + 1]);
            let quad = Quad {
                from: [at(l0, e0), at(r0, e0)],
                to: [at(l1, e1), at(r1, e1)],
                normals: [[0.0, 0.0, 1.0]; 2],
            };
            self.strip_quad(up, &mut strips[0], &quad);
            let quad = Quad {
                from: [at(l0, d0), at(r0, d0)],
                to: [at(l1, d1), at(r1, d1)],
                normals: [[0.0, 0.0, -1.0]; 2],
            };
            self.strip_quad(down, &mut strips[1], &quad);
            for (side, strip) in [(&run.left, 2), (&run.right, 3)] {
                let (p0, p1) = (side[k], side[k + 1]);
                let quad = Quad {
                    from: [at(p0, e0), at(p0, d0)],
                    to: [at(p1, e1), at(p1, d1)],
                    normals: [facing(k, side), facing(k + 1, side)],
                };
                self.strip_quad(sides, &mut strips[strip], &quad);
            }
        }
    }

    /// Adds a quad of a strip (see [`Quad`]) to `part`: inside the tile it shares the
    /// vertices of its `from` edge with the quad before it (`previous`, the last quad's `to`
    /// vertices, updated), each vertex with its station's normal; across the tile's edge it
    /// is clipped and drawn flat, and the strip starts again after it.
    fn strip_quad(
        &mut self,
        (part, feature): (Part, u32),
        previous: &mut Option<[u32; 2]>,
        quad: &Quad,
    ) {
        let corners = [quad.from[0], quad.to[0], quad.to[1], quad.from[1]];
        let facing = {
            let [n0, n1] = quad.normals;
            [n0[0] + n1[0], n0[1] + n1[1], n0[2] + n1[2]]
        };
        let inside = |c: &[f64; 3]| self.rect.contains([c[0], c[1]]);
        if !corners.iter().all(inside) {
            *previous = None;
            self.face(part, &corners, facing, feature);
            return;
        }
        let frame = self.context.frame;
        let local = |[u, v, elevation]: [f64; 3]| {
            let (x, z) = frame.uv_to_local(u, v);
            [x, frame.elevation_to_y(elevation, z), z]
        };
        let normal = |n: [f64; 3]| {
            let length = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2])
                .sqrt()
                .max(f64::MIN_POSITIVE);
            [n[0] / length, n[2] / length, n[1] / length]
        };
        let buffers = self.parts.entry(part).or_default();
        let mut edge = |edge: [[f64; 3]; 2], n: [f64; 3]| {
            edge.map(|c| buffers.push_vertex(local(c), normal(n), feature))
        };
        let [a, d] = previous.unwrap_or_else(|| edge(quad.from, quad.normals[0]));
        let [b, c] = edge(quad.to, quad.normals[1]);
        buffers.push_quad([a, b, c, d], normal(facing));
        *previous = Some([b, c]);
    }

    fn bridge(&mut self, profile: &Profile) {
        let n = profile.points.len();
        let length = profile.along_m[n - 1];
        let stations = profile.stretch(0.0, length);
        for run in self.runs(&stations) {
            let way = &self.context.ways[run.way as usize];
            let traits = self.traits(way);
            let thickness = traits.deck_thickness_m;
            let deck = Part::BridgeDeck(traits.paving);
            let s = &run.stations;
            // The deck's top, its underside and each side.
            let section = Section {
                parts: [deck, Part::BridgeStructure, Part::BridgeStructure],
                down_m: -thickness,
                sides_out: true,
            };
            self.strips(&run, &section);
            // Ends of the deck.
            let last = s.len() - 1;
            for (k, inner) in [(0, 1), (last, last - 1)] {
                let e = s[k].elevation;
                let (l, r) = (run.left[k], run.right[k]);
                let out = [
                    s[k].point[0] - s[inner].point[0],
                    s[k].point[1] - s[inner].point[1],
                    0.0,
                ];
                self.face(
                    Part::BridgeStructure,
                    &[
                        [l[0], l[1], e],
                        [r[0], r[1], e],
                        [r[0], r[1], e - thickness],
                        [l[0], l[1], e - thickness],
                    ],
                    out,
                    run.feature,
                );
            }
            self.lines(&run, false);
        }
        self.piers(profile);
    }

    /// The lines painted on a run's top (a deck, a tunnel's floor) where its way has any, or
    /// on a tunnel's ramp (`ramp`), which is cut into the ground and drawn as part of it: its
    /// lines lie on the ground as drawn, as the ground roads' do.
    fn lines(&mut self, run: &Run, ramp: bool) {
        let Some((feature, plan)) = self.context.lines.get(&run.way) else {
            return;
        };
        let way = &self.context.ways[run.way as usize];
        let width = self.traits(way).width_m;
        let centre: Vec<Point> = run.stations.iter().map(|s| s.point).collect();
        let elevations: Vec<f64> = run.stations.iter().map(|s| s.elevation).collect();
        let top = structure_lines::Top::new(&centre, (&run.left, &run.right), &elevations);
        let way_line = self.context.projection.points(&way.positions);
        let metre = self.in_units(way, 1.0);
        let lines = structure_lines::lines(*feature, plan, &top, &way_line, (width, metre));
        let surface: &dyn markings::Canvas = if ramp { self.context.ground } else { &top };
        markings::paint(self.parts, &lines, self.context.frame, surface);
    }

    fn piers(&mut self, profile: &Profile) {
        let n = profile.points.len();
        let length = profile.along_m[n - 1];
        let mut along = PIER_SPACING_M;
        while along < length - PIER_CLEAR_M {
            let here = along;
            along += PIER_SPACING_M;
            if here < PIER_CLEAR_M
                || profile
                    .crossings_m
                    .iter()
                    .any(|&c| (c - here).abs() < PIER_CLEAR_M)
            {
                continue;
            }
            let pair = profile.stretch(here, here + PIER_LENGTH_M);
            let (Some(a), Some(b)) = (pair.first(), pair.last()) else {
                continue;
            };
            let Some(&feature) = self.context.features.get(&a.way) else {
                continue;
            };
            let way = &self.context.ways[a.way as usize];
            let traits = self.traits(way);
            let bottom = a.elevation.min(b.elevation) - traits.deck_thickness_m;
            if bottom - a.terrain.max(b.terrain) < PIER_MIN_HEIGHT_M {
                continue;
            }
            let foot = a.terrain.min(b.terrain) - PIER_FOOTING_M - self.context.surface_margin_m;
            let width = (traits.width_m * PIER_WIDTH_SHARE).min(PIER_MAX_WIDTH_M);
            let half = self.in_units(way, width / 2.0);
            let Some((left, right)) = offset_polyline(&[a.point, b.point], half) else {
                continue;
            };
            let corners = [left[0], left[1], right[1], right[0]];
            let centre = [
                (a.point[0] + b.point[0]) / 2.0,
                (a.point[1] + b.point[1]) / 2.0,
            ];
            for i in 0..4 {
                let (p, q) = (corners[i], corners[(i + 1) % 4]);
                let mid = [(p[0] + q[0]) / 2.0, (p[1] + q[1]) / 2.0];
                self.face(
                    Part::BridgeStructure,
                    &[
                        [p[0], p[1], foot],
                        [q[0], q[1], foot],
                        [q[0], q[1], bottom],
                        [p[0], p[1], bottom],
                    ],
                    [mid[0] - centre[0], mid[1] - centre[1], 0.0],
                    feature,
                );
            }
        }
    }

    fn tunnel(&mut self, profile: &Profile) {
        let plan = plan_tunnel(profile, self.context.ways, self.context.surface_margin_m);
        for &(from, to) in &plan.tube {
            let stations = profile.stretch(from, to);
            for run in self.runs(&stations) {
                let way = &self.context.ways[run.way as usize];
                let traits = self.traits(way);
                let height = traits.tunnel_height_m;
                let floor = Part::TunnelFloor(traits.paving);
                // The floor, the ceiling and each wall.
                let section = Section {
                    parts: [floor, Part::TunnelLining, Part::TunnelLining],
                    down_m: height,
                    sides_out: false,
                };
                self.strips(&run, &section);
                self.lines(&run, false);
            }
        }
        for &(from, to) in &plan.ramps {
            for run in self.runs(&profile.stretch(from, to)) {
                self.lines(&run, true);
            }
        }
        // The opening at each portal, facing out along the ramp.
        let heights = tube_heights(profile, self.context.ways);
        let n = profile.points.len();
        for &at in &plan.portals {
            let outwards = if at < profile.along_m[n - 1] / 2.0 {
                -1.0
            } else {
                1.0
            };
            let pair = profile.stretch(at, at + 0.1);
            let (Some(a), Some(b)) = (pair.first(), pair.last()) else {
                continue;
            };
            let Some(&feature) = self.context.features.get(&a.way) else {
                continue;
            };
            let way = &self.context.ways[a.way as usize];
            let half = self.in_units(way, self.traits(way).width_m / 2.0);
            let Some((left, right)) = offset_polyline(&[a.point, b.point], half) else {
                continue;
            };
            let k = profile.along_m.partition_point(|&s| s <= at).min(n - 1);
            let top = a.elevation + heights[k] - TUNNEL_ROOF_M;
            let facing = [
                outwards * (b.point[0] - a.point[0]),
                outwards * (b.point[1] - a.point[1]),
                0.0,
            ];
            self.face(
                Part::TunnelPortal,
                &[
                    [left[0][0], left[0][1], a.elevation],
                    [right[0][0], right[0][1], a.elevation],
                    [right[0][0], right[0][1], top],
                    [left[0][0], left[0][1], top],
                ],
                facing,
                feature,
            );
        }
    }
}
