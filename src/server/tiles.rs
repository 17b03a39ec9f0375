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
use crate::cache::encoding::Accepted;
use crate::cache::{CacheError, Origin, Served};
use crate::format::Encoding;
use crate::format::Extensions;
use crate::format::{Format, TileKey};
use crate::format::{Frame, Variant};
use crate::provider::{Availability, Deadline, MakeError, TileProvider};
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
                "none" => false,
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

/// A tile in `format`: from memory, the store, or made now by the provider.
pub async fn serve(
    state: AppState,
    tile: TileId,
    format: Format,
    request_headers: HeaderMap,
) -> Result<Response, ApiError> {
    let provider = state.provider()?;
    let key = provider.resolve(tile, format)?;
    match provider.availability(key) {
        Availability::Ready => {}
        Availability::AfterFetch => fetch(&state, &provider, tile).await?,
        Availability::Missing(reason) => return Err(ApiError::not_found(reason)),
    }
    if let Some((status, message)) = state.work.failed_renders.get(&key) {
        return Err(ApiError {
            retry_after: Some(super::FAILED_RENDER_MEMORY.as_secs()),
            ..ApiError::new(
                status,
                format!("{message} (not tried again for a while after it failed)"),
            )
        });
    }
    // What a tile made now is made from: asked on the blocking pool, as a store's provider
    // reads the tile's last diff there.
    let asking = provider.clone();
    let wanted = tokio::task::spawn_blocking(move || asking.provenance(tile))
        .await
        .map_err(|e| ApiError::internal(e.to_string()))?;
    let keep = provider.holds_data(key);
    let render = render_job(&state, provider, key, Priority::Request);
    let accepted = accepted_codings(&request_headers);
    let served = state
        .cache
        .get_or_render_kept(key, wanted.as_ref(), keep, Some(accepted), render)
        .await
        .map_err(|e| {
            let error = failure_response(&state, tile, &e);
            if matches!(
                &*e,
                CacheError::Render(
                    RenderFailure::TimedOut(_)
                        | RenderFailure::OverBudget(_)
                        | RenderFailure::Failed(_)
                ) | CacheError::Store(_)
            ) {
                state
                    .work
                    .failed_renders
                    .insert(key, (error.status, error.message.as_str().into()));
            }
            error
        })?;
    match served.origin {
        Origin::Memory => Metrics::count(&state.metrics.hits_memory),
        Origin::Store => Metrics::count(&state.metrics.hits_store),
        Origin::Rendered => {
            Metrics::count(&state.metrics.misses);
            // A tile answered in haste is stored later, and counted then if it cannot be.
            if !served.tile.stored && keep && served.tile.bodies.quick.is_none() {
                Metrics::count(&state.metrics.tiles_unstored);
            }
        }
    }
    if served.stale {
        Metrics::count(&state.metrics.stale_served);
        state.work.regenerator.stale(key);
    }
    Ok(respond(&state, key, &served, &request_headers))
}

/// Has the provider download what `tile` lacks. Waiting for a download holds a blocking
/// thread: only so many wait there; the others wait here, on the executor, holding nothing.
async fn fetch(
    state: &AppState,
    provider: &Arc<dyn TileProvider>,
    tile: TileId,
) -> Result<(), ApiError> {
    let permit = state
        .work
        .download_waits
        .clone()
        .acquire_owned()
        .await
        .map_err(|_| ApiError::unavailable("the server is shutting down", RETRY_AFTER_S))?;
    let fetching = provider.clone();
    tokio::task::spawn_blocking(move || {
        let _permit = permit;
        crate::provider::capabilities::fetch(fetching.as_ref(), tile)
    })
    .await
    .map_err(|e| ApiError::internal(e.to_string()))??;
    Ok(())
}

