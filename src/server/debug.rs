//! `GET /debug/tiles/{z}/{x}/{y}.geojson`: the settled bridges, tunnels and ground roads of a
//! tile with their connectors and constraints (see [`crate::output::debug`]), for looking into
//! how a tile came out. Made like a tile: in a render slot, queued or refused with the tiles,
//! one making per tile at a time; kept a while in memory, never stored. `server.debug_view`
//! turns the route off.

use std::sync::Arc;

use axum::extract::{Path, State};
use axum::http::{header, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};

use super::error::ApiError;
use super::pool::Refused;
use super::{AppState, RETRY_AFTER_S};
use crate::provider::{Availability, MakeError, TileProvider};
use crate::tile::TileId;

pub async fn elevations(
    State(state): State<AppState>,
    Path((z, x, file)): Path<(String, String, String)>,
) -> Result<Response, ApiError> {
    let Some(views) = state.work.debug_views.clone() else {
        return Err(ApiError::not_found(
            "the debug view is turned off on this server (server.debug_view)",
        ));
    };
    let tile = parse(&z, &x, &file)?;
    if tile.z != state.zoom {
        return Err(ApiError::not_found(format!(
            "zoom {} is not served; debug views are at zoom {}",
            tile.z, state.zoom
        )));
    }
    let provider = state.provider()?;
    let key = crate::format::TileKey {
        tile,
        format: crate::format::Format::GLB,
    };
    match provider.availability(key) {
        Availability::Ready => {}
        Availability::Missing(reason) => return Err(ApiError::not_found(reason)),
        Availability::AfterFetch => {
            return Err(ApiError::not_found(format!(
                "the SRTM data of tile {tile} is not downloaded yet: ask for the tile first"
            )))
        }
    }
    let (work, metrics) = (state.work.clone(), state.metrics.clone());
    let made = async move {
        tokio::task::spawn_blocking(move || {
            let made = explain(&work, &*provider, tile);
            if made.is_ok() {
                super::metrics::Metrics::count(&metrics.debug_views);
            }
            made
        })
        .await
        .map_err(|e| ApiError::internal(format!("debug view of {tile} failed: {e}")))?
    };
    let body = views
        .try_get_with(tile, made)
        .await
        .map_err(|error| (*error).clone())?;
    Ok((
        StatusCode::OK,
        [(
            header::CONTENT_TYPE,
            HeaderValue::from_static("application/geo+json"),
        )],
        axum::body::Bytes::copy_from_slice(&body),
    )
        .into_response())
}

/// Makes the view in a render slot (on the blocking pool).
fn explain(
    work: &super::Work,
    provider: &dyn TileProvider,
    tile: TileId,
) -> Result<Arc<[u8]>, ApiError> {
    let Some(explaining) = provider.explaining() else {
        return Err(ApiError::not_found(format!(
            "no view of how tile {tile} was made: this server does not make tiles"
        )));
    };
    let _slot = work.pool.acquire().map_err(|refused| match refused {
        Refused::Busy { .. } => ApiError::unavailable(
            format!("the debug view of {tile} cannot be made now: {refused}; retry shortly"),
            RETRY_AFTER_S,
        ),
        Refused::Closed => ApiError::unavailable("the server is shutting down", RETRY_AFTER_S),
    })?;
    let started = std::time::Instant::now();
    let body = explaining.explain(tile).map_err(|e| match e {
        MakeError::NotHeld(message) => ApiError::not_found(message),
        e => ApiError::internal(format!("debug view of {tile} failed: {e}")),
    })?;
    tracing::info!(%tile, ms = started.elapsed().as_millis() as u64, bytes = body.len(), "debug view made");
    Ok(body.into())
}

/// Parses `z`, `x` and `y.geojson`.
fn parse(z: &str, x: &str, file: &str) -> Result<TileId, ApiError> {
    let y = file
        .strip_suffix(".geojson")
        .ok_or_else(|| ApiError::bad_request(format!("'{file}' is not Y.geojson")))?;
    TileId::from_parts(z, x, y).map_err(|e| ApiError::bad_request(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_geojson_paths_parse() {
        assert_eq!(
            parse("14", "8529", "5973.geojson").ok(),
            Some(TileId {
                z: 14,
                x: 8529,
                y: 5973
            })
        );
        for (z, x, file) in [
            ("14", "8529", "5973.glb"),
            ("14", "x", "1.geojson"),
            ("14", "1", "99999.geojson"),
        ] {
            assert_eq!(
                parse(z, x, file).unwrap_err().status,
                StatusCode::BAD_REQUEST
            );
        }
    }
}
