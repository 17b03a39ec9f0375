//! The straight skeleton of a polygon with holes (paper 003 §5.1, after Aichholzer et al.).
//!
//! Every edge moves inwards at unit speed; the polygon's vertices slide along the bisectors of
//! their edges. An edge that shrinks to nothing ends two vertices in one (an *edge event*); a
//! reflex vertex that runs into an edge splits the wavefront in two (a *split event*). The
//! skeleton is the set of paths the vertices trace; the face of an input edge is the area its
//! wavefront edge sweeps, and raised by the time of each point (its distance to that edge) it is
//! a plane: the hipped roof.
//!
//! The wavefront is simulated one event at a time: after each event every candidate event is
//! computed afresh from the current wavefront, so no queued event can go stale, and events at
//! the same moment (a square's four edges, two reflex vertices meeting) are taken one after the
//! other with zero time between them. Building footprints have tens of vertices, so the cubic
//! worst case costs little; the caller limits the size.

use crate::geometry::{signed_area2, Point};

/// A point of the skeleton: an input vertex (time 0) or where an event happened.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SkeletonNode {
    pub point: Point,
    /// The distance the edges had moved when the event happened.
    pub time: f64,
}

/// The straight skeleton of a polygon.
#[derive(Debug, Clone)]
pub struct Skeleton {
    /// The polygon as the skeleton saw it: the outer ring counter-clockwise, holes clockwise,
    /// without repeated or collinear vertices. Edge `k` runs from the `k`-th vertex (counting
    /// through the rings in order) to the next one in its ring.
    pub rings: Vec<Vec<Point>>,
    /// The input vertices first, in ring order, then the event points.
    pub nodes: Vec<SkeletonNode>,
    /// The face of each edge: node indices, counter-clockwise, starting with the edge's two ends.
    pub faces: Vec<Vec<usize>>,
    /// Skeleton arcs between nodes, with the two edges whose faces they separate.
    pub arcs: Vec<SkeletonArc>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SkeletonArc {
    pub from: usize,
    pub to: usize,
    pub edges: [usize; 2],
}

/// How far, relative to the polygon's size, [`Skeleton::verify`] lets a node stray from its
/// faces' planes: a millimetre on a 10 m house.
const TOLERANCE: f64 = 1e-4;

impl Skeleton {
    /// Checks what every straight skeleton satisfies: the faces tile the polygon (their areas
    /// add up to its area), and every node of a face lies on that edge's line moved inwards by
    /// the node's time, so the face raised by time is a plane.
    pub fn verify(&self) -> Result<(), SkeletonError> {
        let size = self
            .rings
            .iter()
            .flatten()
            .fold(0.0f64, |m, p| m.max(p[0].abs()).max(p[1].abs()))
            .max(1.0);
        let area: f64 = self.rings.iter().map(|r| signed_area2(r) / 2.0).sum();
        let faces: f64 = self
            .faces
            .iter()
            .map(|f| {
                let points: Vec<Point> = f.iter().map(|&n| self.nodes[n].point).collect();
                signed_area2(&points) / 2.0
            })
            .sum();
        if (area - faces).abs() > TOLERANCE * area.abs().max(size) {
            return Err(SkeletonError::Faces { faces, area });
        }
        let mut k = 0;
        for ring in &self.rings {
            for i in 0..ring.len() {
                let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
                let d = sub(b, a);
                let len = d[0].hypot(d[1]);
                let normal = [-d[1] / len, d[0] / len];
                for &n in &self.faces[k] {
                    let node = self.nodes[n];
                    let distance = dot(normal, sub(node.point, a));
                    if (distance - node.time).abs() > TOLERANCE * size {
                        return Err(SkeletonError::OffPlane {
                            edge: k,
                            distance,
                            time: node.time,
                        });
                    }
                }
                k += 1;
            }
        }
        Ok(())
    }
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SkeletonError {
    #[error("the faces cover {faces}, the polygon {area}")]
    Faces { faces: f64, area: f64 },
    #[error("a node of edge {edge}'s face lies {distance} from it at time {time}")]
    OffPlane {
        edge: usize,
        distance: f64,
        time: f64,
    },
    #[error("the polygon has no area")]
    Degenerate,
    #[error("the wavefront did not collapse within {0} events")]
    TooManyEvents(usize),
    #[error("no event found while the wavefront still had {0} vertices")]
    Stuck(usize),
    #[error("the face of edge {0} is not closed")]
    OpenFace(usize),
}

/// An input edge's moving line: points `x` with `normal · x = offset + t` at time `t`.
#[derive(Debug, Clone, Copy)]
struct Edge {
    direction: Point,
    normal: Point,
    offset: f64,
}

/// A vertex of the wavefront.
#[derive(Debug, Clone, Copy)]
struct Vertex {
    origin: Point,
    born: f64,
    velocity: Point,
    /// The edge arriving at the vertex and the edge leaving it.
    incoming: usize,
    outgoing: usize,
    node: usize,
    previous: usize,
    next: usize,
    alive: bool,
}

impl Vertex {
    fn at(&self, t: f64) -> Point {
        let dt = t - self.born;
        [
            self.origin[0] + self.velocity[0] * dt,
            self.origin[1] + self.velocity[1] * dt,
        ]
    }
}

#[derive(Debug, Clone, Copy)]
enum Event {
    /// The wavefront edge leaving this vertex shrinks to nothing.
    EdgeCollapse { vertex: usize },
    /// A reflex vertex reaches the wavefront edge leaving `edge_start`.
    Split { vertex: usize, edge_start: usize },
}

fn dot(a: Point, b: Point) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}

fn cross(a: Point, b: Point) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

fn sub(a: Point, b: Point) -> Point {
    [a[0] - b[0], a[1] - b[1]]
}

/// Rings without repeated points, collinear points or spikes, oriented for the skeleton (the
/// outer ring counter-clockwise, holes clockwise), holes that share an edge merged into one.
/// Empty when the outer ring has no area.
fn clean_rings(rings: &[Vec<Point>], eps: f64) -> Vec<Vec<Point>> {
    let near = |p: Point, q: Point| (p[0] - q[0]).hypot(p[1] - q[1]) <= eps;
    let mut cleaned: Vec<Vec<Point>> = rings
        .iter()
        .map(|ring| {
            let mut points: Vec<Point> = Vec::with_capacity(ring.len());
            for &p in ring {
                if points.last().is_none_or(|&q| !near(p, q)) {
                    points.push(p);
                }
            }
            while points.len() > 1 && near(points[0], points[points.len() - 1]) {
                points.pop();
            }
            points
        })
        .collect();
    for (index, ring) in cleaned.iter_mut().enumerate() {
        let area = signed_area2(ring);
        if (index == 0 && area < 0.0) || (index > 0 && area > 0.0) {
            ring.reverse();
        }
    }
    merge_touching_holes(&mut cleaned, &near);
    let mut out = Vec::with_capacity(cleaned.len());
    for (index, ring) in cleaned.into_iter().enumerate() {
        let ring = straighten(ring, eps);
        if ring.len() < 3 {
            if index == 0 {
                return Vec::new();
            }
            continue;
        }
        out.push(ring);
    }
    out
}

/// Drops vertices where a ring goes straight on or turns right back.
fn straighten(mut points: Vec<Point>, eps: f64) -> Vec<Point> {
    let mut changed = true;
    while changed && points.len() >= 3 {
        changed = false;
        let n = points.len();
        for i in 0..n {
            let (a, b, c) = (points[(i + n - 1) % n], points[i], points[(i + 1) % n]);
            let (u, v) = (sub(b, a), sub(c, b));
            let (lu, lv) = (u[0].hypot(u[1]), v[0].hypot(v[1]));
            if lu <= eps || lv <= eps || cross(u, v).abs() <= 1e-9 * lu * lv {
                points.remove(i);
                changed = true;
                break;
            }
        }
    }
    points
}

/// Merges holes that share an edge (two courtyards drawn side by side): the shared edge goes and
/// the two rings become one.
fn merge_touching_holes(rings: &mut Vec<Vec<Point>>, near: &impl Fn(Point, Point) -> bool) {
    'again: loop {
        for i in 1..rings.len() {
            for j in i + 1..rings.len() {
                let (a, b) = (&rings[i], &rings[j]);
                for k in 0..a.len() {
                    for l in 0..b.len() {
                        let shared =
                            near(a[k], b[(l + 1) % b.len()]) && near(a[(k + 1) % a.len()], b[l]);
                        if !shared {
                            continue;
                        }
                        // `a` from the shared edge's end round to its start, then `b` from
                        // that start round to the end, leaving out the shared edge both ways.
                        let mut merged: Vec<Point> =
                            a[k + 1..].iter().chain(&a[..=k]).copied().collect();
                        let b_from: Vec<Point> = b[(l + 1) % b.len()..]
                            .iter()
                            .chain(&b[..(l + 1) % b.len()])
                            .copied()
                            .collect();
                        merged.extend_from_slice(&b_from[1..b_from.len() - 1]);
                        rings[i] = merged;
                        rings.remove(j);
                        continue 'again;
                    }
                }
            }
        }
        return;
    }
}

