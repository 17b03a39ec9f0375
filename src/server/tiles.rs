//! `GET /tiles/{z}/{x}/{y}.glb`.
//!
//! The route captures the last segment whole (`{y}.glb`): axum 0.8 panics on a capture followed
//! by a literal in one segment.

use std::sync::Arc;

use axum::extract::{Path, RawQuery, State};
use axum::http::{header, HeaderMap, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};

use super::error::ApiError;
use super::metrics::Metrics;
use super::pool::Refused;
use super::{AppState, RETRY_AFTER_S};
use crate::cache::encoding::{Accepted, Encoding};
use crate::cache::{CacheError, Origin, Provenance, Served};
use crate::format::Extensions;
use crate::format::{Format, TileKey};
use crate::format::{Frame, Variant};
use crate::provider::inputs::{Inputs, MissingSrtm};
use crate::render::Deadline;
use crate::tile::TileId;

/// Whether the query asks for compressed glb: `compress=meshopt` (`EXT_meshopt_compression`
/// over `KHR_mesh_quantization`) or `compress=none` (the default). Other parameters are left
/// alone (a cache-busting one, say); a `compress` of anything else is refused.
pub fn wants_meshopt(query: Option<&str>) -> Result<bool, ApiError> {
    let mut meshopt = false;
    for pair in query.unwrap_or("").split('&') {
        let (key, value) = pair.split_once('=').unwrap_or((pair, ""));
        if key == "compress" {
            meshopt = match value {
                "meshopt" => true,
                "none" | "" => false,
                other => {
                    return Err(ApiError::bad_request(format!(
                        "compress={other} is not offered; use compress=meshopt or compress=none"
                    )))
                }
            };
        }
    }
    Ok(meshopt)
}

/// Parses `z`, `x` and `y.ext` into a tile and a format; `accept` chooses quantized-mesh
/// extensions, `glb` the frame and compression of a glb.
pub fn parse_tile_path(
    z: &str,
    x: &str,
    file: &str,
    accept: &str,
    glb: Variant,
) -> Result<(TileId, Format), ApiError> {
    let (y, extension) = file.rsplit_once('.').ok_or_else(|| {
        ApiError::bad_request(format!(
            "'{file}' has no format extension; expected Y.glb or Y.terrain"
        ))
    })?;
    let format = match extension {
        "glb" => Format::Glb(glb),
        "terrain" if glb.frame == Frame::WebMercator => {
            Format::Terrain(Extensions::from_accept(accept))
        }
        other => {
            return Err(ApiError::bad_request(match glb.frame {
                Frame::WebMercator => {
                    format!("unknown tile format '.{other}'; expected .glb or .terrain")
                }
                Frame::EastNorthUp => {
                    format!("unknown 3D Tiles file '.{other}'; expected .glb or .json")
                }
            }))
        }
    };
    let tile = TileId::from_parts(z, x, y).map_err(|e| ApiError::bad_request(e.to_string()))?;
    Ok((tile, format))
}

/// `GET /tiles/{z}/{x}/{y}.glb|.terrain`: the flat frame.
pub async fn tile(
    State(state): State<AppState>,
    Path((z, x, file)): Path<(String, String, String)>,
    RawQuery(query): RawQuery,
    request_headers: HeaderMap,
) -> Result<Response, ApiError> {
    Metrics::count(&state.metrics.tile_requests);
    let accept = request_headers
        .get(header::ACCEPT)
        .and_then(|v| v.to_str().ok())
        .unwrap_or("");
    let variant = Variant {
        frame: Frame::WebMercator,
        meshopt: wants_meshopt(query.as_deref())?,
    };
    let (tile, format) = parse_tile_path(&z, &x, &file, accept, variant)?;
    serve(state, tile, format, request_headers).await
}

