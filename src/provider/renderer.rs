//! The provider that renders: the opened [`Inputs`] with the render settings and the zoom of the
//! served tiles. Terrain tiles at coarser zooms are overviews of the SRTM files alone.

use std::sync::Arc;

use super::osm_source::OsmSource;
use super::{
    Availability, Explaining, Fetching, Inputs, Made, MakeError, Offer, Reloading, TileProvider,
    Unavailable,
};
use crate::cache::Provenance;
use crate::config::SourcesConfig;
use crate::format::{Format, TileKey};
use crate::render::{Context, Deadline, RenderSettings, Solutions};
use crate::source::fetch::{FetchStats, Fetcher};
use crate::source::replication::Replication;
use crate::tile::{LonLatBounds, TileId};

/// Samples read per tile for its ground range.
const HEIGHT_SAMPLES: usize = 40_000;

/// The identity of the rendering code and settings, stored with every tile made.
pub fn pipeline_id(settings: &RenderSettings) -> String {
    format!("{}+{}", env!("CARGO_PKG_VERSION"), settings.fingerprint())
}

/// Renders tiles from opened inputs.
#[derive(Debug)]
pub struct Renderer {
    inputs: Arc<Inputs>,
    settings: Arc<RenderSettings>,
    zoom: u8,
    pipeline: Arc<str>,
    /// What the inputs were opened from, to open them again when they change.
    origin: Option<(Arc<SourcesConfig>, Arc<Fetcher>)>,
    /// The LP components solved by this renderer's renders (and those before it, when it is a
    /// reload), found again by the next.
    solutions: Arc<Solutions>,
}

impl Renderer {
    pub fn new(inputs: Inputs, settings: RenderSettings, zoom: u8) -> Renderer {
        Renderer {
            inputs: Arc::new(inputs),
            pipeline: pipeline_id(&settings).into(),
            settings: Arc::new(settings),
            zoom,
            origin: None,
            solutions: Arc::default(),
        }
    }

    /// The same renderer, finding and keeping solved LP components in `solutions` (shared with
    /// whoever else reads or saves them).
    pub fn with_solutions(mut self, solutions: Arc<Solutions>) -> Renderer {
        self.solutions = solutions;
        self
    }

    /// The memo of solved LP components its renders read and fill.
    pub fn solutions(&self) -> &Arc<Solutions> {
        &self.solutions
    }

    /// Opens the sources a configuration names (downloading with `fetcher`), and keeps the
    /// configuration to open them again when they change.
    pub fn load(
        config: &SourcesConfig,
        settings: RenderSettings,
        zoom: u8,
        fetcher: Arc<Fetcher>,
    ) -> Result<Renderer, super::inputs::SourceError> {
        let inputs = Inputs::load(config, zoom, fetcher.clone())?;
        Ok(Renderer::new(inputs, settings, zoom).reopening_from(config.clone(), fetcher))
    }

    /// The same renderer, told what its inputs were opened from.
    pub fn reopening_from(mut self, config: SourcesConfig, fetcher: Arc<Fetcher>) -> Renderer {
        self.origin = Some((Arc::new(config), fetcher));
        self
    }

    /// Applies the diffs of the configured replication source the store lacks, at most
    /// `DIFFS_PER_CALL`; returns how many.
    fn replicate(&self, config: &SourcesConfig, fetcher: &Fetcher) -> usize {
        const DIFFS_PER_CALL: usize = 60;
        if config.replication.is_empty() {
            return 0;
        }
        let OsmSource::Store(store) = &self.inputs.osm else {
            tracing::warn!("sources.replication needs sources.store: diffs apply to the store");
            return 0;
        };
        let source = Replication::new(&config.replication);
        match super::osm_source::catch_up(store.path(), &source, fetcher, DIFFS_PER_CALL) {
            Ok(caught) => {
                if !caught.applied.is_empty() {
                    tracing::info!(
                        diffs = caught.applied.len(),
                        last = caught.applied.last().map_or(0, |(s, _)| *s),
                        source = caught.source,
                        "the OSM store caught up with its replication source"
                    );
                }
                caught.applied.len()
            }
            Err(error) => {
                tracing::error!(%error, "applying the replication source's diffs failed");
                0
            }
        }
    }

