//! The `terrastitch` command: `serve`, `render`, `seed` and `export`.

use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};

use terrastitch::cache::{Cluster, PostgresStore, SqliteStore, TileCache, TileStore};

/// The system allocator, counting what a render allocates against its memory budget
/// (`server.render_memory_mib`).
#[global_allocator]
static ALLOCATOR: terrastitch::budget::Counting = terrastitch::budget::Counting;
use terrastitch::config::ServerConfig;
use terrastitch::config::{Config, LogFormat};
use terrastitch::format::Format;
use terrastitch::offline::{export, seed, shared_seed};
use terrastitch::provider::{Archive, Renderer, TileProvider};
use terrastitch::render::StageTimings;
use terrastitch::server::{self, AppState};
use terrastitch::source::fetch::Fetcher;
use terrastitch::tile::LonLatBounds;
use terrastitch::TileId;

#[derive(Parser)]
#[command(
    name = "terrastitch",
    version,
    about = "Seamless 3D map tiles from OpenStreetMap and SRTM"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Serve tiles over HTTP.
    Serve(ServeArgs),
    /// Render one tile to a file, without the server.
    Render(RenderArgs),
    /// Render every tile of a box into the cache (resumable; --shard splits the work; with a
    /// PostgreSQL cache, workers on any number of machines share one queue).
    Seed(SeedArgs),
    /// Write a box's tiles to an MBTiles file, or to DIR/z/x/y.glb with `-o DIR/`.
    Export(ExportArgs),
    /// Read the OSM extracts once into the on-disk store the other commands read.
    Import(ImportArgs),
    /// Apply OSM change files (.osc, .osc.gz) to the store and list the tiles they expire.
    Update(UpdateArgs),
}

/// Where the data comes from; flags override the configuration file.
#[derive(Args)]
struct SourceArgs {
    /// Configuration file [default: config/default.toml if it exists]
    #[arg(long)]
    config: Option<PathBuf>,
    /// OSM extract (.osm.pbf); repeat for several [default: data/monaco-osrm-2016.osm.pbf]
    #[arg(long = "osm", value_name = "FILE")]
    osm: Vec<PathBuf>,
    /// Directory of SRTM .hgt, .hgt.zip or .hgt.gz files [default: data]
    #[arg(long, value_name = "DIR")]
    srtm: Option<PathBuf>,
    /// The imported OSM store to read (imported when missing or older than the extracts)
    /// [default: none, the extracts are read into memory]
    #[arg(long, value_name = "FILE")]
    store: Option<PathBuf>,
}

#[derive(Args)]
struct ImportArgs {
    #[command(flatten)]
    sources: SourceArgs,
    /// Replace the store even when the extracts hold fewer than half of a kind of element it
    /// holds (an extract cut short reads as a smaller one)
    #[arg(long)]
    force: bool,
}

#[derive(Args)]
struct UpdateArgs {
    #[command(flatten)]
    sources: SourceArgs,
    /// OSM change file (.osc or .osc.gz); repeat for several, applied in the order given, in
    /// one transaction
    #[arg(
        long = "osc",
        value_name = "FILE",
        required_unless_present = "replication"
    )]
    osc: Vec<PathBuf>,
    /// Apply the diffs a replication source (directory or URL) has that the store lacks, each
    /// in its own transaction [default: sources.replication]
    #[arg(long, value_name = "URL", conflicts_with = "osc")]
    replication: Option<String>,
    /// Write the expired tiles, one Z/X/Y a line, to this file (- for standard output)
    #[arg(long, value_name = "FILE")]
    expired: Option<PathBuf>,
    /// A running server to tell: its stored tiles that expired are made again in the
    /// background and served until then (needs the admin token, TERRASTITCH_ADMIN_TOKEN)
    #[arg(long, value_name = "URL")]
    server: Option<String>,
    /// The server's admin token
    #[arg(long, env = "TERRASTITCH_ADMIN_TOKEN", hide_env_values = true)]
    token: Option<String>,
}

#[derive(Args)]
struct ServeArgs {
    #[command(flatten)]
    sources: SourceArgs,
    /// Address to listen on [default: 127.0.0.1:8080]
    #[arg(long, value_name = "ADDR")]
    listen: Option<String>,
    /// SQLite file of the tile cache [default: cache/tiles.sqlite]
    #[arg(long, value_name = "FILE")]
    cache: Option<PathBuf>,
    /// Serve the tiles of a PMTiles or MBTiles file made by `export`, read-only, without
    /// sources, with its 3D Tiles tileset or terrain layer
    #[arg(long, alias = "mbtiles", value_name = "FILE", conflicts_with_all = ["cache", "osm", "srtm", "store"])]
    archive: Option<PathBuf>,
}

