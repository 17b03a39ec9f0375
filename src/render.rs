//! The rendering pipeline of one tile, from OSM elements and SRTM samples to glb or
//! quantized-mesh bytes. It orchestrates; each stage's work lives in its module:
//!
//! features (`features::collect`) → structures (bridges and tunnels settled whole,
//! `elevation::structures`) → roads (ground road profiles, `elevation::road_profiles`) →
//! triangulation (the ground with features stitched in, `mesh::ground`, settled elevations put
//! on its vertices, `mesh::flatten`) → normals (`mesh::normals`) → ground (its triangles into
//! parts, `mesh::ground_parts`) → shapes (buildings, barriers, bridges and tunnels, power lines,
//! trees and objects, `mesh::*`) → encode (`output::glb`, `output::quantized_mesh`).
//!
//! Everything here is a pure function of its inputs: no I/O, no randomness, sorted iteration
//! wherever order reaches the output, so the same inputs give the same bytes. Stage times are
//! measured for reporting only ([`StageTimings`]); they never reach the output.

use std::collections::{BTreeMap, HashMap};
use std::time::{Duration, Instant};

use crate::elevation;
use crate::elevation::ground::{Ground as SettledGround, LevelIndex};
pub use crate::elevation::solutions::Solutions;
use crate::features::{self, FeatureClass, FeatureSet, FeatureSettings};
use crate::geoid::VerticalDatum;
use crate::mesh::ground::{self, Ground, MeshSettings};
use crate::mesh::ground_parts::GroundParts;
use crate::mesh::{self, MeshBuffers, Part};
use crate::osm::index::Selection;
use crate::output::{glb, quantized_mesh};
use crate::terrain::{Elevation, Interpolation, Mosaic, TerrainModel};
use crate::tile::{TileFrame, TileId};

mod elevations;
mod stats;
mod terrain;
use elevations::{elevations, Elevations};
pub use elevations::{settle_road_profiles, settle_structures};
pub use stats::{RenderStats, StageTimings};
pub use terrain::{render_overview_terrain, render_terrain, RenderedTerrain};

/// Settings that change what a tile looks like (and so belong in the cache key).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct RenderSettings {
    pub interpolation: Interpolation,
    pub mesh: MeshSettings,
    pub features: FeatureSettings,
    /// What the heights of east-north-up content and quantized-mesh terrain are measured from
    /// (the flat frame keeps SRTM's heights). Added after the first fingerprints: left out of
    /// them at its default (see [`Fingerprinted`]), so tiles made before it existed keep theirs.
    pub vertical_datum: VerticalDatum,
}

impl RenderSettings {
    /// A short stable fingerprint of the settings, for cache keys: the first 6 bytes of the
    /// SHA-256 of [`Fingerprinted`] as JSON.
    pub fn fingerprint(&self) -> String {
        use sha2::Digest;
        let fingerprinted = Fingerprinted {
            interpolation: &self.interpolation,
            mesh: &self.mesh,
            features: &self.features,
            vertical_datum: &self.vertical_datum,
        };
        let text = serde_json::to_string(&fingerprinted).expect("settings serialize");
        let digest = sha2::Sha256::digest(text.as_bytes());
        digest[..6].iter().map(|b| format!("{b:02x}")).collect()
    }
}

/// What a fingerprint is the digest of: the settings the first fingerprints were made of, in
/// their order, then each setting added since, written only away from its default. A setting
/// added at its default leaves every fingerprint (and the tiles cached under it) as it was; a
/// setting changed, or one added and then set, makes a new one.
#[derive(serde::Serialize)]
struct Fingerprinted<'a> {
    interpolation: &'a Interpolation,
    mesh: &'a MeshSettings,
    features: &'a FeatureSettings,
    /// Added after the first fingerprints.
    #[serde(skip_serializing_if = "is_default")]
    vertical_datum: &'a VerticalDatum,
}

fn is_default<T: Default + PartialEq>(value: &&T) -> bool {
    **value == T::default()
}

#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error(transparent)]
    Ground(#[from] ground::GroundError),
    #[error("rendering tile {tile} failed unexpectedly: {message}")]
    Panicked { tile: TileId, message: String },
    #[error("rendering tile {tile} took longer than its limit of {} s (stopped after {stage})", .limit.as_secs_f64())]
    TimedOut {
        tile: TileId,
        limit: Duration,
        stage: &'static str,
    },
    #[error("rendering tile {tile} took more memory than its limit of {limit_mib} MiB (stopped after {stage})")]
    OverBudget {
        tile: TileId,
        limit_mib: usize,
        stage: &'static str,
    },
}

