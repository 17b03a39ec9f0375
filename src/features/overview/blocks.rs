//! Buildings merged into blocks for far views: the footprints of one height band are closed
//! (grown by a tolerance and shrunk back) so buildings nearer each other than two tolerances
//! join, then simplified; a block keeps the mean height of its buildings (weighted by area) and
//! belongs to the one tile that holds the centre of its bounds. Blocks of a coarser level are
//! made alike from the finer level's blocks.

use std::collections::HashMap;

use geo::algorithm::buffer::{BufferStyle, LineJoin};
use geo::{Buffer, Simplify, SimplifyVwPreserve};

use super::super::{buildings, tile_rect, Area, BuildingShape, FeatureSettings, Projection};
use super::Level;
use crate::geometry::{Point, Polygon, Rect};
use crate::osm::far::{Block, WorldPoint};
use crate::osm::Tags;

/// Blocks smaller than a square this many tolerances wide are left out.
const MIN_BLOCK_TOLERANCES: f64 = 3.0;
/// The upper bounds of the height bands buildings merge within, metres.
const HEIGHT_BANDS_M: [f64; 4] = [12.0, 24.0, 48.0, 96.0];
/// Footprints whose boxes, grown by this many tolerances, share a cell of a grid this fine
/// are closed together: a closing by one tolerance (with mitred corners reaching out two)
/// joins nothing farther apart.
const CLUSTER_REACH_TOLERANCES: f64 = 2.5;

/// A building footprint (or a finer level's block) with the height it stands to.
pub(super) struct Footprint {
    polygon: Polygon,
    height_m: f64,
    area: f64,
    centre: Point,
}

impl Footprint {
    fn new(polygon: Polygon, height_m: f64) -> Footprint {
        Footprint {
            area: polygon.area(),
            centre: centre_of(&polygon.bounds()),
            polygon,
            height_m,
        }
    }
}

/// Footprints by height band.
pub(super) type Bands = Vec<Vec<Footprint>>;

fn band_of(height_m: f64) -> usize {
    HEIGHT_BANDS_M
        .iter()
        .position(|&top| height_m < top)
        .unwrap_or(HEIGHT_BANDS_M.len())
}

fn empty_bands() -> Bands {
    (0..=HEIGHT_BANDS_M.len()).map(|_| Vec::new()).collect()
}

