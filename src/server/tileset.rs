//! 3D Tiles 1.1: `GET /tileset.json` (also at `/3dtiles/tileset.json`), the tileset files `GET /3dtiles/{z}/{x}/{y}.json`, and the
//! content `GET /3dtiles/{z}/{x}/{y}.glb` (the tile in its east-north-up frame). `?compress=
//! meshopt` on the root is carried to every file and content tile below it.
//!
//! Bounding volumes need the ground's height under each tile: read from the SRTM files on the
//! blocking pool ([`Inputs::ground_range`]: a content tile's samples, at most
//! `HEIGHT_SAMPLES` of them; a parent's whole files, whose ranges are kept once read). A
//! server of an MBTiles archive serves the tileset when the archive holds east-north-up glb,
//! with the archive's compression and without heights.

use axum::extract::{Path, RawQuery, State};
use axum::http::{header, HeaderMap, HeaderValue};
use axum::response::{IntoResponse, Response};
use serde_json::Value;

use super::error::ApiError;
use super::metrics::Metrics;
use super::tiles::{parse_tile_path, serve, wants_meshopt};
use super::AppState;
use crate::format::Format;
use crate::format::{Frame, Variant};
use crate::output::tileset::{Plan, Root};
use crate::provider::Inputs;
use crate::tile::TileId;

/// Samples read per tile for its heights.
const HEIGHT_SAMPLES: usize = 40_000;

/// The plan of the served data: its coverage and the query to carry.
fn plan(state: &AppState, meshopt: bool) -> Result<Plan, ApiError> {
    let query = |meshopt: bool| match meshopt {
        true => "?compress=meshopt".to_string(),
        false => String::new(),
    };
    if let Some(archive) = &state.archive {
        return match archive.format {
            Format::Glb(variant) if variant.frame == Frame::EastNorthUp => Ok(Plan {
                content_zoom: state.zoom,
                coverage: archive.bounds.into_iter().collect(),
                query: query(variant.meshopt),
                list_unknown: true,
            }),
            other => Err(ApiError::not_found(format!(
                "this archive holds {} tiles; a 3D Tiles tileset needs glb-enu or \
                 glb-enu-meshopt (export with --format glb-enu-meshopt)",
                other.as_str()
            ))),
        };
    }
    let sources = state.sources()?;
    Ok(Plan {
        content_zoom: state.zoom,
        coverage: sources.osm.data().coverage.clone(),
        query: query(meshopt),
        list_unknown: sources.can_fetch_srtm(),
    })
}

/// Lowest and highest SRTM ground under a tile, from the opened sources: sampled for a content
/// tile, whole files for a parent.
fn heights(sources: Option<&Inputs>, content_zoom: u8, tile: TileId) -> Option<(f64, f64)> {
    let sampled = tile.z == content_zoom;
    match sources?.ground_range(tile, sampled, HEIGHT_SAMPLES) {
        Ok(range) => range,
        Err(error) => {
            tracing::warn!(%tile, %error, "no heights for the tile's bounding volume");
            None
        }
    }
}

/// Builds a tileset document on the blocking pool.
async fn document(
    state: &AppState,
    build: impl FnOnce(&Plan, &dyn Fn(TileId) -> Option<(f64, f64)>) -> Value + Send + 'static,
    plan: Plan,
) -> Result<Response, ApiError> {
    let sources = state.sources().ok().filter(|_| state.archive.is_none());
    let value = tokio::task::spawn_blocking(move || {
        let zoom = plan.content_zoom;
        let heights = |tile: TileId| heights(sources.as_deref(), zoom, tile);
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
    document(&state, |plan, heights| plan.root(heights, Root::Top), plan).await
}

/// `GET /3dtiles/tileset.json`: the same root, next to the files it names.
pub async fn root_in_folder(
    State(state): State<AppState>,
    RawQuery(query): RawQuery,
) -> Result<Response, ApiError> {
    let plan = plan(&state, wants_meshopt(query.as_deref())?)?;
    document(
        &state,
        |plan, heights| plan.root(heights, Root::InFolder),
        plan,
    )
    .await
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
    Metrics::count(&state.metrics.tile_requests);
    let variant = Variant {
        frame: Frame::EastNorthUp,
        meshopt,
    };
    let (tile, format) = parse_tile_path(&z, &x, &file, "", variant)?;
    serve(state, tile, format, request_headers).await
}
