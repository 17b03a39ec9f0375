//! `terrastitch seed`: the tiles of a box rendered into the cache, and `seed status`, what a
//! cluster's queue holds.

use std::path::PathBuf;
use std::sync::Arc;

use anyhow::{Context, Result};
use clap::{Args, Subcommand};

use super::flags::{Flags, SourceArgs};
use crate::cache::{Coordinator, TileReader, TileStore};
use crate::config::Config;
use crate::format::Format;
use crate::offline::seed;
use crate::provider::{Renderer, Solutions, TileProvider};
use crate::tile::LonLatBounds;

/// The tiles of a box, for `seed` and `export`.
#[derive(Args)]
pub struct AreaArgs {
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
    pub all_zooms: bool,
}

impl AreaArgs {
    /// The flags over the configuration, with those of the sources.
    pub fn flags(&self, sources: &SourceArgs) -> Flags {
        Flags {
            cache: self.cache.clone(),
            cache_url: self.cache_url.clone(),
            ..sources.flags()
        }
    }

    pub fn bbox(&self) -> Result<LonLatBounds> {
        self.bbox.context("--bbox W,S,E,N is needed")
    }

    /// The formats named, or `defaults` when none is.
    pub fn formats(&self, defaults: &[Format]) -> Result<Vec<Format>> {
        if self.formats.is_empty() {
            return Ok(defaults.to_vec());
        }
        parse_formats(&self.formats)
    }
}

#[derive(Args)]
#[command(subcommand_negates_reqs = true, args_conflicts_with_subcommands = true)]
pub struct SeedArgs {
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

impl SeedArgs {
    pub fn flags(&self) -> Flags {
        match &self.action {
            Some(SeedAction::Status(status)) => Flags {
                cache_url: status.cache_url.clone(),
                ..status.sources.flags()
            },
            None => self.area.flags(&self.sources),
        }
    }
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

pub fn run(args: SeedArgs, config: Config) -> Result<()> {
    if let Some(SeedAction::Status(_)) = &args.action {
        return status(&config);
    }
    let formats = args.area.formats(&crate::config::SEED_FORMATS)?;
    let shard = args.shard.unwrap_or_default();
    into_store(&config, &args.area, &formats, shard).map(|_| ())
}

/// The formats named on the command line, each once: glb variants by name, or `terrain`.
fn parse_formats(names: &[String]) -> Result<Vec<Format>> {
    let mut formats = Vec::new();
    for name in names.iter().flat_map(|n| n.split(',')) {
        let format = match name.trim() {
            "terrain" => Format::Terrain(crate::format::Extensions {
                normals: true,
                watermask: true,
            }),
            other => match crate::format::Variant::from_name(other) {
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

/// Opens the sources and the configured store and makes this shard of the area's tiles the
/// store lacks; an error if any could not be made.
pub fn into_store(
    config: &Config,
    area: &AreaArgs,
    formats: &[Format],
    shard: seed::Shard,
) -> Result<(Renderer, Arc<dyn TileStore>)> {
    if !config.cache.url.trim().is_empty() && shard != seed::Shard::default() {
        anyhow::bail!(
            "--shard is for separate caches: workers on a PostgreSQL cache share its queue"
        );
    }
    let renderer = super::open_renderer(config)?;
    let (store, coordinator) = super::open_store(config)?;
    let work = Work {
        area,
        formats,
        config,
        shard,
    };
    let report = work.seed(&renderer, store.as_ref(), coordinator.as_ref())?;
    if !report.failed.is_empty() {
        anyhow::bail!("{} tiles could not be made", report.failed.len());
    }
    Ok((renderer, store))
}

/// What to seed.
struct Work<'a> {
    area: &'a AreaArgs,
    formats: &'a [Format],
    config: &'a Config,
    shard: seed::Shard,
}

impl Work<'_> {
    /// Renders the planned tiles into the store, with a progress bar on a terminal.
    fn seed(
        &self,
        renderer: &Renderer,
        store: &dyn TileStore,
        coordinator: &dyn Coordinator,
    ) -> Result<seed::SeedReport> {
        let (provider, solutions): (&dyn TileProvider, _) = (renderer, renderer.solutions());
        let bbox = self.area.bbox()?;
        let layers = seed::layers(&provider.offer(), &bbox, self.formats, self.area.all_zooms);
        let plan = seed::plan(provider, store, &layers, self.shard)?;
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
        let threads = self
            .area
            .threads
            .unwrap_or_else(|| std::thread::available_parallelism().map_or(2, |n| n.get()));
        let limit = (self.config.server.render_timeout_ms > 0)
            .then(|| std::time::Duration::from_millis(self.config.server.render_timeout_ms));
        let show = |progress: seed::Progress| {
            bar.set_length(progress.total as u64);
            bar.set_position(progress.done as u64);
        };
        eprintln!("working on the seed queue as {}", coordinator.holder());
        let report = seed::seed(
            (provider, solutions),
            store,
            coordinator,
            &plan.to_make,
            (threads, limit),
            &show,
        )?;
        bar.finish_and_clear();
        print_report(&report, solutions);
        Ok(report)
    }
}

fn print_report(report: &seed::SeedReport, solutions: &Solutions) {
    let (found, solved) = solutions.counts();
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
    if report.made > 0 {
        let stages = crate::provider::StageTimings::NAMES
            .iter()
            .zip(report.stages.stages())
            .map(|(name, time)| format!("{name} {:.2}", time.as_secs_f64()))
            .collect::<Vec<_>>()
            .join(", ");
        eprintln!(
            "time in each stage, seconds summed over the tiles made: {stages}; compressing {:.2}",
            report.compressing.as_secs_f64()
        );
    }
    for (key, error) in &report.failed {
        eprintln!("  {} ({}): {error}", key.tile, key.format.as_str());
    }
}

/// Prints what the cluster's queue holds, its workers and its failed tiles.
fn status(config: &Config) -> Result<()> {
    let url = config.cache.url.trim();
    if url.is_empty() {
        anyhow::bail!(
            "seed status reads a cluster's PostgreSQL cache: name it with --cache-url or cache.url"
        );
    }
    let store = super::open_postgres(url, None)?;
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
