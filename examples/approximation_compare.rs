//! Least squares against natural neighbour over a whole SRTM tile, as thesis §3.5 reports it:
//! both surfaces sampled on a 1-arc-second grid (about 30 m), the mean and the distribution of
//! their difference, and the time each takes; then the time per zoom-14 tile (the 257² sample
//! grid of one tile).
//!
//! Usage: approximation_compare FILE.hgt [Z/X/Y]

use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Instant;

use terrastitch::source::srtm;
use terrastitch::terrain::cell::CellId;
use terrastitch::terrain::{Interpolation, Mosaic, TerrainModel};
use terrastitch::TileId;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let path = std::path::Path::new(
        args.get(1)
            .ok_or("usage: approximation_compare FILE.hgt [Z/X/Y]")?,
    );
    let stem = path
        .file_stem()
        .and_then(|s| s.to_str())
        .ok_or("bad file name")?;
    let cell = CellId::from_name(&stem[..7]).ok_or("file name is not an SRTM cell")?;
    let mosaic = Mosaic::new([Arc::new(srtm::read(cell, path)?)]);

    // The whole cell at 1″, one row of SRTM cells at a time (the models cache per-site work).
    let steps = 3600usize;
    let evaluate = |interpolation: Interpolation| -> (Vec<f32>, f64) {
        let started = Instant::now();
        let mut values = Vec::with_capacity((steps + 1) * (steps + 1));
        let mut model = TerrainModel::new(&mosaic, interpolation, 14);
        let mut cell_row = usize::MAX;
        for row in 0..=steps {
            // A new model per row of 3″ cells keeps its caches small.
            if row / 3 != cell_row {
                cell_row = row / 3;
                model = TerrainModel::new(&mosaic, interpolation, 14);
            }
            let lat = f64::from(cell.lat) + 1.0 - row as f64 / steps as f64;
            for column in 0..=steps {
                let lon = f64::from(cell.lon) + column as f64 / steps as f64;
                values.push(model.elevation(lon, lat).unwrap_or(f64::NAN) as f32);
            }
        }
        (values, started.elapsed().as_secs_f64())
    };
    let (ls, ls_seconds) = evaluate(Interpolation::LeastSquares);
    let (nn, nn_seconds) = evaluate(Interpolation::NaturalNeighbor);
    let (_, bl_seconds) = evaluate(Interpolation::Bilinear);

    let mut histogram: BTreeMap<i64, u64> = BTreeMap::new();
    let (mut sum, mut sum_abs, mut count, mut max_abs) = (0.0f64, 0.0f64, 0u64, 0.0f64);
    for (a, b) in ls.iter().zip(&nn) {
        let d = f64::from(*a) - f64::from(*b);
        if !d.is_finite() {
            continue;
        }
        sum += d;
        sum_abs += d.abs();
        max_abs = max_abs.max(d.abs());
        count += 1;
        *histogram.entry(d.round() as i64).or_default() += 1;
    }
    println!("{stem}: {count} points on a 1-arc-second grid");
    println!(
        "least squares − natural neighbour: mean {:.3} m, mean absolute {:.3} m, max |d| {:.1} m",
        sum / count as f64,
        sum_abs / count as f64,
        max_abs
    );
    println!("distribution (difference rounded to whole metres: share of points):");
    for (metres, n) in &histogram {
        let share = *n as f64 / count as f64;
        if share >= 0.0005 {
            println!("  {metres:>4} m  {:>6.2} %", share * 100.0);
        }
    }
    println!("time for the whole cell: least squares {ls_seconds:.1} s, natural neighbour {nn_seconds:.1} s, bilinear {bl_seconds:.1} s");

    // One zoom-14 tile: its 257 × 257 samples.
    let tile: TileId = match args.get(2) {
        Some(t) => t.parse()?,
        None => {
            let centre = (f64::from(cell.lon) + 0.5, f64::from(cell.lat) + 0.5);
            TileId::containing(14, centre.0, centre.1).ok_or("no tile")?
        }
    };
    for interpolation in [
        Interpolation::Bilinear,
        Interpolation::LeastSquares,
        Interpolation::NaturalNeighbor,
    ] {
        let model = TerrainModel::new(&mosaic, interpolation, tile.z);
        let started = Instant::now();
        let mut total = 0.0;
        for j in 0..=256 {
            for i in 0..=256 {
                total += model.elevation_uv([
                    f64::from(tile.x) + i as f64 / 256.0,
                    f64::from(tile.y) + j as f64 / 256.0,
                ]);
            }
        }
        println!(
            "tile {tile}: {interpolation:?} on 257² samples in {:.1} ms (mean {:.1} m)",
            started.elapsed().as_secs_f64() * 1000.0,
            total / 257.0 / 257.0
        );
    }
    Ok(())
}
