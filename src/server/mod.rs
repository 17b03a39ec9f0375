//! The HTTP server: routes, shared state, and how requests reach the cache and the renderer.

pub mod admin;
pub mod connections;
pub mod debug;
pub mod error;
pub mod files;
pub mod layer;
pub mod memory;
pub mod metrics;
pub mod pool;
pub mod regenerate;
pub mod tilejson;
pub mod tiles;
pub mod tileset;

use std::sync::{Arc, RwLock};
use std::time::{Duration, Instant};

use axum::extract::{MatchedPath, Request, State};
use axum::http::{header, StatusCode};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::Router;

use crate::cache::TileCache;
use crate::config::ServerConfig;
use crate::provider::TileProvider;
use error::ApiError;
use metrics::{Metrics, PoolGauges};
use pool::RenderPool;

/// How long a client is asked to wait before retrying when sources load or renders queue.
pub const RETRY_AFTER_S: u64 = 5;

/// Where the provider stands.
#[derive(Debug, Clone)]
enum ProviderState {
    Loading,
    Ready(Arc<dyn TileProvider>),
    Failed(String),
}

/// Everything a request handler needs.
#[derive(Debug, Clone)]
pub struct AppState {
    provider: Arc<RwLock<ProviderState>>,
    pub cache: TileCache,
    /// The zoom of the served tiles.
    pub zoom: u8,
    pub metrics: Arc<Metrics>,
    pub work: Arc<Work>,
    pub http: Arc<Http>,
}

/// How tiles are made: the render slots and their limits, and the background work.
#[derive(Debug)]
pub struct Work {
    pub pool: RenderPool,
    /// Longest a render may take.
    pub render_limit: Option<Duration>,
    /// Most memory one render may take, bytes.
    pub render_memory: Option<usize>,
    /// Requests that may wait at once for a download on a blocking thread; the others wait
    /// for a turn without holding one.
    pub download_waits: Arc<tokio::sync::Semaphore>,
    /// Tiles whose render failed or ran out of time lately, with the error (status, message).
    pub failed_renders: moka::sync::Cache<crate::format::TileKey, (StatusCode, Arc<str>)>,
    /// The LP components the renders solved, read from the store at start and kept in it:
    /// the renderer finds and fills them (see [`crate::provider::Renderer::with_solutions`]).
    pub solutions: Arc<crate::provider::Solutions>,
    /// Tiles to make again in the background.
    pub regenerator: Arc<regenerate::Regenerator>,
    /// Workers making them (each holds at most one render slot).
    pub background_workers: usize,
    /// How often the provider is asked whether its inputs changed, and to apply its
    /// replication diffs.
    pub check_interval: Option<Duration>,
    /// Held by the check of the sources under way.
    pub checking: tokio::sync::Mutex<()>,
    /// Debug views made lately (`None`: the view is turned off).
    pub debug_views: Option<moka::future::Cache<crate::tile::TileId, Arc<[u8]>>>,
}

/// Memory for debug views, bytes, and how long one is kept.
const DEBUG_VIEW_BYTES: u64 = 32 << 20;
const DEBUG_VIEW_MEMORY: Duration = Duration::from_secs(600);

/// What the HTTP side is told: who may read, how long clients may keep tiles, the admin
/// token, and the viewer's files.
#[derive(Debug)]
pub struct Http {
    /// Origins allowed to read responses in a browser (`*` for any).
    pub cors_origins: Vec<String>,
    /// `Cache-Control` for tiles, if any.
    pub cache_control: Option<axum::http::HeaderValue>,
    /// The bearer token `/admin/*` asks for; `None` turns those routes off.
    pub admin_token: Option<Arc<str>>,
    /// The viewer's files, served at `/`.
    pub static_dir: std::path::PathBuf,
    /// Bounds on connections.
    pub limits: connections::Limits,
    /// Longest a client may take to send a request's body.
    pub body_timeout: Duration,
}

/// Requests that may wait at once for a download.
const DOWNLOAD_WAITS: usize = 32;

/// How long a tile whose render failed or ran out of time is answered with that error before
/// it is tried again, so retries of one bad tile cannot hold the render slots.
pub const FAILED_RENDER_MEMORY: Duration = Duration::from_secs(600);