/// A tile in `format`: from memory, the store, or made now.
pub async fn serve(
    state: AppState,
    tile: TileId,
    format: Format,
    request_headers: HeaderMap,
) -> Result<Response, ApiError> {
    let overview = matches!(format, Format::Terrain(_)) && tile.z < state.zoom;
    if tile.z != state.zoom && !overview {
        return Err(ApiError::not_found(match format {
            Format::Glb(_) => format!(
                "zoom {} is not served; this server serves glb tiles at zoom {}",
                tile.z, state.zoom
            ),
            Format::Terrain(_) => format!(
                "zoom {} is not served; this server serves terrain at zooms 0 to {}",
                tile.z, state.zoom
            ),
        }));
    }
    if let Some(archive) = &state.archive {
        return from_archive(&state, archive, tile, format, &request_headers).await;
    }
    let sources = state.sources()?;
    if !overview {
        // Overview tiles cover whatever they cover: sea level where there is no data.
        if sources.check_coverage(tile).is_err() && sources.can_fetch_srtm() {
            // Waiting for a download holds a blocking thread: only so many wait there; the
            // others wait here, on the executor, holding nothing.
            let permit = state
                .download_waits
                .clone()
                .acquire_owned()
                .await
                .map_err(|_| ApiError::unavailable("the server is shutting down", RETRY_AFTER_S))?;
            let fetching = sources.clone();
            tokio::task::spawn_blocking(move || {
                let _permit = permit;
                fetching.fetch_missing_srtm(tile)
            })
            .await
            .map_err(|e| ApiError::internal(e.to_string()))?
            .map_err(|e| match e {
                MissingSrtm::NotFound { .. } => ApiError::not_found(e.to_string()),
                MissingSrtm::Failed { .. } => ApiError::new(StatusCode::BAD_GATEWAY, e.to_string()),
            })?;
        }
        sources
            .check_coverage(tile)
            .map_err(|e| ApiError::not_found(e.to_string()))?;
    }

    let key = TileKey { tile, format };
    if let Some((status, message)) = state.failed_renders.get(&key) {
        return Err(ApiError {
            retry_after: Some(super::FAILED_RENDER_MEMORY.as_secs()),
            ..ApiError::new(
                status,
                format!("{message} (not tried again for a while after it failed)"),
            )
        });
    }
    let wanted = provenance(&state, &sources, tile);
    let render = render_job(&state, sources.clone(), key, Priority::Request);
    let served = state
        .cache
        .get_or_render(key, Some(&wanted), render)
        .await
        .map_err(|e| {
            let error = failure_response(&state, tile, &e);
            if matches!(
                &*e,
                CacheError::Render(RenderFailure::TimedOut(_) | RenderFailure::Failed(_))
            ) {
                state
                    .failed_renders
                    .insert(key, (error.status, error.message.as_str().into()));
            }
            error
        })?;
    match served.origin {
        Origin::Memory => Metrics::count(&state.metrics.hits_memory),
        Origin::Store => Metrics::count(&state.metrics.hits_store),
        Origin::Rendered => Metrics::count(&state.metrics.misses),
    }
    if served.stale {
        Metrics::count(&state.metrics.stale_served);
        state.regenerator.stale(key);
    }
    Ok(respond(&state, key, &served, &request_headers))
}

/// A tile of the served archive; one it lacks is a `404`.
async fn from_archive(
    state: &AppState,
    archive: &super::Archive,
    tile: TileId,
    format: Format,
    request_headers: &HeaderMap,
) -> Result<Response, ApiError> {
    let format = match (format, archive.format) {
        (Format::Terrain(_), Format::Terrain(held)) => Format::Terrain(held),
        (asked, _) => asked,
    };
    let key = TileKey { tile, format };
    let path = archive.path.display().to_string();
    let missing = move || -> Result<Vec<u8>, RenderFailure> {
        Err(RenderFailure::NotInArchive(format!(
            "tile {tile} ({}) is not in {path}",
            format.as_str()
        )))
    };
    let served = state
        .cache
        .get_or_render(key, None, missing)
        .await
        .map_err(|e| failure_response(state, tile, &e))?;
    match served.origin {
        Origin::Memory => Metrics::count(&state.metrics.hits_memory),
        _ => Metrics::count(&state.metrics.hits_store),
    }
    Ok(respond(state, key, &served, request_headers))
}

/// What a tile made now from these sources is made from.
pub fn provenance(state: &AppState, sources: &Inputs, tile: TileId) -> Provenance {
    Provenance {
        pipeline: state.pipeline.to_string(),
        sources: sources.version_for(tile),
    }
}

