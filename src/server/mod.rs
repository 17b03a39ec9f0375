//! The HTTP server: routes, shared state, and how requests reach the cache and the renderer.

pub mod debug;
pub mod error;
pub mod layer;
pub mod metrics;
pub mod tilejson;
pub mod tiles;

use std::sync::Arc;

use axum::http::{header, StatusCode};
use axum::response::IntoResponse;
use axum::routing::get;
use axum::Router;
use tokio::sync::Semaphore;

use crate::cache::TileCache;
use crate::config::ServerConfig;
use crate::render::RenderSettings;
use crate::source::Sources;
use error::ApiError;
use metrics::Metrics;

/// Everything a request handler needs.
#[derive(Debug, Clone)]
pub struct AppState {
    pub sources: Arc<Sources>,
    pub cache: TileCache,
    pub settings: Arc<RenderSettings>,
    pub zoom: u8,
    pub metrics: Arc<Metrics>,
    /// Renders allowed to run at once.
    pub render_permits: Arc<Semaphore>,
    /// Origins allowed to read responses in a browser (`*` for any).
    pub cors_origins: Arc<Vec<String>>,
    /// `Cache-Control` for tiles, if any.
    pub cache_control: Option<axum::http::HeaderValue>,
}

impl AppState {
    pub fn new(
        sources: Sources,
        cache: TileCache,
        settings: RenderSettings,
        server: &ServerConfig,
    ) -> AppState {
        let threads = if server.render_threads == 0 {
            std::thread::available_parallelism().map_or(2, |n| n.get())
        } else {
            server.render_threads
        };
        AppState {
            sources: Arc::new(sources),
            cache,
            settings: Arc::new(settings),
            zoom: server.zoom,
            metrics: Arc::new(Metrics::default()),
            render_permits: Arc::new(Semaphore::new(threads)),
            cors_origins: Arc::new(server.cors_origins.clone()),
            cache_control: match axum::http::HeaderValue::from_str(&server.cache_control) {
                Ok(value) if !server.cache_control.is_empty() => Some(value),
                Ok(_) => None,
                Err(_) => {
                    tracing::warn!(value = %server.cache_control, "Cache-Control is not a valid header value; none sent");
                    None
                }
            },
        }
    }
}

/// The identity of the rendering code and settings, stored with every cached tile.
pub fn pipeline_id(settings: &RenderSettings) -> String {
    format!("{}+{}", env!("CARGO_PKG_VERSION"), settings.fingerprint())
}

pub fn router(state: AppState) -> Router {
    let cors = cors(&state.cors_origins);
    let router = Router::new()
        .route("/tiles/{z}/{x}/{file}", get(tiles::tile))
        .route("/debug/tiles/{z}/{x}/{file}", get(debug::elevations))
        .route("/layer.json", get(layer::layer))
        .route("/tiles.json", get(tilejson::tilejson))
        .route("/health", get(health))
        .route("/metrics", get(metrics))
        .fallback(not_found)
        .with_state(state);
    let router = match cors {
        Some(cors) => router.layer(cors),
        None => router,
    };
    router.layer(tower_http::trace::TraceLayer::new_for_http())
}

/// CORS for `GET` and `HEAD` from the configured origins; `None` when there are none.
fn cors(origins: &[String]) -> Option<tower_http::cors::CorsLayer> {
    use tower_http::cors::{AllowOrigin, CorsLayer};
    let allow = if origins.iter().any(|o| o == "*") {
        AllowOrigin::any()
    } else {
        let exact: Vec<axum::http::HeaderValue> = origins
            .iter()
            .filter_map(|o| match axum::http::HeaderValue::from_str(o) {
                Ok(value) => Some(value),
                Err(_) => {
                    tracing::warn!(origin = %o, "CORS origin is not a valid header value; ignored");
                    None
                }
            })
            .collect();
        if exact.is_empty() {
            return None;
        }
        AllowOrigin::list(exact)
    };
    Some(
        CorsLayer::new()
            .allow_methods([axum::http::Method::GET, axum::http::Method::HEAD])
            .allow_origin(allow)
            .expose_headers([header::ETAG, header::CONTENT_DISPOSITION]),
    )
}

async fn health() -> impl IntoResponse {
    axum::Json(serde_json::json!({ "status": "ok" }))
}

async fn metrics(axum::extract::State(state): axum::extract::State<AppState>) -> impl IntoResponse {
    (
        [(header::CONTENT_TYPE, "text/plain; version=0.0.4")],
        state.metrics.render_text(),
    )
}

async fn not_found(uri: axum::http::Uri) -> ApiError {
    ApiError::new(
        StatusCode::NOT_FOUND,
        format!("no route for {}", uri.path()),
    )
}

/// Serves until `shutdown` completes.
pub async fn serve(
    listener: tokio::net::TcpListener,
    state: AppState,
    shutdown: impl std::future::Future<Output = ()> + Send + 'static,
) -> std::io::Result<()> {
    axum::serve(listener, router(state))
        .with_graceful_shutdown(shutdown)
        .await
}
