//! `GET /tiles/{z}/{x}/{y}.glb`.
//!
//! The route captures the last segment whole (`{y}.glb`): axum 0.8 panics on a capture followed
//! by a literal in one segment.

use std::time::Instant;

use axum::extract::{Path, State};
use axum::http::{header, HeaderMap, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};

use super::error::ApiError;
use super::metrics::Metrics;
use super::AppState;
use crate::cache::{Format, Origin, TileKey};
use crate::output::quantized_mesh::Extensions;
use crate::tile::{TileId, TileIdError};

/// Parses `z`, `x` and `y.ext` into a tile and a format; `accept` chooses quantized-mesh
/// extensions.
pub fn parse_tile_path(
    z: &str,
    x: &str,
    file: &str,
    accept: &str,
) -> Result<(TileId, Format), ApiError> {
    let (y, extension) = file.rsplit_once('.').ok_or_else(|| {
        ApiError::bad_request(format!(
            "'{file}' has no format extension; expected Y.glb or Y.terrain"
        ))
    })?;
    let format = match extension {
        "glb" => Format::Glb,
        "terrain" => Format::Terrain(Extensions::from_accept(accept)),
        other => {
            return Err(ApiError::bad_request(format!(
                "unknown tile format '.{other}'; expected .glb or .terrain"
            )))
        }
    };
    let number = |name: &str, text: &str| {
        text.parse::<u64>().map_err(|_| {
            ApiError::bad_request(format!("{name} = '{text}' is not a non-negative integer"))
        })
    };
    let z = number("z", z)?;
    let x = number("x", x)?;
    let y = number("y", y)?;
    let z =
        u32::try_from(z).map_err(|_| ApiError::bad_request(format!("zoom {z} is out of range")))?;
    let tile =
        TileId::new(z, x, y).map_err(|e: TileIdError| ApiError::bad_request(e.to_string()))?;
    Ok((tile, format))
}

pub async fn tile(
    State(state): State<AppState>,
    Path((z, x, file)): Path<(String, String, String)>,
    request_headers: HeaderMap,
) -> Result<Response, ApiError> {
    Metrics::count(&state.metrics.tile_requests);
    let accept = request_headers
        .get(header::ACCEPT)
        .and_then(|v| v.to_str().ok())
        .unwrap_or("");
    let (tile, format) = parse_tile_path(&z, &x, &file, accept)?;
    let overview = matches!(format, Format::Terrain(_)) && tile.z < state.zoom;
    if tile.z != state.zoom && !overview {
        return Err(ApiError::not_found(match format {
            Format::Glb => format!(
                "zoom {} is not served; this server serves glb tiles at zoom {}",
                tile.z, state.zoom
            ),
            Format::Terrain(_) => format!(
                "zoom {} is not served; this server serves terrain at zooms 0 to {}",
                tile.z, state.zoom
            ),
        }));
    }
    if !overview {
        // Overview tiles cover whatever they cover: sea level where there is no data.
        state
            .sources
            .check_coverage(tile)
            .map_err(|e| ApiError::not_found(e.to_string()))?;
    }

    let key = TileKey { tile, format };
    let render_state = state.clone();
    let permits = state.render_permits.clone();
    let runtime = tokio::runtime::Handle::current();
    let render = move || -> Result<Vec<u8>, RenderFailure> {
        // Runs on the blocking pool: wait here for one of the render slots.
        let _permit = runtime
            .block_on(permits.acquire_owned())
            .map_err(|_| RenderFailure("the server is shutting down".to_string()))?;
        let started = Instant::now();
        let result = render_format(&render_state, tile, format);
        let metrics = &render_state.metrics;
        Metrics::count(&metrics.renders);
        metrics.render_seconds_micros.fetch_add(
            started.elapsed().as_micros() as u64,
            std::sync::atomic::Ordering::Relaxed,
        );
        if result.is_err() {
            Metrics::count(&metrics.render_failures);
        }
        result
    };
    let (cached, origin) = state.cache.get_or_render(key, render).await.map_err(|e| {
        tracing::error!(%tile, error = %e, "tile failed");
        ApiError::internal(format!("tile {tile} could not be made: {e}"))
    })?;
    match origin {
        Origin::Memory => Metrics::count(&state.metrics.hits_memory),
        Origin::Store => Metrics::count(&state.metrics.hits_store),
        Origin::Rendered => {}
    }

    let mut headers = HeaderMap::new();
    match format {
        Format::Glb => {
            headers.insert(
                header::CONTENT_TYPE,
                HeaderValue::from_static("model/gltf-binary"),
            );
        }
        Format::Terrain(_) => {
            headers.insert(
                header::CONTENT_TYPE,
                HeaderValue::from_static("application/vnd.quantized-mesh"),
            );
            headers.insert(header::CONTENT_ENCODING, HeaderValue::from_static("gzip"));
            headers.insert(header::VARY, HeaderValue::from_static("Accept"));
        }
    }
    if let Ok(etag) = HeaderValue::from_str(&cached.etag) {
        headers.insert(header::ETAG, etag);
    }
    if let Some(cache_control) = &state.cache_control {
        headers.insert(header::CACHE_CONTROL, cache_control.clone());
    }
    // A client that holds this very tile gets a `304` without the body.
    if request_headers
        .get_all(header::IF_NONE_MATCH)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .any(|v| matches_etag(v, &cached.etag))
    {
        headers.remove(header::CONTENT_ENCODING);
        return Ok((StatusCode::NOT_MODIFIED, headers).into_response());
    }
    headers.insert(
        "x-cache",
        HeaderValue::from_static(if origin == Origin::Rendered {
            "miss"
        } else {
            "hit"
        }),
    );
    headers.insert("x-cache-layer", HeaderValue::from_static(origin.as_str()));
    if let Ok(disposition) = HeaderValue::from_str(&format!(
        "attachment; filename=\"{}_{}_{}.{}\"",
        tile.z,
        tile.x,
        tile.y,
        format.extension()
    )) {
        headers.insert(header::CONTENT_DISPOSITION, disposition);
    }
    Ok((StatusCode::OK, headers, cached.data.clone()).into_response())
}

