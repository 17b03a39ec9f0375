//! 3D Tiles 1.1: `GET /tileset.json`, the tileset files `GET /3dtiles/{z}/{x}/{y}.json`, and the
//! content `GET /3dtiles/{z}/{x}/{y}.glb` (the tile in its east-north-up frame). `?compress=
//! meshopt` on the root is carried to every file and content tile below it.
//!
//! Bounding volumes need the ground's height under each tile: read from the SRTM files on the
//! blocking pool (a sample budget per tile, see [`Mosaic::height_range`]).

use axum::extract::{Path, RawQuery, State};
use axum::http::{header, HeaderMap, HeaderValue};
use axum::response::{IntoResponse, Response};
use serde_json::Value;

use super::error::ApiError;
use super::tiles::{parse_tile_path, serve, wants_meshopt};
use super::AppState;
use crate::output::glb::{Frame, Variant};
use crate::output::tileset::Plan;
use crate::source::Sources;
use crate::tile::{LonLatBounds, TileId};

/// Samples read per tile for its heights.
const HEIGHT_SAMPLES: usize = 40_000;

/// The plan of the served data: its coverage and the query to carry.
fn plan(state: &AppState, meshopt: bool) -> Result<Plan, ApiError> {
    let coverage: Vec<LonLatBounds> = match (&state.archive, state.sources()) {
        (_, Ok(sources)) => sources.osm.data().coverage.clone(),
        (Some(archive), Err(_)) => archive.bounds.into_iter().collect(),
        (None, Err(error)) => return Err(error),
    };
    Ok(Plan {
        content_zoom: state.zoom,
        coverage,
        query: if meshopt {
            "?compress=meshopt".to_string()
        } else {
            String::new()
        },
    })
}

/// Lowest and highest SRTM ground under a tile, from the opened sources.
fn heights(sources: Option<&Sources>, tile: TileId) -> Option<(f64, f64)> {
    let sources = sources?;
    sources.check_coverage(tile).ok()?;
    let mosaic = match sources.mosaic(tile) {
        Ok(mosaic) => mosaic,
        Err(error) => {
            tracing::warn!(%tile, %error, "no heights for the tile's bounding volume");
            return None;
        }
    };
    let b = tile.bounds();
    mosaic.height_range(b.west, b.south, b.east, b.north, HEIGHT_SAMPLES)
}

/// Builds a tileset document on the blocking pool.
async fn document(
    state: &AppState,
    build: impl FnOnce(&Plan, &dyn Fn(TileId) -> Option<(f64, f64)>) -> Value + Send + 'static,
    plan: Plan,
) -> Result<Response, ApiError> {
    let sources = state.sources().ok();
    let value = tokio::task::spawn_blocking(move || {
        let heights = |tile: TileId| heights(sources.as_deref(), tile);
        build(&plan, &heights)
    })
    .await
    .map_err(|e| ApiError::internal(e.to_string()))?;
    let mut headers = HeaderMap::new();
    headers.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("application/json"),
    );
    if let Some(cache_control) = &state.cache_control {
        headers.insert(header::CACHE_CONTROL, cache_control.clone());
    }
    Ok((headers, value.to_string()).into_response())
}

/// `GET /tileset.json`.
pub async fn root(
    State(state): State<AppState>,
    RawQuery(query): RawQuery,
) -> Result<Response, ApiError> {
    let plan = plan(&state, wants_meshopt(query.as_deref())?)?;
    document(&state, |plan, heights| plan.root(heights), plan).await
}

/// `GET /3dtiles/{z}/{x}/{y}.json` and `.glb`.
pub async fn file(
    State(state): State<AppState>,
    Path((z, x, file)): Path<(String, String, String)>,
    RawQuery(query): RawQuery,
    request_headers: HeaderMap,
) -> Result<Response, ApiError> {
    let meshopt = wants_meshopt(query.as_deref())?;
    if let Some(y) = file.strip_suffix(".json") {
        let (tile, _) = parse_tile_path(&z, &x, &format!("{y}.glb"), "", Variant::default())?;
        let plan = plan(&state, meshopt)?;
        if !plan.has_tileset(tile) {
            return Err(ApiError::not_found(format!(
                "no tileset file for tile {tile}: files stand at zooms {} - 2k down to the \
                 root's, over the data's coverage",
                plan.content_zoom
            )));
        }
        return document(
            &state,
            move |plan, heights| plan.subtree(tile, heights),
            plan,
        )
        .await;
    }
    let variant = Variant {
        frame: Frame::EastNorthUp,
        meshopt,
    };
    let (tile, format) = parse_tile_path(&z, &x, &file, "", variant)?;
    serve(state, tile, format, request_headers).await
}