/// Edges whose unit normals `n₁`, `n₂` have `1 + n₁·n₂` below this (about 1.4·10⁻⁵ rad from
/// opposite) meet as a spike of no width; the error in so taking them is that angle times the
/// spike's length, under a millimetre for a building.
const SPIKE: f64 = 1e-10;

/// The velocity of a vertex between the lines of two edges: the `v` with `n·v = 1` for both
/// unit normals, `(n₁ + n₂) / (1 + n₁·n₂)`, exact for collinear edges too. Between edges that run
/// in opposite directions (a spike of no width, closed at once) it moves with the first.
fn velocity(a: &Edge, b: &Edge) -> Point {
    let sum = [a.normal[0] + b.normal[0], a.normal[1] + b.normal[1]];
    let denominator = 1.0 + dot(a.normal, b.normal);
    if denominator < SPIKE {
        return a.normal;
    }
    [sum[0] / denominator, sum[1] / denominator]
}

/// The straight skeleton of the polygon whose first ring is the outer boundary and the rest
/// holes (either orientation).
pub fn skeleton(rings: &[Vec<Point>]) -> Result<Skeleton, SkeletonError> {
    let size = rings
        .iter()
        .flatten()
        .fold(0.0f64, |m, p| m.max(p[0].abs()).max(p[1].abs()));
    let eps = 1e-9 * size.max(1.0);
    let rings = clean_rings(rings, eps);
    if rings.is_empty() {
        return Err(SkeletonError::Degenerate);
    }
    // Work around the first vertex, for precision.
    let base = rings[0][0];
    let local: Vec<Vec<Point>> = rings
        .iter()
        .map(|r| r.iter().map(|&p| sub(p, base)).collect())
        .collect();

    let mut edges: Vec<Edge> = Vec::new();
    let mut nodes: Vec<SkeletonNode> = Vec::new();
    let mut vertices: Vec<Vertex> = Vec::new();
    let mut edge_ends: Vec<(usize, usize)> = Vec::new();
    for ring in &local {
        let first = vertices.len();
        let n = ring.len();
        for i in 0..n {
            let (a, b) = (ring[i], ring[(i + 1) % n]);
            let d = sub(b, a);
            let len = d[0].hypot(d[1]);
            let direction = [d[0] / len, d[1] / len];
            let normal = [-direction[1], direction[0]];
            edges.push(Edge {
                direction,
                normal,
                offset: dot(normal, a),
            });
            edge_ends.push((first + i, first + (i + 1) % n));
            nodes.push(SkeletonNode {
                point: a,
                time: 0.0,
            });
        }
        for (i, &origin) in ring.iter().enumerate() {
            let incoming = first + (i + n - 1) % n;
            let outgoing = first + i;
            vertices.push(Vertex {
                origin,
                born: 0.0,
                velocity: velocity(&edges[incoming], &edges[outgoing]),
                incoming,
                outgoing,
                node: first + i,
                previous: first + (i + n - 1) % n,
                next: first + (i + 1) % n,
                alive: true,
            });
        }
    }

    let mut arcs: Vec<SkeletonArc> = Vec::new();
    let mut now = 0.0f64;
    let limit = 20 * edges.len() + 100;
    let mut events = 0;
    let flat = 1e-9 * size.max(1.0) * size.max(1.0);
    loop {
        collapse_flat_rings(&mut vertices, &edges, &mut nodes, &mut arcs, now, flat, eps);
        if !vertices.iter().any(|v| v.alive) {
            break;
        }
        events += 1;
        if events > limit {
            return Err(SkeletonError::TooManyEvents(limit));
        }
        let Some((dt, event)) = next_event(&vertices, &edges, now, eps) else {
            return Err(SkeletonError::Stuck(
                vertices.iter().filter(|v| v.alive).count(),
            ));
        };
        now += dt;
        match event {
            Event::EdgeCollapse { vertex } => {
                collapse_edge(&mut vertices, &edges, &mut nodes, &mut arcs, vertex, now)
            }
            Event::Split { vertex, edge_start } => split(
                &mut vertices,
                &edges,
                &mut nodes,
                &mut arcs,
                vertex,
                edge_start,
                now,
            ),
        }
    }

    // Events at one place and time (a square's centre) leave several nodes there: one stands
    // for all, and the arcs between them, of no length, go.
    let mut canonical: Vec<usize> = (0..nodes.len()).collect();
    for i in 0..nodes.len() {
        if let Some(j) = (0..i).find(|&j| {
            canonical[j] == j
                && (nodes[j].point[0] - nodes[i].point[0])
                    .hypot(nodes[j].point[1] - nodes[i].point[1])
                    <= 10.0 * eps
        }) {
            canonical[i] = j;
        }
    }
    let mut merged: Vec<SkeletonArc> = Vec::with_capacity(arcs.len());
    for arc in &arcs {
        let (from, to) = (canonical[arc.from], canonical[arc.to]);
        if from == to {
            continue;
        }
        let same = |a: &SkeletonArc| {
            ((a.from == from && a.to == to) || (a.from == to && a.to == from))
                && (a.edges == arc.edges || a.edges == [arc.edges[1], arc.edges[0]])
        };
        if !merged.iter().any(same) {
            merged.push(SkeletonArc {
                from,
                to,
                edges: arc.edges,
            });
        }
    }
    let arcs = merged;
    let mut faces = (0..edges.len())
        .map(|e| face(e, edge_ends[e], &arcs, &nodes))
        .collect::<Result<Vec<_>, _>>()?;
    insert_passing_nodes(&mut faces, &nodes, eps);
    for node in &mut nodes {
        node.point = [node.point[0] + base[0], node.point[1] + base[1]];
    }
    // The input vertices keep their exact bits, so walls built on the footprint meet the roof.
    for (node, &p) in nodes.iter_mut().zip(rings.iter().flatten()) {
        node.point = p;
    }
    Ok(Skeleton {
        rings,
        nodes,
        faces,
        arcs,
    })
}