/// When a render must give up: checked between its stages. It gives up past its time, and
/// when the memory budget its thread runs under ([`crate::budget`]) is exceeded.
#[derive(Debug, Clone, Copy, Default)]
pub struct Deadline {
    at: Option<(Instant, Duration)>,
}

impl Deadline {
    /// No limit.
    pub fn none() -> Deadline {
        Deadline { at: None }
    }

    /// `limit` from now.
    pub fn after(limit: Duration) -> Deadline {
        Deadline {
            at: Some((Instant::now() + limit, limit)),
        }
    }

    fn check(&self, tile: TileId, stage: &'static str) -> Result<(), RenderError> {
        if let Some(limit) = crate::budget::exceeded() {
            return Err(RenderError::OverBudget {
                tile,
                limit_mib: limit >> 20,
                stage,
            });
        }
        match self.at {
            Some((at, limit)) if Instant::now() > at => {
                Err(RenderError::TimedOut { tile, limit, stage })
            }
            _ => Ok(()),
        }
    }
}

/// What a render is given besides its data and settings: when to give up, and the memo of the
/// LP components solved before (by earlier renders, or read from a store), which it also fills.
#[derive(Debug, Clone, Copy)]
pub struct Context<'a> {
    pub deadline: Deadline,
    pub solutions: &'a Solutions,
}

#[derive(Debug, Clone)]
pub struct RenderedTile {
    pub glb: Vec<u8>,
    pub stats: RenderStats,
    pub timings: StageTimings,
}

/// Runs `f`, turning a panic (a bug, or a library tripping on degenerate input) into an error
/// for this tile only.
fn guarded<T>(tile: TileId, f: impl FnOnce() -> Result<T, RenderError>) -> Result<T, RenderError> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).unwrap_or_else(|payload| {
        Err(RenderError::Panicked {
            tile,
            message: crate::panics::text(payload.as_ref()),
        })
    })
}

/// What both outputs are made from: the features and the ground with its elevations and normals.
struct Prepared<'a> {
    frame: TileFrame,
    terrain: TerrainModel<'a>,
    /// Water surfaces and the elevations their water takes.
    water: Vec<elevation::settled::Level>,
    /// Bridges and tunnels near the tile, settled whole.
    structures: Vec<elevation::structures::Settled>,
    /// The feature row of each structure way drawn here (by index into all ways).
    structure_features: HashMap<u32, u32>,
    /// The ground tunnels reshape: their approach cuts and the ground raised over them.
    cuts: Vec<elevation::settled::Level>,
    /// Roads and junctions, level across.
    roads: elevation::roads::RoadLevels,
    /// Cliffs and retaining walls.
    steps: elevation::steps::Steps,
    /// Where the water and the cuts lie: the settled ground's index, made once.
    levels: LevelIndex,
    /// The profiles of the ground roads, held to their grade.
    road_profiles: elevation::road_profiles::RoadProfiles,
    /// Every way of the data, for the structures' indices.
    all_ways: &'a [crate::osm::Way],
    feature_settings: FeatureSettings,
    /// The mesh's error bound, metres.
    surface_margin_m: f64,
    feature_set: FeatureSet,
    ground: Ground,
    /// Unit normal of each ground vertex in the local frame.
    normals: Vec<[f64; 3]>,
}

fn prepare<'a>(
    tile: TileId,
    selection: &Selection<'a>,
    mosaic: &'a Mosaic,
    settings: &RenderSettings,
    timings: &mut StageTimings,
    context: Context<'_>,
) -> Result<Prepared<'a>, RenderError> {
    let deadline = context.deadline;
    let frame = tile.frame();
    let terrain = TerrainModel::new(mosaic, settings.interpolation, tile.z);

    let all_ways = selection.all_ways;
    let Elevations {
        feature_set,
        structure_features,
        structures,
        cuts,
        road_profiles,
    } = elevations(tile, selection, (&terrain, settings), timings, context)?;

    let started = Instant::now();
    let Surfaces {
        water,
        roads,
        steps,
        levels,
    } = settled_surfaces(&feature_set, &road_profiles, &terrain, frame.size_m, &cuts);
    let settled = SettledGround::indexed(&terrain, (&water, &cuts), &roads, &steps, &levels);
    let ground = triangulated(&frame, mosaic, settings, &feature_set, &settled)?;
    timings.triangulation = started.elapsed();
    deadline.check(tile, "triangulation")?;

    let started = Instant::now();
    let normals = mesh::normals::ground_normals(&ground, &frame, &terrain);
    timings.normals = started.elapsed();
    Ok(Prepared {
        frame,
        terrain,
        water,
        structures,
        structure_features,
        cuts,
        roads,
        steps,
        levels,
        road_profiles,
        all_ways,
        feature_settings: settings.features.clone(),
        surface_margin_m: settings.mesh.max_error_m,
        feature_set,
        ground,
        normals,
    })
}

