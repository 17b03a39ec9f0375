//! The stages before a tile's ground is made: its features, its bridges and tunnels settled
//! whole and the ground their tunnels cut, and its ground roads held to their grade.

use super::*;

/// How far beyond a tile a line cut to the tile is kept, degrees (about 2 km): ten times as far
/// as a tile's query reaches, so that where the line bends near the tile, the segments on
/// either side are long enough that the bend is drawn as in the whole way.
const LONG_WAY_MARGIN_DEG: f64 = 0.02;

/// What the tile draws, and the elevations settled before its ground is made.
pub(super) struct Elevations {
    /// What the tile draws, with a row for each bridge and tunnel way near it, and the
    /// surfaces of the ground tunnels cut.
    pub(super) feature_set: FeatureSet,
    pub(super) structure_features: HashMap<u32, u32>,
    pub(super) structures: Vec<elevation::structures::Settled>,
    pub(super) cuts: Vec<elevation::settled::Level>,
    pub(super) road_profiles: elevation::road_profiles::RoadProfiles,
}

/// The features, the bridges and tunnels settled whole and the ground their tunnels cut, and
/// the ground roads' profiles. Bridges and tunnels read the OSM data and the terrain only: they
/// are settled on a thread of their own while the features are collected and the roads they
/// draw are settled. The cuts are added to the features afterwards; should a cut add a road
/// to those drawn, the roads are settled again, so the result is always that of settling the
/// roads after the cuts.
pub(super) fn elevations(
    tile: TileId,
    selection: &Selection<'_>,
    (terrain, settings): (&TerrainModel<'_>, &RenderSettings),
    timings: &mut StageTimings,
    context: Context<'_>,
) -> Result<Elevations, RenderError> {
    // Lines too long to settle whole are drawn on the terrain, cut to the part near the tile
    // (counted with the features).
    let started = Instant::now();
    let (cut, draped) = long_ways_cut(tile, selection, settings);
    let selection = &selection.with_cut_ways(&cut);
    let draped = &draped;
    let cutting = started.elapsed();

    let started = Instant::now();
    let (mosaic, solutions) = (terrain.mosaic, context.solutions);
    let ((structures, structures_took), (mut feature_set, structure_features, roads)) =
        crate::parallel::join(
            || {
                let started = Instant::now();
                let terrain = TerrainModel::new(mosaic, settings.interpolation, tile.z);
                let groups = settle_groups(tile, selection, &terrain, settings, solutions);
                (groups, started.elapsed())
            },
            || {
                let started = Instant::now();
                let (set, structure_features) = drawn_features(tile, selection, settings);
                let features_took = started.elapsed();
                let started = Instant::now();
                let drawn = drawn_road_ways(&set);
                let profiles = settle_roads(
                    tile,
                    selection,
                    &drawn,
                    (terrain, settings),
                    draped,
                    solutions,
                );
                let roads = (drawn, profiles, features_took, started.elapsed());
                (set, structure_features, roads)
            },
        );
    let (drawn, mut road_profiles, features_took, roads_took) = roads;
    timings.features = cutting + features_took;
    timings.roads = roads_took;
    // Settling the bridges and tunnels counts for what it took beyond the features and roads.
    let hidden = started
        .elapsed()
        .saturating_sub(features_took + roads_took)
        .min(structures_took);
    context.deadline.check(tile, "features")?;

    // The ground the tunnels cut.
    let started = Instant::now();
    let margin = settings.mesh.max_error_m;
    let cuts = elevation::structures::ground_cuts(
        &structures,
        selection.all_ways,
        &structure_features,
        &features::Projection::new(tile.z),
        &settings.features,
        margin,
    );
    let cuts = add_ground_cuts(
        &mut feature_set,
        cuts,
        &structure_features,
        selection.all_ways,
    );
    timings.structures = hidden + started.elapsed();
    context.deadline.check(tile, "structures")?;

    let drawn_now = drawn_road_ways(&feature_set);
    if drawn_now != drawn {
        let started = Instant::now();
        road_profiles = settle_roads(
            tile,
            selection,
            &drawn_now,
            (terrain, settings),
            draped,
            solutions,
        );
        timings.roads += started.elapsed();
    }
    context.deadline.check(tile, "roads")?;
    Ok(Elevations {
        feature_set,
        structure_features,
        structures,
        cuts,
        road_profiles,
    })
}

/// The features stage: what the tile draws, and the feature row of each bridge and tunnel way
/// near it (by index into all ways).
fn drawn_features(
    tile: TileId,
    selection: &Selection<'_>,
    settings: &RenderSettings,
) -> (FeatureSet, HashMap<u32, u32>) {
    let mut feature_set = features::collect(selection, tile, &settings.features);
    let structure_features = features::structures::rows(
        &mut feature_set,
        &selection.structures,
        selection.all_ways,
        tile,
    );
    (feature_set, structure_features)
}

/// Adds the ground the tunnels reshape to the feature set: a row for each way's approach cuts,
/// a surface for each cut and raised stretch; returns the levels the ground takes, each naming
/// its surface.
fn add_ground_cuts(
    set: &mut FeatureSet,
    cuts: elevation::structures::GroundCuts,
    structure_rows: &HashMap<u32, u32>,
    ways: &[crate::osm::Way],
) -> Vec<elevation::settled::Level> {
    let mut rows: HashMap<u32, u32> = HashMap::new();
    for (way, class) in cuts.rows {
        if let Some(&structure_row) = structure_rows.get(&way) {
            let row =
                features::structures::add_cut_row(set, structure_row, class, &ways[way as usize]);
            rows.insert(way, row);
        }
    }
    let mut levels = Vec::with_capacity(cuts.cuts.len());
    for cut in cuts.cuts {
        let mut level = cut.level;
        if let Some(mut surface) = cut.surface {
            if let Some(&row) = cut.row_of.and_then(|way| rows.get(&way)) {
                surface.feature = row;
            }
            level.surface = set.surfaces.len() as u32;
            set.surfaces.push(surface);
        }
        levels.push(level);
    }
    levels
}

/// Settles every bridge and tunnel that reaches the tile, each group whole; violated soft
/// constraints are logged at debug level. A group near the tile none of whose ways reaches it
/// is left unsettled: the tile neither draws it nor cuts its ground for it.
fn settle_groups(
    tile: TileId,
    selection: &Selection<'_>,
    terrain: &dyn Elevation,
    settings: &RenderSettings,
    solutions: &Solutions,
) -> Vec<elevation::structures::Settled> {
    let projection = features::Projection::new(tile.z);
    selection
        .structures
        .iter()
        .filter(|group| features::structures::group_reaches(group, selection.all_ways, tile))
        .map(|group| {
            let settled = elevation::structures::settle(
                group,
                selection.all_ways,
                terrain,
                &projection,
                &settings.features,
                settings.mesh.max_error_m,
                solutions,
            );
            log_violations(
                tile,
                settled.violations(crate::output::debug::VIOLATION_TOLERANCE_M),
            );
            settled
        })
        .collect()
}

/// Settles the profiles of the ground roads drawn in `set`; violated soft constraints are
/// logged at debug level.
/// The profiles of the ground roads the tile draws, `draped` aside (they follow the terrain).
fn settle_roads(
    tile: TileId,
    selection: &Selection<'_>,
    drawn: &std::collections::BTreeSet<i64>,
    (terrain, settings): (&dyn Elevation, &RenderSettings),
    draped: &std::collections::BTreeSet<i64>,
    solutions: &Solutions,
) -> elevation::road_profiles::RoadProfiles {
    let Some(graph) = selection.roads else {
        return Default::default();
    };
    let ways: Vec<&crate::osm::Way> = selection
        .ways
        .iter()
        .copied()
        .filter(|w| drawn.contains(&w.id) && !draped.contains(&w.id))
        .collect();
    // The tile and a little around it: what the tile draws of a stretch reaches no farther.
    let reach = 0.05;
    let (x, y) = (f64::from(tile.x), f64::from(tile.y));
    let area = crate::geometry::Rect {
        min: [x - reach, y - reach],
        max: [x + 1.0 + reach, y + 1.0 + reach],
    };
    let profiles = elevation::road_profiles::settle(
        area,
        &ways,
        selection.all_ways,
        graph,
        terrain,
        &features::Projection::new(tile.z),
        &settings.features,
        solutions,
    );
    log_violations(tile, profiles.violations.iter());
    profiles
}

/// The ways whose road surfaces `set` draws on the ground.
fn drawn_road_ways(set: &FeatureSet) -> std::collections::BTreeSet<i64> {
    set.surfaces
        .iter()
        .filter(|s| s.class == features::FeatureClass::Road && !s.piece_lines.is_empty())
        .filter_map(|s| set.features.get(s.feature as usize)?.element)
        .filter(|e| e.element_type == crate::osm::ElementType::Way)
        .map(|e| e.id)
        .collect()
}

/// Logs soft constraints that had to give way, at debug level.
fn log_violations<'a>(
    tile: TileId,
    reports: impl Iterator<Item = &'a elevation::structures::ConstraintReport>,
) {
    for report in reports {
        tracing::debug!(
            %tile,
            way = report.way,
            constraint = report.kind.as_str(),
            bound = report.bound,
            violation = report.violation,
            "soft constraint violated"
        );
    }
}

