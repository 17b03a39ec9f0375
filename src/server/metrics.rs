//! Counters, gauges and histograms exposed at `/metrics` in the Prometheus text format.

use std::collections::BTreeMap;
use std::fmt::Write;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;
use std::time::Duration;

use crate::provider::{FetchStats, StageTimings};

/// Upper bounds of the render-time buckets, seconds.
const SECONDS_BUCKETS: &[f64] = &[
    0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0,
];

/// A histogram with fixed buckets.
#[derive(Debug)]
pub struct Histogram {
    bounds: &'static [f64],
    /// One count per bound, then one for +Inf (not cumulative).
    counts: Vec<AtomicU64>,
    sum_micros: AtomicU64,
}

impl Histogram {
    pub fn new(bounds: &'static [f64]) -> Histogram {
        Histogram {
            bounds,
            counts: (0..=bounds.len()).map(|_| AtomicU64::new(0)).collect(),
            sum_micros: AtomicU64::new(0),
        }
    }

    pub fn observe(&self, duration: Duration) {
        let seconds = duration.as_secs_f64();
        let bucket = self
            .bounds
            .iter()
            .position(|&b| seconds <= b)
            .unwrap_or(self.bounds.len());
        self.counts[bucket].fetch_add(1, Ordering::Relaxed);
        self.sum_micros
            .fetch_add(duration.as_micros() as u64, Ordering::Relaxed);
    }

    /// The series lines of this histogram under `name` with `labels` (`key="value"` pairs).
    fn write(&self, out: &mut String, name: &str, labels: &str) {
        let separator = if labels.is_empty() { "" } else { "," };
        let mut cumulative = 0;
        for (i, count) in self.counts.iter().enumerate() {
            cumulative += count.load(Ordering::Relaxed);
            let bound = self
                .bounds
                .get(i)
                .map_or("+Inf".to_string(), |b| b.to_string());
            let _ = writeln!(
                out,
                "{name}_bucket{{{labels}{separator}le=\"{bound}\"}} {cumulative}"
            );
        }
        let braces = if labels.is_empty() {
            String::new()
        } else {
            format!("{{{labels}}}")
        };
        let _ = writeln!(
            out,
            "{name}_sum{braces} {:.6}\n{name}_count{braces} {cumulative}",
            self.sum_micros.load(Ordering::Relaxed) as f64 / 1e6
        );
    }
}

/// The render stages timed, with their label: each stage of a render, then the whole.
const STAGES: [&str; 9] = {
    let mut names = ["total"; 9];
    let mut i = 0;
    while i < StageTimings::NAMES.len() {
        names[i] = StageTimings::NAMES[i];
        i += 1;
    }
    names
};

fn stage_durations(t: &StageTimings) -> [Duration; 9] {
    let mut durations = [t.total(); 9];
    durations[..8].copy_from_slice(&t.stages());
    durations
}

#[derive(Debug)]
pub struct Metrics {
    pub renders: AtomicU64,
    pub render_failures: AtomicU64,
    /// Renders stopped at the time limit.
    pub render_timeouts: AtomicU64,
    /// Requests turned away because the render queue was full.
    pub rejected_busy: AtomicU64,
    pub hits_memory: AtomicU64,
    pub hits_store: AtomicU64,
    pub misses: AtomicU64,
    /// Stale tiles served while their replacement was made.
    pub stale_served: AtomicU64,
    /// Tiles made but not stored (the store could not take them) and served from memory.
    pub tiles_unstored: AtomicU64,
    /// Debug views made.
    pub debug_views: AtomicU64,
    pub tile_requests: AtomicU64,
    /// Components of the elevation LP solved, and soft constraints they violated.
    pub lp_components: AtomicU64,
    pub lp_violations: AtomicU64,
    /// Tiles made again in the background (stale, regenerated), and those that failed.
    pub regenerations: AtomicU64,
    pub regeneration_failures: AtomicU64,
    /// Connections open now (a gauge).
    pub connections_open: AtomicU64,
    /// Render time per stage (index as [`STAGES`]).
    stage_seconds: Vec<Histogram>,
    /// Responses by route template and status.
    responses: Mutex<BTreeMap<(String, u16), u64>>,
    request_seconds: Histogram,
}

impl Default for Metrics {
    fn default() -> Self {
        Metrics {
            renders: AtomicU64::new(0),
            render_failures: AtomicU64::new(0),
            render_timeouts: AtomicU64::new(0),
            rejected_busy: AtomicU64::new(0),
            hits_memory: AtomicU64::new(0),
            hits_store: AtomicU64::new(0),
            misses: AtomicU64::new(0),
            stale_served: AtomicU64::new(0),
            tiles_unstored: AtomicU64::new(0),
            debug_views: AtomicU64::new(0),
            tile_requests: AtomicU64::new(0),
            lp_components: AtomicU64::new(0),
            lp_violations: AtomicU64::new(0),
            regenerations: AtomicU64::new(0),
            regeneration_failures: AtomicU64::new(0),
            connections_open: AtomicU64::new(0),
            stage_seconds: STAGES
                .iter()
                .map(|_| Histogram::new(SECONDS_BUCKETS))
                .collect(),
            responses: Mutex::new(BTreeMap::new()),
            request_seconds: Histogram::new(SECONDS_BUCKETS),
        }
    }
}