/// The levels the settled surfaces give the ground, and their index.
struct Surfaces {
    /// Water areas, flat at the level of their lowest shore.
    water: Vec<elevation::settled::Level>,
    /// Roads level across their width, junctions level.
    roads: elevation::roads::RoadLevels,
    /// Cliffs and retaining walls, stepping the terrain.
    steps: elevation::steps::Steps,
    /// Where the water and `cuts` lie.
    levels: LevelIndex,
}

/// Settles the water, the roads across and the steps of `set` on `terrain`, the roads on their
/// `profiles`, beside the ground `cuts`.
fn settled_surfaces(
    set: &FeatureSet,
    profiles: &elevation::road_profiles::RoadProfiles,
    terrain: &dyn Elevation,
    size_m: f64,
    cuts: &[elevation::settled::Level],
) -> Surfaces {
    let water = elevation::water::levels(set, terrain, size_m);
    let cut_surfaces: Vec<u32> = cuts.iter().map(|c| c.surface).collect();
    let roads = elevation::roads::levels(set, profiles, terrain, size_m, &cut_surfaces);
    let steps = elevation::steps::Steps::new(&set.steps);
    let levels = LevelIndex::new(&water, cuts);
    Surfaces {
        water,
        roads,
        steps,
        levels,
    }
}

/// The ground of a tile triangulated with its surfaces stitched in, the settled elevations on
/// its vertices.
fn triangulated(
    frame: &TileFrame,
    mosaic: &Mosaic,
    settings: &RenderSettings,
    feature_set: &FeatureSet,
    settled: &elevation::ground::Ground<'_>,
) -> Result<Ground, RenderError> {
    // The settled ground at many points at once (the tile's sample grid), over threads.
    let sample = |points: &[[f64; 2]]| {
        with_ground_models(
            points,
            frame,
            mosaic,
            settings,
            settled,
            &|points, _, settled| points.iter().map(|&p| settled.elevation_uv(p)).collect(),
        )
    };
    let mut ground = ground::triangulate_lines(
        frame,
        &settings.mesh,
        (&feature_set.surfaces, settled.roads.edges()),
        &feature_set.nearby_outlines,
        settled,
        &sample,
    )?;
    mesh::flatten::flatten(&mut ground, settled, frame);
    Ok(ground)
}

/// What a tile coarser than the served zoom is made from: its generalised features (see
/// [`features::overview`]) and its ground at the coarser error bound, draped: no bridges,
/// tunnels or road profiles, water at its levels.
fn prepare_overview<'a>(
    tile: TileId,
    selection: &Selection<'_>,
    mosaic: &'a Mosaic,
    settings: &RenderSettings,
    level: features::overview::Level,
    timings: &mut StageTimings,
    context: Context<'_>,
) -> Result<Prepared<'a>, RenderError> {
    let frame = tile.frame();
    let terrain = TerrainModel::new(mosaic, settings.interpolation, tile.z);
    let started = Instant::now();
    let feature_set = features::overview::collect(selection, level, &settings.features);
    timings.features = started.elapsed();
    let deadline = context.deadline;
    deadline.check(tile, "features")?;

    let started = Instant::now();
    let water = elevation::water::levels(&feature_set, &terrain, frame.size_m);
    let roads = elevation::roads::RoadLevels::default();
    let steps = elevation::steps::Steps::new(&[]);
    let levels = LevelIndex::new(&water, &[]);
    let settled = SettledGround::indexed(&terrain, (&water, &[]), &roads, &steps, &levels);
    let ground = triangulated(&frame, mosaic, settings, &feature_set, &settled)?;
    timings.triangulation = started.elapsed();
    deadline.check(tile, "triangulation")?;

    let started = Instant::now();
    let normals = mesh::normals::ground_normals(&ground, &frame, &terrain);
    timings.normals = started.elapsed();
    Ok(Prepared {
        frame,
        terrain,
        water,
        structures: Vec::new(),
        structure_features: HashMap::new(),
        cuts: Vec::new(),
        roads,
        steps,
        levels,
        road_profiles: elevation::road_profiles::RoadProfiles::default(),
        all_ways: &[],
        feature_settings: settings.features.clone(),
        surface_margin_m: settings.mesh.max_error_m,
        feature_set,
        ground,
        normals,
    })
}