/// The ground roads of a tile, settled as its glb settles them.
pub fn settle_road_profiles(
    tile: TileId,
    selection: &Selection<'_>,
    mosaic: &Mosaic,
    settings: &RenderSettings,
    solutions: &Solutions,
) -> elevation::road_profiles::RoadProfiles {
    let terrain = TerrainModel::new(mosaic, settings.interpolation, tile.z);
    let (cut, draped) = long_ways_cut(tile, selection, settings);
    let selection = &selection.with_cut_ways(&cut);
    let set = features::collect(selection, tile, &settings.features);
    settle_roads(
        tile,
        selection,
        &drawn_road_ways(&set),
        (&terrain, settings),
        &draped,
        solutions,
    )
}

/// The lines of `selection` too long to settle whole, cut to the part near the tile, and
/// their ids: they are drawn on the terrain.
fn long_ways_cut(
    tile: TileId,
    selection: &Selection<'_>,
    settings: &RenderSettings,
) -> (Vec<crate::osm::Way>, std::collections::BTreeSet<i64>) {
    let near = tile.bounds().expanded(LONG_WAY_MARGIN_DEG);
    let cut = selection.cut_long_ways(&near, settings.features.longest_way_m());
    let draped: std::collections::BTreeSet<i64> = cut.iter().map(|w| w.id).collect();
    if !draped.is_empty() {
        tracing::debug!(%tile, ways = ?draped, "lines too long to settle whole drawn from the part near the tile");
    }
    (cut, draped)
}

/// The bridges and tunnels that reach a tile, settled as its glb settles them.
pub fn settle_structures(
    tile: TileId,
    selection: &Selection<'_>,
    mosaic: &Mosaic,
    settings: &RenderSettings,
    solutions: &Solutions,
) -> Vec<elevation::structures::Settled> {
    let terrain = TerrainModel::new(mosaic, settings.interpolation, tile.z);
    settle_groups(tile, selection, &terrain, settings, solutions)
}
