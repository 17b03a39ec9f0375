//! OSM replication sources: a directory, local or at an `http(s)://` URL, with `state.txt`
//! (`sequenceNumber=`, `timestamp=`) and the change file of each sequence number at
//! `AAA/BBB/CCC.osc.gz` (sequence AAABBBCCC), as planet.openstreetmap.org and Geofabrik
//! publish them. Downloaded change files are kept in the downloads directory: they never
//! change.

use std::path::{Path, PathBuf};

use super::fetch::{Download, FetchError, Fetcher};

/// The most bytes a replication source's `state.txt` may have (it holds two short lines).
const STATE_FILE_MAX_BYTES: u64 = 64 * 1024;

#[derive(Debug, thiserror::Error)]
pub enum ReplicationError {
    #[error(transparent)]
    Fetch(#[from] FetchError),
    #[error("replication source {base}: cannot read {path}: {source}")]
    Io {
        base: String,
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("replication source {base}: its state.txt {why}")]
    State { base: String, why: String },
}

/// Where a replication source stands.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct State {
    pub sequence: u64,
    pub timestamp: Option<String>,
}

/// Reads a `state.txt`; its timestamp's escaped colons (`\:`) are unescaped. What is wrong
/// with one that gives no sequence, said after "its state.txt".
pub fn parse_state(text: &str) -> Result<State, String> {
    let mut sequence = None;
    let mut timestamp = None;
    for line in text.lines() {
        let line = line.trim();
        if let Some(value) = line.strip_prefix("sequenceNumber=") {
            let value = value.trim();
            let number = value
                .parse()
                .map_err(|_| format!("says sequenceNumber={value}, which is not a whole number"))?;
            sequence = Some(number);
        } else if let Some(value) = line.strip_prefix("timestamp=") {
            timestamp = Some(value.trim().replace("\\:", ":"));
        }
    }
    Ok(State {
        sequence: sequence.ok_or("has no sequenceNumber")?,
        timestamp,
    })
}

/// The path of a sequence's change file in the directory: `000/001/234.osc.gz`.
pub fn diff_path(sequence: u64) -> String {
    format!(
        "{:03}/{:03}/{:03}.osc.gz",
        sequence / 1_000_000,
        (sequence / 1000) % 1000,
        sequence % 1000
    )
}

/// A replication source.
#[derive(Debug, Clone)]
pub struct Replication {
    base: String,
}

impl Replication {
    /// The source at `base`: an `http(s)://` URL, a `file://` URL or a directory.
    pub fn new(base: &str) -> Replication {
        Replication {
            base: base.trim_end_matches('/').to_string(),
        }
    }

    pub fn base(&self) -> &str {
        &self.base
    }

    fn local(&self) -> Option<PathBuf> {
        if super::fetch::is_url(&self.base) {
            return None;
        }
        let path = self.base.strip_prefix("file://").unwrap_or(&self.base);
        Some(PathBuf::from(path))
    }

    /// The name downloads of this source are kept under: its own per base.
    fn download_name(&self, file: &str) -> String {
        use sha2::Digest;
        let digest = sha2::Sha256::digest(self.base.as_bytes());
        let tag: String = digest[..6].iter().map(|b| format!("{b:02x}")).collect();
        format!("replication-{tag}-{}", file.replace('/', "-"))
    }

    /// Where the source stands now.
    pub fn state(&self, fetcher: &Fetcher) -> Result<State, ReplicationError> {
        let path = match self.local() {
            Some(dir) => dir.join("state.txt"),
            None => {
                let url = format!("{}/state.txt", self.base);
                let name = self.download_name("state.txt");
                let download = Download {
                    url: &url,
                    name: &name,
                    source_name: "OSM replication",
                    max_bytes: Some(STATE_FILE_MAX_BYTES),
                };
                if fetcher.path_of(&name).exists() {
                    fetcher.refresh(&download)?;
                    fetcher.path_of(&name)
                } else {
                    fetcher.fetch(&download)?
                }
            }
        };
        let text = self.read(&path)?;
        parse_state(&String::from_utf8_lossy(&text)).map_err(|why| ReplicationError::State {
            base: self.base.clone(),
            why,
        })
    }

    /// The change file of `sequence`, as a local path, with the name errors give it.
    pub fn diff(
        &self,
        fetcher: &Fetcher,
        sequence: u64,
    ) -> Result<(PathBuf, String), ReplicationError> {
        let relative = diff_path(sequence);
        match self.local() {
            Some(dir) => {
                let path = dir.join(&relative);
                let name = path.display().to_string();
                Ok((path, name))
            }
            None => {
                let url = format!("{}/{relative}", self.base);
                let name = self.download_name(&relative);
                let path = fetcher.fetch(&Download {
                    url: &url,
                    name: &name,
                    source_name: "OSM replication",
                    max_bytes: None,
                })?;
                Ok((path, url))
            }
        }
    }

    fn read(&self, path: &Path) -> Result<Vec<u8>, ReplicationError> {
        std::fs::read(path).map_err(|source| ReplicationError::Io {
            base: self.base.clone(),
            path: path.to_path_buf(),
            source,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_state_file_gives_its_sequence_and_time() {
        let state = parse_state(
            "#Sat Jan 01 00:00:00 UTC 2030\nsequenceNumber=4321\ntimestamp=2030-01-01T00\\:00\\:00Z\n",
        )
        .unwrap();
        assert_eq!(state.sequence, 4321);
        assert_eq!(state.timestamp.as_deref(), Some("2030-01-01T00:00:00Z"));
        assert_eq!(
            parse_state("timestamp=2030-01-01T00\\:00\\:00Z"),
            Err("has no sequenceNumber".to_string())
        );
        let error = parse_state("sequenceNumber=abc\n").unwrap_err();
        assert_eq!(
            error,
            "says sequenceNumber=abc, which is not a whole number"
        );
    }

    #[test]
    fn a_sequence_names_its_file_in_three_levels() {
        assert_eq!(diff_path(4_321), "000/004/321.osc.gz");
        assert_eq!(diff_path(6_123_456), "006/123/456.osc.gz");
    }
}