/// The depth of the skirts under the ground's sides, in error bounds of the tile's level (local
/// units, which are metres times the Mercator scale): a neighbour of the next zoom up or down
/// meets a side within the two levels' error bounds, three of this level's at most, or a road
/// settled off the terrain at the side a little more.
const SKIRT_ERRORS: f64 = 6.0;

/// Points below this many are read on the calling thread.
const POINTS_PER_THREAD: usize = 8_192;
/// Most threads one tile's points are spread over.
const MAX_POINT_THREADS: usize = 4;

/// Work on points with the models of the ground: the terrain, then the settled ground.
type AtPoints<'a, R> = dyn Fn(&[[f64; 2]], &dyn Elevation, &dyn Elevation) -> Vec<R> + Sync + 'a;

/// `f` over `points` with the models of the ground, spread over the cores when there are many:
/// each thread reads the terrain through a model of its own (the models keep caches), and every
/// point's result is its own, so the result is the one a single thread gives.
fn with_ground_models<R: Send>(
    points: &[[f64; 2]],
    frame: &crate::tile::TileFrame,
    mosaic: &Mosaic,
    settings: &RenderSettings,
    settled: &elevation::ground::Ground<'_>,
    f: &AtPoints<'_, R>,
) -> Vec<R> {
    let threads = crate::parallel::threads_for(points.len(), POINTS_PER_THREAD, MAX_POINT_THREADS);
    if threads == 1 {
        return f(points, settled.terrain, settled);
    }
    // The settled parts, not the ground itself: its terrain model is one thread's.
    let (water, cuts, roads, steps) = (settled.water, settled.cuts, settled.roads, settled.steps);
    let index = settled.index();
    crate::parallel::map_chunks(points, threads, &|chunk| {
        let terrain = TerrainModel::new(mosaic, settings.interpolation, frame.tile.z);
        let ground = SettledGround::indexed(&terrain, (water, cuts), roads, steps, index);
        f(chunk, &terrain, &ground)
    })
}

/// Renders one tile as glb from the elements near it and the SRTM files around it, with a memo
/// of its own.
pub fn render(
    tile: TileId,
    selection: &Selection<'_>,
    mosaic: &Mosaic,
    settings: &RenderSettings,
) -> Result<RenderedTile, RenderError> {
    let context = Context {
        deadline: Deadline::none(),
        solutions: &Solutions::default(),
    };
    render_within(
        tile,
        selection,
        mosaic,
        settings,
        crate::format::Variant::default(),
        context,
    )
}

/// [`render`] as `variant`, giving up with [`RenderError::TimedOut`] once the context's
/// deadline has passed.
pub fn render_within(
    tile: TileId,
    selection: &Selection<'_>,
    mosaic: &Mosaic,
    settings: &RenderSettings,
    variant: crate::format::Variant,
    context: Context<'_>,
) -> Result<RenderedTile, RenderError> {
    guarded(tile, || {
        let mut timings = StageTimings::default();
        let prepared = prepare(tile, selection, mosaic, settings, &mut timings, context)?;
        let datum = settings.vertical_datum;
        let rendered = render_glb(tile, &prepared, variant, datum, timings);
        context.deadline.check(tile, "encode")?;
        Ok(rendered)
    })
}

fn render_glb(
    tile: TileId,
    prepared: &Prepared<'_>,
    variant: crate::format::Variant,
    vertical_datum: VerticalDatum,
    mut timings: StageTimings,
) -> RenderedTile {
    let shapes = shapes(tile, prepared, &mut timings);
    written(tile, prepared, &shapes, (variant, vertical_datum), timings)
}

/// Everything a glb holds before it is written, whatever its variant: the parts' meshes and
/// the instances placed.
struct Shapes {
    parts: BTreeMap<Part, MeshBuffers>,
    instanced: BTreeMap<mesh::models::Model, mesh::instances::Instances>,
    slivers: usize,
}