impl Work {
    fn new(server: &ServerConfig, coordinator: Arc<dyn crate::cache::Coordinator>) -> Work {
        let threads = if server.render_threads == 0 {
            std::thread::available_parallelism().map_or(2, |n| n.get())
        } else {
            server.render_threads
        };
        Work {
            pool: RenderPool::new(threads, server.render_queue, server.background_renders),
            render_limit: (server.render_timeout_ms > 0)
                .then(|| Duration::from_millis(server.render_timeout_ms)),
            render_memory: (server.render_memory_mib > 0)
                .then(|| usize::try_from(server.render_memory_mib << 20).unwrap_or(usize::MAX)),
            download_waits: Arc::new(tokio::sync::Semaphore::new(DOWNLOAD_WAITS)),
            failed_renders: moka::sync::Cache::builder()
                .max_capacity(100_000)
                .time_to_live(FAILED_RENDER_MEMORY)
                .build(),
            solutions: Arc::default(),
            regenerator: Arc::new(regenerate::Regenerator::new(coordinator)),
            background_workers: server.background_renders.max(1),
            check_interval: (server.check_interval_s > 0)
                .then(|| Duration::from_secs(server.check_interval_s)),
            checking: tokio::sync::Mutex::new(()),
            debug_views: server.debug_view.then(|| {
                moka::future::Cache::builder()
                    .weigher(|_: &crate::tile::TileId, body: &Arc<[u8]>| {
                        body.len().try_into().unwrap_or(u32::MAX)
                    })
                    .max_capacity(DEBUG_VIEW_BYTES)
                    .time_to_live(DEBUG_VIEW_MEMORY)
                    .build()
            }),
        }
    }
}

impl Http {
    fn new(server: &ServerConfig) -> Http {
        Http {
            cors_origins: server.cors_origins.clone(),
            cache_control: match axum::http::HeaderValue::from_str(&server.cache_control) {
                Ok(value) if !server.cache_control.is_empty() => Some(value),
                Ok(_) => None,
                Err(_) => {
                    tracing::warn!(value = %server.cache_control, "Cache-Control is not a valid header value; none sent");
                    None
                }
            },
            admin_token: (!server.admin_token.is_empty())
                .then(|| server.admin_token.as_str().into()),
            static_dir: server.static_dir.clone(),
            limits: connections::Limits {
                head: Duration::from_secs(server.header_timeout_s.max(1)),
                connections: connections::connections_to_allow(server.max_connections),
                grace: Duration::from_secs(server.shutdown_grace_s),
            },
            body_timeout: Duration::from_secs(server.body_timeout_s.max(1)),
        }
    }
}

impl AppState {
    /// A server without a provider yet: tiles are refused with `503` until
    /// [`AppState::provide`].
    pub fn new(cache: TileCache, server: &ServerConfig) -> AppState {
        let work = Work::new(server, cache.coordinator().clone());
        AppState {
            provider: Arc::new(RwLock::new(ProviderState::Loading)),
            cache,
            zoom: server.zoom,
            metrics: Arc::new(Metrics::default()),
            work: Arc::new(work),
            http: Arc::new(Http::new(server)),
        }
    }

    /// The provider, or a `503` while it loads (a `500` if loading failed).
    pub fn provider(&self) -> Result<Arc<dyn TileProvider>, ApiError> {
        match &*self.provider.read().unwrap_or_else(|p| p.into_inner()) {
            ProviderState::Ready(provider) => Ok(provider.clone()),
            ProviderState::Loading => Err(ApiError::unavailable(
                "the sources are still loading; retry shortly",
                RETRY_AFTER_S,
            )),
            ProviderState::Failed(message) => Err(ApiError::internal(format!(
                "the sources could not be loaded: {message}"
            ))),
        }
    }

    /// Puts a provider in place (replacing any before it: tiles it would make otherwise
    /// become stale).
    pub fn provide(&self, provider: Arc<dyn TileProvider>) {
        *self.provider.write().unwrap_or_else(|p| p.into_inner()) = ProviderState::Ready(provider);
        if let Some(views) = &self.work.debug_views {
            views.invalidate_all();
        }
    }

    /// Records that the provider could not be loaded (`/ready` says why).
    pub fn provider_failed(&self, message: String) {
        *self.provider.write().unwrap_or_else(|p| p.into_inner()) = ProviderState::Failed(message);
    }

    pub fn pool_gauges(&self) -> PoolGauges {
        let (running, waiting, background_waiting) = self.work.pool.gauges();
        PoolGauges {
            running,
            waiting,
            background_waiting,
            regenerating: self.work.regenerator.len(),
            for_tiles: self.cache.waiting(),
            refining: self.cache.refining(),
            unstored_after_answer: self.cache.unstored_after_answer(),
        }
    }
}

