//! Greedy-insertion meshing of raw SRTM windows, for comparison with pydelatin and pymartini
//! on the same windows (`scripts/terrain_compare.py` runs all three and checks every mesh with
//! the same independent error measure).
//!
//! Usage: tin_bench FILE.hgt WINDOW ERROR OUT_PREFIX
//!   WINDOW: full | crop1025 | win256 | win257 (as in the peers' benchmark)
//! Writes OUT_PREFIX.vertices (f64 x, y=row, z triples, little-endian) and OUT_PREFIX.triangles
//! (u32 triples) and prints one JSON line with the time and counts.

use std::time::Instant;

use terrastitch::mesh::tin::{corner_seed, refine, HeightGrid, RefineLimits};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let [_, path, window, error, prefix] = args.as_slice() else {
        return Err("usage: tin_bench FILE.hgt WINDOW ERROR OUT_PREFIX".into());
    };
    let bytes = std::fs::read(path)?;
    let n = ((bytes.len() / 2) as f64).sqrt() as usize;
    if n * n * 2 != bytes.len() {
        return Err(format!("{path} is not a square .hgt").into());
    }
    let raw: Vec<f64> = bytes
        .chunks_exact(2)
        .map(|p| f64::from(i16::from_be_bytes([p[0], p[1]])))
        .collect();
    let (offset, size) = match window.as_str() {
        "full" => (0, n),
        "crop1025" => (0, 1025),
        "win256" => ((n - 257) / 2, 256),
        "win257" => ((n - 257) / 2, 257),
        other => return Err(format!("unknown window {other}").into()),
    };
    let mut heights = Vec::with_capacity(size * size);
    for row in offset..offset + size {
        heights.extend_from_slice(&raw[row * n + offset..row * n + offset + size]);
    }
    let grid = HeightGrid::unit(size, size, heights);
    let max_error: f64 = error.parse()?;
    let mut best = f64::INFINITY;
    let mut result = None;
    for _ in 0..3 {
        let started = Instant::now();
        let limits = RefineLimits {
            max_error,
            keep_border: false,
            max_insertions: usize::MAX,
        };
        let (tin, _) = refine(&corner_seed(&grid), &grid, limits, &mut |_| f64::NAN);
        best = best.min(started.elapsed().as_secs_f64());
        result = Some(tin);
    }
    let tin = result.ok_or("no run")?;
    let mut vertices = Vec::new();
    for (p, h) in tin.positions.iter().zip(&tin.heights) {
        for value in [p.x, p.y, *h] {
            vertices.extend_from_slice(&value.to_le_bytes());
        }
    }
    let triangles: Vec<u8> = tin
        .triangles
        .iter()
        .flatten()
        .flat_map(|i| i.to_le_bytes())
        .collect();
    std::fs::write(format!("{prefix}.vertices"), vertices)?;
    std::fs::write(format!("{prefix}.triangles"), triangles)?;
    println!(
        "{{\"tool\":\"terrastitch\",\"window\":\"{window}\",\"max_error\":{max_error},\"seconds\":{best:.4},\"triangles\":{},\"vertices\":{}}}",
        tin.triangles.len(),
        tin.positions.len()
    );
    Ok(())
}