/// The footprints of the buildings among `areas`, in the projection's units.
pub(super) fn of_buildings(
    areas: &[Area<'_>],
    projection: &Projection,
    settings: &FeatureSettings,
) -> Bands {
    let mut bands = empty_bands();
    for area in areas {
        if !buildings::is_building(area.tags) {
            continue;
        }
        let (height_m, _) = buildings::height_m(area.tags, settings);
        for polygon in area.polygons.iter().filter_map(|p| projection.polygon(p)) {
            bands[band_of(height_m)].push(Footprint::new(polygon, height_m));
        }
    }
    bands
}

/// The footprints of a finer level's blocks, in the units of tiles of `zoom`.
pub(super) fn of_blocks(blocks: &[&Block], zoom: u8) -> Bands {
    let mut bands = empty_bands();
    for block in blocks {
        let polygon = from_world(block, zoom);
        if polygon.outer.len() >= 3 {
            bands[band_of(block.height_m)].push(Footprint::new(polygon, block.height_m));
        }
    }
    bands
}

/// The blocks `level`'s tile owns, made from `bands`, with their heights: small ones too (a
/// coarser level may join them to others; see [`large_enough`]).
pub(super) fn owned(bands: &Bands, level: Level) -> Vec<(Polygon, f64)> {
    let tile = tile_rect(level.tile);
    let mut owned = Vec::new();
    for footprints in bands.iter().filter(|b| !b.is_empty()) {
        for (outline, height_m) in blocks_of(footprints, level.tolerance_uv()) {
            if tile.owns(centre_of(&outline.bounds())) {
                owned.push((outline, height_m));
            }
        }
    }
    owned
}

/// A block as kept: its outline in world coordinates.
pub(super) fn to_world(outline: &Polygon, height_m: f64, zoom: u8) -> Block {
    let scale = 1.0 / f64::from(1u32 << zoom);
    let ring = |points: &[Point]| -> Vec<WorldPoint> {
        points
            .iter()
            .map(|p| [p[0] * scale, p[1] * scale])
            .collect()
    };
    Block {
        outer: ring(&outline.outer),
        holes: outline.holes.iter().map(|h| ring(h)).collect(),
        height_m,
    }
}

/// A kept block's outline in the units of tiles of `zoom`.
pub(super) fn from_world(block: &Block, zoom: u8) -> Polygon {
    let scale = f64::from(1u32 << zoom);
    let ring = |points: &[WorldPoint]| -> Vec<Point> {
        points
            .iter()
            .map(|p| [p[0] * scale, p[1] * scale])
            .collect()
    };
    Polygon {
        outer: ring(&block.outer),
        holes: block.holes.iter().map(|h| ring(h)).collect(),
    }
}

/// Whether a block is large enough to be drawn at a level of this tolerance: at least a square
/// [`MIN_BLOCK_TOLERANCES`] wide.
pub(super) fn large_enough(outline: &Polygon, tolerance: f64) -> bool {
    outline.area() >= (MIN_BLOCK_TOLERANCES * tolerance).powi(2)
}

fn centre_of(rect: &Rect) -> Point {
    [
        (rect.min[0] + rect.max[0]) / 2.0,
        (rect.min[1] + rect.max[1]) / 2.0,
    ]
}

/// A flat-roofed block standing on its lowest ground.
pub(super) fn block_shape(
    feature: u32,
    footprint: Polygon,
    height_m: f64,
    settings: &FeatureSettings,
) -> BuildingShape {
    let flat = Tags::from_pairs([("roof:shape", "flat")]);
    BuildingShape {
        feature,
        footprint,
        height_m,
        height_tagged: true,
        basement_m: 0.0,
        roof: buildings::roof_spec(&flat, settings),
        min_height_m: 0.0,
        drawn: true,
        base: None,
        appearance: buildings::appearance(&Tags::default()),
        // Far views draw walls without windows.
        facade: Default::default(),
        passages: Vec::new(),
    }
}

/// The blocks of one height band: the footprints closed by `tolerance`, simplified; each with
/// the area-weighted mean height of the footprints whose centre it holds. Footprints too far
/// apart to join are closed apart, so the work grows with the number of footprints, not with
/// its square.
fn blocks_of(footprints: &[Footprint], tolerance: f64) -> Vec<(Polygon, f64)> {
    let mut blocks: Vec<(Polygon, f64)> = clusters(footprints, tolerance)
        .iter()
        .flat_map(|members| {
            let cluster: Vec<&Footprint> = members.iter().map(|&i| &footprints[i]).collect();
            blocks_of_cluster(&cluster, tolerance)
        })
        .collect();
    // The order the overlay returns them in, made independent of it.
    blocks.sort_by(|a, b| {
        let (ka, kb) = (a.0.outer[0], b.0.outer[0]);
        ka[0].total_cmp(&kb[0]).then(ka[1].total_cmp(&kb[1]))
    });
    blocks
}

/// The footprints in groups that no closing by `tolerance` joins across, each in input order.
fn clusters(footprints: &[Footprint], tolerance: f64) -> Vec<Vec<usize>> {
    let reach = CLUSTER_REACH_TOLERANCES * tolerance;
    let cell = 2.0 * reach;
    let mut parent: Vec<usize> = (0..footprints.len()).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    let mut first_in: HashMap<(i64, i64), usize> = HashMap::new();
    for (i, f) in footprints.iter().enumerate() {
        let b = f.polygon.bounds();
        let span = |lo: f64, hi: f64| {
            ((lo - reach) / cell).floor() as i64..=((hi + reach) / cell).floor() as i64
        };
        for x in span(b.min[0], b.max[0]) {
            for y in span(b.min[1], b.max[1]) {
                let other = *first_in.entry((x, y)).or_insert(i);
                let (ri, ro) = (root(&mut parent, i), root(&mut parent, other));
                parent[ri.max(ro)] = ri.min(ro);
            }
        }
    }
    let mut groups: HashMap<usize, Vec<usize>> = HashMap::new();
    for i in 0..footprints.len() {
        let r = root(&mut parent, i);
        groups.entry(r).or_default().push(i);
    }
    let mut groups: Vec<Vec<usize>> = groups.into_values().collect();
    groups.sort_unstable_by_key(|g| g[0]);
    groups
}

/// The blocks of footprints that may join. Each outline is thinned first (the footprints to half
/// the tolerance, the grown and the closed shapes to a quarter): the overlay's work grows with
/// the vertices, and the shapes hardly move.
fn blocks_of_cluster(footprints: &[&Footprint], tolerance: f64) -> Vec<(Polygon, f64)> {
    let all = geo::MultiPolygon::new(
        footprints
            .iter()
            .map(|f| thinned(to_geo(&f.polygon), tolerance / 2.0))
            .collect(),
    );
    let style = |distance: f64| BufferStyle::new(distance).line_join(LineJoin::Miter(2.0));
    let closed = all
        .buffer_with_style(style(tolerance))
        .simplify(tolerance / 4.0)
        .buffer_with_style(style(-tolerance));
    closed
        .0
        .iter()
        .map(|p| {
            p.simplify(tolerance / 4.0)
                .simplify_vw_preserve(tolerance * tolerance)
        })
        .filter_map(|p| from_geo(&p))
        .filter_map(|polygon| {
            let bounds = polygon.bounds();
            let (mut weighted, mut total) = (0.0, 0.0);
            for f in footprints {
                if bounds.contains(f.centre) && polygon.contains(f.centre) {
                    weighted += f.height_m * f.area;
                    total += f.area;
                }
            }
            (total > 0.0).then(|| (polygon, weighted / total))
        })
        .collect()
}

/// A footprint thinned to `epsilon`, or as it is where thinning would leave no area (a
/// footprint about as small as `epsilon`: it still counts where it joins others).
fn thinned(polygon: geo::Polygon<f64>, epsilon: f64) -> geo::Polygon<f64> {
    use geo::Area;
    let thin = polygon.simplify(epsilon);
    if thin.exterior().0.len() >= 4 && thin.unsigned_area() >= 0.5 * polygon.unsigned_area() {
        thin
    } else {
        polygon
    }
}

fn to_geo(polygon: &Polygon) -> geo::Polygon<f64> {
    let ring = |points: &[Point]| {
        geo::LineString::from(points.iter().map(|p| (p[0], p[1])).collect::<Vec<_>>())
    };
    geo::Polygon::new(
        ring(&polygon.outer),
        polygon.holes.iter().map(|h| ring(h)).collect(),
    )
}

fn from_geo(polygon: &geo::Polygon<f64>) -> Option<Polygon> {
    let ring = |line: &geo::LineString<f64>| {
        crate::geometry::dedup_ring(&line.coords().map(|c| [c.x, c.y]).collect::<Vec<_>>())
    };
    let outer = ring(polygon.exterior());
    if outer.len() < 3 {
        return None;
    }
    let holes = polygon
        .interiors()
        .iter()
        .map(ring)
        .filter(|h| h.len() >= 3)
        .collect();
    Some(Polygon { outer, holes })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(x: f64, y: f64, size: f64) -> Polygon {
        Polygon {
            outer: vec![[x, y], [x + size, y], [x + size, y + size], [x, y + size]],
            holes: Vec::new(),
        }
    }

    fn footprint(polygon: Polygon, height_m: f64) -> Footprint {
        Footprint::new(polygon, height_m)
    }

    #[test]
    fn buildings_nearer_than_two_tolerances_merge_into_one_block() {
        let t = 0.001;
        let near = [
            footprint(square(0.0, 0.0, 0.01), 10.0),
            footprint(square(0.0115, 0.0, 0.01), 20.0),
        ];
        let blocks = blocks_of(&near, t);
        assert_eq!(blocks.len(), 1);
        // Weighted by area (equal here): the mean.
        assert!((blocks[0].1 - 15.0).abs() < 1e-9);
        let far = [
            footprint(square(0.0, 0.0, 0.01), 10.0),
            footprint(square(0.0130, 0.0, 0.01), 20.0),
        ];
        assert_eq!(blocks_of(&far, t).len(), 2);
    }

    #[test]
    fn blocks_smaller_than_the_level_shows_are_left_out() {
        let t = 0.001;
        let shown = |f: Footprint| {
            let blocks = blocks_of(&[f], t);
            assert_eq!(blocks.len(), 1, "kept, for a coarser level to join");
            large_enough(&blocks[0].0, t)
        };
        assert!(!shown(footprint(square(0.0, 0.0, 0.002), 10.0)));
        assert!(shown(footprint(square(0.0, 0.0, 0.004), 10.0)));
    }

    #[test]
    fn a_block_keeps_its_footprints_outline_within_the_tolerance() {
        let t = 0.001;
        // An L of two touching rectangles with a notch far smaller than the tolerance.
        let l = Polygon {
            outer: vec![
                [0.0, 0.0],
                [0.02, 0.0],
                [0.02, 0.0001],
                [0.0201, 0.0001],
                [0.0201, 0.01],
                [0.01, 0.01],
                [0.01, 0.02],
                [0.0, 0.02],
            ],
            holes: Vec::new(),
        };
        let blocks = blocks_of(&[footprint(l.clone(), 9.0)], t);
        assert_eq!(blocks.len(), 1);
        let block = &blocks[0].0;
        assert!(block.outer.len() < l.outer.len(), "{:?}", block.outer);
        for p in &block.outer {
            let off = l
                .outer
                .iter()
                .zip(l.outer.iter().cycle().skip(1))
                .map(|(&a, &b)| crate::geometry::distance_to_segment(*p, a, b))
                .fold(f64::INFINITY, f64::min);
            assert!(off <= t, "{p:?} lies {off} from the footprint");
        }
        assert!((block.area() - l.area()).abs() < 0.02 * l.area());
    }

    #[test]
    fn footprints_closed_apart_make_the_blocks_they_make_together() {
        let t = 0.001;
        // Rows of houses, near each other within a row, the rows far apart.
        let mut houses = Vec::new();
        for row in 0..4 {
            for k in 0..6 {
                let (x, y) = (f64::from(k) * 0.006, f64::from(row) * 0.05);
                houses.push(footprint(square(x, y, 0.005), 6.0 + f64::from(k)));
            }
        }
        assert_eq!(clusters(&houses, t).len(), 4);
        let apart = blocks_of(&houses, t);
        let all: Vec<&Footprint> = houses.iter().collect();
        let mut together = blocks_of_cluster(&all, t);
        together.sort_by(|a, b| a.0.outer[0][0].total_cmp(&b.0.outer[0][0]));
        assert_eq!(apart.len(), 4);
        assert_eq!(together.len(), 4);
        let key = |b: &(Polygon, f64)| (b.0.area(), b.1);
        let mut apart: Vec<_> = apart.iter().map(key).collect();
        let mut together: Vec<_> = together.iter().map(key).collect();
        apart.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
        together.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
        for (a, b) in apart.iter().zip(&together) {
            assert!(
                (a.0 - b.0).abs() <= 1e-12 && (a.1 - b.1).abs() <= 1e-9,
                "{a:?} {b:?}"
            );
        }
        assert!((apart[0].1 - 8.5).abs() < 1e-9);
    }

    #[test]
    fn a_block_kept_in_world_coordinates_comes_back_at_any_zoom() {
        let outline = square(8529.25, 5974.5, 0.01);
        let block = to_world(&outline, 7.5, 14);
        assert_eq!(from_world(&block, 14), outline);
        let coarser = from_world(&block, 12);
        assert_eq!(coarser.outer[0], [8529.25 / 4.0, 5974.5 / 4.0]);
        assert_eq!(block.height_m, 7.5);
    }
}
