//! `terrastitch render`: one tile to a file, made by the provider as the server makes it.

use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use clap::Args;

use super::flags::SourceArgs;
use crate::config::Config;
use crate::format::{Format, Variant};
use crate::provider::{
    Availability, Deadline, Fetching, Made, Renderer, Solutions, StageTimings, TileProvider,
};
use crate::tile::TileId;

#[derive(Args)]
pub struct RenderArgs {
    /// The tile, as Z/X/Y (e.g. 14/8529/5973)
    tile: String,
    /// Output file
    #[arg(short = 'o', long = "output", value_name = "OUT.glb")]
    output: PathBuf,
    #[command(flatten)]
    pub sources: SourceArgs,
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
    /// Write the input of every LP component solved afresh (by this tile and those of
    /// `--after`) to this file, as text: fixtures for holding one solver to another
    #[arg(long, value_name = "FILE")]
    record_lp: Option<PathBuf>,
}

pub fn run(args: RenderArgs, config: Config) -> Result<()> {
    let tile: TileId = args.tile.parse()?;
    let variant = Variant::from_name(&args.variant).with_context(|| {
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
    let mut renderer = super::open_renderer(&config)?;
    if args.record_lp.is_some() {
        renderer = renderer.with_solutions(Arc::new(Solutions::recording()));
    }
    // Opening the sources counts in the load of the first tile rendered.
    let mut opened = Some(started.elapsed());
    for &earlier in &before {
        opened = None;
        make(&renderer, earlier, variant)?;
    }
    let counted = renderer.solutions().counts();
    let (took, made) = make(&renderer, tile, variant)?;
    std::fs::write(&args.output, &made.bytes)
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    if let Some(path) = &args.record_lp {
        let recorded = renderer.solutions().take_recorded().concat();
        std::fs::write(path, recorded)
            .with_context(|| format!("cannot write {}", path.display()))?;
    }
    if args.timings {
        // What the render's stages did not take went to reading the tile's inputs.
        let load = took.saturating_sub(made.timings.total()) + opened.unwrap_or_default();
        print_timings(load, &made, counted, renderer.solutions().counts());
    }
    Ok(())
}

/// Makes one tile through the provider, downloading what it lacks first; with the time the
/// whole took.
fn make(renderer: &Renderer, tile: TileId, variant: Variant) -> Result<(Duration, Made)> {
    let started = Instant::now();
    let key = renderer.resolve(tile, Format::Glb(variant))?;
    match renderer.availability(key) {
        Availability::Ready => {}
        Availability::AfterFetch => renderer.fetch(tile)?,
        Availability::Missing(why) => anyhow::bail!(why),
    }
    let made = renderer.make(key, Deadline::none())?;
    Ok((started.elapsed(), made))
}

/// The figures of `--timings`, on stderr.
/// `counted` and `now`: the LP components found and solved before and after the tile.
fn print_timings(load: Duration, made: &Made, counted: (u64, u64), now: (u64, u64)) {
    let t = made.timings;
    let ms = |d: Duration| d.as_secs_f64() * 1000.0;
    eprintln!("load           {:8.1} ms", ms(load));
    for (name, duration) in StageTimings::NAMES.iter().zip(t.stages()) {
        eprintln!("{name:<14} {:8.1} ms", ms(duration));
    }
    eprintln!(
        "total          {:8.1} ms (render {:.1} ms)",
        ms(load + t.total()),
        ms(t.total())
    );
    if let Some(s) = &made.stats {
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
    let (found, solved) = now;
    eprintln!(
        "LP components: {} solved, {} found solved by an earlier tile",
        solved - counted.1,
        found - counted.0
    );
}