#[derive(Args)]
struct RenderArgs {
    /// The tile, as Z/X/Y (e.g. 14/8529/5973)
    tile: String,
    /// Output file
    #[arg(short = 'o', long = "output", value_name = "OUT.glb")]
    output: PathBuf,
    #[command(flatten)]
    sources: SourceArgs,
    /// Print the time of each stage to stderr
    #[arg(long)]
    timings: bool,
    /// glb variant: glb (flat frame), glb-meshopt (compressed), glb-enu (east-north-up, the
    /// 3D Tiles content), glb-enu-meshopt
    #[arg(long, value_name = "VARIANT", default_value = "glb")]
    variant: String,
    /// Tiles to render first, in the same process, and throw away: the tile then finds the
    /// bridges and road stretches they settled already settled, as a server or a seed does
    #[arg(long, value_name = "Z/X/Y")]
    after: Vec<String>,
}

/// The tiles of a box, for `seed` and `export`.
#[derive(Args)]
struct AreaArgs {
    /// The box, as W,S,E,N in degrees (e.g. 7.40,43.72,7.44,43.75)
    #[arg(
        long,
        value_name = "W,S,E,N",
        allow_hyphen_values = true,
        required = true
    )]
    bbox: Option<LonLatBounds>,
    /// Formats to make: glb, glb-meshopt, glb-enu, glb-enu-meshopt, terrain (quantized-mesh
    /// with normals and water mask); repeat or separate with commas for several [default:
    /// seed: glb-meshopt,glb-enu-meshopt (what the viewer and the globe ask for); export: glb]
    #[arg(long = "format", value_name = "FORMAT")]
    formats: Vec<String>,
    /// SQLite file of the tile cache [default: cache/tiles.sqlite]
    #[arg(long, value_name = "FILE")]
    cache: Option<PathBuf>,
    /// PostgreSQL tile cache shared by a cluster (postgres://user:password@host/database),
    /// instead of the SQLite file [default: cache.url]
    #[arg(long, value_name = "URL")]
    cache_url: Option<String>,
    /// Renders at once [default: one per core]
    #[arg(long, value_name = "N")]
    threads: Option<usize>,
    /// Also the coarser zooms the viewers ask for: glb for far views (13, 12, 10 and 8 under
    /// 14) and terrain at every zoom from 0 (always, for export)
    #[arg(long)]
    all_zooms: bool,
}

impl AreaArgs {
    fn bbox(&self) -> Result<LonLatBounds> {
        self.bbox.context("--bbox W,S,E,N is needed")
    }

    /// The same area, in `defaults` when no format was named.
    fn or_formats(mut self, defaults: &[&str]) -> AreaArgs {
        if self.formats.is_empty() {
            self.formats = defaults.iter().map(|f| f.to_string()).collect();
        }
        self
    }
}

/// What `seed` makes when no format is named: the variants the bundled viewer
/// (`glb-meshopt`) and globe (`glb-enu-meshopt`) ask for, so a seeded region opens warm.
const SEED_FORMATS: &[&str] = &["glb-meshopt", "glb-enu-meshopt"];

/// What `export` writes when no format is named (an MBTiles file holds one).
const EXPORT_FORMATS: &[&str] = &["glb"];

#[derive(Args)]
#[command(subcommand_negates_reqs = true, args_conflicts_with_subcommands = true)]
struct SeedArgs {
    #[command(subcommand)]
    action: Option<SeedAction>,
    #[command(flatten)]
    area: AreaArgs,
    #[command(flatten)]
    sources: SourceArgs,
    /// Make only the i-th of n shares of the box's tiles (1 ≤ i ≤ n), e.g. 2/4
    #[arg(long, value_name = "i/n")]
    shard: Option<seed::Shard>,
}

#[derive(Subcommand)]
enum SeedAction {
    /// What the cluster's queue holds, which workers work on it, and which tiles failed.
    Status(StatusArgs),
}

#[derive(Args)]
struct StatusArgs {
    #[command(flatten)]
    sources: SourceArgs,
    /// PostgreSQL tile cache shared by the cluster [default: cache.url]
    #[arg(long, value_name = "URL")]
    cache_url: Option<String>,
}