/// The tile's response: the smallest coding the client accepts, its validator, and the
/// headers a download and a browser need; `304` when the client holds it.
fn respond(state: &AppState, key: TileKey, served: &Served, request: &HeaderMap) -> Response {
    let accepted = Accepted::parse(
        request
            .get_all(header::ACCEPT_ENCODING)
            .iter()
            .filter_map(|v| v.to_str().ok()),
    );
    let tile = &served.tile;
    let (coding, body) = tile.bodies.choose(&accepted);
    let etag = coded_etag(&tile.etag, coding);
    let mut headers = HeaderMap::new();
    match key.format {
        Format::Glb(_) => {
            headers.insert(
                header::CONTENT_TYPE,
                HeaderValue::from_static("model/gltf-binary"),
            );
            headers.insert(header::VARY, HeaderValue::from_static("Accept-Encoding"));
        }
        Format::Terrain(_) => {
            headers.insert(
                header::CONTENT_TYPE,
                HeaderValue::from_static("application/vnd.quantized-mesh"),
            );
            headers.insert(
                header::VARY,
                HeaderValue::from_static("Accept, Accept-Encoding"),
            );
        }
    }
    if let Ok(value) = HeaderValue::from_str(&etag) {
        headers.insert(header::ETAG, value);
    }
    if let Some(cache_control) = &state.cache_control {
        headers.insert(header::CACHE_CONTROL, cache_control.clone());
    }
    // A client that holds this tile in the coding it would get now receives a `304` without
    // the body (with the validator it holds, as RFC 9111 §4.3.4 needs to match it).
    if request
        .get_all(header::IF_NONE_MATCH)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .any(|v| matches_etag(v, &etag))
    {
        return (StatusCode::NOT_MODIFIED, headers).into_response();
    }
    if coding != Encoding::Identity {
        headers.insert(
            header::CONTENT_ENCODING,
            HeaderValue::from_static(coding.as_str()),
        );
    }
    headers.insert(
        "x-cache",
        HeaderValue::from_static(match (served.origin, served.stale) {
            (_, true) => "stale",
            (Origin::Rendered, false) => "miss",
            _ => "hit",
        }),
    );
    headers.insert(
        "x-cache-layer",
        HeaderValue::from_static(served.origin.as_str()),
    );
    let tile_id = key.tile;
    if let Ok(disposition) = HeaderValue::from_str(&format!(
        "attachment; filename=\"{}_{}_{}.{}\"",
        tile_id.z,
        tile_id.x,
        tile_id.y,
        key.format.extension()
    )) {
        headers.insert(header::CONTENT_DISPOSITION, disposition);
    }
    (StatusCode::OK, headers, body.clone()).into_response()
}

/// The validator of one coding of a tile: a strong ETag must differ between codings
/// (RFC 9110 §8.8.3), so the coding is appended to the content's digest.
fn coded_etag(etag: &str, coding: Encoding) -> String {
    match coding {
        Encoding::Identity => etag.to_string(),
        other => format!("{}-{}\"", etag.trim_end_matches('"'), other.as_str()),
    }
}

/// True when an `If-None-Match` value names `etag` (or is `*`): a comma-separated list of
/// entity tags, compared weakly as RFC 9110 asks (a `W/` prefix is ignored).
fn matches_etag(if_none_match: &str, etag: &str) -> bool {
    let bare = |tag: &str| tag.trim().trim_start_matches("W/").to_string();
    if_none_match
        .split(',')
        .any(|tag| tag.trim() == "*" || bare(tag) == etag)
}

/// Who a render is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Priority {
    /// A request waits for it: it may queue, or be refused when the queue is full.
    Request,
    /// Background work: it waits until no request does.
    Background,
}

