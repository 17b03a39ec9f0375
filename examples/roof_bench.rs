//! Buildings per second through footprint, straight skeleton and roof, and the share of
//! buildings whose roof fell back to a simpler shape, over every zoom-14 tile of an extract.
//!
//! Usage: roof_bench EXTRACT.osm.pbf SRTM_DIR [SHAPE] [X0 X1 Y0 Y1]
//! (tile columns and rows inclusive; Monaco's by default). SHAPE (a `roof:shape` value) gives
//! every building that roof, to measure it on real footprints; `tagged` keeps the tags' roofs.
//! Prints the roof shapes built, the time spent building shells, and the fallbacks by reason.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use terrastitch::features::{self, buildings::RoofShape};
use terrastitch::mesh::buildings::{self, Fallback};
use terrastitch::provider::Inputs;
use terrastitch::render::srtm_step_uv;
use terrastitch::terrain::{Interpolation, TerrainModel};
use terrastitch::TileId;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let (osm, srtm) = match args.as_slice() {
        [_, osm, srtm, ..] => (PathBuf::from(osm), PathBuf::from(srtm)),
        _ => return Err("usage: roof_bench EXTRACT.osm.pbf SRTM_DIR [SHAPE] [X0 X1 Y0 Y1]".into()),
    };
    let forced = match args.get(3).map(String::as_str) {
        None | Some("tagged") => None,
        Some(value) => {
            Some(RoofShape::from_tag(value).ok_or_else(|| format!("unknown roof shape {value}"))?)
        }
    };
    let range: Vec<u32> = args
        .get(4..)
        .unwrap_or_default()
        .iter()
        .map(|a| a.parse())
        .collect::<Result<_, _>>()?;
    let [x0, x1, y0, y1] = match range.as_slice() {
        [] => [8527, 8531, 5973, 5974],
        &[a, b, c, d] => [a, b, c, d],
        _ => return Err("give all four of X0 X1 Y0 Y1".into()),
    };
    let sources = Inputs::open(std::slice::from_ref(&osm), &srtm, 14)?;
    let mut shapes: BTreeMap<RoofShape, usize> = BTreeMap::new();
    let mut fallbacks: BTreeMap<Fallback, usize> = BTreeMap::new();
    let (mut shells, mut spent) = (0usize, Duration::ZERO);
    let mut examples: Vec<String> = Vec::new();
    for x in x0..=x1 {
        for y in y0..=y1 {
            let tile = TileId { z: 14, x, y };
            let mut set = features::collect(
                &sources.osm_for(tile)?.selection(tile),
                tile,
                &Default::default(),
            );
            if let Some(shape) = forced {
                for building in &mut set.buildings {
                    building.roof.shape = shape;
                }
            }
            let mosaic = sources.mosaic(tile)?;
            let terrain = TerrainModel::new(&mosaic, Interpolation::default(), tile.z);
            // The ground under each outline is sampled first so that the timing covers the
            // footprint, the skeleton and the roof alone.
            let frame = tile.frame();
            let ranges: Vec<(f64, f64)> = set
                .buildings
                .iter()
                .map(|b| {
                    buildings::ground_range(&b.footprint, &terrain, &terrain, srtm_step_uv(tile))
                })
                .collect();
            let started = Instant::now();
            let built: Vec<_> = set
                .buildings
                .iter()
                .zip(&ranges)
                .filter(|(b, _)| b.drawn)
                .map(|(b, &(low, high))| (b, buildings::solid(b, frame.size_m, low, high)))
                .collect();
            spent += started.elapsed();
            for (building, solid) in &built {
                shells += 1;
                *shapes.entry(building.roof.shape).or_default() += 1;
                if let Some(fallback) = solid.fallback {
                    *fallbacks.entry(fallback).or_default() += 1;
                    if examples.len() < 10 {
                        let element = set.features[building.feature as usize].element;
                        examples.push(format!("{element:?}: {}", fallback.describe()));
                    }
                }
            }
        }
    }
    println!(
        "{}: tiles x {x0}..={x1}, y {y0}..={y1}, roofs {}",
        osm.display(),
        forced.map_or("as tagged".to_string(), |s| format!("all {s:?}"))
    );
    println!(
        "  {shells} buildings in {:.1} ms: {:.0} buildings/s",
        spent.as_secs_f64() * 1e3,
        shells as f64 / spent.as_secs_f64().max(1e-9)
    );
    println!("  roof shapes: {shapes:?}");
    let pitched: usize = shapes
        .iter()
        .filter(|(s, _)| **s != RoofShape::Flat)
        .map(|(_, n)| n)
        .sum();
    let fell: usize = fallbacks.values().sum();
    println!(
        "  fell back: {fell} of {pitched} pitched ({:.2} %)",
        100.0 * fell as f64 / pitched.max(1) as f64
    );
    for (fallback, n) in &fallbacks {
        println!("    {n:6}  {}", fallback.describe());
    }
    for example in &examples {
        println!("  e.g. {example}");
    }
    Ok(())
}
