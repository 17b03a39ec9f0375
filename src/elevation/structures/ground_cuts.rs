//! The ground tunnels and bridges reshape in a tile: approach cuts drawn as their way's road or
//! railway, the ground raised over a tunnel's roof where its cover is short, and the terrain
//! lowered under a bridge's deck.

use super::*;

/// How far the ground raised over a tunnel reaches beyond the tube's sides, metres.
const RAISED_BEYOND_M: f64 = 0.5;

/// The ground tunnels and bridges reshape in a tile.
#[derive(Debug, Clone, Default)]
pub struct GroundCuts {
    /// The rows the approach cuts need, in order: one per structure way (by index into the
    /// ways) with a cut, standing for that way's element, of the class the cut is drawn as.
    pub rows: Vec<(u32, FeatureClass)>,
    pub cuts: Vec<GroundCut>,
}

/// A stretch of ground a tunnel or a bridge reshapes.
#[derive(Debug, Clone)]
pub struct GroundCut {
    /// The elevation the ground takes there. Its `surface` is left for whoever adds
    /// `surface` to the feature set.
    pub level: Level,
    /// What to draw there, if anything: an approach cut as its way's road or railway, or the
    /// ground raised over the roof (a part of the terrain, row 0).
    pub surface: Option<Surface>,
    /// For an approach cut: the structure way (by index into the ways) whose row in
    /// [`GroundCuts::rows`] it is drawn as.
    pub row_of: Option<u32>,
}

/// The ground tunnels and bridges reshape in a tile: each approach cut drawn as its way's
/// road or railway down at the floor, and the ground raised over the roof where the cover is
/// short, with a floor over every tube that keeps other cuts from exposing it; and the
/// terrain lowered under each bridge's deck ([`trough_under`]). `features` gives the feature
/// row of each structure way drawn in the tile (by index into `ways`); only their stretches
/// (and the bridges with a way drawn) are returned. The feature set is left as it is: adding
/// the cuts is the caller's part.
pub fn ground_cuts(
    settled: &[Settled],
    ways: &[Way],
    features: &std::collections::HashMap<u32, u32>,
    projection: &Projection,
    settings: &FeatureSettings,
    surface_margin_m: f64,
) -> GroundCuts {
    let mut cuts = GroundCuts::default();
    for profile in settled.iter().flat_map(|s| &s.profiles) {
        if profile.kind == StructureKind::Bridge {
            let drawn = profile.ways.iter().any(|w| features.contains_key(w));
            if let Some(trough) = drawn
                .then(|| trough_under(profile, ways, projection, settings))
                .flatten()
            {
                cuts.cuts.push(trough);
            }
            continue;
        }
        let plan = plan_tunnel(profile, ways, surface_margin_m);
        let heights = tube_heights(profile, ways);
        let stretches = plan
            .ramps
            .iter()
            .map(|&r| (r, Reshape::Cut))
            .chain(plan.raised.iter().map(|&r| (r, Reshape::Raised)))
            .chain(plan.tube.iter().map(|&r| (r, Reshape::Guard)));
        for ((from, to), reshape) in stretches {
            let raised = reshape != Reshape::Cut;
            let stations = profile.stretch(from, to);
            let Some(first) = stations.first() else {
                continue;
            };
            // The ramp is the way at its portal; raised ground belongs to the terrain.
            let portal_way = if from <= 0.0 {
                first.way
            } else {
                stations[stations.len() - 1].way
            };
            if !features.contains_key(&portal_way) {
                continue;
            }
            let way = &ways[portal_way as usize];
            let traits = WayTraits::of(way, settings);
            let (line, profile_uv) = line_with_profile(stations.iter().map(|s| {
                let k = profile
                    .along_m
                    .partition_point(|&a| a <= s.along_m)
                    .clamp(1, heights.len())
                    - 1;
                let elevation = if raised {
                    s.elevation + heights[k] + TUNNEL_COVER_M
                } else {
                    s.elevation
                };
                (s.point, elevation)
            }));
            let lat = way.positions.first().map_or(0.0, |p| p.lat);
            let mut width = traits.width_m;
            if raised {
                width += 2.0 * RAISED_BEYOND_M;
            }
            let half = projection.metres(width / 2.0, lat);
            // The cut is drawn as the way's road or railway, a row of that class of its own;
            // raised ground belongs to the terrain.
            let class = match (raised, traits.railway) {
                (true, _) => FeatureClass::Terrain,
                (false, true) => FeatureClass::Railway,
                (false, false) => FeatureClass::Road,
            };
            if !raised && cuts.rows.iter().all(|&(w, _)| w != portal_way) {
                cuts.rows.push((portal_way, class));
            }
            let Some(mut surface) = widened_surface(class, 0, &line, half) else {
                continue;
            };
            if class == FeatureClass::Road {
                surface.paving = traits.paving;
            }
            let rule = Rule::Along {
                stations: Stations::new(&line),
                profile: profile_uv,
            };
            let level = Level::new(u32::MAX, surface.pieces.clone(), surface.bounds, rule);
            cuts.cuts.push(match reshape {
                Reshape::Cut => GroundCut {
                    level,
                    surface: Some(surface),
                    row_of: Some(portal_way),
                },
                Reshape::Raised => GroundCut {
                    level: level.at_least(),
                    surface: Some(surface),
                    row_of: None,
                },
                // Not a surface of its own: it only keeps other ways' cuts off the roof.
                Reshape::Guard => GroundCut {
                    level: level.detached(),
                    surface: None,
                    row_of: None,
                },
            });
        }
    }
    cuts
}