/// The earliest event after `now`, as the time until it and the event.
fn next_event(vertices: &[Vertex], edges: &[Edge], now: f64, eps: f64) -> Option<(f64, Event)> {
    let mut best: Option<(f64, Event)> = None;
    let consider = |dt: f64, event: Event, best: &mut Option<(f64, Event)>| {
        // Edge events win ties: they keep the wavefront simpler.
        let better = match best {
            None => true,
            Some((b, Event::EdgeCollapse { .. })) => dt < *b - eps,
            Some((b, Event::Split { .. })) => match event {
                Event::EdgeCollapse { .. } => dt <= *b + eps,
                Event::Split { .. } => dt < *b,
            },
        };
        if better {
            *best = Some((dt, event));
        }
    };
    for (index, a) in vertices.iter().enumerate().filter(|(_, v)| v.alive) {
        let b = &vertices[a.next];
        let edge = &edges[a.outgoing];
        // Edge event: the distance between the ends along the edge reaches zero.
        let gap = dot(edge.direction, sub(b.at(now), a.at(now)));
        let closing = dot(edge.direction, sub(b.velocity, a.velocity));
        if gap <= eps {
            consider(0.0, Event::EdgeCollapse { vertex: index }, &mut best);
        } else if closing < 0.0 {
            consider(
                -gap / closing,
                Event::EdgeCollapse { vertex: index },
                &mut best,
            );
        }
    }
    for (index, r) in vertices.iter().enumerate().filter(|(_, v)| v.alive) {
        let (incoming, outgoing) = (&edges[r.incoming], &edges[r.outgoing]);
        if cross(incoming.direction, outgoing.direction) >= -1e-12 {
            continue;
        }
        let position = r.at(now);
        for (start, c) in vertices.iter().enumerate().filter(|(_, v)| v.alive) {
            if start == index || c.next == index {
                continue;
            }
            let e = c.outgoing;
            if e == r.incoming || e == r.outgoing {
                continue;
            }
            let edge = &edges[e];
            let gap = dot(edge.normal, position) - (edge.offset + now);
            let approach = 1.0 - dot(edge.normal, r.velocity);
            if gap < -eps || approach <= 1e-12 {
                continue;
            }
            let dt = gap.max(0.0) / approach;
            if best.is_some_and(|(b, _)| dt > b + eps) {
                continue;
            }
            let t = now + dt;
            let hit = [
                position[0] + r.velocity[0] * dt,
                position[1] + r.velocity[1] * dt,
            ];
            let d = &vertices[c.next];
            let (from, to, at) = (
                dot(edge.direction, c.at(t)),
                dot(edge.direction, d.at(t)),
                dot(edge.direction, hit),
            );
            if to - from > eps && at > from + eps && at < to - eps {
                consider(
                    dt,
                    Event::Split {
                        vertex: index,
                        edge_start: start,
                    },
                    &mut best,
                );
            }
        }
    }
    best
}