#[derive(Args)]
struct ExportArgs {
    #[command(flatten)]
    area: AreaArgs,
    #[command(flatten)]
    sources: SourceArgs,
    /// Output: a PMTiles file (FILE.pmtiles), an MBTiles file (any other name), or a directory
    /// when the path ends in / (DIR/z/x/y.glb, with tileset.json or layer.json)
    #[arg(
        short = 'o',
        long = "output",
        value_name = "FILE.pmtiles|FILE.mbtiles|DIR/"
    )]
    output: PathBuf,
}

fn load_config(args: &SourceArgs) -> Result<Config> {
    let mut config = Config::load(args.config.as_deref())?;
    if !args.osm.is_empty() {
        config.sources.osm = args.osm.clone();
    }
    if let Some(srtm) = &args.srtm {
        config.sources.srtm = srtm.clone();
    }
    if let Some(store) = &args.store {
        config.sources.store = Some(store.clone());
    }
    Ok(config)
}

/// Opens (downloading what the data directory lacks) the configured sources, to render from.
fn open_renderer(config: &Config, fetcher: Arc<Fetcher>) -> Result<Renderer> {
    let started = Instant::now();
    let renderer = Renderer::load(
        &config.sources,
        config.render.clone(),
        config.server.zoom,
        fetcher,
    )?;
    let sources = renderer.inputs();
    tracing::info!(
        extracts = sources.osm_paths.len(),
        srtm_files = sources.srtm.cells().len(),
        ms = started.elapsed().as_millis() as u64,
        "sources loaded"
    );
    Ok(renderer)
}

/// Caps glibc's malloc arenas at two per core (unless `MALLOC_ARENA_MAX` says otherwise). By
/// default glibc gives up to eight per core, and each keeps the peak of the renders that ran in
/// it: under a burst of cold tiles the server's memory doubled (650 MB against 390 MB for 20
/// dense tiles on two cores), for no gain in speed.
fn limit_malloc_arenas() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    if std::env::var_os("MALLOC_ARENA_MAX").is_none() {
        let cores = std::thread::available_parallelism().map_or(2, |n| n.get());
        let arenas = i32::try_from(2 * cores).unwrap_or(i32::MAX);
        // SAFETY: mallopt only sets a tuning parameter of the allocator; it is called before
        // any other thread exists.
        unsafe {
            libc::mallopt(libc::M_ARENA_MAX, arenas);
        }
    }
}

fn main() -> Result<()> {
    limit_malloc_arenas();
    let cli = Cli::parse();
    let sources = match &cli.command {
        Command::Serve(args) => &args.sources,
        Command::Render(args) => &args.sources,
        Command::Seed(args) => match &args.action {
            Some(SeedAction::Status(status)) => &status.sources,
            None => &args.sources,
        },
        Command::Export(args) => &args.sources,
        Command::Import(args) => &args.sources,
        Command::Update(args) => &args.sources,
    };
    let config = load_config(sources)?;
    init_logging(config.log.format);
    match cli.command {
        Command::Serve(args) => serve(args, config),
        Command::Render(args) => render(args, config),
        Command::Seed(args) => seed(args, config),
        Command::Export(args) => export(args, config),
        Command::Import(args) => import(args.force, config),
        Command::Update(args) => update(args, config),
    }
}

/// Logs to stderr, as text or as one JSON object per line; `RUST_LOG` filters.
fn init_logging(format: LogFormat) {
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info"));
    let builder = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr);
    match format {
        LogFormat::Text => builder.init(),
        LogFormat::Json => builder.json().with_current_span(true).init(),
    }
}

/// The processes sharing a PostgreSQL store.
type SharedBy = Arc<Cluster>;

/// The tile store a configuration names: its PostgreSQL database (`cache.url`), with the
/// cluster that shares it, else its SQLite file.
fn open_store(config: &Config) -> Result<(Arc<dyn TileStore>, Option<SharedBy>)> {
    let cap = (config.cache.max_size_mib > 0).then(|| config.cache.max_size_mib * 1024 * 1024);
    let url = config.cache.url.trim();
    if url.is_empty() {
        let store = SqliteStore::open_or_set_aside(&config.cache.path, cap)?
            .with_max_tile(config.cache.max_tile_bytes());
        return Ok((Arc::new(store), None));
    }
    let store = open_postgres(url, cap)?.with_max_tile(config.cache.max_tile_bytes());
    let cluster = store.cluster(std::time::Duration::from_secs(config.cache.lease_s));
    tracing::info!(place = store.place(), "tiles kept in PostgreSQL");
    Ok((Arc::new(store), Some(Arc::new(cluster))))
}