/// What the render pool holds at one moment.
#[derive(Debug, Clone, Copy, Default)]
pub struct PoolGauges {
    pub running: usize,
    pub waiting: usize,
    pub background_waiting: usize,
    /// Tiles queued to be made again, or being made.
    pub regenerating: usize,
    /// Requests waiting for a tile to be looked up or made (many on one tile share its make).
    pub for_tiles: usize,
    /// Tiles answered in haste whose forms kept are being made.
    pub refining: usize,
    /// Tiles answered in haste that the store then could not take (a count so far, added to
    /// the tiles unstored).
    pub unstored_after_answer: u64,
}

impl Metrics {
    pub fn count(counter: &AtomicU64) {
        counter.fetch_add(1, Ordering::Relaxed);
    }

    pub fn add(counter: &AtomicU64, n: u64) {
        counter.fetch_add(n, Ordering::Relaxed);
    }

    pub fn observe_render(&self, timings: &StageTimings) {
        for (histogram, duration) in self.stage_seconds.iter().zip(stage_durations(timings)) {
            histogram.observe(duration);
        }
    }

    pub fn observe_response(&self, route: &str, status: u16, elapsed: Duration) {
        *self
            .responses
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .entry((route.to_string(), status))
            .or_insert(0) += 1;
        self.request_seconds.observe(elapsed);
    }

    /// The metrics in Prometheus' text format; `downloads` counts the provider's downloads
    /// (none when it downloads nothing), `lp_found` the LP components renders found solved.
    pub fn render_text(
        &self,
        pool: PoolGauges,
        downloads: Option<&FetchStats>,
        lp_found: u64,
    ) -> String {
        let none = FetchStats::default();
        let mut out = String::new();
        let counters = self.counters(
            downloads.unwrap_or(&none),
            lp_found,
            pool.unstored_after_answer,
        );
        for (name, help, value) in counters {
            let _ = writeln!(
                out,
                "# HELP {name} {help}\n# TYPE {name} counter\n{name} {value}"
            );
        }
        self.write_cache(&mut out);
        write_queue(&mut out, pool);
        let _ = writeln!(
            out,
            "# HELP terrastitch_connections_open Connections open now.\n# TYPE terrastitch_connections_open gauge\nterrastitch_connections_open {}",
            self.connections_open.load(Ordering::Relaxed)
        );
        self.write_stages(&mut out);
        self.write_http(&mut out);
        out
    }

    /// The plain counters, as name, help and value, in the order they are written.
    fn counters(
        &self,
        downloads: &FetchStats,
        lp_found: u64,
        unstored_after_answer: u64,
    ) -> [(&'static str, &'static str, u64); 17] {
        let get = |c: &AtomicU64| c.load(Ordering::Relaxed);
        [
            (
                "terrastitch_tile_requests_total",
                "Tile requests received.",
                get(&self.tile_requests),
            ),
            (
                "terrastitch_renders_total",
                "Tiles rendered.",
                get(&self.renders),
            ),
            (
                "terrastitch_render_failures_total",
                "Renders that failed.",
                get(&self.render_failures),
            ),
            (
                "terrastitch_render_timeouts_total",
                "Renders stopped at the time limit.",
                get(&self.render_timeouts),
            ),
            (
                "terrastitch_rejected_busy_total",
                "Tile requests answered 503 because the render queue was full.",
                get(&self.rejected_busy),
            ),
            (
                "terrastitch_stale_served_total",
                "Stale tiles served while their replacement was made.",
                get(&self.stale_served),
            ),
            (
                "terrastitch_tiles_unstored_total",
                "Tiles made but not stored, the store unable to take them (disk full, damaged), and served from memory only.",
                get(&self.tiles_unstored) + unstored_after_answer,
            ),
            (
                "terrastitch_debug_views_total",
                "Debug views made (each in a render slot; requests for one tile at once share one).",
                get(&self.debug_views),
            ),
            (
                "terrastitch_lp_components_total",
                "Components of the elevation linear program solved.",
                get(&self.lp_components),
            ),
            (
                "terrastitch_lp_components_found_total",
                "Components of the elevation linear program found solved by an earlier tile of the process instead of solved again.",
                lp_found,
            ),
            (
                "terrastitch_lp_violations_total",
                "Soft elevation constraints (from tags and defaults) violated in rendered tiles.",
                get(&self.lp_violations),
            ),
            (
                "terrastitch_regenerations_total",
                "Tiles made again in the background.",
                get(&self.regenerations),
            ),
            (
                "terrastitch_regeneration_failures_total",
                "Background remakes that failed (the old tile stays).",
                get(&self.regeneration_failures),
            ),
            (
                "terrastitch_downloads_total",
                "Source files downloaded whole.",
                get(&downloads.downloads),
            ),
            (
                "terrastitch_download_failures_total",
                "Source downloads that failed after their retries.",
                get(&downloads.failures),
            ),
            (
                "terrastitch_download_requests_total",
                "HTTP requests sent for source files, retries included.",
                get(&downloads.requests),
            ),
            (
                "terrastitch_download_bytes_total",
                "Bytes of source files received.",
                get(&downloads.bytes),
            ),
        ]
    }