#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct RenderFailure(String);

/// Loads the tile's inputs and renders it in a format (runs on the blocking pool).
fn render_format(state: &AppState, tile: TileId, format: Format) -> Result<Vec<u8>, RenderFailure> {
    let mosaic = state
        .sources
        .mosaic(tile)
        .map_err(|e| RenderFailure(e.to_string()))?;
    let failure = |e: crate::render::RenderError| RenderFailure(e.to_string());
    match format {
        Format::Glb => {
            let selection = state.sources.selection(tile);
            let rendered = crate::render::render(tile, &selection, &mosaic, &state.settings)
                .map_err(failure)?;
            let metrics = &state.metrics;
            let add = |counter: &std::sync::atomic::AtomicU64, n: usize| {
                counter.fetch_add(n as u64, std::sync::atomic::Ordering::Relaxed);
            };
            add(&metrics.lp_components, rendered.stats.lp_components);
            add(&metrics.lp_violations, rendered.stats.lp_violations);
            tracing::info!(
                %tile,
                triangles = rendered.stats.triangles,
                lp_violations = rendered.stats.lp_violations,
                bytes = rendered.stats.glb_bytes,
                ms = rendered.timings.total().as_millis() as u64,
                "rendered glb"
            );
            Ok(rendered.glb)
        }
        Format::Terrain(extensions) => {
            let rendered = if tile.z < state.zoom {
                crate::render::render_overview_terrain(
                    tile,
                    &mosaic,
                    &state.settings,
                    state.zoom,
                    extensions,
                )
            } else {
                crate::render::render_terrain(
                    tile,
                    &state.sources.selection(tile),
                    &mosaic,
                    &state.settings,
                    extensions,
                )
            }
            .map_err(failure)?;
            tracing::info!(
                %tile,
                triangles = rendered.report.triangles,
                bytes = rendered.bytes.len(),
                ms = rendered.timings.total().as_millis() as u64,
                "rendered terrain"
            );
            gzip(&rendered.bytes).map_err(|e| RenderFailure(format!("gzip: {e}")))
        }
    }
}

/// True when an `If-None-Match` value names `etag` (or is `*`): a comma-separated list of
/// entity tags, compared weakly as RFC 9110 asks (a `W/` prefix is ignored).
fn matches_etag(if_none_match: &str, etag: &str) -> bool {
    let bare = |tag: &str| tag.trim().trim_start_matches("W/").to_string();
    if_none_match
        .split(',')
        .any(|tag| tag.trim() == "*" || bare(tag) == bare(etag))
}

fn gzip(data: &[u8]) -> std::io::Result<Vec<u8>> {
    use std::io::Write;
    let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    encoder.write_all(data)?;
    encoder.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_good_paths_and_rejects_bad_ones() {
        let (tile, format) = parse_tile_path("14", "8529", "5973.glb", "").unwrap();
        assert_eq!(
            tile,
            TileId {
                z: 14,
                x: 8529,
                y: 5973
            }
        );
        assert_eq!(format, Format::Glb);
        let accept = "application/vnd.quantized-mesh;extensions=watermask";
        let (_, format) = parse_tile_path("14", "8529", "5973.terrain", accept).unwrap();
        let watermask = Extensions {
            normals: false,
            watermask: true,
        };
        assert_eq!(format, Format::Terrain(watermask));
        for (z, x, file) in [
            ("14", "abc", "1.glb"),
            ("14", "99999", "1.glb"),
            ("14", "1", "1.png"),
            ("14", "1", "1"),
            ("-1", "0", "0.glb"),
        ] {
            let error = parse_tile_path(z, x, file, "").unwrap_err();
            assert_eq!(error.status, StatusCode::BAD_REQUEST, "{z}/{x}/{file}");
        }
    }
}
