//! Filling the voids of an elevation grid, and what is no elevation at all.

/// Elevations a sample of the Earth's surface may take, metres (the Dead Sea's shore, Everest,
/// with room for the data's noise).
pub const PLAUSIBLE_M: (i16, i16) = (-500, 9000);

/// Share of samples outside [`PLAUSIBLE_M`] past which a file is taken for something else than
/// elevations (random bytes put ~70 % there; real files a handful of samples at most).
pub const IMPLAUSIBLE_SHARE: f64 = 0.01;

/// Fills the voids (NaN) of a square grid of `size` samples a side: each takes the
/// inverse-distance blend of the nearest valid sample in each of the eight compass directions
/// (a cheap, deterministic stand-in for a full interpolation that behaves well for the small
/// holes SRTM has). Returns `None` if every sample is void.
pub fn fill_nan_voids(mut heights: Vec<f32>, size: usize) -> Option<Vec<f32>> {
    let voids: Vec<usize> = (0..heights.len())
        .filter(|&i| heights[i].is_nan())
        .collect();
    if voids.is_empty() {
        return Some(heights);
    }
    if voids.len() == heights.len() {
        return None;
    }
    const DIRECTIONS: [(isize, isize); 8] = [
        (-1, 0),
        (1, 0),
        (0, -1),
        (0, 1),
        (-1, -1),
        (-1, 1),
        (1, -1),
        (1, 1),
    ];
    let raw = heights.clone();
    for &index in &voids {
        let (row, column) = ((index / size) as isize, (index % size) as isize);
        let mut weighted = 0.0f64;
        let mut weights = 0.0f64;
        for (dr, dc) in DIRECTIONS {
            let (mut r, mut c, mut steps) = (row + dr, column + dc, 1.0f64);
            while r >= 0 && c >= 0 && (r as usize) < size && (c as usize) < size {
                let value = raw[r as usize * size + c as usize];
                if !value.is_nan() {
                    let distance = steps * ((dr * dr + dc * dc) as f64).sqrt();
                    let weight = 1.0 / (distance * distance);
                    weighted += weight * f64::from(value);
                    weights += weight;
                    break;
                }
                r += dr;
                c += dc;
                steps += 1.0;
            }
        }
        if weights > 0.0 {
            heights[index] = (weighted / weights) as f32;
        }
    }
    // A void with no valid sample on any of its eight rays (only possible in a nearly empty
    // file) takes the mean of the valid samples.
    let still_void: Vec<usize> = voids
        .iter()
        .copied()
        .filter(|&i| heights[i].is_nan())
        .collect();
    if !still_void.is_empty() {
        let valid: Vec<f64> = raw
            .iter()
            .filter(|h| !h.is_nan())
            .map(|&h| f64::from(h))
            .collect();
        let mean = (valid.iter().sum::<f64>() / valid.len() as f64) as f32;
        for i in still_void {
            heights[i] = mean;
        }
    }
    Some(heights)
}
