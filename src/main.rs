//! The `terrastitch` command: `serve` and `render`.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};

use terrastitch::cache::{TileCache, TileStore};
use terrastitch::config::Config;
use terrastitch::server::{self, AppState};
use terrastitch::source::Sources;
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
    /// Directory of SRTM .hgt / .hgt.zip files [default: data]
    #[arg(long, value_name = "DIR")]
    srtm: Option<PathBuf>,
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
}

fn load_config(args: &SourceArgs) -> Result<Config> {
    let mut config = Config::load(args.config.as_deref())?;
    if !args.osm.is_empty() {
        config.sources.osm = args.osm.clone();
    }
    if let Some(srtm) = &args.srtm {
        config.sources.srtm = srtm.clone();
    }
    Ok(config)
}

fn open_sources(config: &Config) -> Result<Sources> {
    let started = Instant::now();
    let sources = Sources::open(
        &config.sources.osm,
        &config.sources.srtm,
        config.server.zoom,
    )?;
    tracing::info!(
        ways = sources.osm.data().ways.len(),
        srtm_files = sources.srtm.cells().count(),
        ms = started.elapsed().as_millis() as u64,
        "sources loaded"
    );
    Ok(sources)
}

fn main() -> Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info")),
        )
        .with_writer(std::io::stderr)
        .init();
    match Cli::parse().command {
        Command::Serve(args) => serve(args),
        Command::Render(args) => render(args),
    }
}

fn serve(args: ServeArgs) -> Result<()> {
    let mut config = load_config(&args.sources)?;
    if let Some(listen) = args.listen {
        config.server.listen = listen;
    }
    if let Some(cache) = args.cache {
        config.cache.path = cache;
    }
    let sources = open_sources(&config)?;
    let store = TileStore::open(&config.cache.path)?;
    let cache = TileCache::new(
        store,
        config.cache.memory_mib * 1024 * 1024,
        server::pipeline_id(&config.render),
    );
    let state = AppState::new(sources, cache, config.render.clone(), &config.server);
    let runtime = tokio::runtime::Runtime::new().context("starting the async runtime")?;
    runtime.block_on(async move {
        let listener = tokio::net::TcpListener::bind(&config.server.listen)
            .await
            .with_context(|| format!("cannot listen on {}", config.server.listen))?;
        let address = listener.local_addr()?;
        tracing::info!("serving on http://{address}/");
        // The line tests and scripts wait for.
        eprintln!("listening on http://{address}");
        server::serve(listener, state, shutdown_signal()).await?;
        Ok(())
    })
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

fn render(args: RenderArgs) -> Result<()> {
    let tile: TileId = args.tile.parse()?;
    let config = load_config(&args.sources)?;
    let started = Instant::now();
    let sources = open_sources(&config)?;
    if let Err(uncovered) = sources.check_coverage(tile) {
        anyhow::bail!(uncovered);
    }
    let mosaic = sources.mosaic(tile)?;
    let selection = sources.selection(tile);
    let load = started.elapsed();
    let rendered = terrastitch::render_tile(tile, &selection, &mosaic, &config.render)?;
    std::fs::write(&args.output, &rendered.glb)
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    if args.timings {
        let t = rendered.timings;
        let ms = |d: std::time::Duration| d.as_secs_f64() * 1000.0;
        eprintln!("load           {:8.1} ms", ms(load));
        eprintln!("features       {:8.1} ms", ms(t.features));
        eprintln!("structures     {:8.1} ms", ms(t.structures));
        eprintln!("roads          {:8.1} ms", ms(t.roads));
        eprintln!("triangulation  {:8.1} ms", ms(t.triangulation));
        eprintln!("terrain        {:8.1} ms", ms(t.terrain));
        eprintln!("elevation      {:8.1} ms", ms(t.elevation));
        eprintln!("glb            {:8.1} ms", ms(t.glb));
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
    }
    Ok(())
}