fn open_postgres(url: &str, cap: Option<u64>) -> Result<PostgresStore> {
    if !(url.starts_with("postgres://") || url.starts_with("postgresql://")) {
        anyhow::bail!(
            "cache.url must be a PostgreSQL URL (postgres://user:password@host/database), not {:?}",
            terrastitch::cache::postgres::redacted(url)
        );
    }
    Ok(PostgresStore::open(url, cap)?)
}

fn serve(args: ServeArgs, mut config: Config) -> Result<()> {
    if let Some(listen) = args.listen {
        config.server.listen = listen;
    }
    if let Some(cache) = args.cache {
        config.cache.path = cache;
    }
    if let Some(file) = args.archive {
        return serve_archive(&file, config);
    }
    server::memory::limit_arenas();
    let (store, cluster) = open_store(&config)?;
    let cache = TileCache::new(store, config.cache.memory_mib * 1024 * 1024);
    let cache = match cluster {
        Some(cluster) => cache.with_cluster(cluster),
        None => cache,
    };
    let state = AppState::new(cache, &config.server);
    let fetcher = Arc::new(Fetcher::new(config.sources.fetch_settings()));
    let grace = Duration::from_secs(config.server.shutdown_grace_s);
    run_server(grace, async move {
        let listener = tokio::net::TcpListener::bind(&config.server.listen)
            .await
            .with_context(|| format!("cannot listen on {}", config.server.listen))?;
        let address = listener.local_addr()?;
        tracing::info!("serving on http://{address}/");
        // The line tests and scripts wait for.
        eprintln!("listening on http://{address}");
        // The sources load while the server already answers `/health` (and `/ready` with
        // `503`); a source that cannot be loaded stops the server with its error.
        let (failed_tx, failed_rx) = tokio::sync::oneshot::channel::<anyhow::Error>();
        let loading = state.clone();
        tokio::task::spawn_blocking(move || match open_renderer(&config, fetcher) {
            Ok(renderer) => loading.provide(Arc::new(renderer)),
            Err(error) => {
                loading.provider_failed(format!("{error:#}"));
                let _ = failed_tx.send(error);
            }
        });
        let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<anyhow::Error>();
        let watcher = tokio::spawn(async move {
            if let Ok(error) = failed_rx.await {
                let _ = stop_tx.send(error);
            }
        });
        let failure = Arc::new(std::sync::Mutex::new(None));
        let recorded = failure.clone();
        let shutdown = async move {
            tokio::select! {
                _ = shutdown_signal() => {},
                Ok(error) = stop_rx => {
                    if let Ok(mut slot) = recorded.lock() {
                        *slot = Some(error);
                    }
                },
            }
        };
        server::serve(listener, state, shutdown).await?;
        watcher.abort();
        let failure = failure.lock().ok().and_then(|mut f| f.take());
        match failure {
            Some(error) => Err(error),
            None => Ok(()),
        }
    })
}

/// Serves an exported archive as it is.
fn serve_archive(file: &std::path::Path, config: Config) -> Result<()> {
    let store = terrastitch::cache::open_archive(file, config.cache.max_tile_bytes())?;
    let archive = Archive::of(store.as_ref());
    let server = ServerConfig {
        zoom: archive.contents.max_zoom(),
        ..config.server.clone()
    };
    let cache = TileCache::new(store, config.cache.memory_mib * 1024 * 1024);
    let state = AppState::new(cache, &server);
    state.provide(Arc::new(archive));
    run_server(Duration::from_secs(server.shutdown_grace_s), async move {
        let listener = tokio::net::TcpListener::bind(&server.listen)
            .await
            .with_context(|| format!("cannot listen on {}", server.listen))?;
        let address = listener.local_addr()?;
        tracing::info!(file = %file.display(), "serving an exported file on http://{address}/");
        eprintln!("listening on http://{address}");
        server::serve(listener, state, shutdown_signal()).await?;
        Ok(())
    })
}

/// Runs a server on a runtime of its own until it stops. Blocking work still running then (a
/// render, a read of a file that hangs) gets `grace` more and is left behind: a stop always
/// ends the process.
fn run_server(
    grace: Duration,
    server: impl std::future::Future<Output = Result<()>>,
) -> Result<()> {
    let runtime = tokio::runtime::Runtime::new().context("starting the async runtime")?;
    let result = runtime.block_on(server);
    runtime.shutdown_timeout(grace);
    result
}

async fn shutdown_signal() {
    let ctrl_c = async {
        let _ = tokio::signal::ctrl_c().await;
    };
    #[cfg(unix)]
    let terminate = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut signal) => {
                signal.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    #[cfg(not(unix))]
    let terminate = std::future::pending::<()>();
    tokio::select! {
        _ = ctrl_c => {},
        _ = terminate => {},
    }
    tracing::info!("shutting down");
}

