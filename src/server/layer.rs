//! `GET /layer.json`: the quantized-mesh layer description Cesium's terrain provider reads (see
//! [`crate::output::layer`]), with the tiles at `tiles/{z}/{x}/{y}.terrain`.

use axum::extract::State;
use axum::Json;
use serde_json::Value;

use super::error::ApiError;
use super::AppState;

pub async fn layer(State(state): State<AppState>) -> Result<Json<Value>, ApiError> {
    let layer = state.provider()?.terrain_layer().ok_or_else(|| {
        ApiError::not_found("this server has no terrain layer: it serves the glb tiles of a file")
    })?;
    Ok(Json(layer.document("tiles/{z}/{x}/{y}.terrain")))
}