    /// Cache hits by layer, and misses.
    fn write_cache(&self, out: &mut String) {
        let get = |c: &AtomicU64| c.load(Ordering::Relaxed);
        let _ = writeln!(
            out,
            "# HELP terrastitch_cache_hits_total Tiles served from a cache layer.\n# TYPE terrastitch_cache_hits_total counter\nterrastitch_cache_hits_total{{layer=\"memory\"}} {}\nterrastitch_cache_hits_total{{layer=\"sqlite\"}} {}",
            get(&self.hits_memory),
            get(&self.hits_store)
        );
        let _ = writeln!(
            out,
            "# HELP terrastitch_cache_misses_total Tiles found in no cache layer and rendered.\n# TYPE terrastitch_cache_misses_total counter\nterrastitch_cache_misses_total {}",
            get(&self.misses)
        );
    }

    /// The render time histogram of each stage.
    fn write_stages(&self, out: &mut String) {
        let _ = writeln!(
            out,
            "# HELP terrastitch_render_stage_seconds Render time by stage.\n# TYPE terrastitch_render_stage_seconds histogram"
        );
        for (stage, histogram) in STAGES.iter().zip(&self.stage_seconds) {
            histogram.write(
                out,
                "terrastitch_render_stage_seconds",
                &format!("stage=\"{stage}\""),
            );
        }
    }

    /// Responses by route and status, and the time to answer.
    fn write_http(&self, out: &mut String) {
        let _ = writeln!(
            out,
            "# HELP terrastitch_http_requests_total HTTP responses by route and status.\n# TYPE terrastitch_http_requests_total counter"
        );
        for ((route, status), n) in self
            .responses
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .iter()
        {
            let _ = writeln!(
                out,
                "terrastitch_http_requests_total{{route=\"{route}\",status=\"{status}\"}} {n}"
            );
        }
        let _ = writeln!(
            out,
            "# HELP terrastitch_http_request_seconds Time to answer a request (to its headers).\n# TYPE terrastitch_http_request_seconds histogram"
        );
        self.request_seconds
            .write(out, "terrastitch_http_request_seconds", "");
    }
}

/// The render queue's gauges by state.
fn write_queue(out: &mut String, pool: PoolGauges) {
    let _ = writeln!(
        out,
        "# HELP terrastitch_render_queue Renders by state: running, waiting (requests waiting for a slot), background (remakes waiting for a slot), regenerating (tiles queued to be made again, or being made).\n# TYPE terrastitch_render_queue gauge\nterrastitch_render_queue{{state=\"running\"}} {}\nterrastitch_render_queue{{state=\"waiting\"}} {}\nterrastitch_render_queue{{state=\"background\"}} {}\nterrastitch_render_queue{{state=\"regenerating\"}} {}",
        pool.running, pool.waiting, pool.background_waiting, pool.regenerating
    );
    let _ = writeln!(
        out,
        "# HELP terrastitch_tile_requests_waiting Requests waiting for a tile to be looked up or made; those for one tile share one make.\n# TYPE terrastitch_tile_requests_waiting gauge\nterrastitch_tile_requests_waiting {}",
        pool.for_tiles
    );
    let _ = writeln!(
        out,
        "# HELP terrastitch_tiles_refining Tiles answered in haste, in the coding asked for made fast, whose smaller forms are being made and stored.\n# TYPE terrastitch_tiles_refining gauge\nterrastitch_tiles_refining {}",
        pool.refining
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn histograms_are_cumulative_and_count_everything() {
        let histogram = Histogram::new(&[0.1, 1.0]);
        for ms in [50, 500, 5000, 70] {
            histogram.observe(Duration::from_millis(ms));
        }
        let mut out = String::new();
        histogram.write(&mut out, "h", "stage=\"x\"");
        assert!(
            out.contains("h_bucket{stage=\"x\",le=\"0.1\"} 2\n"),
            "{out}"
        );
        assert!(out.contains("h_bucket{stage=\"x\",le=\"1\"} 3\n"), "{out}");
        assert!(
            out.contains("h_bucket{stage=\"x\",le=\"+Inf\"} 4\n"),
            "{out}"
        );
        assert!(out.contains("h_count{stage=\"x\"} 4\n"), "{out}");
        assert!(out.contains("h_sum{stage=\"x\"} 5.620000\n"), "{out}");
    }
}
