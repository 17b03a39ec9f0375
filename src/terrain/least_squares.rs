//! Local quadratic least squares (thesis §3.3).
//!
//! Each SRTM site gets a quadratic `a0 + a1·x + a2·z + a3·x² + a4·xz + a5·z²` fitted to the site
//! and its k = 8 nearest sites, which on the SRTM grid are its 3×3 neighbourhood. Because the
//! sites are a regular grid, the least-squares problem is the same for every site up to the
//! right-hand side: the 6×9 pseudo-inverse `(AᵀA)⁻¹Aᵀ` is computed once (Cholesky, nalgebra) and
//! a site's coefficients are one matrix–vector product. (The fit is done in grid-step units: the
//! space of quadratics is closed under scaling each axis, so the fitted surface is the same as in
//! metres.) This is the speed-up the thesis names in §3.5: exploit the grid structure.
//!
//! The elevation at a point blends the polynomials of the sites within a cutoff radius with
//! inverse-distance weights that fall to zero at the cutoff (`((R − d)₊ / (R·d))²`, Franke and
//! Little's modified Shepard weights), so the surface stays continuous where the set of nearby
//! sites changes.

use std::cell::RefCell;

use nalgebra::{SMatrix, SVector};

use super::Mosaic;

/// Cutoff radius of the blend, in grid steps (of the longer spacing).
const CUTOFF_STEPS: f64 = 1.5;

/// Metres per degree of latitude on the sphere used for distances.
const METRES_PER_DEGREE: f64 = 111_319.490_793;

type Coefficients = [f64; 6];

/// The 6×9 matrix that maps the 3×3 neighbourhood (row-major, north-west first) to coefficients.
fn pseudo_inverse() -> SMatrix<f64, 6, 9> {
    let mut a = SMatrix::<f64, 9, 6>::zeros();
    for (i, (dr, dc)) in stencil().enumerate() {
        let (x, z) = (dc as f64, dr as f64);
        let row = [1.0, x, z, x * x, x * z, z * z];
        for (j, value) in row.into_iter().enumerate() {
            a[(i, j)] = value;
        }
    }
    let normal = a.transpose() * a;
    let cholesky = normal
        .cholesky()
        .expect("the 3×3 stencil determines a quadratic: AᵀA is positive definite");
    cholesky.inverse() * a.transpose()
}

/// Offsets (row, column) of the 3×3 neighbourhood, in the order the pseudo-inverse expects.
fn stencil() -> impl Iterator<Item = (i64, i64)> {
    (-1..=1).flat_map(|dr| (-1..=1).map(move |dc| (dr, dc)))
}

/// Evaluates the blended local quadratics over a mosaic; caches each site's coefficients, and
/// keeps the sites around the last point read, which the next point often shares (a grid of
/// samples along a row, the four reads of a normal).
pub struct LeastSquares<'a> {
    mosaic: &'a Mosaic,
    pseudo_inverse: SMatrix<f64, 6, 9>,
    coefficients: RefCell<rustc_hash::FxHashMap<(i64, i64, i64), Coefficients>>,
    window: RefCell<Window>,
}

/// Most sites a quarter of a [`Window`] holds (its reach north times its reach east): 2 × 18 at
/// 85° of latitude, where tiles end.
const MAX_WINDOW: i64 = 64;

/// The sites a point's elevation blends: a rectangle of them around its grid cell, named by
/// the grid's steps, the cell and the rectangle's reach, with each site's coefficients once
/// read (`None` inside: outside the data).
#[derive(Default)]
struct Window {
    key: Option<[i64; 5]>,
    sites: Vec<Option<Option<Coefficients>>>,
}

