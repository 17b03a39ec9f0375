//! Natural-neighbour (Sibson) interpolation of the SRTM sites (thesis §3.4), with spade.
//!
//! The value at a point depends only on the sites around it, so it is computed from a canonical
//! window: the 6×6 sites around the SRTM cell that holds the point (which contains every natural
//! neighbour a point inside that cell can have on a grid), in a fixed order, at positions in
//! metres relative to the cell's south-west site. The same point gets the same bits whichever
//! tile asks, which the seamless tile edges rely on. Windows are cached per cell, and queries
//! inside one cell reuse its triangulation.

use std::cell::RefCell;
use std::rc::Rc;

use spade::{DelaunayTriangulation, HasPosition, Point2, Triangulation};

use super::Mosaic;

const METRES_PER_DEGREE: f64 = 111_319.490_793;

/// Sites on each side of the cell in a window: 2 + the cell's 2 + 2.
const WINDOW_MARGIN: i64 = 2;

#[derive(Debug, Clone, Copy)]
struct Site {
    position: Point2<f64>,
    elevation: f64,
}

impl HasPosition for Site {
    type Scalar = f64;

    fn position(&self) -> Point2<f64> {
        self.position
    }
}

struct Window {
    triangulation: DelaunayTriangulation<Site>,
    step_x: f64,
    step_z: f64,
}

/// Windows by (steps, lat_step, lon_step) of their cell; `None` where the data has too few sites.
type WindowCache = rustc_hash::FxHashMap<(i64, i64, i64), Option<Rc<Window>>>;

pub struct NaturalNeighbor<'a> {
    mosaic: &'a Mosaic,
    windows: RefCell<WindowCache>,
}

impl<'a> NaturalNeighbor<'a> {
    pub fn new(mosaic: &'a Mosaic) -> NaturalNeighbor<'a> {
        NaturalNeighbor {
            mosaic,
            windows: RefCell::new(WindowCache::default()),
        }
    }

    fn window(&self, steps: i64, lat_step: i64, lon_step: i64) -> Option<Rc<Window>> {
        if let Some(w) = self.windows.borrow().get(&(steps, lat_step, lon_step)) {
            return w.clone();
        }
        let step_z = METRES_PER_DEGREE / steps as f64;
        // The spacing at the cell's own latitude, so every point of the cell uses one window.
        let lat = (lat_step as f64 + 0.5) / steps as f64;
        let step_x = step_z * lat.to_radians().cos();
        let mut sites = Vec::with_capacity(36);
        for dr in -WINDOW_MARGIN..=WINDOW_MARGIN + 1 {
            for dc in -WINDOW_MARGIN..=WINDOW_MARGIN + 1 {
                if let Some(elevation) = self.mosaic.site(steps, lat_step + dr, lon_step + dc) {
                    sites.push(Site {
                        position: Point2::new(dc as f64 * step_x, dr as f64 * step_z),
                        elevation,
                    });
                }
            }
        }
        let window = DelaunayTriangulation::<Site>::bulk_load_stable(sites)
            .ok()
            .filter(|t| t.num_vertices() >= 3)
            .map(|triangulation| {
                Rc::new(Window {
                    triangulation,
                    step_x,
                    step_z,
                })
            });
        self.windows
            .borrow_mut()
            .insert((steps, lat_step, lon_step), window.clone());
        window
    }

    /// The elevation at a point, `None` outside the data.
    pub fn elevation(&self, lon: f64, lat: f64) -> Option<f64> {
        let steps = self.mosaic.steps_at(lon, lat)?;
        let fx = lon * steps as f64;
        let fz = lat * steps as f64;
        let (cx, cz) = (fx.floor() as i64, fz.floor() as i64);
        let Some(window) = self.window(steps, cz, cx) else {
            return self.mosaic.bilinear(lon, lat);
        };
        let point = Point2::new(
            (fx - cx as f64) * window.step_x,
            (fz - cz as f64) * window.step_z,
        );
        window
            .triangulation
            .natural_neighbor()
            .interpolate(|v| v.data().elevation, point)
            .or_else(|| self.mosaic.bilinear(lon, lat))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::terrain::mosaic::synthetic as file;

    #[test]
    fn honours_the_sites_and_linear_surfaces() {
        let mosaic = file(|r, c| 50.0 + 2.0 * c - 3.0 * r);
        let nn = NaturalNeighbor::new(&mosaic);
        // At a site: exactly its sample.
        let site = nn
            .elevation(7.0 + 300.0 / 1200.0, 44.0 - 200.0 / 1200.0)
            .unwrap();
        assert!((site - (50.0 + 600.0 - 600.0)).abs() < 1e-6, "{site}");
        // Sibson coordinates reproduce linear functions.
        let (lon, lat) = (7.3456, 43.6543);
        let expected = 50.0 + 2.0 * (lon - 7.0) * 1200.0 - 3.0 * (44.0 - lat) * 1200.0;
        let value = nn.elevation(lon, lat).unwrap();
        assert!((value - expected).abs() < 1e-3, "{value} vs {expected}");
    }
}
