//! `terrastitch serve`: the HTTP server, on the configured sources or on an exported archive,
//! until SIGTERM or Ctrl-C.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context, Result};
use clap::Args;

use super::flags::{Flags, SourceArgs};
use crate::cache::TileCache;
use crate::config::{Config, ServerConfig};
use crate::provider::Archive;
use crate::server::{self, AppState};

#[derive(Args)]
pub struct ServeArgs {
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

impl ServeArgs {
    pub fn flags(&self) -> Flags {
        Flags {
            listen: self.listen.clone(),
            cache: self.cache.clone(),
            ..self.sources.flags()
        }
    }
}

pub fn run(args: ServeArgs, config: Config) -> Result<()> {
    match args.archive {
        Some(file) => serve_archive(&file, config),
        None => serve_sources(config),
    }
}

/// Serves the configured sources: tiles are made when first asked for and kept in the cache.
fn serve_sources(config: Config) -> Result<()> {
    let (store, coordinator) = super::open_store(&config)?;
    let cache =
        TileCache::new(store, config.cache.memory_mib * 1024 * 1024).coordinated_by(coordinator);
    let state = AppState::new(cache, &config.server);
    let grace = Duration::from_secs(config.server.shutdown_grace_s);
    run_server(grace, async move {
        let stop = shutdown_signal();
        let listener = listen(&config.server.listen).await?;
        tracing::info!("serving on http://{}/", listener.local_addr()?);
        // The sources load while the server already answers `/health` (and `/ready` with
        // `503`); a source that cannot be loaded stops the server with its error.
        let (failed_tx, failed_rx) = tokio::sync::oneshot::channel::<anyhow::Error>();
        let loading = state.clone();
        tokio::task::spawn_blocking(move || match super::open_renderer(&config) {
            Ok(renderer) => {
                let renderer = renderer.with_solutions(loading.work.solutions.clone());
                loading.provide(Arc::new(renderer))
            }
            Err(error) => {
                loading.provider_failed(format!("{error:#}"));
                let _ = failed_tx.send(error);
            }
        });
        let failure = Arc::new(std::sync::Mutex::new(None));
        let recorded = failure.clone();
        let shutdown = async move {
            tokio::select! {
                _ = stop => {},
                Ok(error) = failed_rx => {
                    if let Ok(mut slot) = recorded.lock() {
                        *slot = Some(error);
                    }
                },
            }
        };
        server::serve(listener, state, shutdown).await?;
        let failure = failure.lock().ok().and_then(|mut f| f.take());
        match failure {
            Some(error) => Err(error),
            None => Ok(()),
        }
    })
}

/// Serves an exported archive as it is.
fn serve_archive(file: &Path, config: Config) -> Result<()> {
    let store = crate::cache::open_archive(file, config.cache.max_tile_bytes())?;
    let archive = Archive::of(store.as_ref());
    let server = ServerConfig {
        zoom: archive.contents.max_zoom(),
        ..config.server.clone()
    };
    let cache = TileCache::reading(store, config.cache.memory_mib * 1024 * 1024);
    let state = AppState::new(cache, &server);
    state.provide(Arc::new(archive));
    run_server(Duration::from_secs(server.shutdown_grace_s), async move {
        let stop = shutdown_signal();
        let listener = listen(&server.listen).await?;
        let address = listener.local_addr()?;
        tracing::info!(file = %file.display(), "serving an exported file on http://{address}/");
        server::serve(listener, state, stop).await?;
        Ok(())
    })
}

/// Binds the address, and says so on stderr in the line tests and scripts wait for.
async fn listen(address: &str) -> Result<tokio::net::TcpListener> {
    let listener = tokio::net::TcpListener::bind(address)
        .await
        .with_context(|| format!("cannot listen on {address}"))?;
    eprintln!("listening on http://{}", listener.local_addr()?);
    Ok(listener)
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

/// Resolves at the first SIGTERM or Ctrl-C. The handlers are installed when this is called, not
/// when the future is first polled: a server that has said it listens already stops cleanly on
/// a signal, even while its shutdown task has not run yet.
fn shutdown_signal() -> impl std::future::Future<Output = ()> {
    #[cfg(unix)]
    let signals = {
        use tokio::signal::unix::{signal, SignalKind};
        (
            signal(SignalKind::terminate()).ok(),
            signal(SignalKind::interrupt()).ok(),
        )
    };
    async move {
        #[cfg(unix)]
        {
            let (mut terminate, mut interrupt) = signals;
            tokio::select! {
                _ = recv(terminate.as_mut()) => {},
                _ = recv(interrupt.as_mut()) => {},
            }
        }
        #[cfg(not(unix))]
        {
            let _ = tokio::signal::ctrl_c().await;
        }
        tracing::info!("shutting down");
    }
}

/// The next signal of an installed handler; never, without one.
#[cfg(unix)]
async fn recv(signal: Option<&mut tokio::signal::unix::Signal>) {
    match signal {
        Some(signal) => {
            signal.recv().await;
        }
        None => std::future::pending::<()>().await,
    }
}