/// Ends every ring of the wavefront that has no area left (two edges meeting along their whole
/// length, as in an L whose wings are as wide as each other): each vertex ends where it is, and
/// the ring's edges become skeleton arcs, closing the faces of their edges.
fn collapse_flat_rings(
    vertices: &mut [Vertex],
    edges: &[Edge],
    nodes: &mut Vec<SkeletonNode>,
    arcs: &mut Vec<SkeletonArc>,
    now: f64,
    flat: f64,
    eps: f64,
) {
    let mut seen = vec![false; vertices.len()];
    for start in 0..vertices.len() {
        if !vertices[start].alive || seen[start] {
            continue;
        }
        let mut ring = vec![start];
        seen[start] = true;
        let mut at = vertices[start].next;
        while at != start && ring.len() <= vertices.len() {
            seen[at] = true;
            ring.push(at);
            at = vertices[at].next;
        }
        let points: Vec<Point> = ring.iter().map(|&v| vertices[v].at(now)).collect();
        if signed_area2(&points).abs() > flat {
            continue;
        }
        if ring.len() == 3 {
            // A tiny triangle: its three lines meet in one point, where it ends.
            let lines = [
                &edges[vertices[ring[0]].outgoing],
                &edges[vertices[ring[1]].outgoing],
                &edges[vertices[ring[2]].outgoing],
            ];
            let middle = [
                points.iter().map(|p| p[0]).sum::<f64>() / 3.0,
                points.iter().map(|p| p[1]).sum::<f64>() / 3.0,
            ];
            let spread = points
                .iter()
                .map(|p| (p[0] - middle[0]).hypot(p[1] - middle[1]))
                .fold(0.0, f64::max);
            let (point, time) = three_lines_meet(lines)
                .filter(|&(p, t)| {
                    t >= now - eps
                        && (p[0] - middle[0]).hypot(p[1] - middle[1]) <= 2.0 * spread + eps
                })
                .unwrap_or((middle, now));
            let node = add_node(nodes, point, time);
            for &v in &ring {
                end_vertex(vertices, arcs, v, node);
            }
            continue;
        }
        let first_new = nodes.len();
        let mut ends = Vec::with_capacity(ring.len());
        for (&v, &p) in ring.iter().zip(&points) {
            let near = |n: usize| (nodes[n].point[0] - p[0]).hypot(nodes[n].point[1] - p[1]) <= eps;
            let own = vertices[v].node;
            let existing = if near(own) {
                Some(own)
            } else {
                (first_new..nodes.len()).find(|&n| near(n))
            };
            ends.push(existing.unwrap_or_else(|| add_node(nodes, p, now)));
        }
        for (i, &v) in ring.iter().enumerate() {
            let edge = vertices[v].outgoing;
            let (from, to) = (ends[i], ends[(i + 1) % ring.len()]);
            end_vertex(vertices, arcs, v, from);
            if from != to {
                arcs.push(SkeletonArc {
                    from,
                    to,
                    edges: [edge, edge],
                });
            }
        }
    }
}

