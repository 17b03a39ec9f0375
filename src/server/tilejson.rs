//! `GET /tiles.json`: the tileset described TileJSON-style, for clients that discover tiles
//! from one URL: its name and attribution, the area the OSM data covers, the zoom tiles are
//! served at, and URL templates for the glb tiles and the quantized-mesh terrain.
//!
//! The templates are absolute, built from the request's `Host` (and `X-Forwarded-Proto`, behind
//! a proxy that ends TLS), since TileJSON clients resolve them on their own; without a `Host`
//! they are paths from the server's root.

use axum::extract::State;
use axum::http::{header, HeaderMap};
use axum::Json;
use serde_json::json;

use super::error::ApiError;
use super::AppState;
use crate::format::Format;
use crate::format::Frame;
use crate::output::glb::ATTRIBUTION;

pub async fn tilejson(
    State(state): State<AppState>,
    headers: HeaderMap,
) -> Result<impl axum::response::IntoResponse, ApiError> {
    let text = |name| {
        headers
            .get(name)
            .and_then(|v| v.to_str().ok())
            .filter(|v| !v.is_empty())
    };
    let base = match text(header::HOST.as_str()) {
        Some(host) => {
            let scheme = match text("x-forwarded-proto") {
                Some("https") => "https",
                _ => "http",
            };
            format!("{scheme}://{host}")
        }
        None => String::new(),
    };
    let offer = state.provider()?.offer();
    let bounds = crate::output::layer::enclosing(&offer.coverage);
    // The compressions of glb asked for with `?compress=`: a provider of one format has that.
    let compressions: Vec<&str> = match offer.only {
        Some(Format::Glb(v)) if v.frame == Frame::WebMercator => {
            vec![if v.meshopt { "meshopt" } else { "none" }]
        }
        Some(_) => Vec::new(),
        None => vec!["none", "meshopt"],
    };
    let z = offer.zoom;
    // The URLs are built from `Host`: a shared cache must key the document on it.
    let vary = [(header::VARY, "Host, X-Forwarded-Proto")];
    Ok((
        vary,
        Json(json!({
            "tilejson": "3.0.0",
            "name": "terrastitch",
            "description": "3D tiles of OpenStreetMap on SRTM terrain: glTF binary, one per zoom-14 tile",
            "attribution": ATTRIBUTION,
            "scheme": "xyz",
            "format": "glb",
            "minzoom": z,
            "maxzoom": z,
            "bounds": bounds,
            "center": [(bounds[0] + bounds[2]) / 2.0, (bounds[1] + bounds[3]) / 2.0, z],
            "tiles": [format!("{base}/tiles/{{z}}/{{x}}/{{y}}.glb")],
            "terrain": [format!("{base}/tiles/{{z}}/{{x}}/{{y}}.terrain")],
            "terrain_layer": format!("{base}/layer.json"),
            "tileset_3d": format!("{base}/tileset.json"),
            "glb_compressions": compressions,
            "far_zooms": offer.far_zooms,
        })),
    ))
}
