//! A tile's ground as quantized-mesh terrain: at the served zoom from the same preparation as
//! its glb, above it from the SRTM files alone.

use super::*;

/// A tile's terrain as quantized-mesh.
#[derive(Debug, Clone)]
pub struct RenderedTerrain {
    pub bytes: Vec<u8>,
    pub report: quantized_mesh::EncodeReport,
    pub timings: StageTimings,
}

/// Renders one tile's ground (the same triangulation as the glb's, with the ground under
/// buildings kept) as quantized-mesh-1.0, uncompressed.
pub fn render_terrain(
    tile: TileId,
    selection: &Selection<'_>,
    mosaic: &Mosaic,
    settings: &RenderSettings,
    extensions: crate::format::Extensions,
    context: Context<'_>,
) -> Result<RenderedTerrain, RenderError> {
    guarded(tile, || {
        let mut timings = StageTimings::default();
        let prepared = prepare(tile, selection, mosaic, settings, &mut timings, context)?;
        Ok(encode_terrain(
            &prepared,
            extensions,
            settings.vertical_datum,
            timings,
        ))
    })
}

/// Renders a tile above the served zoom (a coarser one, for Cesium's levels of detail) as
/// terrain alone: no features, and an error bound that doubles with each level above
/// `served_zoom`, so a tile holds about as many triangles at every level. Points no SRTM file
/// covers are at sea level.
pub fn render_overview_terrain(
    tile: TileId,
    mosaic: &Mosaic,
    settings: &RenderSettings,
    served_zoom: u8,
    extensions: crate::format::Extensions,
    context: Context<'_>,
) -> Result<RenderedTerrain, RenderError> {
    let settings = overview_settings(settings, tile, served_zoom);
    guarded(tile, || {
        let mut timings = StageTimings::default();
        let prepared = prepare(
            tile,
            &Selection::default(),
            mosaic,
            &settings,
            &mut timings,
            context,
        )?;
        Ok(encode_terrain(
            &prepared,
            extensions,
            settings.vertical_datum,
            timings,
        ))
    })
}

pub(super) fn encode_terrain(
    prepared: &Prepared<'_>,
    extensions: crate::format::Extensions,
    datum: VerticalDatum,
    mut timings: StageTimings,
) -> RenderedTerrain {
    let started = Instant::now();
    let Prepared {
        frame,
        feature_set,
        ground,
        normals,
        ..
    } = prepared;
    let waters: Vec<&features::Surface> = feature_set
        .surfaces
        .iter()
        .filter(|s| s.class == FeatureClass::Water)
        .collect();
    let water = extensions.watermask.then_some(waters.as_slice());
    let terrain_tile =
        quantized_mesh::TerrainTile::of_ground(ground, normals, frame, water).in_datum(datum);
    let (bytes, report) = quantized_mesh::encode(&terrain_tile, extensions);
    timings.encode = started.elapsed();
    RenderedTerrain {
        bytes,
        report,
        timings,
    }
}