pub fn router(state: AppState) -> Router {
    let cors = cors(&state.http.cors_origins);
    let router = Router::new()
        .route("/tiles/{z}/{x}/{file}", get(tiles::tile))
        .route("/debug/tiles/{z}/{x}/{file}", get(debug::elevations))
        .route("/layer.json", get(layer::layer))
        .route("/tiles.json", get(tilejson::tilejson))
        .route("/tileset.json", get(tileset::root))
        .route("/3dtiles/tileset.json", get(tileset::root_in_folder))
        .route("/3dtiles/{z}/{x}/{file}", get(tileset::file))
        .route("/health", get(health))
        .route("/ready", get(ready))
        .route("/metrics", get(metrics))
        .route("/admin/regenerate", post(admin::regenerate))
        .route("/admin/purge", post(admin::purge))
        // Anything else is a file of the viewer, or a JSON 404.
        .fallback(files::serve)
        .method_not_allowed_fallback(method_not_allowed)
        .layer(axum::middleware::from_fn_with_state(
            state.clone(),
            count_response,
        ))
        .layer(axum::middleware::from_fn(error::json_errors))
        .with_state(state);
    let router = match cors {
        Some(cors) => router.layer(cors),
        None => router,
    };
    router
        .layer(
            tower_http::trace::TraceLayer::new_for_http()
                .make_span_with(|request: &Request| {
                    let id = request
                        .headers()
                        .get(REQUEST_ID)
                        .and_then(|v| v.to_str().ok())
                        .unwrap_or("");
                    tracing::info_span!("request", id = %id, method = %request.method(), uri = %request.uri())
                })
                // One line per answered request, with its status and latency.
                .on_response(
                    tower_http::trace::DefaultOnResponse::new().level(tracing::Level::INFO),
                ),
        )
        .layer(tower_http::request_id::PropagateRequestIdLayer::new(
            header::HeaderName::from_static(REQUEST_ID),
        ))
        .layer(tower_http::request_id::SetRequestIdLayer::new(
            header::HeaderName::from_static(REQUEST_ID),
            RequestIds::default(),
        ))
        .layer(axum::middleware::from_fn(drop_unfit_request_id))
}

/// Longest request id kept from a client.
const REQUEST_ID_MAX: usize = 128;

/// Drops a client's request id that is longer than [`REQUEST_ID_MAX`] or not plain visible
/// ASCII: the server gives the request one of its own.
async fn drop_unfit_request_id(mut request: Request, next: Next) -> Response {
    let fit = |value: &axum::http::HeaderValue| {
        let bytes = value.as_bytes();
        !bytes.is_empty()
            && bytes.len() <= REQUEST_ID_MAX
            && bytes.iter().all(|b| b.is_ascii_graphic())
    };
    let ids = request.headers().get_all(REQUEST_ID);
    if ids.iter().count() > 1 || ids.iter().any(|v| !fit(v)) {
        request.headers_mut().remove(REQUEST_ID);
    }
    next.run(request).await
}

/// The header that carries a request's id (kept if the client sent one).
pub const REQUEST_ID: &str = "x-request-id";

/// Request ids: this process's start time and a counter, unique across restarts.
#[derive(Debug, Clone)]
struct RequestIds {
    prefix: Arc<str>,
    next: Arc<std::sync::atomic::AtomicU64>,
}

impl Default for RequestIds {
    fn default() -> Self {
        let started = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_millis() as u64);
        RequestIds {
            prefix: format!("{started:x}").into(),
            next: Arc::default(),
        }
    }
}

impl tower_http::request_id::MakeRequestId for RequestIds {
    fn make_request_id<B>(
        &mut self,
        _request: &axum::http::Request<B>,
    ) -> Option<tower_http::request_id::RequestId> {
        let n = self.next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        axum::http::HeaderValue::from_str(&format!("{}-{n}", self.prefix))
            .ok()
            .map(tower_http::request_id::RequestId::new)
    }
}

