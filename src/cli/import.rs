//! `terrastitch import`: the OSM extracts read once into the on-disk store.

use std::time::Instant;

use anyhow::Result;
use clap::Args;

use super::flags::SourceArgs;
use crate::config::Config;
use crate::source::fetch::Fetcher;
use crate::source::store::import::{Imported, Progress};

#[derive(Args)]
pub struct ImportArgs {
    #[command(flatten)]
    pub sources: SourceArgs,
    /// Replace the store even when the extracts hold fewer than half of a kind of element it
    /// holds (an extract cut short reads as a smaller one)
    #[arg(long)]
    force: bool,
}

pub fn run(args: ImportArgs, config: Config) -> Result<()> {
    let store = config.sources.store_to_write();
    let fetcher = Fetcher::new(config.sources.fetch_settings());
    let (extracts, _) = crate::provider::inputs::local_extracts(&config.sources, &fetcher)?;
    let bar = indicatif::ProgressBar::new(0);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{msg:<20} {bar:30} {bytes}/{total_bytes}  {bytes_per_sec}  {elapsed_precise} elapsed, {eta} left  {prefix}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let started = Instant::now();
    let progress = |p: &Progress| {
        bar.set_length(p.total_bytes);
        bar.set_position(p.bytes);
        bar.set_message(p.phase.as_str());
        bar.set_prefix(format!(
            "{} nodes, {} ways, {} relations",
            p.nodes, p.ways, p.relations
        ));
    };
    let imported = crate::provider::osm_source::import_locked(
        &store,
        &extracts,
        config.server.zoom,
        args.force,
        &progress,
    )?;
    bar.finish_and_clear();
    let seconds = started.elapsed().as_secs_f64();
    let bytes: u64 = extracts
        .iter()
        .map(|p| std::fs::metadata(p).map_or(0, |m| m.len()))
        .sum();
    print_summary(&imported, seconds, bytes, &store);
    Ok(())
}

/// What was read from each extract and what the store now holds.
fn print_summary(imported: &Imported, seconds: f64, bytes: u64, store: &std::path::Path) {
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
}
