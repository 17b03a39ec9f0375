//! `GET /debug/tiles/{z}/{x}/{y}.geojson`: the settled bridges, tunnels and ground roads of a
//! tile with their connectors and constraints (see [`crate::output::debug`]). Made on every request,
//! never cached: it is for looking into how a tile came out.

use axum::extract::{Path, State};
use axum::http::{header, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};

use super::error::ApiError;
use super::AppState;
use crate::provider::{Availability, MakeError};
use crate::tile::TileId;

pub async fn elevations(
    State(state): State<AppState>,
    Path((z, x, file)): Path<(String, String, String)>,
) -> Result<Response, ApiError> {
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
    let body = tokio::task::spawn_blocking(move || provider.explain(tile))
        .await
        .map_err(|e| ApiError::internal(format!("debug view of {tile} failed: {e}")))?
        .map_err(|e| match e {
            MakeError::NotHeld(message) => ApiError::not_found(message),
            e => ApiError::internal(format!("debug view of {tile} failed: {e}")),
        })?;
    Ok((
        StatusCode::OK,
        [(
            header::CONTENT_TYPE,
            HeaderValue::from_static("application/geo+json"),
        )],
        body,
    )
        .into_response())
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