/// The line through `points` (tile units, each with an elevation), a point where the one
/// before it stands dropped, and each kept point's elevation at its distance along the line.
fn line_with_profile(points: impl Iterator<Item = (Point, f64)>) -> (Vec<Point>, Vec<(f64, f64)>) {
    let mut line: Vec<Point> = Vec::new();
    let mut profile: Vec<(f64, f64)> = Vec::new();
    let mut along = 0.0;
    for (point, elevation) in points {
        if let Some(&last) = line.last() {
            let step = distance(last, point);
            if step <= 0.0 {
                continue;
            }
            along += step;
        }
        line.push(point);
        profile.push((along, elevation));
    }
    (line, profile)
}

/// How far under a bridge deck's underside the ground is kept, metres.
const UNDER_DECK_M: f64 = 1.0;
/// How far beyond a deck's sides the ground is kept under it, metres.
const TROUGH_BEYOND_M: f64 = 1.5;
/// How far the ground lowered under a deck slopes back up to the terrain beside it, metres,
/// and how steeply (metres up per metre out).
const TROUGH_SIDE_M: f64 = 12.0;
const TROUGH_SIDE_SLOPE: f64 = 1.0;
/// How steeply the lowered ground deepens from an abutment, where the deck meets the ground
/// (metres down per metre along).
const TROUGH_END_SLOPE: f64 = 0.5;

/// The ground a bridge's deck leaves under it: a ceiling over the terrain along the deck,
/// its underside less [`UNDER_DECK_M`] (shallower towards an abutment, where the deck comes
/// down to the ground), over the deck's width and [`TROUGH_BEYOND_M`] to each side (drawn as
/// a part of the terrain, so the triangulation has its edges), then sloping back up to the
/// terrain. The ceiling only bites where the terrain stands higher: in a valley the ground
/// stays as it is.
fn trough_under(
    profile: &Profile,
    ways: &[Way],
    projection: &Projection,
    settings: &FeatureSettings,
) -> Option<GroundCut> {
    let n = profile.points.len();
    let length = *profile.along_m.last()?;
    let traits: Vec<WayTraits> = profile
        .ways
        .iter()
        .map(|&w| WayTraits::of(&ways[w as usize], settings))
        .collect();
    let depth = |i: usize| {
        let full = traits[i].deck_thickness_m + UNDER_DECK_M;
        let along = profile.along_m[i];
        let from_ground = [
            (profile.grounded[0], along),
            (profile.grounded[1], length - along),
        ]
        .iter()
        .filter(|(grounded, _)| *grounded)
        .map(|&(_, d)| d * TROUGH_END_SLOPE)
        .fold(full, f64::min);
        from_ground.max(0.0)
    };
    let (line, ceiling) =
        line_with_profile((0..n).map(|i| (profile.points[i], profile.elevations[i] - depth(i))));
    let lat = ways[profile.ways[0] as usize]
        .positions
        .first()
        .map_or(0.0, |p| p.lat);
    let width = traits.iter().map(|t| t.width_m).fold(0.0, f64::max);
    let floor_half = projection.metres(width / 2.0 + TROUGH_BEYOND_M, lat);
    let side = projection.metres(TROUGH_SIDE_M, lat);
    let mut floor = widened_surface(FeatureClass::Terrain, 0, &line, floor_half)?;
    // The deck's own edges are edges of the ground too: every vertex under the deck is then
    // one the ceiling holds down, and a slope up to a road held higher beside the deck (two
    // legs of a hairpin) starts at the deck's edge, not under it.
    let deck_half = projection.metres(width / 2.0, lat);
    if let Some(deck) = widened_surface(FeatureClass::Terrain, 0, &line, deck_half) {
        floor.outline.extend(deck.outline);
    }
    let band = widened_surface(FeatureClass::Terrain, 0, &line, floor_half + side)?;
    let rule = Rule::Trough {
        stations: Stations::new(&line),
        profile: ceiling,
        half_width: floor_half,
        rise: TROUGH_SIDE_SLOPE * projection.metres(1.0, lat).recip(),
    };
    Some(GroundCut {
        level: Level::new(u32::MAX, band.pieces, band.bounds, rule).at_most(),
        surface: Some(floor),
        row_of: None,
    })
}

/// How a tunnel reshapes the ground along a stretch.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Reshape {
    /// Down to the floor: the approach to a portal.
    Cut,
    /// Up over the roof where the cover is short: a surface of the ground.
    Raised,
    /// Over the roof along the whole tube, only where something else would cut lower (the
    /// approach of another way beside or across it).
    Guard,
}
