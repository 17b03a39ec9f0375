//! Typed configuration: built-in defaults, then a TOML file (`config/default.toml` unless
//! another is named), then `TERRASTITCH_*` environment variables (`__` separates sections:
//! `TERRASTITCH_SERVER__LISTEN=0.0.0.0:8080`), then command-line flags.
//! Relative paths are relative to the working directory.

use std::path::{Path, PathBuf};

use figment::providers::{Env, Format as _, Serialized, Toml};
use figment::Figment;
use serde::{Deserialize, Serialize};

use crate::format::{Format, Frame, Variant};
use crate::render::RenderSettings;

/// The configuration file read when none is named.
pub const DEFAULT_CONFIG_FILE: &str = "config/default.toml";

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(default)]
pub struct Config {
    pub server: ServerConfig,
    pub sources: SourcesConfig,
    pub cache: CacheConfig,
    pub render: RenderSettings,
    pub log: LogConfig,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ServerConfig {
    /// Address to listen on.
    pub listen: String,
    /// The zoom level tiles are served at.
    pub zoom: u8,
    /// Renders that may run at once (0: one per core).
    pub render_threads: usize,
    /// Origins browsers may read the tiles from (CORS, for `GET` and `HEAD`): `["*"]` for any,
    /// else exact origins such as `https://maps.example.org`; empty to send no CORS headers.
    pub cors_origins: Vec<String>,
    /// `Cache-Control` sent with tiles (and their `304`s); empty to send none.
    pub cache_control: String,
    /// Requests that may wait for a render slot; past that a request gets `503` with
    /// `Retry-After`.
    pub render_queue: usize,
    /// Longest a render may take, milliseconds (0: no limit).
    pub render_timeout_ms: u64,
    /// Most memory one render may take, MiB (0: no limit): past it the render stops at its
    /// next stage, and the tile is answered `503`.
    pub render_memory_mib: u64,
    /// Bearer token for `/admin/*`; empty turns those routes off.
    pub admin_token: String,
    /// Render slots background work (stale tiles, regeneration) may hold at once.
    pub background_renders: usize,
    /// Seconds between checks of the sources for new versions (0: never).
    pub check_interval_s: u64,
    /// Directory of the viewer's files, served at `/`.
    pub static_dir: PathBuf,
    /// Serve `/debug/tiles/{z}/{x}/{y}.geojson` (how a tile's elevations were settled), made
    /// in the render slots like a tile.
    pub debug_view: bool,
    /// Longest a client may take to send a request's head, and longest a kept-alive connection
    /// may stay idle, seconds.
    pub header_timeout_s: u64,
    /// Longest a client may take to send a request's body (admin requests), seconds.
    pub body_timeout_s: u64,
    /// Connections open at once; past it one more is answered `503` and closed. Bounded below
    /// the process's open-file limit.
    pub max_connections: usize,
    /// Longest the open connections are given to finish after the shutdown signal, seconds.
    pub shutdown_grace_s: u64,
}

impl Default for ServerConfig {
    fn default() -> Self {
        ServerConfig {
            listen: "127.0.0.1:8080".to_string(),
            zoom: 14,
            render_threads: 0,
            cors_origins: vec!["*".to_string()],
            cache_control: "public, max-age=86400".to_string(),
            render_queue: 64,
            render_timeout_ms: 120_000,
            render_memory_mib: 1024,
            admin_token: String::new(),
            background_renders: 1,
            check_interval_s: 300,
            static_dir: PathBuf::from("static"),
            debug_view: true,
            header_timeout_s: 10,
            body_timeout_s: 30,
            max_connections: 1024,
            shutdown_grace_s: 20,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct SourcesConfig {
    /// OSM extracts (`.osm.pbf`): local files, or `http(s)://` URLs downloaded once into
    /// `downloads` and checked for new versions with the other sources.
    pub osm: Vec<PathBuf>,
    /// The imported OSM store (SQLite): tiles read their data from it instead of holding the
    /// extracts in memory; imported from `osm` when missing or older than the extracts. None:
    /// the extracts are read into memory at start.
    pub store: Option<PathBuf>,
    /// An OSM replication source (a directory or URL with `state.txt` and `AAA/BBB/CCC.osc.gz`
    /// files) whose diffs are applied to the store every `server.check_interval_s`, resuming
    /// after the last applied. Empty: none.
    pub replication: String,
    /// Directory of SRTM files (`.hgt`, `.hgt.zip`).
    pub srtm: PathBuf,
    /// URL template of SRTM files the directory lacks, fetched when a tile needs one:
    /// `{lat}` (`N43`), `{lon}` (`E007`), `{name}` (`N43E007`), e.g.
    /// `https://example.org/srtm/{lat}{lon}.hgt.zip`. Empty: none.
    pub srtm_url: String,
    /// Where downloads go.
    pub downloads: PathBuf,
    /// Longest wait to connect, for a response to start, and between two reads, seconds.
    pub download_timeout_s: u64,
    /// Attempts after the first when a download fails in transit or with a 5xx.
    pub download_retries: u32,
    /// Wait before the first retry, milliseconds; doubled for each further one.
    pub download_backoff_ms: u64,
    /// How long a failed download is answered from memory before it is tried again, seconds.
    pub download_failure_memory_s: u64,
    /// Expected SHA-256 (hex) of downloaded files, by file name.
    pub checksums: std::collections::BTreeMap<String, String>,
}

impl Default for SourcesConfig {
    fn default() -> Self {
        SourcesConfig {
            osm: vec![PathBuf::from("data/monaco-osrm-2016.osm.pbf")],
            store: None,
            replication: String::new(),
            srtm: PathBuf::from("data"),
            srtm_url: String::new(),
            downloads: PathBuf::from("data/downloads"),
            download_timeout_s: 30,
            download_retries: 3,
            download_backoff_ms: 500,
            download_failure_memory_s: 60,
            checksums: std::collections::BTreeMap::new(),
        }
    }
}

/// The store `import` and `update` write when `sources.store` names none.
pub const DEFAULT_STORE: &str = "cache/osm.sqlite";

/// What `seed` makes when no format is named: the variants the bundled viewer
/// (`glb-meshopt`) and globe (`glb-enu-meshopt`) ask for, so a seeded region opens warm.
pub const SEED_FORMATS: [Format; 2] = [
    Format::Glb(Variant {
        frame: Frame::WebMercator,
        meshopt: true,
    }),
    Format::Glb(Variant {
        frame: Frame::EastNorthUp,
        meshopt: true,
    }),
];

/// What `export` writes when no format is named (an MBTiles file holds one).
pub const EXPORT_FORMATS: [Format; 1] = [Format::Glb(Variant {
    frame: Frame::WebMercator,
    meshopt: false,
})];

impl SourcesConfig {
    /// The store `import` and `update` write: the configured one, else [`DEFAULT_STORE`].
    pub fn store_to_write(&self) -> PathBuf {
        self.store
            .clone()
            .unwrap_or_else(|| PathBuf::from(DEFAULT_STORE))
    }

    /// The download settings.
    pub fn fetch_settings(&self) -> crate::source::fetch::FetchSettings {
        crate::source::fetch::FetchSettings {
            data_dir: self.downloads.clone(),
            timeout: std::time::Duration::from_secs(self.download_timeout_s.max(1)),
            retries: self.download_retries,
            backoff: std::time::Duration::from_millis(self.download_backoff_ms),
            failure_memory: std::time::Duration::from_secs(self.download_failure_memory_s),
            checksums: self.checksums.clone().into_iter().collect(),
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct CacheConfig {
    /// The SQLite file tiles are kept in (created with its directory if missing).
    pub path: PathBuf,
    /// A PostgreSQL database to keep the tiles in instead (`postgres://user:password@host/db`),
    /// shared by every process that names it; empty for the SQLite file.
    pub url: String,
    /// Memory for the in-process cache in front of the store, in MiB.
    pub memory_mib: u64,
    /// Largest size of the stored tiles, MiB; past it the least recently served go
    /// (0: no cap).
    pub max_size_mib: u64,
    /// With `url`: how long a process's claim on a tile it renders, or on queued work it took,
    /// lasts unrenewed, seconds; a process that dies lets its claims lapse after this long.
    pub lease_s: u64,
    /// Largest tile, uncompressed, MiB, that a store or an archive may give: one that would
    /// inflate past it is damaged and is not decompressed further.
    pub max_tile_mib: u64,
}

impl CacheConfig {
    /// [`CacheConfig::max_tile_mib`] in bytes.
    pub fn max_tile_bytes(&self) -> u64 {
        self.max_tile_mib.saturating_mul(1 << 20)
    }
}

impl Default for CacheConfig {
    fn default() -> Self {
        CacheConfig {
            path: PathBuf::from("cache/tiles.sqlite"),
            url: String::new(),
            memory_mib: 256,
            max_size_mib: 10240,
            lease_s: 15,
            max_tile_mib: 64,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct LogConfig {
    /// `text` (for people) or `json` (one object per line, for log collectors).
    pub format: LogFormat,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum LogFormat {
    #[default]
    Text,
    Json,
}

impl Default for LogConfig {
    fn default() -> Self {
        LogConfig {
            format: LogFormat::Text,
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("configuration file {0} does not exist")]
    Missing(PathBuf),
    #[error("invalid configuration: {0}")]
    Invalid(#[from] Box<figment::Error>),
    #[error("unknown configuration key {key} (from {source_name}){}", suggestion(.nearest))]
    Unknown {
        key: String,
        source_name: String,
        nearest: Option<String>,
    },
    #[error("configuration key {key} = {value}: {rule}")]
    OutOfRange {
        key: &'static str,
        value: String,
        rule: &'static str,
    },
}

fn suggestion(nearest: &Option<String>) -> String {
    nearest
        .as_ref()
        .map(|n| format!("; did you mean {n}?"))
        .unwrap_or_default()
}

impl Config {
    /// Loads defaults, the file (the default one if it exists, or `file`, which must exist)
    /// and the environment.
    pub fn load(file: Option<&Path>) -> Result<Config, ConfigError> {
        let mut figment = Figment::from(Serialized::defaults(Config::default()));
        match file {
            Some(path) if !path.exists() => return Err(ConfigError::Missing(path.to_path_buf())),
            Some(path) => figment = figment.merge(Toml::file(path)),
            None if Path::new(DEFAULT_CONFIG_FILE).exists() => {
                figment = figment.merge(Toml::file(DEFAULT_CONFIG_FILE))
            }
            None => {}
        }
        // Configuration variables name a section and a key (`__` between them); other
        // `TERRASTITCH_*` variables (a token for a command's flag) are not configuration.
        figment = figment.merge(
            Env::prefixed("TERRASTITCH_")
                .filter(|key| key.as_str().contains("__"))
                .split("__"),
        );
        unknown_keys(&figment)?;
        let config: Config = figment
            .extract()
            .map_err(|e| ConfigError::Invalid(Box::new(e)))?;
        config.validate()?;
        Ok(config)
    }

    /// Checks the values a typo or a slip can make meaningless.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let (server, mesh, features) = (&self.server, &self.render.mesh, &self.render.features);
        let checks: [(&'static str, String, bool, &'static str); 14] = [
            (
                "server.zoom",
                server.zoom.to_string(),
                (1..=20).contains(&server.zoom),
                "tiles are served at a zoom from 1 to 20",
            ),
            (
                "server.max_connections",
                server.max_connections.to_string(),
                server.max_connections >= 1,
                "at least one connection",
            ),
            (
                "server.header_timeout_s",
                server.header_timeout_s.to_string(),
                server.header_timeout_s >= 1,
                "at least one second",
            ),
            (
                "server.body_timeout_s",
                server.body_timeout_s.to_string(),
                server.body_timeout_s >= 1,
                "at least one second",
            ),
            (
                "cache.max_tile_mib",
                self.cache.max_tile_mib.to_string(),
                self.cache.max_tile_mib >= 1,
                "at least one MiB",
            ),
            (
                "render.mesh.sample_cells",
                mesh.sample_cells.to_string(),
                (2..=4096).contains(&mesh.sample_cells),
                "from 2 to 4096 cells along a tile's edge",
            ),
            (
                "render.mesh.max_error_m",
                mesh.max_error_m.to_string(),
                positive(mesh.max_error_m),
                "a finite number of metres above 0",
            ),
            (
                "render.mesh.feature_weight",
                mesh.feature_weight.to_string(),
                not_negative(mesh.feature_weight),
                "a finite number, 0 or more",
            ),
            (
                "render.mesh.feature_distance_m",
                mesh.feature_distance_m.to_string(),
                not_negative(mesh.feature_distance_m),
                "a finite number of metres, 0 or more",
            ),
            (
                "render.features.lane_width_m",
                features.lane_width_m.to_string(),
                positive(features.lane_width_m),
                "a finite number of metres above 0",
            ),
            (
                "render.features.level_height_m",
                features.level_height_m.to_string(),
                positive(features.level_height_m),
                "a finite number of metres above 0",
            ),
            (
                "render.features.default_building_height_m",
                features.default_building_height_m.to_string(),
                positive(features.default_building_height_m),
                "a finite number of metres above 0",
            ),
            (
                "render.features.longest_way_km",
                features.longest_way_km.to_string(),
                positive(features.longest_way_km),
                "a finite number of kilometres above 0",
            ),
            (
                "render.features.vegetation.forest_spacing_m",
                features.vegetation.forest_spacing_m.to_string(),
                positive(features.vegetation.forest_spacing_m)
                    && positive(features.vegetation.row_spacing_m),
                "tree spacings are finite numbers of metres above 0",
            ),
        ];
        match checks.into_iter().find(|check| !check.2) {
            Some((key, value, _, rule)) => Err(ConfigError::OutOfRange { key, value, rule }),
            None => Ok(()),
        }
    }
}

fn positive(value: f64) -> bool {
    value.is_finite() && value > 0.0
}

fn not_negative(value: f64) -> bool {
    value.is_finite() && value >= 0.0
}

/// Refuses a key the configuration does not have (a typo would otherwise leave the default in
/// place unseen), naming where it came from and the nearest known key.
fn unknown_keys(figment: &Figment) -> Result<(), ConfigError> {
    let known = serde_json::to_value(Config::default()).unwrap_or_default();
    let given: serde_json::Value = figment
        .extract()
        .map_err(|e| ConfigError::Invalid(Box::new(e)))?;
    match first_unknown(&known, &given, "") {
        None => Ok(()),
        Some((key, nearest)) => {
            let source_name = figment
                .find_metadata(&key)
                .map(|m| match &m.source {
                    Some(source) => format!("{} {source}", m.name),
                    None => m.name.to_string(),
                })
                .unwrap_or_else(|| "the configuration".to_string());
            Err(ConfigError::Unknown {
                key,
                source_name,
                nearest,
            })
        }
    }
}

/// The first key of `given` that `known` lacks (a map empty in `known`, as the checksums,
/// takes any key), with the nearest key `known` has at that place.
fn first_unknown(
    known: &serde_json::Value,
    given: &serde_json::Value,
    prefix: &str,
) -> Option<(String, Option<String>)> {
    let (serde_json::Value::Object(known), serde_json::Value::Object(given)) = (known, given)
    else {
        return None;
    };
    if known.is_empty() {
        return None;
    }
    for (key, value) in given {
        let path = format!("{prefix}{key}");
        match known.get(key) {
            Some(inner) => {
                if let Some(found) = first_unknown(inner, value, &format!("{path}.")) {
                    return Some(found);
                }
            }
            None => {
                let nearest = known
                    .keys()
                    .map(|k| (edit_distance(k, key), k))
                    .filter(|(d, k)| *d <= k.len().max(key.len()) / 2)
                    .min()
                    .map(|(_, k)| format!("{prefix}{k}"));
                return Some((path, nearest));
            }
        }
    }
    None
}

/// Levenshtein distance between two keys.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diagonal = row[0];
        row[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let above = row[j + 1];
            row[j + 1] = (above + 1)
                .min(row[j] + 1)
                .min(diagonal + usize::from(ca != cb));
            diagonal = above;
        }
    }
    row[b.len()]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shipped_default_file_matches_the_built_in_defaults() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(DEFAULT_CONFIG_FILE);
        let from_file: Config = Figment::from(Serialized::defaults(Config::default()))
            .merge(Toml::file(&path))
            .extract()
            .unwrap();
        assert_eq!(from_file, Config::default());
    }

    fn load_text(text: &str) -> Result<Config, ConfigError> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.toml");
        std::fs::write(&path, text).unwrap();
        Config::load(Some(&path))
    }

    #[test]
    fn an_unknown_key_is_refused_with_the_nearest_known_one() {
        for (text, key, nearest) in [
            (
                "[server]\nlistn = \"0.0.0.0:80\"\n",
                "server.listn",
                Some("server.listen"),
            ),
            ("[cahce]\npath = \"x\"\n", "cahce", Some("cache")),
            (
                "[render.mesh]\nmax_eror_m = 2.0\n",
                "render.mesh.max_eror_m",
                Some("render.mesh.max_error_m"),
            ),
            ("[server]\nzzzzzzzz = 1\n", "server.zzzzzzzz", None),
        ] {
            match load_text(text) {
                Err(ConfigError::Unknown {
                    key: k, nearest: n, ..
                }) => {
                    assert_eq!(k, key);
                    assert_eq!(n.as_deref(), nearest);
                }
                other => panic!("{text}: {other:?}"),
            }
        }
        // A checksum may name any file.
        let config = load_text("[sources.checksums]\n\"N43E007.hgt.zip\" = \"ab\"\n").unwrap();
        assert_eq!(config.sources.checksums.len(), 1);
    }

    #[test]
    fn values_out_of_their_range_are_refused() {
        for (text, key) in [
            ("[server]\nzoom = 40\n", "server.zoom"),
            (
                "[render.mesh]\nmax_error_m = nan\n",
                "render.mesh.max_error_m",
            ),
            (
                "[render.mesh]\nfeature_weight = -1.0\n",
                "render.mesh.feature_weight",
            ),
            (
                "[render.features.vegetation]\nrow_spacing_m = 0.0\n",
                "render.features.vegetation.forest_spacing_m",
            ),
        ] {
            match load_text(text) {
                Err(ConfigError::OutOfRange { key: k, .. }) => assert_eq!(k, key, "{text}"),
                other => panic!("{text}: {other:?}"),
            }
        }
    }

    #[test]
    fn a_missing_named_file_is_an_error() {
        let error = Config::load(Some(Path::new("/nonexistent/terrastitch.toml"))).unwrap_err();
        assert!(error.to_string().contains("/nonexistent/terrastitch.toml"));
    }
}