/// The tile's response: the smallest coding the client accepts, its validator, and the
/// headers a download and a browser need; `304` when the client holds it.
fn respond(state: &AppState, key: TileKey, served: &Served, request: &HeaderMap) -> Response {
    let accepted = accepted_codings(request);
    let tile = &served.tile;
    let (coding, body) = tile.bodies.choose(&accepted);
    let etag = coded_etag(&tile.etag, coding, tile.bodies.quick.is_some());
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
    if let Some(cache_control) = &state.http.cache_control {
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

/// The codings a request's `Accept-Encoding` allows.
fn accepted_codings(request: &HeaderMap) -> Accepted {
    Accepted::parse(
        request
            .get_all(header::ACCEPT_ENCODING)
            .iter()
            .filter_map(|v| v.to_str().ok()),
    )
}

/// The validator of one coding of a tile: a strong ETag must differ between codings
/// (RFC 9110 §8.8.3), so the coding is appended to the content's digest. A form made in haste
/// is replaced by a smaller one of the same content: its validator is weak.
fn coded_etag(etag: &str, coding: Encoding, quick: bool) -> String {
    let weak = if quick { "W/" } else { "" };
    match coding {
        Encoding::Identity => etag.to_string(),
        other => format!("{weak}{}-{}\"", etag.trim_end_matches('"'), other.as_str()),
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
    /// It would take more memory than a render may.
    #[error("{0}")]
    OverBudget(String),
    #[error("{0}")]
    Failed(String),
    /// The provider does not hold the tile and cannot make it.
    #[error("{0}")]
    NotHeld(String),
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
        CacheError::Render(RenderFailure::NotHeld(message)) => ApiError::not_found(message.clone()),
        CacheError::Render(RenderFailure::TimedOut(message)) => {
            tracing::error!(%tile, %message, "render stopped at its time limit");
            ApiError::unavailable(message.clone(), RETRY_AFTER_S)
        }
        CacheError::Render(RenderFailure::OverBudget(message)) => {
            tracing::error!(%tile, %message, "render stopped at its memory limit");
            ApiError::unavailable(message.clone(), RETRY_AFTER_S)
        }
        CacheError::Store(error) => {
            tracing::error!(%tile, %error, "a held tile cannot be read");
            ApiError::internal(format!("tile {tile} cannot be read: {error}"))
        }
        other => {
            tracing::error!(%tile, error = %other, "tile failed");
            ApiError::internal(format!("tile {tile} could not be made: {other}"))
        }
    }
}

/// A render of `key` by `provider`, to run on the blocking pool: it takes a render slot first
/// (at `priority`), then makes the tile within the time limit, counting what it did.
pub fn render_job(
    state: &AppState,
    provider: Arc<dyn TileProvider>,
    key: TileKey,
    priority: Priority,
) -> impl FnOnce() -> Result<Vec<u8>, RenderFailure> + Send + 'static {
    let work = state.work.clone();
    let metrics = state.metrics.clone();
    // The render's log lines carry the request's span (and id) onto the blocking pool.
    let span = tracing::Span::current();
    move || {
        let _entered = span.enter();
        let _slot = match priority {
            Priority::Request => work.pool.acquire()?,
            Priority::Background => work.pool.acquire_background()?,
        };
        let deadline = work.render_limit.map_or(Deadline::none(), Deadline::after);
        let result = match work.render_memory {
            Some(bytes) => {
                let budget = crate::budget::Budget::new(bytes);
                crate::budget::within(&budget, || make(&*provider, &metrics, key, deadline))
            }
            None => make(&*provider, &metrics, key, deadline),
        };
        crate::server::memory::give_back();
        match &result {
            Ok(_) => Metrics::count(&metrics.renders),
            // Not a render: the provider holds tiles and lacks this one.
            Err(RenderFailure::NotHeld(_)) => {}
            Err(RenderFailure::TimedOut(_)) => {
                Metrics::count(&metrics.renders);
                Metrics::count(&metrics.render_timeouts);
            }
            Err(_) => {
                Metrics::count(&metrics.renders);
                Metrics::count(&metrics.render_failures);
            }
        }
        result
    }
}

/// Makes the tile, uncompressed, and records what the render measured (runs on the blocking
/// pool).
fn make(
    provider: &dyn TileProvider,
    metrics: &Metrics,
    key: TileKey,
    deadline: Deadline,
) -> Result<Vec<u8>, RenderFailure> {
    let made = provider.make(key, deadline).map_err(|e| match e {
        MakeError::NotHeld(message) => RenderFailure::NotHeld(message),
        e if e.timed_out() => RenderFailure::TimedOut(e.to_string()),
        e if e.over_budget() => RenderFailure::OverBudget(e.to_string()),
        e => RenderFailure::Failed(e.to_string()),
    })?;
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
        assert!(wants_meshopt(Some("compress=")).is_err());
        assert!(wants_meshopt(Some("compress")).is_err());
        let error = wants_meshopt(Some("compress=draco")).unwrap_err();
        assert_eq!(error.status, StatusCode::BAD_REQUEST);
        assert!(error.message.contains("draco"), "{}", error.message);
    }
}
