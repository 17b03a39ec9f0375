//! The quantized-mesh layer description (`layer.json`) that Cesium's `CesiumTerrainProvider`
//! reads: tiles addressed like the glb tiles (Web Mercator, `EPSG:3857`, slippy-map numbering,
//! `scheme: slippyMap`, `y` growing southwards), and per zoom the ranges of tiles available.
//!
//! A server of the sources offers every tile below its zoom (terrain alone, sea level where
//! there is no data) and, at its zoom, the tiles over its SRTM files; an export offers the tiles
//! it holds: at each zoom, those over its box.

use serde_json::{json, Value};

use super::glb::ATTRIBUTION;
use crate::tile::{LonLatBounds, TileId, TileRange, MAX_LATITUDE_DEG};

/// A rectangle of tiles at one zoom, both ends included: `[start_x, start_y, end_x, end_y]`.
pub type Span = [u32; 4];

/// What a terrain layer offers.
#[derive(Debug, Clone, PartialEq)]
pub struct TerrainLayer {
    /// West, south, east, north in degrees.
    pub bounds: [f64; 4],
    /// The spans available at each zoom from 0; the last zoom is the layer's finest.
    pub available: Vec<Vec<Span>>,
}

impl TerrainLayer {
    /// Every tile below `zoom`, and at `zoom` the tiles meeting each of `boxes` (a hair inside
    /// their edges, so a neighbour is not counted).
    pub fn everywhere_above(zoom: u8, boxes: &[LonLatBounds]) -> TerrainLayer {
        let mut available: Vec<Vec<Span>> = (0..zoom)
            .map(|level| {
                let last = (1u32 << level) - 1;
                vec![[0, 0, last, last]]
            })
            .collect();
        available.push(boxes.iter().filter_map(|b| span_inside(zoom, b)).collect());
        TerrainLayer {
            bounds: enclosing(boxes),
            available,
        }
    }

    /// At every zoom from 0 to `zoom`, the tiles meeting `bbox`.
    pub fn over_box(zoom: u8, bbox: &LonLatBounds) -> TerrainLayer {
        let available = (0..=zoom)
            .map(|level| {
                let range = TileRange::covering(level, bbox);
                vec![[range.min_x, range.min_y, range.max_x, range.max_y]]
            })
            .collect();
        TerrainLayer {
            bounds: enclosing(std::slice::from_ref(bbox)),
            available,
        }
    }

    /// The finest zoom.
    pub fn max_zoom(&self) -> u8 {
        self.available.len().saturating_sub(1) as u8
    }

    /// Whether the layer offers `tile`.
    pub fn offers(&self, tile: TileId) -> bool {
        self.available
            .get(usize::from(tile.z))
            .is_some_and(|spans| {
                spans.iter().any(|&[x0, y0, x1, y1]| {
                    (x0..=x1).contains(&tile.x) && (y0..=y1).contains(&tile.y)
                })
            })
    }

    /// The `layer.json` document, its tiles at `template` (`tiles/{z}/{x}/{y}.terrain`).
    pub fn document(&self, template: &str) -> Value {
        let available: Vec<Value> = self
            .available
            .iter()
            .map(|spans| {
                spans
                    .iter()
                    .map(|&[x0, y0, x1, y1]| {
                        json!({ "startX": x0, "startY": y0, "endX": x1, "endY": y1 })
                    })
                    .collect()
            })
            .collect();
        json!({
            "tilejson": "2.1.0",
            "name": "terrastitch",
            "description": "Terrain from SRTM with OpenStreetMap roads, railways and water stitched into it",
            "version": "1.0.0",
            "format": "quantized-mesh-1.0",
            "scheme": "slippyMap",
            "projection": "EPSG:3857",
            "tiles": [template],
            "minzoom": 0,
            "maxzoom": self.max_zoom(),
            "bounds": self.bounds,
            "available": available,
            "extensions": ["octvertexnormals", "watermask"],
            "attribution": ATTRIBUTION,
        })
    }

