//! 3D Tiles 1.1: `GET /tileset.json` (also at `/3dtiles/tileset.json`), the tileset files `GET /3dtiles/{z}/{x}/{y}.json`, and the
//! content `GET /3dtiles/{z}/{x}/{y}.glb` (the tile in its east-north-up frame). `?compress=
//! meshopt` on the root is carried to every file and content tile below it.
//!
//! Bounding volumes need the ground's height under each tile: asked of the provider on the
//! blocking pool ([`TileProvider::ground_range`]). A provider of one format (an exported
//! archive) has a tileset when it holds east-north-up glb, with that compression and without
//! heights.

use std::sync::Arc;

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
use crate::provider::TileProvider;
use crate::tile::TileId;

/// The plan of the served data: its coverage and the query to carry.
fn plan(provider: &dyn TileProvider, meshopt: bool) -> Result<Plan, ApiError> {
    let query = |meshopt: bool| match meshopt {
        true => "?compress=meshopt".to_string(),
        false => String::new(),
    };
    let offer = provider.offer();
    // A provider of one format carries its compression.
    let meshopt = match offer.only {
        None => meshopt,
        Some(Format::Glb(variant)) if variant.frame == Frame::EastNorthUp => variant.meshopt,
        Some(other) => {
            return Err(ApiError::not_found(format!(
                "this server holds {} tiles; a 3D Tiles tileset needs glb-enu or \
                 glb-enu-meshopt (export with --format glb-enu-meshopt)",
                other.as_str()
            )))
        }
    };
    Ok(Plan {
        content_zoom: offer.zoom,
        coverage: offer.coverage,
        query: query(meshopt),
        list_unknown: offer.open_ended,
        parent_content: !offer.far_zooms.is_empty(),
        files: None,
    })
}

/// Builds a tileset document on the blocking pool.
async fn document(
    state: &AppState,
    provider: Arc<dyn TileProvider>,
    build: impl FnOnce(&Plan, &dyn Fn(TileId) -> Option<(f64, f64)>) -> Value + Send + 'static,
    plan: Plan,
) -> Result<Response, ApiError> {
    let value = tokio::task::spawn_blocking(move || {
        let heights = |tile: TileId| provider.ground_range(tile);
        build(&plan, &heights)
    })
    .await
    .map_err(|e| ApiError::internal(e.to_string()))?;
    let mut headers = HeaderMap::new();
    headers.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("application/json"),
    );
    if let Some(cache_control) = &state.http.cache_control {
        headers.insert(header::CACHE_CONTROL, cache_control.clone());
    }
    Ok((headers, value.to_string()).into_response())
}

/// `GET /tileset.json`.
pub async fn root(
    State(state): State<AppState>,
    RawQuery(query): RawQuery,
) -> Result<Response, ApiError> {
    let provider = state.provider()?;
    let plan = plan(&*provider, wants_meshopt(query.as_deref())?)?;
    document(
        &state,
        provider,
        |plan, heights| plan.root(heights, Root::Top),
        plan,
    )
    .await
}

/// `GET /3dtiles/tileset.json`: the same root, next to the files it names.
pub async fn root_in_folder(
    State(state): State<AppState>,
    RawQuery(query): RawQuery,
) -> Result<Response, ApiError> {
    let provider = state.provider()?;
    let plan = plan(&*provider, wants_meshopt(query.as_deref())?)?;
    document(
        &state,
        provider,
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
        let provider = state.provider()?;
        let plan = plan(&*provider, meshopt)?;
        if !plan.has_tileset(tile) {
            return Err(ApiError::not_found(format!(
                "no tileset file for tile {tile}: files stand at zooms {} - 2k down to the \
                 root's, over the data's coverage",
                plan.content_zoom
            )));
        }
        return document(
            &state,
            provider,
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