impl<'a> LeastSquares<'a> {
    pub fn new(mosaic: &'a Mosaic) -> LeastSquares<'a> {
        LeastSquares {
            mosaic,
            pseudo_inverse: pseudo_inverse(),
            coefficients: RefCell::new(rustc_hash::FxHashMap::default()),
            window: RefCell::new(Window::default()),
        }
    }

    /// The fitted coefficients of a site, in grid steps (x east, z north) from the site.
    fn site_coefficients(&self, steps: i64, lat_step: i64, lon_step: i64) -> Option<Coefficients> {
        let key = (steps, lat_step, lon_step);
        if let Some(c) = self.coefficients.borrow().get(&key) {
            return Some(*c);
        }
        let c = self.fitted(steps, lat_step, lon_step)?;
        self.coefficients.borrow_mut().insert(key, c);
        Some(c)
    }

    /// The coefficients of a site fitted to its neighbourhood; `None` outside the data.
    fn fitted(&self, steps: i64, lat_step: i64, lon_step: i64) -> Option<Coefficients> {
        let centre = self.mosaic.site(steps, lat_step, lon_step)?;
        let mut values = SVector::<f64, 9>::zeros();
        for (i, (dr, dc)) in stencil().enumerate() {
            // A neighbour outside every file (the edge of the data) mirrors across the site,
            // which keeps the fit's slope there instead of inventing one.
            values[i] = self
                .mosaic
                .site(steps, lat_step + dr, lon_step + dc)
                .or_else(|| {
                    self.mosaic
                        .site(steps, lat_step - dr, lon_step - dc)
                        .map(|opposite| 2.0 * centre - opposite)
                })
                .unwrap_or(centre);
        }
        let solved = self.pseudo_inverse * values;
        Some([
            solved[0], solved[1], solved[2], solved[3], solved[4], solved[5],
        ])
    }

    /// The elevation at a point, `None` outside the data.
    pub fn elevation(&self, lon: f64, lat: f64) -> Option<f64> {
        let steps = self.mosaic.steps_at(lon, lat)?;
        let fx = lon * steps as f64;
        let fz = lat * steps as f64;
        // Metres per grid step east and north at this latitude.
        let step_z = METRES_PER_DEGREE / steps as f64;
        let step_x = step_z * lat.to_radians().cos();
        let radius_m = CUTOFF_STEPS * step_x.max(step_z);
        let reach_x = (radius_m / step_x).ceil() as i64;
        let reach_z = (radius_m / step_z).ceil() as i64;
        let (cx, cz) = (fx.floor() as i64, fz.floor() as i64);
        let mut window = self.window.borrow_mut();
        let key = [steps, cz, cx, reach_z, reach_x];
        // Near a pole the sites blended are many: those are read from the map alone.
        let windowed = reach_z.saturating_mul(reach_x) <= MAX_WINDOW;
        if windowed && window.key != Some(key) {
            window.key = Some(key);
            window.sites.clear();
            window.sites.resize((4 * reach_z * reach_x) as usize, None);
        }
        let mut weighted = 0.0;
        let mut weights = 0.0;
        let mut site = 0;
        for lat_step in cz - reach_z + 1..=cz + reach_z {
            for lon_step in cx - reach_x + 1..=cx + reach_x {
                site += 1;
                let (dx, dz) = (fx - lon_step as f64, fz - lat_step as f64);
                let distance = ((dx * step_x).powi(2) + (dz * step_z).powi(2)).sqrt();
                if distance >= radius_m {
                    continue;
                }
                let read = match window.sites.get_mut(site - 1).filter(|_| windowed) {
                    Some(kept) => *kept
                        .get_or_insert_with(|| self.site_coefficients(steps, lat_step, lon_step)),
                    None => self.site_coefficients(steps, lat_step, lon_step),
                };
                let Some(c) = read else {
                    continue;
                };
                let value =
                    c[0] + c[1] * dx + c[2] * dz + c[3] * dx * dx + c[4] * dx * dz + c[5] * dz * dz;
                if distance < 1e-9 {
                    return Some(value);
                }
                let w = ((radius_m - distance) / (radius_m * distance)).powi(2);
                weighted += w * value;
                weights += w;
            }
        }
        if weights > 0.0 {
            Some(weighted / weights)
        } else {
            self.mosaic.bilinear(lon, lat)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::terrain::mosaic::synthetic as file;

    #[test]
    fn reproduces_a_quadratic_surface_exactly() {
        // f in grid steps; rows grow southwards, so z (north) = −row.
        let mosaic =
            file(|r, c| 100.0 + 0.5 * c - 0.25 * r + 0.01 * c * c + 0.02 * r * c - 0.005 * r * r);
        let ls = LeastSquares::new(&mosaic);
        for (lon, lat) in [(7.5003, 43.4999), (7.25, 43.75), (7.12345, 43.6789)] {
            let column = (lon - 7.0) * 1200.0;
            let row = (44.0 - lat) * 1200.0;
            let expected =
                100.0 + 0.5 * column - 0.25 * row + 0.01 * column * column + 0.02 * row * column
                    - 0.005 * row * row;
            let value = ls.elevation(lon, lat).unwrap();
            assert!(
                (value - expected).abs() < 1e-2 * expected.abs().max(1.0),
                "{value} vs {expected}"
            );
        }
    }

    #[test]
    fn follows_a_smooth_surface_without_jumps() {
        let f = |r: f64, c: f64| 30.0 * (c / 7.0).sin() + 20.0 * (r / 5.0).cos();
        let mosaic = file(f);
        let ls = LeastSquares::new(&mosaic);
        let mut previous: Option<f64> = None;
        for i in 0..=4000 {
            // Across several cells and sites, in steps of 0.012 grid steps.
            let lon = 7.49 + 0.04 * i as f64 / 4000.0;
            let lat = 43.5 + 0.0001234;
            let value = ls.elevation(lon, lat).unwrap();
            let expected = f((44.0 - lat) * 1200.0, (lon - 7.0) * 1200.0);
            assert!(
                (value - expected).abs() < 2.0,
                "{value} vs {expected} at {lon}"
            );
            if let Some(previous) = previous {
                // |f'| ≤ 30/7 m per step: a step of 0.012 moves at most ~0.05 m.
                assert!(
                    (value - previous).abs() < 0.1,
                    "jump at {lon}: {previous} → {value}"
                );
            }
            previous = Some(value);
        }
    }

    #[test]
    fn a_model_read_at_many_points_gives_what_a_fresh_model_gives_at_each() {
        // Points over many cells in a scattered order, each followed by one a few metres off
        // (mostly among the same sites).
        let mosaic = file(|r, c| 50.0 * (c / 11.0).sin() * (r / 13.0).cos() + 0.3 * r);
        let reused = LeastSquares::new(&mosaic);
        for k in 0..2000u32 {
            let t = f64::from(k);
            let lon = 7.45 + 0.1 * ((t * 0.618_034).fract());
            let lat = 43.45 + 0.1 * ((t * 0.414_214).fract());
            for (lon, lat) in [(lon, lat), (lon + 0.000_05, lat - 0.000_03)] {
                let fresh = LeastSquares::new(&mosaic).elevation(lon, lat);
                assert_eq!(
                    reused.elevation(lon, lat).map(f64::to_bits),
                    fresh.map(f64::to_bits),
                    "{lon} {lat}"
                );
            }
        }
    }

    #[test]
    fn smooths_a_spike_without_wild_overshoot() {
        let mosaic = file(|r, c| if r == 600.0 && c == 600.0 { 100.0 } else { 0.0 });
        let ls = LeastSquares::new(&mosaic);
        let at_spike = ls.elevation(7.5, 43.5).unwrap();
        assert!(at_spike > 10.0 && at_spike < 100.0, "{at_spike}");
        for i in 0..=400 {
            let value = ls
                .elevation(7.49 + 0.02 * i as f64 / 400.0, 43.5 + 0.0003)
                .unwrap();
            assert!((-60.0..=100.0).contains(&value), "{value}");
        }
    }
}
