//! The flags that override the configuration, and the one place they are merged into it: a
//! flag given wins over the configuration file and the environment; a flag left out leaves
//! the configured value.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

use crate::config::Config;

/// Where the data comes from; every command takes these.
#[derive(Args, Debug, Clone, Default)]
pub struct SourceArgs {
    /// Configuration file [default: config/default.toml if it exists]
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// OSM extract (.osm.pbf); repeat for several [default: data/monaco-osrm-2016.osm.pbf]
    #[arg(long = "osm", value_name = "FILE")]
    pub osm: Vec<PathBuf>,
    /// Directory of SRTM .hgt, .hgt.zip or .hgt.gz files [default: data]
    #[arg(long, value_name = "DIR")]
    pub srtm: Option<PathBuf>,
    /// The imported OSM store to read (imported when missing or older than the extracts)
    /// [default: none, the extracts are read into memory]
    #[arg(long, value_name = "FILE")]
    pub store: Option<PathBuf>,
}

impl SourceArgs {
    /// These flags alone.
    pub fn flags(&self) -> Flags {
        Flags {
            config: self.config.clone(),
            osm: self.osm.clone(),
            srtm: self.srtm.clone(),
            store: self.store.clone(),
            ..Flags::default()
        }
    }
}

/// Every flag that overrides a configured value; `None` (or empty) where not given.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Flags {
    /// The configuration file.
    pub config: Option<PathBuf>,
    /// `sources.osm`.
    pub osm: Vec<PathBuf>,
    /// `sources.srtm`.
    pub srtm: Option<PathBuf>,
    /// `sources.store`.
    pub store: Option<PathBuf>,
    /// `sources.replication`.
    pub replication: Option<String>,
    /// `server.listen`.
    pub listen: Option<String>,
    /// `cache.path`.
    pub cache: Option<PathBuf>,
    /// `cache.url`.
    pub cache_url: Option<String>,
}

/// The configuration a command runs with: the file (or the default one) and the environment,
/// with the flags over them, checked.
pub fn configuration(flags: &Flags) -> Result<Config> {
    let mut config = Config::load(flags.config.as_deref())?;
    merge_into_config(flags, &mut config);
    config.validate()?;
    Ok(config)
}

/// Sets every configured value a flag was given for.
pub fn merge_into_config(flags: &Flags, config: &mut Config) {
    if !flags.osm.is_empty() {
        config.sources.osm = flags.osm.clone();
    }
    if let Some(srtm) = &flags.srtm {
        config.sources.srtm = srtm.clone();
    }
    if let Some(store) = &flags.store {
        config.sources.store = Some(store.clone());
    }
    if let Some(replication) = &flags.replication {
        config.sources.replication = replication.clone();
    }
    if let Some(listen) = &flags.listen {
        config.server.listen = listen.clone();
    }
    if let Some(cache) = &flags.cache {
        config.cache.path = cache.clone();
    }
    if let Some(url) = &flags.cache_url {
        config.cache.url = url.clone();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_flag_leaves_the_configuration_as_it_was() {
        let mut config = Config::default();
        config.sources.osm = vec!["a.osm.pbf".into()];
        config.cache.url = "postgres://tiles@db/tiles".into();
        let before = config.clone();
        merge_into_config(&Flags::default(), &mut config);
        assert_eq!(config, before);
    }

    #[test]
    fn each_flag_given_wins_over_its_configured_value() {
        let mut config = Config::default();
        config.sources.store = Some("configured.sqlite".into());
        let flags = Flags {
            config: None,
            osm: vec!["x.osm.pbf".into(), "y.osm.pbf".into()],
            srtm: Some("dem".into()),
            store: Some("flagged.sqlite".into()),
            replication: Some("https://example.org/minute".into()),
            listen: Some("0.0.0.0:9000".into()),
            cache: Some("tiles.sqlite".into()),
            cache_url: Some("postgres://a@b/c".into()),
        };
        merge_into_config(&flags, &mut config);
        let osm: Vec<PathBuf> = vec!["x.osm.pbf".into(), "y.osm.pbf".into()];
        assert_eq!(config.sources.osm, osm);
        assert_eq!(config.sources.srtm, PathBuf::from("dem"));
        assert_eq!(config.sources.store, Some("flagged.sqlite".into()));
        assert_eq!(config.sources.replication, "https://example.org/minute");
        assert_eq!(config.server.listen, "0.0.0.0:9000");
        assert_eq!(config.cache.path, PathBuf::from("tiles.sqlite"));
        assert_eq!(config.cache.url, "postgres://a@b/c");
    }

    #[test]
    fn a_flag_left_out_keeps_the_configured_value_beside_one_given() {
        let mut config = Config::default();
        config.server.listen = "127.0.0.1:7000".into();
        config.cache.url = "postgres://configured@db/tiles".into();
        let flags = Flags {
            cache: Some("elsewhere.sqlite".into()),
            ..Flags::default()
        };
        merge_into_config(&flags, &mut config);
        assert_eq!(config.server.listen, "127.0.0.1:7000");
        assert_eq!(config.cache.url, "postgres://configured@db/tiles");
        assert_eq!(config.cache.path, PathBuf::from("elsewhere.sqlite"));
    }

    #[test]
    fn a_missing_configuration_file_named_by_a_flag_is_an_error() {
        let flags = Flags {
            config: Some("/nonexistent/terrastitch.toml".into()),
            ..Flags::default()
        };
        assert!(configuration(&flags).is_err());
    }
}
