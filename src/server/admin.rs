//! `POST /admin/regenerate` and `POST /admin/purge`, guarded by the bearer token of
//! `server.admin_token` (without one they are off: `404`).
//!
//! The body names the tiles: `{"bbox": [W, S, E, N]}` (or `"W,S,E,N"`), `{"tiles":
//! ["14/8529/5973", ...]}`, or `{"all": true}`. Regeneration queues the stored tiles chosen,
//! most recently served first, and makes them again in the background while the old ones are
//! served; purging removes them from the store and from memory.

use axum::extract::State;
use axum::http::{header, HeaderMap, StatusCode};
use axum::Json;
use serde::Deserialize;
use serde_json::{json, Value};

use super::error::ApiError;
use super::regenerate::queue_stored;
use super::AppState;
use crate::cache::coordinator::JobKind;
use crate::cache::TileFilter;
use crate::tile::{LonLatBounds, TileId, TileRange};

/// Which tiles an admin request is about.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Selection {
    bbox: Option<BoxSpec>,
    tiles: Option<Vec<String>>,
    #[serde(default)]
    all: bool,
}

#[derive(Debug, Deserialize)]
#[serde(untagged)]
enum BoxSpec {
    Numbers([f64; 4]),
    Text(String),
}

impl Selection {
    fn filter(&self, zoom: u8) -> Result<TileFilter, ApiError> {
        match (&self.bbox, &self.tiles, self.all) {
            (Some(spec), None, false) => {
                let text = match spec {
                    BoxSpec::Numbers([w, s, e, n]) => format!("{w},{s},{e},{n}"),
                    BoxSpec::Text(text) => text.clone(),
                };
                let bounds: LonLatBounds = text.parse().map_err(ApiError::bad_request)?;
                Ok(TileFilter::Range(TileRange::covering(zoom, &bounds)))
            }
            (None, Some(tiles), false) => {
                let tiles = tiles
                    .iter()
                    .map(|t| {
                        t.parse::<TileId>()
                            .map_err(|e| ApiError::bad_request(format!("tile '{t}': {e}")))
                    })
                    .collect::<Result<Vec<_>, _>>()?;
                Ok(TileFilter::tiles(tiles))
            }
            (None, None, true) => Ok(TileFilter::All),
            _ => Err(ApiError::bad_request(
                "name the tiles with exactly one of \"bbox\": [W, S, E, N], \"tiles\": [\"Z/X/Y\", ...] or \"all\": true",
            )),
        }
    }
}

/// Checks the bearer token: `404` when admin routes are off, `401` without the right token.
fn authorize(state: &AppState, headers: &HeaderMap) -> Result<(), ApiError> {
    let Some(token) = &state.http.admin_token else {
        return Err(ApiError::not_found(
            "admin routes are off: set server.admin_token to turn them on",
        ));
    };
    // The scheme's name is case-insensitive (RFC 9110 §11.1).
    let given = headers
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.trim_start().split_once(' '))
        .filter(|(scheme, _)| scheme.eq_ignore_ascii_case("bearer"))
        .map(|(_, token)| token.trim());
    match given {
        Some(given) if constant_time_eq(given.as_bytes(), token.as_bytes()) => Ok(()),
        Some(_) => Err(ApiError::new(
            StatusCode::UNAUTHORIZED,
            "the bearer token is not the admin token",
        )),
        None => Err(ApiError::new(
            StatusCode::UNAUTHORIZED,
            "admin routes need an Authorization: Bearer <token> header",
        )),
    }
}

/// Compares without stopping at the first difference, so timing tells nothing of the token.
fn constant_time_eq(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

/// Largest admin body, bytes.
const BODY_LIMIT: usize = 2 << 20;

/// Reads a request's body, once its token was checked: within the body timeout, and no longer
/// than [`BODY_LIMIT`].
async fn read_body(
    state: &AppState,
    headers: &HeaderMap,
    body: axum::body::Body,
) -> Result<axum::body::Bytes, ApiError> {
    let too_long = || {
        ApiError::new(
            StatusCode::PAYLOAD_TOO_LARGE,
            format!("the body is longer than {BODY_LIMIT} bytes"),
        )
    };
    let announced = headers
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<u64>().ok());
    if announced.is_some_and(|length| length > BODY_LIMIT as u64) {
        return Err(too_long());
    }
    let read = tokio::time::timeout(
        state.http.body_timeout,
        axum::body::to_bytes(body, BODY_LIMIT),
    );
    match read.await {
        Ok(Ok(bytes)) => Ok(bytes),
        Ok(Err(error)) => {
            let too_long_read = std::error::Error::source(&error)
                .is_some_and(|e| e.is::<http_body_util::LengthLimitError>());
            Err(if too_long_read {
                too_long()
            } else {
                ApiError::bad_request(format!("the body could not be read: {error}"))
            })
        }
        Err(_) => Err(ApiError::new(
            StatusCode::REQUEST_TIMEOUT,
            format!(
                "the body did not arrive within {} s",
                state.http.body_timeout.as_secs()
            ),
        )),
    }
}