/// Why a render gave no tile.
#[derive(Debug, thiserror::Error)]
pub enum RenderFailure {
    #[error(transparent)]
    Refused(#[from] Refused),
    #[error("{0}")]
    TimedOut(String),
    #[error("{0}")]
    Failed(String),
    /// A server of an archive was asked for a tile the archive lacks.
    #[error("{0}")]
    NotInArchive(String),
}

/// The error response for a tile that could not be made.
fn failure_response(state: &AppState, tile: TileId, error: &CacheError<RenderFailure>) -> ApiError {
    match error {
        CacheError::Render(RenderFailure::Refused(refused)) => {
            Metrics::count(&state.metrics.rejected_busy);
            tracing::warn!(%tile, %refused, "tile refused");
            ApiError::unavailable(
                format!("tile {tile} cannot be rendered now: {refused}; retry shortly"),
                RETRY_AFTER_S,
            )
        }
        CacheError::Render(RenderFailure::NotInArchive(message)) => {
            ApiError::not_found(message.clone())
        }
        CacheError::Render(RenderFailure::TimedOut(message)) => {
            tracing::error!(%tile, %message, "render stopped at its time limit");
            ApiError::unavailable(message.clone(), RETRY_AFTER_S)
        }
        other => {
            tracing::error!(%tile, error = %other, "tile failed");
            ApiError::internal(format!("tile {tile} could not be made: {other}"))
        }
    }
}

/// A render of `key` from `sources`, to run on the blocking pool: it takes a render slot
/// first (at `priority`), then renders within the time limit, counting what it did.
pub fn render_job(
    state: &AppState,
    sources: Arc<Inputs>,
    key: TileKey,
    priority: Priority,
) -> impl FnOnce() -> Result<Vec<u8>, RenderFailure> + Send + 'static {
    let state = state.clone();
    // The render's log lines carry the request's span (and id) onto the blocking pool.
    let span = tracing::Span::current();
    move || {
        let _entered = span.enter();
        let pool = state.pool.clone();
        let _slot = match priority {
            Priority::Request => pool.acquire()?,
            Priority::Background => pool.acquire_background()?,
        };
        let deadline = state.render_limit.map_or(Deadline::none(), Deadline::after);
        let result = render_format(&state, &sources, key, deadline);
        let metrics = &state.metrics;
        Metrics::count(&metrics.renders);
        match &result {
            Ok(_) => {}
            Err(RenderFailure::TimedOut(_)) => Metrics::count(&metrics.render_timeouts),
            Err(_) => Metrics::count(&metrics.render_failures),
        }
        result
    }
}

/// Makes the tile, uncompressed, and records what the render measured (runs on the blocking
/// pool).
fn render_format(
    state: &AppState,
    sources: &Inputs,
    key: TileKey,
    deadline: Deadline,
) -> Result<Vec<u8>, RenderFailure> {
    let made = crate::provider::pipeline::make(sources, key, &state.settings, state.zoom, deadline)
        .map_err(|e| {
            if e.timed_out() {
                RenderFailure::TimedOut(e.to_string())
            } else {
                RenderFailure::Failed(e.to_string())
            }
        })?;
    let metrics = &state.metrics;
    Metrics::add(&metrics.lp_components, made.lp_components as u64);
    Metrics::add(&metrics.lp_violations, made.lp_violations as u64);
    metrics.observe_render(&made.timings);
    tracing::info!(
        tile = %key.tile,
        format = key.format.as_str(),
        triangles = made.triangles,
        lp_violations = made.lp_violations,
        bytes = made.bytes.len(),
        ms = made.timings.total().as_millis() as u64,
        "rendered"
    );
    Ok(made.bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_good_paths_and_rejects_bad_ones() {
        let plain = Variant::default();
        let (tile, format) = parse_tile_path("14", "8529", "5973.glb", "", plain).unwrap();
        assert_eq!(
            tile,
            TileId {
                z: 14,
                x: 8529,
                y: 5973
            }
        );
        assert_eq!(format, Format::GLB);
        let accept = "application/vnd.quantized-mesh;extensions=watermask";
        let (_, format) = parse_tile_path("14", "8529", "5973.terrain", accept, plain).unwrap();
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
            let error = parse_tile_path(z, x, file, "", plain).unwrap_err();
            assert_eq!(error.status, StatusCode::BAD_REQUEST, "{z}/{x}/{file}");
        }
        // 3D Tiles content is glb in the east-north-up frame; it has no terrain form.
        let enu = Variant {
            frame: Frame::EastNorthUp,
            meshopt: true,
        };
        let (_, format) = parse_tile_path("14", "8529", "5973.glb", "", enu).unwrap();
        assert_eq!(format, Format::Glb(enu));
        assert!(parse_tile_path("14", "8529", "5973.terrain", "", enu).is_err());
    }

    #[test]
    fn compression_is_asked_for_in_the_query() {
        assert!(!wants_meshopt(None).unwrap());
        assert!(wants_meshopt(Some("compress=meshopt")).unwrap());
        assert!(wants_meshopt(Some("v=3&compress=meshopt")).unwrap());
        assert!(!wants_meshopt(Some("compress=none&x")).unwrap());
        let error = wants_meshopt(Some("compress=draco")).unwrap_err();
        assert_eq!(error.status, StatusCode::BAD_REQUEST);
        assert!(error.message.contains("draco"), "{}", error.message);
    }
}