/// The ground's parts and every shape on it, meshed.
fn shapes(tile: TileId, prepared: &Prepared<'_>, timings: &mut StageTimings) -> Shapes {
    let Prepared {
        frame,
        terrain,
        water,
        cuts,
        roads,
        steps,
        levels,
        feature_set,
        ..
    } = prepared;
    let started = Instant::now();
    // The terrain model keeps caches of one thread's: the other thread makes a model of its own.
    let (mosaic, interpolation) = (terrain.mosaic, terrain.interpolation);
    // Buildings and barriers stand on the settled ground, not on its mesh: they are made on a
    // thread of their own while the ground's parts and what is drawn on them are made here.
    // Their parts are of kinds nothing else makes, so they join the others in any order.
    let (solids, (drawn, ground_took)) = crate::parallel::join(
        || {
            let terrain = TerrainModel::new(mosaic, interpolation, tile.z);
            let settled = SettledGround::indexed(&terrain, (water, cuts), roads, steps, levels);
            let mut parts = mesh::buildings::build(
                &feature_set.buildings,
                frame,
                &terrain,
                &settled,
                srtm_step_uv(tile),
            );
            parts.extend(mesh::barriers::build(
                &feature_set.barriers,
                frame,
                &settled,
            ));
            parts
        },
        || drawn_shapes(tile, prepared),
    );
    let Shapes {
        mut parts,
        mut instanced,
        slivers,
    } = drawn;
    for (part, buffers) in solids {
        let previous = parts.insert(part, buffers);
        debug_assert!(previous.is_none(), "{part:?} made twice");
    }
    // Nothing that is not a finite number reaches the tile, whatever the data made of it.
    let dropped = parts
        .values_mut()
        .map(mesh::MeshBuffers::drop_non_finite)
        .chain(
            instanced
                .values_mut()
                .map(mesh::instances::Instances::drop_non_finite),
        )
        .sum::<usize>();
    if dropped > 0 {
        tracing::warn!(%tile, dropped, "triangles and instances placed at numbers that are not finite were left out");
    }
    timings.ground = ground_took;
    timings.shapes = started.elapsed().saturating_sub(ground_took);
    Shapes {
        parts,
        instanced,
        slivers,
    }
}

/// The ground's parts and what is drawn on the ground's mesh: markings, sidewalks, stairs,
/// bridges and tunnels, power lines and the instances placed; with the time the ground's
/// parts took.
fn drawn_shapes(tile: TileId, prepared: &Prepared<'_>) -> (Shapes, std::time::Duration) {
    let Prepared {
        frame,
        terrain,
        water,
        structures,
        structure_features,
        cuts,
        roads,
        steps,
        levels,
        all_ways,
        feature_settings,
        surface_margin_m,
        feature_set,
        ground,
        normals,
        ..
    } = prepared;
    let started = Instant::now();
    let GroundParts {
        mut parts,
        vertex_y,
        slivers,
    } = mesh::ground_parts::ground_parts(
        ground,
        (&feature_set.surfaces, &feature_set.features),
        normals,
        frame,
        SKIRT_ERRORS * surface_margin_m,
    );
    let ground_took = started.elapsed();

    let settled = SettledGround::indexed(terrain, (water, cuts), roads, steps, levels);
    let drawn = mesh::drawn_ground::DrawnGround::new(
        (ground, &feature_set.surfaces),
        &vertex_y,
        frame,
        &settled,
    );
    parts.extend(mesh::markings::build(&feature_set.markings, frame, &drawn));
    mesh::sidewalks::build(&feature_set.sidewalks, frame, &drawn, &mut parts);
    parts.insert(
        Part::Stairs,
        mesh::stairs::build(&feature_set.stairs, frame, &drawn),
    );
    let projection = features::Projection::new(tile.z);
    let context = mesh::structures::Context {
        ways: all_ways,
        features: structure_features,
        frame,
        projection: &projection,
        settings: feature_settings,
        surface_margin_m: *surface_margin_m,
        lines: &feature_set.structure_lines,
        ground: &drawn,
    };
    mesh::structures::build(structures, &context, &mut parts);
    parts.insert(
        Part::PowerLine,
        mesh::power::build(&feature_set.power_lines, frame, &settled),
    );
    let decks: Vec<&elevation::structures::Profile> = structures
        .iter()
        .flat_map(|s| &s.profiles)
        .filter(|p| p.kind == crate::osm::structures::StructureKind::Bridge)
        .collect();
    let instanced = mesh::instances::place(
        (&feature_set.trees, &feature_set.objects),
        feature_set,
        &drawn,
        &decks,
    );
    let shapes = Shapes {
        parts,
        instanced,
        slivers,
    };
    (shapes, ground_took)
}

