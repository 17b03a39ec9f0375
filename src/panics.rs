//! What a panic said: a render that trips on degenerate input fails its tile alone, and the
//! message it carried goes into that tile's error.

/// The message a panic carried.
pub fn text(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "panic".to_string())
}
