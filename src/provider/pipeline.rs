//! One tile from the opened sources to its bytes, in a format: the step the server, `seed`
//! and `export` share. Reads the tile's SRTM files and OSM elements from [`Inputs`], renders
//! with [`crate::render`], and returns the uncompressed body with what the render measured.

use super::Inputs;
use crate::format::{Format, TileKey};
use crate::render::{
    Context, RenderError, RenderSettings, RenderStats, Rendered, RenderedTerrain, RenderedTile,
    StageTimings,
};
use crate::source::srtm::SrtmError;

/// A tile made.
#[derive(Debug, Clone)]
pub struct Made {
    /// The body, uncompressed.
    pub bytes: Vec<u8>,
    pub timings: StageTimings,
    pub triangles: usize,
    /// Components of the elevation LP solved, and soft constraints they violated (glb only).
    pub lp_components: usize,
    pub lp_violations: usize,
    /// Everything the render counted (glb only).
    pub stats: Option<RenderStats>,
    /// Made from the same render as the tile before it in the same call: the stages before
    /// encoding were spent once for both.
    pub shared: bool,
}

impl From<RenderedTile> for Made {
    fn from(rendered: RenderedTile) -> Made {
        Made {
            triangles: rendered.stats.triangles,
            lp_components: rendered.stats.lp_components,
            lp_violations: rendered.stats.lp_violations,
            timings: rendered.timings,
            bytes: rendered.glb,
            stats: Some(rendered.stats),
            shared: false,
        }
    }
}

impl From<RenderedTerrain> for Made {
    fn from(rendered: RenderedTerrain) -> Made {
        Made {
            triangles: rendered.report.triangles,
            lp_components: 0,
            lp_violations: 0,
            timings: rendered.timings,
            bytes: rendered.bytes,
            stats: None,
            shared: false,
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum MakeError {
    #[error(transparent)]
    Srtm(#[from] SrtmError),
    #[error(transparent)]
    Render(#[from] RenderError),
    #[error(transparent)]
    Store(#[from] crate::source::store::StoreError),
    /// The provider does not hold the tile and cannot make it.
    #[error("{0}")]
    NotHeld(String),
    #[error("the tile could not be written: {0}")]
    Encode(String),
}

impl MakeError {
    pub fn timed_out(&self) -> bool {
        matches!(self, MakeError::Render(RenderError::TimedOut { .. }))
    }

    /// The render took more memory than its budget.
    pub fn over_budget(&self) -> bool {
        matches!(self, MakeError::Render(RenderError::OverBudget { .. }))
    }
}

/// Makes `key` from `sources`. Tiles above `served_zoom` are overviews: terrain alone, or glb
/// generalised for far views.
pub fn make(
    sources: &Inputs,
    key: TileKey,
    settings: &RenderSettings,
    served_zoom: u8,
    context: Context<'_>,
) -> Result<Made, MakeError> {
    let tile = key.tile;
    match key.format {
        Format::Glb(variant) => {
            let osm = sources.osm_for(tile)?;
            let selection = osm.selection(tile);
            let mosaic = sources.mosaic_for(tile, &selection, settings.features.longest_way_m())?;
            let rendered = if tile.z < served_zoom {
                crate::render::render_overview(
                    tile,
                    &selection,
                    &mosaic,
                    settings,
                    crate::features::overview::Level::new(
                        tile,
                        served_zoom,
                        &sources.osm.coverage(),
                    ),
                    variant,
                    context,
                )
            } else {
                crate::render::render_within(tile, &selection, &mosaic, settings, variant, context)
            }?;
            Ok(Made::from(rendered))
        }
        Format::Terrain(extensions) => {
            let rendered = if tile.z < served_zoom {
                crate::render::render_overview_terrain(
                    tile,
                    &sources.mosaic(tile)?,
                    settings,
                    served_zoom,
                    extensions,
                    context,
                )
            } else {
                let osm = sources.osm_for(tile)?;
                let selection = osm.selection(tile);
                crate::render::render_terrain(
                    tile,
                    &selection,
                    &sources.mosaic_for(tile, &selection, settings.features.longest_way_m())?,
                    settings,
                    extensions,
                    context,
                )
            }?;
            Ok(Made::from(rendered))
        }
    }
}

/// Makes one tile in several formats (`keys` all of one tile), in their order: at the served
/// zoom from one preparation ([`crate::render::render_formats`]), coarser tiles one by one.
/// The bytes are those [`make`] gives each key; the keys fail together.
pub fn make_together(
    sources: &Inputs,
    keys: &[TileKey],
    settings: &RenderSettings,
    served_zoom: u8,
    context: Context<'_>,
) -> Result<Vec<Made>, MakeError> {
    let one_by_one = |keys: &[TileKey]| {
        keys.iter()
            .map(|key| make(sources, *key, settings, served_zoom, context))
            .collect()
    };
    let Some(tile) = keys.first().map(|key| key.tile) else {
        return Ok(Vec::new());
    };
    if keys.len() == 1 || tile.z < served_zoom || keys.iter().any(|key| key.tile != tile) {
        return one_by_one(keys);
    }
    let osm = sources.osm_for(tile)?;
    let selection = osm.selection(tile);
    let mosaic = sources.mosaic_for(tile, &selection, settings.features.longest_way_m())?;
    let formats: Vec<_> = keys.iter().map(|key| key.format).collect();
    let rendered =
        crate::render::render_formats(tile, (&selection, &mosaic), settings, &formats, context)?;
    Ok(rendered
        .into_iter()
        .enumerate()
        .map(|(k, rendered)| Made {
            shared: k > 0,
            ..match rendered {
                Rendered::Glb(tile) => Made::from(tile),
                Rendered::Terrain(terrain) => Made::from(terrain),
            }
        })
        .collect())
}