    /// The layer a `layer.json` document describes; `None` when it is not one of ours.
    pub fn from_document(document: &Value) -> Option<TerrainLayer> {
        let bounds = document["bounds"].as_array()?;
        let bounds: Vec<f64> = bounds.iter().filter_map(Value::as_f64).collect();
        let bounds: [f64; 4] = bounds.try_into().ok()?;
        let number =
            |span: &Value, name: &str| -> Option<u32> { u32::try_from(span[name].as_u64()?).ok() };
        let mut available = Vec::new();
        for level in document["available"].as_array()? {
            let mut spans = Vec::new();
            for span in level.as_array()? {
                spans.push([
                    number(span, "startX")?,
                    number(span, "startY")?,
                    number(span, "endX")?,
                    number(span, "endY")?,
                ]);
            }
            available.push(spans);
        }
        (!available.is_empty()).then_some(TerrainLayer { bounds, available })
    }
}

/// The tiles of `zoom` meeting `b`, a hair inside its edges.
fn span_inside(zoom: u8, b: &LonLatBounds) -> Option<Span> {
    let inset = 1e-9;
    let nw = TileId::containing(zoom, b.west + inset, b.north - inset)?;
    let se = TileId::containing(zoom, b.east - inset, b.south + inset)?;
    Some([nw.x, nw.y, se.x, se.y])
}

/// The box around `boxes` (west, south, east, north), the whole Web Mercator world when there
/// are none.
pub fn enclosing(boxes: &[LonLatBounds]) -> [f64; 4] {
    boxes
        .iter()
        .map(|b| [b.west, b.south, b.east, b.north])
        .reduce(|a, b| {
            [
                a[0].min(b[0]),
                a[1].min(b[1]),
                a[2].max(b[2]),
                a[3].max(b[3]),
            ]
        })
        .unwrap_or([-180.0, -MAX_LATITUDE_DEG, 180.0, MAX_LATITUDE_DEG])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn monaco() -> LonLatBounds {
        "7.40,43.72,7.44,43.75".parse().unwrap()
    }

    #[test]
    fn a_box_layer_offers_the_ancestors_of_its_tiles_and_nothing_beside_them() {
        let layer = TerrainLayer::over_box(14, &monaco());
        assert_eq!(layer.max_zoom(), 14);
        let range = TileRange::covering(14, &monaco());
        for tile in range.tiles() {
            let mut t = tile;
            loop {
                assert!(layer.offers(t), "{t}");
                if t.z == 0 {
                    break;
                }
                t = TileId {
                    z: t.z - 1,
                    x: t.x / 2,
                    y: t.y / 2,
                };
            }
        }
        let beside = TileId {
            z: 14,
            x: range.max_x + 1,
            y: range.min_y,
        };
        assert!(!layer.offers(beside));
    }

    #[test]
    fn a_layer_document_reads_back_as_the_same_layer() {
        let layer = TerrainLayer::over_box(14, &monaco());
        let document = layer.document("{z}/{x}/{y}.terrain");
        assert_eq!(document["tiles"][0], "{z}/{x}/{y}.terrain");
        assert_eq!(TerrainLayer::from_document(&document), Some(layer));
        assert_eq!(TerrainLayer::from_document(&json!({"bounds": [1]})), None);
    }

    #[test]
    fn a_served_layer_offers_every_tile_above_its_zoom_and_its_cells_at_it() {
        let cell: LonLatBounds = "7,43,8,44".parse().unwrap();
        let layer = TerrainLayer::everywhere_above(14, &[cell]);
        assert!(layer.offers(TileId { z: 3, x: 7, y: 0 }));
        let inside = TileId::containing(14, 7.5, 43.5).unwrap();
        assert!(layer.offers(inside));
        let east = TileId::containing(14, 8.05, 43.5).unwrap();
        assert!(!layer.offers(east));
        assert_eq!(layer.bounds, [7.0, 43.0, 8.0, 44.0]);
    }
}