/// A tile made in one of its formats.
#[derive(Debug, Clone)]
pub enum Rendered {
    Glb(RenderedTile),
    Terrain(RenderedTerrain),
}

/// Renders one tile at the served zoom in each of `formats`, from one preparation: the glb
/// variants and the terrain of a tile share its features, settled elevations and ground, and
/// its glb variants share their shapes, so each further format costs only its writing. The
/// bytes of each are those [`render_within`] and [`render_terrain`] make alone.
pub fn render_formats(
    tile: TileId,
    (selection, mosaic): (&Selection<'_>, &Mosaic),
    settings: &RenderSettings,
    formats: &[crate::format::Format],
    context: Context<'_>,
) -> Result<Vec<Rendered>, RenderError> {
    use crate::format::Format;
    guarded(tile, || {
        let mut timings = StageTimings::default();
        let prepared = prepare(tile, selection, mosaic, settings, &mut timings, context)?;
        let datum = settings.vertical_datum;
        let mut shaped: Option<(Shapes, StageTimings)> = None;
        let mut rendered = Vec::with_capacity(formats.len());
        for format in formats {
            rendered.push(match *format {
                Format::Glb(variant) => {
                    let (shapes, timings) = shaped.get_or_insert_with(|| {
                        let mut timings = timings;
                        (shapes(tile, &prepared, &mut timings), timings)
                    });
                    let glb = written(tile, &prepared, shapes, (variant, datum), *timings);
                    Rendered::Glb(glb)
                }
                Format::Terrain(extensions) => Rendered::Terrain(terrain::encode_terrain(
                    &prepared, extensions, datum, timings,
                )),
            });
            context.deadline.check(tile, "encode")?;
        }
        Ok(rendered)
    })
}

/// The glb of `shapes` as `variant`, its heights from `vertical_datum`.
fn written(
    tile: TileId,
    prepared: &Prepared<'_>,
    shapes: &Shapes,
    (variant, vertical_datum): (crate::format::Variant, VerticalDatum),
    mut timings: StageTimings,
) -> RenderedTile {
    let Shapes {
        parts,
        instanced,
        slivers,
    } = shapes;
    let (frame, feature_set) = (&prepared.frame, &prepared.feature_set);
    let started = Instant::now();
    let description = glb::TileDescription {
        tile,
        bounds: tile.bounds(),
        size_m: frame.size_m,
        generator: format!("terrastitch {}", env!("CARGO_PKG_VERSION")),
        vertical_datum,
    };
    let bytes = glb::write(
        &description,
        parts,
        instanced,
        &feature_set.features,
        variant,
    );
    timings.encode = started.elapsed();

    let stats = RenderStats::of(prepared, parts, instanced, *slivers, bytes.len());
    RenderedTile {
        glb: bytes,
        stats,
        timings,
    }
}

/// The settings of a tile above the served zoom: an error bound that doubles with each level.
fn overview_settings(settings: &RenderSettings, tile: TileId, served_zoom: u8) -> RenderSettings {
    let levels_above = i32::from(served_zoom) - i32::from(tile.z);
    let mut settings = settings.clone();
    settings.mesh.max_error_m *= 2f64.powi(levels_above.max(0));
    settings
}

/// Renders a tile above the served zoom as glb, for far views: the ground at the error bound of
/// [`render_overview_terrain`], with land cover and water as colours, major roads and railways
/// draped on it, and buildings merged into flat-roofed blocks (see [`features::overview`]).
pub fn render_overview(
    tile: TileId,
    selection: &Selection<'_>,
    mosaic: &Mosaic,
    settings: &RenderSettings,
    level: features::overview::Level,
    variant: crate::format::Variant,
    context: Context<'_>,
) -> Result<RenderedTile, RenderError> {
    let settings = overview_settings(settings, tile, tile.z + level.levels_above);
    guarded(tile, || {
        let mut timings = StageTimings::default();
        let prepared = prepare_overview(
            tile,
            selection,
            mosaic,
            &settings,
            level,
            &mut timings,
            context,
        )?;
        let datum = settings.vertical_datum;
        Ok(render_glb(tile, &prepared, variant, datum, timings))
    })
}

/// The east–west spacing of 3-arc-second samples in global tile units at this zoom: buildings
/// sample the ground under them this finely.
pub fn srtm_step_uv(tile: TileId) -> f64 {
    let degrees = 3.0 / 3600.0;
    degrees / 360.0 * tile.tiles_per_axis()
}