/// One tile from the sources: the time its inputs took to read, and the tile.
fn render_one(
    sources: &terrastitch::provider::inputs::Inputs,
    tile: TileId,
    settings: &terrastitch::render::RenderSettings,
    variant: terrastitch::format::Variant,
    served_zoom: u8,
) -> Result<(std::time::Duration, terrastitch::render::RenderedTile)> {
    let started = Instant::now();
    if tile.z < served_zoom {
        // A tile for far views: sea level where no SRTM file covers it.
        let osm = sources.osm_for(tile)?;
        let selection = osm.selection(tile);
        let mosaic = sources.mosaic_for(tile, &selection, settings.features.longest_way_m())?;
        let load = started.elapsed();
        let rendered = terrastitch::render::render_overview(
            tile,
            &selection,
            &mosaic,
            settings,
            terrastitch::features::overview::Level::new(tile, served_zoom, &sources.osm.coverage()),
            variant,
            terrastitch::render::Deadline::none(),
        )?;
        return Ok((load, rendered));
    }
    if sources.check_coverage(tile).is_err() {
        sources.fetch_missing_srtm(tile)?;
    }
    if let Err(uncovered) = sources.check_coverage(tile) {
        anyhow::bail!(uncovered);
    }
    let osm = sources.osm_for(tile)?;
    let selection = osm.selection(tile);
    let mosaic = sources.mosaic_for(tile, &selection, settings.features.longest_way_m())?;
    let load = started.elapsed();
    let rendered = terrastitch::render::render_within(
        tile,
        &selection,
        &mosaic,
        settings,
        variant,
        terrastitch::render::Deadline::none(),
    )?;
    Ok((load, rendered))
}

fn render(args: RenderArgs, config: Config) -> Result<()> {
    let tile: TileId = args.tile.parse()?;
    let variant = terrastitch::format::Variant::from_name(&args.variant).with_context(|| {
        format!(
            "unknown variant '{}'; expected glb, glb-meshopt, glb-enu or glb-enu-meshopt",
            args.variant
        )
    })?;
    let before: Vec<TileId> = args
        .after
        .iter()
        .map(|t| t.parse())
        .collect::<Result<_, _>>()?;
    let started = Instant::now();
    let renderer = open_renderer(
        &config,
        Arc::new(Fetcher::new(config.sources.fetch_settings())),
    )?;
    // Opening the sources counts in the load of the first tile rendered.
    let mut opened = Some(started.elapsed());
    let sources = renderer.inputs();
    let served_zoom = renderer.offer().zoom;
    for &earlier in &before {
        opened = None;
        render_one(sources, earlier, &config.render, variant, served_zoom)?;
    }
    let counted = terrastitch::render::lp_components_reused();
    let (load, rendered) = render_one(sources, tile, &config.render, variant, served_zoom)?;
    let load = load + opened.unwrap_or_default();
    std::fs::write(&args.output, &rendered.glb)
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    if args.timings {
        let t = rendered.timings;
        let ms = |d: std::time::Duration| d.as_secs_f64() * 1000.0;
        eprintln!("load           {:8.1} ms", ms(load));
        for (name, duration) in StageTimings::NAMES.iter().zip(t.stages()) {
            eprintln!("{name:<14} {:8.1} ms", ms(duration));
        }
        eprintln!(
            "total          {:8.1} ms (render {:.1} ms)",
            ms(load + t.total()),
            ms(t.total())
        );
        let s = &rendered.stats;
        eprintln!(
            "triangles {} vertices {} primitives {} glb {} bytes; ground: {} triangles, {} samples inserted, {} edge vertices, {} slivers dropped; {} trees, {} objects; features {:?}",
            s.triangles,
            s.vertices,
            s.primitives,
            s.glb_bytes,
            s.ground_triangles,
            s.ground_vertices_inserted,
            s.edge_vertices,
            s.slivers_dropped,
            s.trees,
            s.objects,
            s.features_by_class
        );
        eprintln!(
            "elevation LP: {} variables, {} constraints, {} components, {} soft constraints violated",
            s.lp_variables, s.lp_constraints, s.lp_components, s.lp_violations
        );
        eprintln!(
            "of which ground roads: {} stretches, {} variables, {} constraints, {} violated",
            s.road_stretches_settled,
            s.road_lp_variables,
            s.road_lp_constraints,
            s.road_lp_violations
        );
        let (found, solved) = terrastitch::render::lp_components_reused();
        eprintln!(
            "LP components: {} solved, {} found solved by an earlier tile",
            solved - counted.1,
            found - counted.0
        );
    }
    Ok(())
}

