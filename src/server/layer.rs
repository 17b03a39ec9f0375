//! `GET /layer.json`: the quantized-mesh layer description Cesium's terrain provider reads.
//!
//! Tiles are addressed like the glb tiles: Web Mercator (`EPSG:3857`), slippy-map numbering
//! (`scheme: slippyMap`, `y` grows southwards). Every zoom from 0 up to the served one is
//! available: coarser levels everywhere (terrain alone, sea level where there is no data), the
//! served zoom where the SRTM files are; `available` lists, per SRTM file, the range of tiles it
//! covers at the served zoom, in the same numbering as the URLs.

use axum::extract::State;
use axum::Json;
use serde_json::{json, Value};

use super::error::ApiError;
use super::AppState;
use crate::output::glb::ATTRIBUTION;
use crate::tile::TileId;

pub async fn layer(State(state): State<AppState>) -> Result<Json<Value>, ApiError> {
    let offer = state.provider()?.offer();
    let z = offer.zoom;
    let cells = offer.terrain_cells.ok_or_else(|| {
        ApiError::not_found("this server has no terrain layer: it serves the tiles of a file")
    })?;
    let mut bounds: Option<[f64; 4]> = None;
    let mut ranges = Vec::new();
    for cell in &cells {
        let (west, south) = (f64::from(cell.lon), f64::from(cell.lat));
        let (east, north) = (west + 1.0, south + 1.0);
        let b = bounds.get_or_insert([west, south, east, north]);
        *b = [
            b[0].min(west),
            b[1].min(south),
            b[2].max(east),
            b[3].max(north),
        ];
        // Tiles whose area meets the cell (a hair inside its edges, so a neighbour is not counted).
        let inset = 1e-9;
        let (Some(nw), Some(se)) = (
            TileId::containing(z, west + inset, north - inset),
            TileId::containing(z, east - inset, south + inset),
        ) else {
            continue;
        };
        ranges.push(json!({ "startX": nw.x, "startY": nw.y, "endX": se.x, "endY": se.y }));
    }
    let mut available: Vec<Value> = (0..z)
        .map(|level| {
            let last = (1u64 << level) - 1;
            json!([{ "startX": 0, "startY": 0, "endX": last, "endY": last }])
        })
        .collect();
    available.push(Value::Array(ranges));
    Ok(Json(json!({
        "tilejson": "2.1.0",
        "name": "terrastitch",
        "description": "Terrain from SRTM with OpenStreetMap roads, railways and water stitched into it",
        "version": "1.0.0",
        "format": "quantized-mesh-1.0",
        "scheme": "slippyMap",
        "projection": "EPSG:3857",
        "tiles": ["tiles/{z}/{x}/{y}.terrain"],
        "minzoom": 0,
        "maxzoom": z,
        "bounds": bounds.unwrap_or([-180.0, -85.051_128_78, 180.0, 85.051_128_78]),
        "available": available,
        "extensions": ["octvertexnormals", "watermask"],
        "attribution": ATTRIBUTION,
    })))
}
