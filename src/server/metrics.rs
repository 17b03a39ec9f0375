//! Counters exposed at `/metrics` in the Prometheus text format.

use std::fmt::Write;
use std::sync::atomic::{AtomicU64, Ordering};

#[derive(Debug, Default)]
pub struct Metrics {
    pub renders: AtomicU64,
    pub render_failures: AtomicU64,
    pub hits_memory: AtomicU64,
    pub hits_store: AtomicU64,
    pub tile_requests: AtomicU64,
    pub render_seconds_micros: AtomicU64,
    /// Components of the elevation LP solved, and soft constraints they violated.
    pub lp_components: AtomicU64,
    pub lp_violations: AtomicU64,
}

impl Metrics {
    pub fn count(counter: &AtomicU64) {
        counter.fetch_add(1, Ordering::Relaxed);
    }

    pub fn render_text(&self) -> String {
        let get = |c: &AtomicU64| c.load(Ordering::Relaxed);
        let mut out = String::new();
        let mut counter = |name: &str, help: &str, value: String| {
            let _ = writeln!(
                out,
                "# HELP {name} {help}\n# TYPE {name} counter\n{name} {value}"
            );
        };
        counter(
            "terrastitch_tile_requests_total",
            "Tile requests received.",
            get(&self.tile_requests).to_string(),
        );
        counter(
            "terrastitch_renders_total",
            "Tiles rendered.",
            get(&self.renders).to_string(),
        );
        counter(
            "terrastitch_render_failures_total",
            "Renders that failed.",
            get(&self.render_failures).to_string(),
        );
        counter(
            "terrastitch_render_seconds_total",
            "Time spent rendering.",
            format!("{:.6}", get(&self.render_seconds_micros) as f64 / 1e6),
        );
        counter(
            "terrastitch_lp_components_total",
            "Components of the elevation linear program solved.",
            get(&self.lp_components).to_string(),
        );
        counter(
            "terrastitch_lp_violations_total",
            "Soft elevation constraints (from tags and defaults) violated in rendered tiles.",
            get(&self.lp_violations).to_string(),
        );
        let _ = writeln!(
            out,
            "# HELP terrastitch_cache_hits_total Tiles served from a cache layer.\n# TYPE terrastitch_cache_hits_total counter\nterrastitch_cache_hits_total{{layer=\"memory\"}} {}\nterrastitch_cache_hits_total{{layer=\"sqlite\"}} {}",
            get(&self.hits_memory),
            get(&self.hits_store)
        );
        out
    }
}