/// The formats named on the command line.
fn formats(names: &[String]) -> Result<Vec<Format>> {
    let mut formats = Vec::new();
    for name in names.iter().flat_map(|n| n.split(',')) {
        let format = match name.trim() {
            "terrain" => Format::Terrain(terrastitch::format::Extensions {
                normals: true,
                watermask: true,
            }),
            other => match terrastitch::format::Variant::from_name(other) {
                Some(variant) => Format::Glb(variant),
                None => anyhow::bail!(
                    "unknown format '{other}'; expected glb, glb-meshopt, glb-enu, \
                     glb-enu-meshopt or terrain"
                ),
            },
        };
        if !formats.contains(&format) {
            formats.push(format);
        }
    }
    Ok(formats)
}

/// Renders the planned tiles of a box into the store, with a progress bar on a terminal.
fn seed_area(
    area: &AreaArgs,
    config: &Config,
    provider: &dyn TileProvider,
    store: &dyn TileStore,
    cluster: Option<&Arc<Cluster>>,
    shard: seed::Shard,
) -> Result<seed::SeedReport> {
    let formats = formats(&area.formats)?;
    let layers = seed::layers(&provider.offer(), &area.bbox()?, &formats, area.all_zooms);
    let plan = seed::plan(provider, store, &layers, shard)?;
    eprintln!(
        "{} tiles in the box; this share: {} to make, {} already in the cache, {} outside the data",
        plan.in_box,
        plan.to_make.len(),
        plan.already,
        plan.uncovered
    );
    let bar = indicatif::ProgressBar::new(plan.to_make.len() as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{bar:40} {pos}/{len} tiles  {per_sec}  {elapsed_precise} elapsed, {eta} left",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let threads = area
        .threads
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(2, |n| n.get()));
    let limit = (config.server.render_timeout_ms > 0)
        .then(|| std::time::Duration::from_millis(config.server.render_timeout_ms));
    let show = |progress: seed::Progress| {
        bar.set_length(progress.total as u64);
        bar.set_position(progress.done as u64);
    };
    let report = match cluster {
        Some(cluster) => {
            eprintln!(
                "working on the cluster's seed queue as {}",
                cluster.holder()
            );
            shared_seed::seed(
                provider,
                store,
                cluster,
                &plan.to_make,
                threads,
                limit,
                &show,
            )?
        }
        None => seed::seed(provider, store, &plan.to_make, threads, limit, &show)?,
    };
    bar.finish_and_clear();
    let (found, solved) = terrastitch::render::lp_components_reused();
    eprintln!(
        "made {} tiles in {:.1} s ({:.2} tiles/s), {} bytes stored; {} failed; elevation LP: {} components solved, {} found solved",
        report.made,
        report.elapsed.as_secs_f64(),
        report.tiles_per_second(),
        report.stored_bytes,
        report.failed.len(),
        solved,
        found
    );
    for (key, error) in &report.failed {
        eprintln!("  {} ({}): {error}", key.tile, key.format.as_str());
    }
    Ok(report)
}

/// Opens the sources and the store (the cache named on the command line, if one is) and makes
/// this shard of the area's tiles the store lacks; an error if any could not be made.
fn seed_into_store(
    mut config: Config,
    area: &AreaArgs,
    shard: seed::Shard,
) -> Result<(Config, Renderer, Arc<dyn TileStore>)> {
    if let Some(cache) = &area.cache {
        config.cache.path = cache.clone();
    }
    if let Some(url) = &area.cache_url {
        config.cache.url = url.clone();
    }
    let fetcher = Arc::new(Fetcher::new(config.sources.fetch_settings()));
    let renderer = open_renderer(&config, fetcher)?;
    let (store, cluster) = open_store(&config)?;
    if cluster.is_some() && shard != seed::Shard::default() {
        anyhow::bail!(
            "--shard is for separate caches: workers on a PostgreSQL cache share its queue"
        );
    }
    let report = seed_area(
        area,
        &config,
        &renderer,
        store.as_ref(),
        cluster.as_ref(),
        shard,
    )?;
    if !report.failed.is_empty() {
        anyhow::bail!("{} tiles could not be made", report.failed.len());
    }
    Ok((config, renderer, store))
}