/// Reads the body as a [`Selection`], with a JSON error when it is not one.
fn selection(body: &[u8]) -> Result<Selection, ApiError> {
    serde_json::from_slice(body)
        .map_err(|e| ApiError::bad_request(format!("the body is not a tile selection: {e}")))
}

pub async fn regenerate(
    State(state): State<AppState>,
    headers: HeaderMap,
    body: axum::body::Body,
) -> Result<(StatusCode, Json<Value>), ApiError> {
    authorize(&state, &headers)?;
    let body = read_body(&state, &headers, body).await?;
    let filter = selection(&body)?.filter(state.zoom)?;
    // Tiles that failed lately may be tried again at once.
    state.work.failed_renders.invalidate_all();
    let queued = queue_stored(&state, filter, false)
        .await
        .map_err(ApiError::internal)?;
    tracing::info!(queued, "regeneration asked for");
    // The whole queue: every process sharing the store works on it.
    let coordinator = state.cache.coordinator().clone();
    let in_line = tokio::task::spawn_blocking(move || coordinator.pending(JobKind::Regenerate))
        .await
        .map_err(|e| ApiError::internal(e.to_string()))?
        .map_err(|e| ApiError::internal(e.to_string()))? as usize;
    Ok((
        StatusCode::ACCEPTED,
        Json(json!({ "queued": queued, "in_line": in_line })),
    ))
}

pub async fn purge(
    State(state): State<AppState>,
    headers: HeaderMap,
    body: axum::body::Body,
) -> Result<Json<Value>, ApiError> {
    authorize(&state, &headers)?;
    let body = read_body(&state, &headers, body).await?;
    let filter = selection(&body)?.filter(state.zoom)?;
    let unqueued = state.work.regenerator.forget(&filter);
    state.work.failed_renders.invalidate_all();
    let removed = state
        .cache
        .purge(filter)
        .await
        .map_err(|e| ApiError::internal(e.to_string()))?;
    tracing::info!(removed = removed.len(), unqueued, "tiles purged");
    Ok(Json(json!({ "removed": removed.len() })))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_selection_names_its_tiles_one_way_only() {
        let parse = |body: &str| selection(body.as_bytes()).and_then(|s| s.filter(14));
        assert!(matches!(
            parse(r#"{"bbox": [7.41, 43.72, 7.43, 43.74]}"#),
            Ok(TileFilter::Range(_))
        ));
        assert!(matches!(
            parse(r#"{"bbox": "7.41,43.72,7.43,43.74"}"#),
            Ok(TileFilter::Range(_))
        ));
        assert_eq!(
            parse(r#"{"tiles": ["14/8529/5973"]}"#).unwrap(),
            TileFilter::Tiles(vec![TileId {
                z: 14,
                x: 8529,
                y: 5973
            }])
        );
        assert_eq!(parse(r#"{"all": true}"#).unwrap(), TileFilter::All);
        for bad in [
            "{}",
            "not json",
            r#"{"all": true, "tiles": []}"#,
            r#"{"bbox": [1, 2, 3]}"#,
            r#"{"tiles": ["14/x/1"]}"#,
            r#"{"bbox": [7.43, 43.72, 7.41, 43.74]}"#,
            r#"{"every": true}"#,
        ] {
            assert_eq!(
                parse(bad).unwrap_err().status,
                StatusCode::BAD_REQUEST,
                "{bad}"
            );
        }
    }

    #[test]
    fn tokens_compare_whole() {
        assert!(constant_time_eq(b"secret", b"secret"));
        assert!(!constant_time_eq(b"secret", b"secreT"));
        assert!(!constant_time_eq(b"secret", b"secret2"));
    }
}