/// Counts every response by its route template and status.
async fn count_response(State(state): State<AppState>, request: Request, next: Next) -> Response {
    let started = Instant::now();
    let route = request
        .extensions()
        .get::<MatchedPath>()
        .map_or_else(|| "unmatched".to_string(), |p| p.as_str().to_string());
    let response = next.run(request).await;
    state
        .metrics
        .observe_response(&route, response.status().as_u16(), started.elapsed());
    response
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

/// Ready when the provider is in place: `200` with what it serves from, else `503` saying
/// what is missing.
async fn ready(State(state): State<AppState>) -> Response {
    match state.provider() {
        Ok(provider) => {
            let status = provider.status();
            // Sources that load but from which no tile can be made are not ready to serve.
            let ready = status.get("cannot_serve").is_none();
            let mut body =
                serde_json::json!({ "status": if ready { "ready" } else { "not ready" } });
            if let (Some(body), serde_json::Value::Object(status)) = (body.as_object_mut(), status)
            {
                body.extend(status);
            }
            let code = if ready {
                StatusCode::OK
            } else {
                StatusCode::SERVICE_UNAVAILABLE
            };
            (code, axum::Json(body)).into_response()
        }
        Err(error) => (
            StatusCode::SERVICE_UNAVAILABLE,
            axum::Json(serde_json::json!({ "status": "not ready", "error": error.message })),
        )
            .into_response(),
    }
}

async fn metrics(State(state): State<AppState>) -> impl IntoResponse {
    (
        [(header::CONTENT_TYPE, "text/plain; version=0.0.4")],
        state.metrics.render_text(
            state.pool_gauges(),
            state
                .provider()
                .ok()
                .as_deref()
                .and_then(|p| p.fetching().and_then(|f| f.downloads())),
            state.work.solutions.counts().0,
        ),
    )
}

async fn method_not_allowed(method: axum::http::Method, uri: axum::http::Uri) -> ApiError {
    ApiError::new(
        StatusCode::METHOD_NOT_ALLOWED,
        format!("{method} is not allowed on {}", uri.path()),
    )
}

/// Serves until `shutdown` completes, then lets the requests in flight (and their renders,
/// and the coding again of tiles answered in haste) finish within the shutdown grace period.
/// Runs the background tasks: recording which tiles memory served, making stale tiles
/// again, and checking the sources for new versions when configured.
pub async fn serve(
    listener: tokio::net::TcpListener,
    state: AppState,
    shutdown: impl std::future::Future<Output = ()> + Send + 'static,
) -> std::io::Result<()> {
    let mut background = vec![tokio::spawn(background_tasks(state.clone()))];
    let store = state.cache.reader();
    let solutions = state.work.solutions.clone();
    background.push(tokio::task::spawn_blocking(
        move || match crate::provider::load_solutions(store.as_ref(), &solutions) {
            Ok(kept) => tracing::debug!(kept, "solved elevation components read from the cache"),
            Err(error) => tracing::warn!(%error, "reading solved elevation components failed"),
        },
    ));
    join(&state)?;
    background.extend(regenerate::start(&state, state.work.background_workers));
    if let Some(interval) = state.work.check_interval {
        background.push(tokio::spawn(regenerate::watch_sources(
            state.clone(),
            interval,
        )));
        background.push(tokio::spawn(regenerate::watch_replication(
            state.clone(),
            interval,
        )));
    }
    let result = connections::serve(
        listener,
        router(state.clone()),
        state.http.limits,
        state.metrics.clone(),
        shutdown,
    )
    .await;
    // The tiles answered in haste get their forms kept stored, within the grace period.
    if tokio::time::timeout(state.http.limits.grace, state.cache.refined())
        .await
        .is_err()
    {
        tracing::warn!(
            tiles = state.cache.refining(),
            "tiles answered in haste keep their quick forms: coding them again took too long"
        );
    }
    for task in background {
        task.abort();
    }
    state.work.pool.close();
    flush(&state).await;
    result
}

/// Joins the processes sharing the store: says this server is one of them, keeps its claims
/// alive while it runs, and applies what is heard (the others' new tiles and purges leave
/// memory; queued work wakes the workers).
fn join(state: &AppState) -> std::io::Result<()> {
    let coordinator = state.cache.coordinator().clone();
    let joining = coordinator.clone();
    tokio::task::spawn_blocking(move || {
        if let Err(error) = joining.join("serve") {
            tracing::warn!(%error, "joining the processes sharing the store failed");
        }
    });
    let (told, mut heard) = tokio::sync::mpsc::unbounded_channel();
    coordinator
        .listen(Arc::new(move |event| {
            let _ = told.send(event);
        }))
        .map_err(std::io::Error::other)?;
    let applying = state.clone();
    tokio::spawn(async move {
        while let Some(event) = heard.recv().await {
            if event == crate::cache::Event::Work {
                applying.work.regenerator.wake_all();
            }
            applying.cache.heard(event).await;
        }
    });
    tracing::info!(
        holder = coordinator.holder(),
        "joined the processes sharing the store"
    );
    Ok(())
}

/// Every few seconds: tell the store which tiles memory served, and keep the elevation
/// components solved since.
async fn background_tasks(state: AppState) {
    let mut interval = tokio::time::interval(Duration::from_secs(10));
    interval.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    loop {
        interval.tick().await;
        flush(&state).await;
    }
}

async fn flush(state: &AppState) {
    if let Err(error) = state.cache.flush_touches().await {
        tracing::warn!(%error, "recording served tiles failed");
    }
    // An archive keeps none.
    let Ok(store) = state.cache.writer().cloned() else {
        return;
    };
    let solutions = state.work.solutions.clone();
    let saved = tokio::task::spawn_blocking(move || {
        crate::provider::save_solutions(store.as_ref(), &solutions)
    })
    .await;
    if let Ok(Err(error)) = saved {
        tracing::warn!(%error, "keeping solved elevation components failed");
    }
}