fn seed(args: SeedArgs, config: Config) -> Result<()> {
    if let Some(SeedAction::Status(status)) = &args.action {
        return seed_status(status, config);
    }
    let area = args.area.or_formats(SEED_FORMATS);
    seed_into_store(config, &area, args.shard.unwrap_or_default()).map(|_| ())
}

/// Prints what the cluster's queue holds, its workers and its failed tiles.
fn seed_status(args: &StatusArgs, config: Config) -> Result<()> {
    let url = args.cache_url.clone().unwrap_or(config.cache.url.clone());
    if url.trim().is_empty() {
        anyhow::bail!(
            "seed status reads a cluster's PostgreSQL cache: name it with --cache-url or cache.url"
        );
    }
    let store = open_postgres(url.trim(), None)?;
    let status = store
        .cluster(std::time::Duration::from_secs(config.cache.lease_s))
        .status()?;
    let usage = store.usage()?;
    println!(
        "cache {}: {} tiles, {} bytes",
        store.place(),
        usage.tiles,
        usage.bytes
    );
    if status.queues.is_empty() {
        println!("queue: empty");
    }
    for queue in &status.queues {
        println!(
            "queue {}: {} waiting, {} being made, {} failed",
            queue.kind, queue.waiting, queue.taken, queue.failed
        );
    }
    println!("render leases held: {}", status.leases);
    for worker in &status.workers {
        println!(
            "worker {} ({}): up {:.0} s, last heard {:.0} s ago, {} made, {} failed",
            worker.name, worker.kind, worker.running_s, worker.silent_s, worker.made, worker.failed
        );
    }
    for (key, error) in &status.failures {
        println!("failed {} ({}): {error}", key.tile, key.format.as_str());
    }
    Ok(())
}

fn export(args: ExportArgs, config: Config) -> Result<()> {
    let mut area = args.area.or_formats(EXPORT_FORMATS);
    area.all_zooms = true;
    let target = export::Target::from_path(&args.output);
    let formats = formats(&area.formats)?;
    if target.holds_one_format() && formats.len() > 1 {
        return Err(export::ExportError::SeveralFormats.into());
    }
    // Whatever the cache lacks is made first; nothing is exported if a tile fails.
    let (_, renderer, store) = seed_into_store(config, &area, seed::Shard::default())?;
    let bbox = area.bbox()?;
    let layers = seed::layers(&renderer.offer(), &bbox, &formats, true);
    let keys: Vec<_> = layers
        .iter()
        .flat_map(|layer| {
            layer
                .range
                .tiles()
                .flat_map(|tile| layer.formats.iter().map(move |&format| (tile, format)))
        })
        .filter_map(|(tile, format)| seed::available(&renderer, tile, format))
        .collect();
    let heights = |tile: TileId| renderer.ground_range(tile);
    let contents = formats
        .iter()
        .map(|&format| export::contents_of(format, &layers, &bbox, &heights))
        .collect();
    let plan = export::Export { keys, contents };
    let written = export::export(store.as_ref(), &plan, &target)?;
    eprintln!(
        "exported {} tiles, {} bytes of tile data, to {}",
        written.tiles,
        written.bytes,
        args.output.display()
    );
    for name in &written.described {
        eprintln!("wrote {}", args.output.join(name).display());
    }
    Ok(())
}

/// The store `import` writes: the configured one, else `cache/osm.sqlite`.
const DEFAULT_STORE: &str = "cache/osm.sqlite";

fn import(force: bool, config: Config) -> Result<()> {
    let store = config
        .sources
        .store
        .clone()
        .unwrap_or_else(|| PathBuf::from(DEFAULT_STORE));
    let fetcher = Fetcher::new(config.sources.fetch_settings());
    let (extracts, _) = terrastitch::provider::inputs::local_extracts(&config.sources, &fetcher)?;
    let bar = indicatif::ProgressBar::new(0);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{msg:<20} {bar:30} {bytes}/{total_bytes}  {bytes_per_sec}  {elapsed_precise} elapsed, {eta} left  {prefix}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let started = Instant::now();
    let progress = |p: &terrastitch::source::store::import::Progress| {
        bar.set_length(p.total_bytes);
        bar.set_position(p.bytes);
        bar.set_message(p.phase.as_str());
        bar.set_prefix(format!(
            "{} nodes, {} ways, {} relations",
            p.nodes, p.ways, p.relations
        ));
    };
    let imported = terrastitch::provider::osm_source::import_locked(
        &store,
        &extracts,
        config.server.zoom,
        force,
        &progress,
    )?;
    bar.finish_and_clear();
    for read in &imported.read {
        eprintln!(
            "read {}: {} blocks of data, {} nodes, {} ways, {} relations{}",
            read.path.display(),
            read.blocks,
            read.nodes,
            read.ways,
            read.relations,
            match read.sorted {
                true => ", sorted by type then id",
                false => "",
            }
        );
    }
    let seconds = started.elapsed().as_secs_f64();
    let bytes: u64 = extracts
        .iter()
        .map(|p| std::fs::metadata(p).map_or(0, |m| m.len()))
        .sum();
    eprintln!(
        "imported {} nodes ({} tagged), {} ways, {} relations, {} bridge and tunnel groups, {} joints \
         in {:.1} s ({:.1} MB/s of PBF) into {} ({} bytes)",
        imported.nodes,
        imported.tagged_nodes,
        imported.ways,
        imported.relations,
        imported.groups,
        imported.joints,
        seconds,
        bytes as f64 / 1e6 / seconds.max(1e-9),
        store.display(),
        imported.store_bytes
    );
    Ok(())
}

