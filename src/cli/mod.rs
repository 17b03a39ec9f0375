//! The `terrastitch` command line: one file a command (`serve`, `render`, `seed`, `export`,
//! `import`, `update`), the flags they share and how flags override the configuration
//! ([`flags`]). The binary only installs the allocator and calls [`main`].

pub mod export;
pub mod flags;
pub mod import;
pub mod render;
pub mod seed;
pub mod serve;
pub mod update;

use std::sync::Arc;
use std::time::Instant;

use anyhow::Result;
use clap::{Parser, Subcommand};

use crate::cache::postgres::coordinator::Shared;
use crate::cache::{Coordinator, Local, PostgresStore, SqliteStore, TileStore};
use crate::config::{Config, LogFormat};
use crate::provider::Renderer;
use crate::source::fetch::Fetcher;
use flags::Flags;

#[derive(Parser)]
#[command(
    name = "terrastitch",
    version,
    about = "Seamless 3D map tiles from OpenStreetMap and SRTM"
)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Serve tiles over HTTP.
    Serve(serve::ServeArgs),
    /// Render one tile to a file, without the server.
    Render(render::RenderArgs),
    /// Render every tile of a box into the cache (resumable; --shard splits the work; with a
    /// PostgreSQL cache, workers on any number of machines share one queue).
    Seed(seed::SeedArgs),
    /// Write a box's tiles to an MBTiles file, or to DIR/z/x/y.glb with `-o DIR/`.
    Export(export::ExportArgs),
    /// Read the OSM extracts once into the on-disk store the other commands read.
    Import(import::ImportArgs),
    /// Apply OSM change files (.osc, .osc.gz) to the store and list the tiles they expire.
    Update(update::UpdateArgs),
}

impl Command {
    /// The flags of the command that override the configuration.
    fn flags(&self) -> Flags {
        match self {
            Command::Serve(args) => args.flags(),
            Command::Render(args) => args.sources.flags(),
            Command::Seed(args) => args.flags(),
            Command::Export(args) => args.flags(),
            Command::Import(args) => args.sources.flags(),
            Command::Update(args) => args.flags(),
        }
    }
}

/// Parses the command line, loads the configuration with the flags over it, and runs the
/// command.
pub fn main() -> Result<()> {
    crate::server::memory::limit_arenas();
    let cli = Cli::parse();
    let config = flags::configuration(&cli.command.flags())?;
    init_logging(config.log.format);
    match cli.command {
        Command::Serve(args) => serve::run(args, config),
        Command::Render(args) => render::run(args, config),
        Command::Seed(args) => seed::run(args, config),
        Command::Export(args) => export::run(args, config),
        Command::Import(args) => import::run(args, config),
        Command::Update(args) => update::run(args, config),
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

/// Opens (downloading what the data directory lacks) the configured sources, to render from.
fn open_renderer(config: &Config) -> Result<Renderer> {
    let started = Instant::now();
    let fetcher = Arc::new(Fetcher::new(config.sources.fetch_settings()));
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

/// A tile store, with how the processes sharing it share its work.
type Store = (Arc<dyn TileStore>, Arc<dyn Coordinator>);

/// The tile store a configuration names: its PostgreSQL database (`cache.url`), coordinated
/// through the cluster that shares it, else its SQLite file, which this process owns.
fn open_store(config: &Config) -> Result<Store> {
    let cap = (config.cache.max_size_mib > 0).then(|| config.cache.max_size_mib * 1024 * 1024);
    let url = config.cache.url.trim();
    if url.is_empty() {
        let store = SqliteStore::open_or_set_aside(&config.cache.path, cap)?
            .with_max_tile(config.cache.max_tile_bytes());
        return Ok((Arc::new(store), Arc::new(Local::new())));
    }
    let store = open_postgres(url, cap)?.with_max_tile(config.cache.max_tile_bytes());
    let cluster = store.cluster(std::time::Duration::from_secs(config.cache.lease_s));
    tracing::info!(place = store.place(), "tiles kept in PostgreSQL");
    Ok((Arc::new(store), Arc::new(Shared::new(cluster))))
}

fn open_postgres(url: &str, cap: Option<u64>) -> Result<PostgresStore> {
    if !(url.starts_with("postgres://") || url.starts_with("postgresql://")) {
        anyhow::bail!(
            "cache.url must be a PostgreSQL URL (postgres://user:password@host/database), not {:?}",
            crate::cache::postgres::redacted(url)
        );
    }
    Ok(PostgresStore::open(url, cap)?)
}