    pub fn inputs(&self) -> &Arc<Inputs> {
        &self.inputs
    }

    pub fn settings(&self) -> &RenderSettings {
        &self.settings
    }

    /// The identity of its code and settings.
    pub fn pipeline(&self) -> &str {
        &self.pipeline
    }

    /// A tile coarser than the served zoom: terrain at any zoom, glb at the levels of far
    /// views ([`crate::tile::is_overview_zoom`]).
    fn is_overview(&self, key: TileKey) -> bool {
        match key.format {
            Format::Terrain(_) => key.tile.z < self.zoom,
            Format::Glb(_) => crate::tile::is_overview_zoom(key.tile.z, self.zoom),
        }
    }
}

impl TileProvider for Renderer {
    fn offer(&self) -> Offer {
        Offer {
            zoom: self.zoom,
            coverage: self.inputs.osm.coverage(),
            only: None,
            open_ended: self.inputs.can_fetch_srtm(),
            far_zooms: crate::tile::overview_zooms(self.zoom),
        }
    }

    fn resolve(&self, tile: TileId, format: Format) -> Result<TileKey, Unavailable> {
        let key = TileKey { tile, format };
        if tile.z == self.zoom || self.is_overview(key) {
            return Ok(key);
        }
        Err(Unavailable::NotOffered(match format {
            Format::Glb(_) => format!(
                "zoom {} is not served; this server serves glb tiles at zoom {} and, for far \
                 views, at zooms {}",
                tile.z,
                self.zoom,
                crate::tile::overview_zooms(self.zoom)
                    .iter()
                    .map(|z| z.to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
            Format::Terrain(_) => format!(
                "zoom {} is not served; this server serves terrain at zooms 0 to {}",
                tile.z, self.zoom
            ),
        }))
    }

    fn availability(&self, key: TileKey) -> Availability {
        // Overview tiles cover whatever they cover: sea level where there is no data.
        if self.is_overview(key) {
            return Availability::Ready;
        }
        match self.inputs.check_coverage(key.tile) {
            Ok(()) => Availability::Ready,
            Err(_) if self.inputs.can_fetch_srtm() => Availability::AfterFetch,
            Err(uncovered) => Availability::Missing(uncovered.to_string()),
        }
    }

    fn holds_data(&self, key: TileKey) -> bool {
        if !self.is_overview(key) {
            return true;
        }
        let bounds = key.tile.bounds();
        if matches!(key.format, Format::Glb(_)) {
            return self.inputs.osm.covers(&bounds);
        }
        self.inputs.srtm.cells().iter().any(|cell| {
            let (lon, lat) = (f64::from(cell.lon), f64::from(cell.lat));
            let cell = crate::tile::LonLatBounds {
                west: lon,
                south: lat,
                east: lon + 1.0,
                north: lat + 1.0,
            };
            cell.intersects(&bounds)
        })
    }

    fn provenance(&self, tile: TileId) -> Option<Provenance> {
        Some(Provenance {
            pipeline: self.pipeline.to_string(),
            sources: self.inputs.version_for(tile),
        })
    }

    fn make(&self, key: TileKey, deadline: Deadline) -> Result<Made, MakeError> {
        let context = Context {
            deadline,
            solutions: &self.solutions,
        };
        super::pipeline::make(&self.inputs, key, &self.settings, self.zoom, context)
    }

    fn make_together(&self, keys: &[TileKey], deadline: Deadline) -> Result<Vec<Made>, MakeError> {
        let context = Context {
            deadline,
            solutions: &self.solutions,
        };
        super::pipeline::make_together(&self.inputs, keys, &self.settings, self.zoom, context)
    }

    fn terrain_layer(&self) -> Option<crate::output::layer::TerrainLayer> {
        let cells: Vec<LonLatBounds> = self
            .inputs
            .srtm
            .cells()
            .iter()
            .map(|cell| {
                let (west, south) = (f64::from(cell.lon), f64::from(cell.lat));
                LonLatBounds {
                    west,
                    south,
                    east: west + 1.0,
                    north: south + 1.0,
                }
            })
            .collect();
        Some(crate::output::layer::TerrainLayer::everywhere_above(
            self.zoom, &cells,
        ))
    }

    fn ground_range(&self, tile: TileId) -> Option<(f64, f64)> {
        let sampled = tile.z == self.zoom;
        match self.inputs.ground_range(tile, sampled, HEIGHT_SAMPLES) {
            // In the heights the content is written in.
            Ok(range) => range.map(|(low, high)| {
                let b = tile.bounds();
                let (below, above) = self
                    .settings
                    .vertical_datum
                    .offset_range(b.west, b.south, b.east, b.north);
                (low + below, high + above)
            }),
            Err(error) => {
                tracing::warn!(%tile, %error, "no ground range for the tile");
                None
            }
        }
    }

    fn status(&self) -> serde_json::Value {
        let mut status = serde_json::json!({
            "osm_extracts": self.inputs.osm_paths.len(),
            "srtm_files": self.inputs.srtm.cells().len(),
            "zoom": self.zoom,
        });
        if let Some(problem) = self.inputs.cannot_serve() {
            status["cannot_serve"] = problem.into();
        }
        status
    }

    fn fetching(&self) -> Option<&dyn Fetching> {
        Some(self)
    }

    fn explaining(&self) -> Option<&dyn Explaining> {
        Some(self)
    }

    fn reloading(&self) -> Option<&dyn Reloading> {
        Some(self)
    }
}

impl Fetching for Renderer {
    fn fetch(&self, tile: TileId) -> Result<(), Unavailable> {
        use super::inputs::MissingSrtm;
        self.inputs.fetch_missing_srtm(tile).map_err(|e| match e {
            MissingSrtm::NotFound { .. } => Unavailable::NotCovered(e.to_string()),
            MissingSrtm::Failed { .. } => Unavailable::FetchFailed(e.to_string()),
        })?;
        self.inputs
            .check_coverage(tile)
            .map_err(|e| Unavailable::NotCovered(e.to_string()))
    }

    fn downloads(&self) -> Option<&FetchStats> {
        self.origin.as_ref().map(|(_, fetcher)| &fetcher.stats)
    }
}

impl Explaining for Renderer {
    fn explain(&self, tile: TileId) -> Result<Vec<u8>, MakeError> {
        let osm = self.inputs.osm_for(tile)?;
        let selection = osm.selection(tile);
        let mosaic =
            self.inputs
                .mosaic_for(tile, &selection, self.settings.features.longest_way_m())?;
        let memo = &self.solutions;
        let settings = &self.settings;
        let settled = crate::render::settle_structures(tile, &selection, &mosaic, settings, memo);
        let roads = crate::render::settle_road_profiles(tile, &selection, &mosaic, settings, memo);
        let margin = self.settings.mesh.max_error_m;
        let value =
            crate::output::debug::elevations(tile, &settled, &roads, selection.all_ways, margin);
        serde_json::to_vec(&value).map_err(|e| MakeError::Encode(e.to_string()))
    }
}

impl Reloading for Renderer {
    fn reopened(&self) -> Result<Option<Arc<dyn TileProvider>>, String> {
        let Some((config, fetcher)) = &self.origin else {
            return Ok(None);
        };
        let changed = self.inputs.changed_files();
        if changed.is_empty() {
            return Ok(None);
        }
        tracing::info!(files = ?changed, "sources changed; loading them again");
        let settings = (*self.settings).clone();
        let renderer = Renderer::load(config, settings, self.zoom, fetcher.clone())
            .map_err(|e| e.to_string())?
            .with_solutions(self.solutions.clone());
        Ok(Some(Arc::new(renderer)))
    }

    fn catch_up(&self) -> usize {
        match &self.origin {
            Some((config, fetcher)) => self.replicate(config, fetcher),
            None => 0,
        }
    }
}
