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
}

impl AppState {
    pub fn new(
        sources: Sources,
        cache: TileCache,
        settings: RenderSettings,
        zoom: u8,
        render_threads: usize,
    ) -> AppState {
        let threads = if render_threads == 0 {
            std::thread::available_parallelism().map_or(2, |n| n.get())
        } else {
            render_threads
        };
        AppState {
            sources: Arc::new(sources),
            cache,
            settings: Arc::new(settings),
            zoom,
            metrics: Arc::new(Metrics::default()),
            render_permits: Arc::new(Semaphore::new(threads)),
        }
    }
}

/// The identity of the rendering code and settings, stored with every cached tile.
pub fn pipeline_id(settings: &RenderSettings) -> String {
    format!("{}+{}", env!("CARGO_PKG_VERSION"), settings.fingerprint())
}

pub fn router(state: AppState) -> Router {
    Router::new()
        .route("/tiles/{z}/{x}/{file}", get(tiles::tile))
        .route("/debug/tiles/{z}/{x}/{file}", get(debug::elevations))
        .route("/layer.json", get(layer::layer))
        .route("/tiles.json", get(tilejson::tilejson))
        .route("/health", get(health))
        .route("/metrics", get(metrics))
        .fallback(not_found)
        .with_state(state)
        .layer(tower_http::trace::TraceLayer::new_for_http())
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
