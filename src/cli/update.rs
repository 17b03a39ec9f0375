//! `terrastitch update`: OSM change files, or a replication source's diffs, applied to the
//! store; the tiles they expire listed, and a running server told.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;

use super::flags::{Flags, SourceArgs};
use crate::config::Config;
use crate::source::fetch::Fetcher;
use crate::source::replication::Replication;
use crate::source::store::update::Applied;
use crate::tile::TileId;

#[derive(Args)]
pub struct UpdateArgs {
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

impl UpdateArgs {
    pub fn flags(&self) -> Flags {
        Flags {
            replication: self.replication.clone(),
            ..self.sources.flags()
        }
    }
}

pub fn run(args: UpdateArgs, config: Config) -> Result<()> {
    let store = config.sources.store_to_write();
    let started = Instant::now();
    let applied = if args.osc.is_empty() {
        replicate(&config, &store)?
    } else {
        vec![crate::provider::osm_source::update_locked(
            &store, &args.osc, None,
        )?]
    };
    let mut expired = BTreeSet::new();
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
    if let Some(path) = &args.expired {
        write_expired(path, &expired)?;
    }
    if let Some(server) = &args.server {
        tell_server(server, args.token.as_deref(), &expired)?;
    }
    Ok(())
}

/// Applies the diffs the configured replication source has that the store lacks.
fn replicate(config: &Config, store: &Path) -> Result<Vec<Applied>> {
    let base = &config.sources.replication;
    if base.is_empty() {
        anyhow::bail!("name the diffs with --osc, or a replication source with --replication or sources.replication");
    }
    let fetcher = Fetcher::new(config.sources.fetch_settings());
    let source = Replication::new(base);
    let caught = crate::provider::osm_source::catch_up(store, &source, &fetcher, usize::MAX)?;
    eprintln!(
        "{base} is at sequence {}; {} diffs applied",
        caught.source,
        caught.applied.len()
    );
    Ok(caught.applied.into_iter().map(|(_, a)| a).collect())
}

/// The expired tiles, one Z/X/Y a line, to a file or (for `-`) standard output.
fn write_expired(path: &Path, expired: &[TileId]) -> Result<()> {
    let tiles: Vec<String> = expired.iter().map(|t| t.to_string()).collect();
    if path == Path::new("-") {
        for tile in &tiles {
            println!("{tile}");
        }
        return Ok(());
    }
    let mut text = tiles.join("\n");
    if !text.is_empty() {
        text.push('\n');
    }
    std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))
}

/// Asks a running server to make the expired tiles again, with their coarser ancestors.
fn tell_server(server: &str, token: Option<&str>, expired: &[TileId]) -> Result<()> {
    let Some(token) = token else {
        anyhow::bail!("--server needs the admin token (--token or TERRASTITCH_ADMIN_TOKEN)");
    };
    let mut tiles = BTreeSet::new();
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
