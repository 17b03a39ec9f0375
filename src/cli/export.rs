//! `terrastitch export`: a box's tiles, made first where the cache lacks them, written to a
//! PMTiles or MBTiles file or a directory.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

use super::flags::{Flags, SourceArgs};
use super::seed::AreaArgs;
use crate::config::Config;
use crate::offline::{export, seed};
use crate::provider::TileProvider;
use crate::tile::TileId;

#[derive(Args)]
pub struct ExportArgs {
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

impl ExportArgs {
    pub fn flags(&self) -> Flags {
        self.area.flags(&self.sources)
    }
}

pub fn run(args: ExportArgs, config: Config) -> Result<()> {
    let mut area = args.area;
    area.all_zooms = true;
    let target = export::Target::from_path(&args.output);
    let formats = area.formats(&crate::config::EXPORT_FORMATS)?;
    if target.holds_one_format() && formats.len() > 1 {
        return Err(export::ExportError::SeveralFormats.into());
    }
    // Whatever the cache lacks is made first; nothing is exported if a tile fails.
    let (renderer, store) = super::seed::into_store(&config, &area, &formats, Default::default())?;
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