fn update(args: UpdateArgs, config: Config) -> Result<()> {
    let store = config
        .sources
        .store
        .clone()
        .unwrap_or_else(|| PathBuf::from(DEFAULT_STORE));
    let started = Instant::now();
    let mut expired = std::collections::BTreeSet::new();
    let replication = args.replication.clone().or_else(|| {
        (!config.sources.replication.is_empty()).then(|| config.sources.replication.clone())
    });
    let applied = if args.osc.is_empty() {
        let Some(base) = replication else {
            anyhow::bail!("name the diffs with --osc, or a replication source with --replication or sources.replication");
        };
        let fetcher = Fetcher::new(config.sources.fetch_settings());
        let source = terrastitch::source::replication::Replication::new(&base);
        let caught =
            terrastitch::provider::osm_source::catch_up(&store, &source, &fetcher, usize::MAX)?;
        eprintln!(
            "{base} is at sequence {}; {} diffs applied",
            caught.source,
            caught.applied.len()
        );
        caught.applied.into_iter().map(|(_, a)| a).collect()
    } else {
        vec![terrastitch::provider::osm_source::update_locked(
            &store, &args.osc, None,
        )?]
    };
    for applied in &applied {
        eprintln!(
            "applied diff {} ({} nodes, {} ways, {} relations changed; {} bridge and tunnel groups found again); \
             {} of {} tiles read expired",
            applied.generation,
            applied.nodes,
            applied.ways,
            applied.relations,
            applied.groups,
            applied.expired.len(),
            applied.candidates
        );
        expired.extend(applied.expired.iter().copied());
    }
    eprintln!("in {:.2} s", started.elapsed().as_secs_f64());
    let expired: Vec<TileId> = expired.into_iter().collect();
    let tiles: Vec<String> = expired.iter().map(|t| t.to_string()).collect();
    match args.expired.as_deref() {
        Some(path) if path == std::path::Path::new("-") => {
            for tile in &tiles {
                println!("{tile}");
            }
        }
        Some(path) => {
            let mut text = tiles.join("\n");
            if !text.is_empty() {
                text.push('\n');
            }
            std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))?;
        }
        None => {}
    }
    if let Some(server) = &args.server {
        tell_server(server, args.token.as_deref(), &expired)?;
    }
    Ok(())
}

/// Asks a running server to make the expired tiles again, with their coarser ancestors.
fn tell_server(server: &str, token: Option<&str>, expired: &[TileId]) -> Result<()> {
    let Some(token) = token else {
        anyhow::bail!("--server needs the admin token (--token or TERRASTITCH_ADMIN_TOKEN)");
    };
    let mut tiles = std::collections::BTreeSet::new();
    for &tile in expired {
        let mut t = tile;
        tiles.insert(t);
        while t.z > 0 {
            t = TileId {
                z: t.z - 1,
                x: t.x / 2,
                y: t.y / 2,
            };
            tiles.insert(t);
        }
    }
    let names: Vec<String> = tiles.iter().map(|t| t.to_string()).collect();
    let url = format!("{}/admin/regenerate", server.trim_end_matches('/'));
    let body = serde_json::json!({ "tiles": names }).to_string();
    let mut response = ureq::post(&url)
        .header("Authorization", &format!("Bearer {token}"))
        .header("Content-Type", "application/json")
        .send(body.as_bytes())
        .with_context(|| format!("telling {url} of the expired tiles"))?;
    let answer = response.body_mut().read_to_string().unwrap_or_default();
    eprintln!("{url}: {answer}");
    Ok(())
}