/// The point and time at which three moving edge lines pass through one point: the solution of
/// `nᵢ·x − t = cᵢ`; `None` when the lines do not pin it down.
fn three_lines_meet(lines: [&Edge; 3]) -> Option<(Point, f64)> {
    let m = lines.map(|e| [e.normal[0], e.normal[1], -1.0]);
    let c = lines.map(|e| e.offset);
    let det3 = |m: [[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let det = det3(m);
    if det.abs() < 1e-9 {
        return None;
    }
    let column = |k: usize| {
        let mut r = m;
        for i in 0..3 {
            r[i][k] = c[i];
        }
        det3(r) / det
    };
    Some(([column(0), column(1)], column(2)))
}

/// Where the lines of two edges meet at time `t`, unless they are nearly parallel.
fn meeting_point(a: &Edge, b: &Edge, t: f64) -> Option<Point> {
    let det = cross(a.normal, b.normal);
    if det.abs() < 1e-6 {
        return None;
    }
    let (ca, cb) = (a.offset + t, b.offset + t);
    Some([
        (ca * b.normal[1] - cb * a.normal[1]) / det,
        (a.normal[0] * cb - b.normal[0] * ca) / det,
    ])
}

fn add_node(nodes: &mut Vec<SkeletonNode>, point: Point, time: f64) -> usize {
    nodes.push(SkeletonNode { point, time });
    nodes.len() - 1
}

/// Ends a vertex at a node, with its arc.
fn end_vertex(vertices: &mut [Vertex], arcs: &mut Vec<SkeletonArc>, vertex: usize, node: usize) {
    let v = &mut vertices[vertex];
    v.alive = false;
    if v.node != node {
        arcs.push(SkeletonArc {
            from: v.node,
            to: node,
            edges: [v.incoming, v.outgoing],
        });
    }
}

/// A new vertex of the wavefront at a node.
fn new_vertex(
    vertices: &mut Vec<Vertex>,
    edges: &[Edge],
    point: Point,
    now: f64,
    (incoming, outgoing): (usize, usize),
    node: usize,
) -> usize {
    vertices.push(Vertex {
        origin: point,
        born: now,
        velocity: velocity(&edges[incoming], &edges[outgoing]),
        incoming,
        outgoing,
        node,
        previous: usize::MAX,
        next: usize::MAX,
        alive: true,
    });
    vertices.len() - 1
}

/// Closes a ring of fewer than three vertices: they all end where the first is.
fn close_small_ring(
    vertices: &mut [Vertex],
    nodes: &mut Vec<SkeletonNode>,
    arcs: &mut Vec<SkeletonArc>,
    start: usize,
    now: f64,
) -> bool {
    let second = vertices[start].next;
    let third = vertices[second].next;
    if third != start && second != start {
        return false;
    }
    let ring = if second == start {
        vec![start]
    } else {
        vec![start, second]
    };
    let points: Vec<Point> = ring.iter().map(|&v| vertices[v].at(now)).collect();
    let middle = [
        points.iter().map(|p| p[0]).sum::<f64>() / points.len() as f64,
        points.iter().map(|p| p[1]).sum::<f64>() / points.len() as f64,
    ];
    let node = add_node(nodes, middle, now);
    for v in ring {
        end_vertex(vertices, arcs, v, node);
    }
    true
}

fn collapse_edge(
    vertices: &mut Vec<Vertex>,
    edges: &[Edge],
    nodes: &mut Vec<SkeletonNode>,
    arcs: &mut Vec<SkeletonArc>,
    a: usize,
    now: f64,
) {
    let b = vertices[a].next;
    let (pa, pb) = (vertices[a].at(now), vertices[b].at(now));
    let middle = [(pa[0] + pb[0]) / 2.0, (pa[1] + pb[1]) / 2.0];
    // Where the two lines left meet, so the new vertex starts exactly on both; the middle of
    // the two ends where those lines are too close to parallel to say.
    let spread = (pa[0] - pb[0]).hypot(pa[1] - pb[1]);
    let point = meeting_point(
        &edges[vertices[a].incoming],
        &edges[vertices[b].outgoing],
        now,
    )
    .filter(|p| (p[0] - middle[0]).hypot(p[1] - middle[1]) <= spread + 1e-9)
    .unwrap_or(middle);
    let before = vertices[a].previous;
    let after = vertices[b].next;
    if before == b {
        // Two vertices facing each other: the ring ends here.
        let node = add_node(nodes, point, now);
        end_vertex(vertices, arcs, a, node);
        end_vertex(vertices, arcs, b, node);
        return;
    }
    if before == after {
        // A triangle: all three lines meet in one point, where the three vertices end.
        let lines = [
            &edges[vertices[a].incoming],
            &edges[vertices[a].outgoing],
            &edges[vertices[b].outgoing],
        ];
        let (point, time) = three_lines_meet(lines)
            .filter(|&(p, t)| {
                (t - now).abs() <= 1e-6 * (1.0 + now)
                    && (p[0] - point[0]).hypot(p[1] - point[1]) <= 1e-3 * (1.0 + now)
            })
            .unwrap_or((point, now));
        let node = add_node(nodes, point, time);
        for v in [a, b, before] {
            end_vertex(vertices, arcs, v, node);
        }
        return;
    }
    let node = add_node(nodes, point, now);
    end_vertex(vertices, arcs, a, node);
    end_vertex(vertices, arcs, b, node);
    let joined = (vertices[a].incoming, vertices[b].outgoing);
    let v = new_vertex(vertices, edges, point, now, joined, node);
    vertices[v].previous = before;
    vertices[v].next = after;
    vertices[before].next = v;
    vertices[after].previous = v;
    if !close_small_ring(vertices, nodes, arcs, v, now) {
        zip_spike(vertices, edges, nodes, arcs, v, now);
    }
}

/// True when a vertex sits between two edges running in opposite directions along one line: the
/// tip of a spike of no width (two sides of a wing that have met along their length).
fn is_spike(vertex: &Vertex, edges: &[Edge]) -> bool {
    let (a, b) = (&edges[vertex.incoming], &edges[vertex.outgoing]);
    1.0 + dot(a.normal, b.normal) < SPIKE
}

/// Closes a spike of no width from its tip: the tip runs down the spike to the nearer of its
/// two neighbours (a ridge), which ends there too, and a new vertex carries on between the edges
/// left on either side. Repeats while the new vertex is a spike tip again.
fn zip_spike(
    vertices: &mut Vec<Vertex>,
    edges: &[Edge],
    nodes: &mut Vec<SkeletonNode>,
    arcs: &mut Vec<SkeletonArc>,
    mut tip: usize,
    now: f64,
) {
    let limit = vertices.len();
    for _ in 0..limit {
        if !vertices[tip].alive || !is_spike(&vertices[tip], edges) {
            return;
        }
        let (a, b) = (vertices[tip].previous, vertices[tip].next);
        let here = vertices[tip].at(now);
        let (pa, pb) = (vertices[a].at(now), vertices[b].at(now));
        let (da, db) = (
            (pa[0] - here[0]).hypot(pa[1] - here[1]),
            (pb[0] - here[0]).hypot(pb[1] - here[1]),
        );
        if a == b {
            // A ring of two: it ends along the ridge between them.
            let node = add_node(nodes, pa, now);
            end_vertex(vertices, arcs, tip, node);
            end_vertex(vertices, arcs, a, node);
            return;
        }
        let scale = da.max(db).max(1e-12);
        let (point, ending, joined, before, after) = if (da - db).abs() <= 1e-9 * scale {
            let middle = [(pa[0] + pb[0]) / 2.0, (pa[1] + pb[1]) / 2.0];
            (
                middle,
                vec![tip, a, b],
                (vertices[a].incoming, vertices[b].outgoing),
                vertices[a].previous,
                vertices[b].next,
            )
        } else if da < db {
            (
                pa,
                vec![tip, a],
                (vertices[a].incoming, vertices[tip].outgoing),
                vertices[a].previous,
                b,
            )
        } else {
            (
                pb,
                vec![tip, b],
                (vertices[tip].incoming, vertices[b].outgoing),
                a,
                vertices[b].next,
            )
        };
        let node = add_node(nodes, point, now);
        for &v in &ending {
            end_vertex(vertices, arcs, v, node);
        }
        if ending.contains(&before) || ending.contains(&after) || before == after {
            // Nothing is left of the ring but this point (and perhaps one more vertex).
            for v in [before, after] {
                if vertices[v].alive {
                    end_vertex(vertices, arcs, v, node);
                }
            }
            return;
        }
        let v = new_vertex(vertices, edges, point, now, joined, node);
        vertices[v].previous = before;
        vertices[v].next = after;
        vertices[before].next = v;
        vertices[after].previous = v;
        if close_small_ring(vertices, nodes, arcs, v, now) {
            return;
        }
        tip = v;
    }
}

fn split(
    vertices: &mut Vec<Vertex>,
    edges: &[Edge],
    nodes: &mut Vec<SkeletonNode>,
    arcs: &mut Vec<SkeletonArc>,
    r: usize,
    c: usize,
    now: f64,
) {
    let d = vertices[c].next;
    let e = vertices[c].outgoing;
    let point = vertices[r].at(now);
    let node = add_node(nodes, point, now);
    end_vertex(vertices, arcs, r, node);
    let (before, after) = (vertices[r].previous, vertices[r].next);
    let (incoming, outgoing) = (vertices[r].incoming, vertices[r].outgoing);
    // One ring continues from r's predecessor along the split edge to d, the other from c along
    // the split edge to r's successor.
    let v1 = new_vertex(vertices, edges, point, now, (incoming, e), node);
    let v2 = new_vertex(vertices, edges, point, now, (e, outgoing), node);
    vertices[v1].previous = before;
    vertices[v1].next = d;
    vertices[before].next = v1;
    vertices[d].previous = v1;
    vertices[v2].previous = c;
    vertices[v2].next = after;
    vertices[c].next = v2;
    vertices[after].previous = v2;
    for v in [v1, v2] {
        if !close_small_ring(vertices, nodes, arcs, v, now) {
            zip_spike(vertices, edges, nodes, arcs, v, now);
        }
    }
}

/// Adds to each face the nodes that lie on its sides between two of its corners (where an arc
/// of a neighbouring face ends part way along), so neighbouring faces share every corner and a
/// mesh built from them has no T-junctions.
fn insert_passing_nodes(faces: &mut [Vec<usize>], nodes: &[SkeletonNode], eps: f64) {
    let mut used: Vec<usize> = faces.iter().flatten().copied().collect();
    used.sort_unstable();
    used.dedup();
    for face in faces.iter_mut() {
        let mut out = Vec::with_capacity(face.len());
        for k in 0..face.len() {
            let (a, b) = (face[k], face[(k + 1) % face.len()]);
            out.push(a);
            let (pa, pb) = (nodes[a].point, nodes[b].point);
            let d = sub(pb, pa);
            let length2 = dot(d, d);
            if length2 <= eps * eps {
                continue;
            }
            let mut between: Vec<(f64, usize)> = used
                .iter()
                .filter(|&&n| n != a && n != b && !face.contains(&n))
                .filter_map(|&n| {
                    let r = sub(nodes[n].point, pa);
                    let t = dot(r, d) / length2;
                    let off = cross(d, r).abs() / length2.sqrt();
                    (t > 1e-9 && t < 1.0 - 1e-9 && off <= 10.0 * eps).then_some((t, n))
                })
                .collect();
            between.sort_by(|x, y| x.0.total_cmp(&y.0));
            out.extend(between.into_iter().map(|(_, n)| n));
        }
        *face = out;
    }
}

/// The face of edge `e`: from its start and end vertices back round through the skeleton arcs
/// that border it.
fn face(
    e: usize,
    (start, end): (usize, usize),
    arcs: &[SkeletonArc],
    nodes: &[SkeletonNode],
) -> Result<Vec<usize>, SkeletonError> {
    let mine: Vec<&SkeletonArc> = arcs.iter().filter(|a| a.edges.contains(&e)).collect();
    let mut used = vec![false; mine.len()];
    let mut path = vec![start, end];
    let mut at = end;
    while at != start {
        // Among the unused arcs at this node, take the one that turns most to the left, so
        // the walk keeps to this face's side.
        let came_from = nodes[path[path.len() - 2]].point;
        let here = nodes[at].point;
        let back = sub(came_from, here);
        let mut choice: Option<(usize, usize, f64)> = None;
        for (i, arc) in mine.iter().enumerate() {
            if used[i] || (arc.from != at && arc.to != at) {
                continue;
            }
            let other = if arc.from == at { arc.to } else { arc.from };
            let out = sub(nodes[other].point, here);
            // Angle from the way back, turning clockwise: the smallest is the leftmost turn.
            let mut angle = cross(out, back).atan2(dot(out, back));
            if angle <= 0.0 {
                angle += std::f64::consts::TAU;
            }
            if choice.is_none_or(|c| angle < c.2) {
                choice = Some((i, other, angle));
            }
        }
        let Some((i, other, _)) = choice else {
            return Err(SkeletonError::OpenFace(e));
        };
        used[i] = true;
        if other != start {
            path.push(other);
        }
        at = other;
        if path.len() > mine.len() + 2 {
            return Err(SkeletonError::OpenFace(e));
        }
    }
    Ok(path)
}

#[cfg(test)]
pub(crate) mod tests;
