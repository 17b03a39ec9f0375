//! Downloading source files: OSM extracts from their URLs and SRTM files from a URL template,
//! into the data directory.
//!
//! A download streams to a temporary file beside its destination, is checked (the length the
//! server announced, the SHA-256 where the configuration gives one) and only then renamed into
//! place, so a crash never leaves a half file under the real name. Each file has one download
//! at a time: callers that need a file being downloaded wait for that download instead of
//! starting their own, and a failure is remembered for a while, so a burst of requests for a
//! missing file causes one request upstream. Transfer failures, `5xx` and `429` are retried with
//! exponential backoff; other statuses are final.
//!
//! Only URLs from the configuration reach this module; nothing from a request does.

use std::collections::HashMap;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use sha2::Digest;

/// The longest wait between two attempts.
const MAX_BACKOFF: Duration = Duration::from_secs(30);

/// How downloads behave.
#[derive(Debug, Clone, PartialEq)]
pub struct FetchSettings {
    /// Where downloaded files go.
    pub data_dir: PathBuf,
    /// Longest wait to connect, for the response to start, and between two reads of its body.
    pub timeout: Duration,
    /// Attempts after the first.
    pub retries: u32,
    /// Wait before the first retry; doubled for each one after it.
    pub backoff: Duration,
    /// How long a failed download is remembered (and answered from) before it is tried again.
    pub failure_memory: Duration,
    /// Expected SHA-256 (hex) of files, by file name.
    pub checksums: HashMap<String, String>,
}

/// Why a file could not be had.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FetchError {
    #[error("{status} for {name} from the configured {source_name} source ({url})")]
    Status {
        status: u16,
        name: String,
        source_name: String,
        url: String,
    },
    #[error("{name} from the configured {source_name} source ({url}) failed after {attempts} attempts: {message}")]
    Transfer {
        name: String,
        source_name: String,
        url: String,
        attempts: u32,
        message: String,
    },
    #[error("{name} from the configured {source_name} source has SHA-256 {actual}, not the configured {expected}")]
    Checksum {
        name: String,
        source_name: String,
        expected: String,
        actual: String,
    },
    #[error("cannot store {path}: {message}")]
    Io { path: PathBuf, message: String },
    #[error("{name} from the configured {source_name} source ({url}) is longer than the {max_bytes} bytes such a file may have")]
    TooLarge {
        name: String,
        source_name: String,
        url: String,
        max_bytes: u64,
    },
}

impl FetchError {
    /// The upstream said the file does not exist.
    pub fn is_not_found(&self) -> bool {
        matches!(
            self,
            FetchError::Status {
                status: 404 | 410,
                ..
            }
        )
    }
}

/// One file to download.
#[derive(Debug, Clone, Copy)]
pub struct Download<'a> {
    pub url: &'a str,
    /// The file name in the data directory (and in the checksum table).
    pub name: &'a str,
    /// Which configured source it is from, for messages: `OSM`, `SRTM`.
    pub source_name: &'a str,
    /// The most bytes the file may have, when its kind bounds it (an SRTM file, a state file);
    /// a longer body is refused as it arrives, not stored.
    pub max_bytes: Option<u64>,
}

/// Counters of what the fetcher did.
#[derive(Debug, Default)]
pub struct FetchStats {
    /// Files downloaded whole and put in place.
    pub downloads: AtomicU64,
    /// Downloads that failed (after their retries).
    pub failures: AtomicU64,
    /// HTTP requests sent, retries included.
    pub requests: AtomicU64,
    pub bytes: AtomicU64,
}

/// The validators of a downloaded file, kept beside it to ask the server whether it changed.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize, PartialEq, Eq)]
struct Validators {
    etag: Option<String>,
    last_modified: Option<String>,
}

/// The outcome of one attempt.
enum Attempt {
    Done(PathBuf),
    /// `304 Not Modified`.
    Unchanged,
    Retry(String),
    Fail(FetchError),
}

pub struct Fetcher {
    agent: ureq::Agent,
    settings: FetchSettings,
    /// One lock per file name: one download at a time.
    locks: Mutex<HashMap<String, Arc<Mutex<()>>>>,
    /// Failed downloads and when they failed.
    failures: Mutex<HashMap<String, (Instant, FetchError)>>,
    pub stats: FetchStats,
}

impl std::fmt::Debug for Fetcher {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Fetcher")
            .field("settings", &self.settings)
            .finish()
    }
}

impl Fetcher {
    pub fn new(settings: FetchSettings) -> Fetcher {
        let config = ureq::Agent::config_builder()
            .timeout_connect(Some(settings.timeout))
            .timeout_recv_response(Some(settings.timeout))
            .timeout_per_read(Some(settings.timeout))
            .http_status_as_error(false)
            .user_agent(concat!("terrastitch/", env!("CARGO_PKG_VERSION")))
            .build();
        Fetcher {
            agent: config.new_agent(),
            settings,
            locks: Mutex::new(HashMap::new()),
            failures: Mutex::new(HashMap::new()),
            stats: FetchStats::default(),
        }
    }

    pub fn settings(&self) -> &FetchSettings {
        &self.settings
    }

    /// Where a file of this name is kept.
    pub fn path_of(&self, name: &str) -> PathBuf {
        self.settings.data_dir.join(name)
    }

    fn lock_for(&self, name: &str) -> Arc<Mutex<()>> {
        self.locks
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .entry(name.to_string())
            .or_default()
            .clone()
    }

    /// The file, downloaded if the data directory does not have it yet.
    pub fn fetch(&self, download: &Download<'_>) -> Result<PathBuf, FetchError> {
        let path = self.path_of(download.name);
        if path.exists() {
            return Ok(path);
        }
        let lock = self.lock_for(download.name);
        let _one_at_a_time = lock.lock().unwrap_or_else(|p| p.into_inner());
        // Whoever held the lock before may have brought it, or failed to.
        if path.exists() {
            return Ok(path);
        }
        if let Some(error) = self.remembered_failure(download.name) {
            return Err(error);
        }
        match self.download(download, None) {
            Ok(Some(path)) => Ok(path),
            Ok(None) => Err(FetchError::Transfer {
                name: download.name.to_string(),
                source_name: download.source_name.to_string(),
                url: download.url.to_string(),
                attempts: 1,
                message: "the server answered 304 to a request without validators".to_string(),
            }),
            Err(error) => {
                self.remember_failure(download.name, error.clone());
                Err(error)
            }
        }
    }

    /// Asks the server whether a downloaded file changed (with its `ETag` / `Last-Modified`)
    /// and downloads the new version if so. Returns whether the file changed.
    pub fn refresh(&self, download: &Download<'_>) -> Result<bool, FetchError> {
        let lock = self.lock_for(download.name);
        let _one_at_a_time = lock.lock().unwrap_or_else(|p| p.into_inner());
        let path = self.path_of(download.name);
        let validators = read_validators(&path).unwrap_or_default();
        let before = file_digest(&path);
        Ok(self
            .download(download, Some((&validators, before.as_deref())))?
            .is_some())
    }

    /// Remembers that a file could not be had (a download that arrived whole but turned out
    /// unusable), so it is not asked for again before the failure memory runs out.
    pub fn remember_failure(&self, name: &str, error: FetchError) {
        self.failures
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .insert(name.to_string(), (Instant::now(), error));
    }

    fn remembered_failure(&self, name: &str) -> Option<FetchError> {
        let mut failures = self.failures.lock().unwrap_or_else(|p| p.into_inner());
        match failures.get(name) {
            Some((at, error)) if at.elapsed() < self.settings.failure_memory => Some(error.clone()),
            Some(_) => {
                failures.remove(name);
                None
            }
            None => None,
        }
    }

    /// Downloads with retries; `None` when the server says the file did not change, or sends
    /// the same bytes again. `current` holds the validators and digest of the file held.
    fn download(
        &self,
        download: &Download<'_>,
        current: Option<(&Validators, Option<&[u8]>)>,
    ) -> Result<Option<PathBuf>, FetchError> {
        let attempts = self.settings.retries + 1;
        let mut last = String::new();
        for attempt in 0..attempts {
            if attempt > 0 {
                let wait =
                    (self.settings.backoff * 2u32.saturating_pow(attempt - 1)).min(MAX_BACKOFF);
                tracing::info!(name = download.name, attempt, error = %last, ?wait, "download failed; retrying");
                std::thread::sleep(wait);
            }
            match self.attempt(download, current) {
                Attempt::Done(path) => {
                    self.stats.downloads.fetch_add(1, Ordering::Relaxed);
                    tracing::info!(name = download.name, url = download.url, "downloaded");
                    return Ok(Some(path));
                }
                Attempt::Unchanged => return Ok(None),
                Attempt::Retry(message) => last = message,
                Attempt::Fail(error) => {
                    self.stats.failures.fetch_add(1, Ordering::Relaxed);
                    tracing::warn!(%error, "download failed");
                    return Err(error);
                }
            }
        }
        self.stats.failures.fetch_add(1, Ordering::Relaxed);
        let error = FetchError::Transfer {
            name: download.name.to_string(),
            source_name: download.source_name.to_string(),
            url: download.url.to_string(),
            attempts,
            message: last,
        };
        tracing::warn!(%error, "download failed");
        Err(error)
    }

    fn attempt(
        &self,
        download: &Download<'_>,
        current: Option<(&Validators, Option<&[u8]>)>,
    ) -> Attempt {
        self.stats.requests.fetch_add(1, Ordering::Relaxed);
        let mut request = self.agent.get(download.url);
        if let Some((v, _)) = current {
            if let Some(etag) = &v.etag {
                request = request.header("If-None-Match", etag);
            }
            if let Some(modified) = &v.last_modified {
                request = request.header("If-Modified-Since", modified);
            }
        }
        let mut response = match request.call() {
            Ok(response) => response,
            Err(error) => return Attempt::Retry(error.to_string()),
        };
        let status = response.status().as_u16();
        if status == 304 && current.is_some() {
            return Attempt::Unchanged;
        }
        if status == 429 || status >= 500 {
            return Attempt::Retry(format!("the server answered {status}"));
        }
        if status != 200 {
            return Attempt::Fail(FetchError::Status {
                status,
                name: download.name.to_string(),
                source_name: download.source_name.to_string(),
                url: download.url.to_string(),
            });
        }
        let header = |name: &str| {
            response
                .headers()
                .get(name)
                .and_then(|v| v.to_str().ok())
                .map(str::to_string)
        };
        let announced: Option<u64> = header("content-length").and_then(|v| v.parse().ok());
        let too_large = || {
            Attempt::Fail(FetchError::TooLarge {
                name: download.name.to_string(),
                source_name: download.source_name.to_string(),
                url: download.url.to_string(),
                max_bytes: download.max_bytes.unwrap_or(u64::MAX),
            })
        };
        let over = |bytes: u64| download.max_bytes.is_some_and(|max| bytes > max);
        if announced.is_some_and(over) {
            return too_large();
        }
        let fresh = Validators {
            etag: header("etag"),
            last_modified: header("last-modified"),
        };
        let path = self.path_of(download.name);
        let partial = partial_path(&path);
        let io = |e: std::io::Error| {
            Attempt::Fail(FetchError::Io {
                path: path.clone(),
                message: e.to_string(),
            })
        };
        if let Err(e) = std::fs::create_dir_all(&self.settings.data_dir) {
            return io(e);
        }
        let mut file = match std::fs::File::create(&partial) {
            Ok(file) => file,
            Err(e) => return io(e),
        };
        let mut digest = sha2::Sha256::new();
        let mut received: u64 = 0;
        let mut reader = response.body_mut().as_reader();
        let mut buffer = vec![0u8; 1 << 16];
        loop {
            let n = match reader.read(&mut buffer) {
                Ok(0) => break,
                Ok(n) => n,
                Err(e) => {
                    let _ = std::fs::remove_file(&partial);
                    return Attempt::Retry(format!("after {received} bytes: {e}"));
                }
            };
            digest.update(&buffer[..n]);
            received += n as u64;
            if over(received) {
                let _ = std::fs::remove_file(&partial);
                return too_large();
            }
            self.stats.bytes.fetch_add(n as u64, Ordering::Relaxed);
            if let Err(e) = file.write_all(&buffer[..n]) {
                let _ = std::fs::remove_file(&partial);
                return io(e);
            }
        }
        if let Some(announced) = announced.filter(|&a| a != received) {
            let _ = std::fs::remove_file(&partial);
            return Attempt::Retry(format!(
                "the body ended after {received} of {announced} bytes"
            ));
        }
        let digest = digest.finalize();
        if current.is_some_and(|(_, held)| held == Some(&digest[..])) {
            // The same bytes again: the file held stays as it is.
            let _ = std::fs::remove_file(&partial);
            write_validators(&path, &fresh);
            return Attempt::Unchanged;
        }
        let actual: String = digest.iter().map(|b| format!("{b:02x}")).collect();
        if let Some(expected) = self.settings.checksums.get(download.name) {
            if !expected.eq_ignore_ascii_case(&actual) {
                let _ = std::fs::remove_file(&partial);
                return Attempt::Fail(FetchError::Checksum {
                    name: download.name.to_string(),
                    source_name: download.source_name.to_string(),
                    expected: expected.clone(),
                    actual,
                });
            }
        }
        if let Err(e) = file.sync_all() {
            let _ = std::fs::remove_file(&partial);
            return io(e);
        }
        drop(file);
        if let Err(e) = std::fs::rename(&partial, &path) {
            let _ = std::fs::remove_file(&partial);
            return io(e);
        }
        write_validators(&path, &fresh);
        Attempt::Done(path)
    }
}

/// Where a file is written before it is whole.
fn partial_path(path: &Path) -> PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(format!(".partial-{}", std::process::id()));
    path.with_file_name(name)
}

fn validators_path(path: &Path) -> PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(".validators.json");
    path.with_file_name(name)
}

fn read_validators(path: &Path) -> Option<Validators> {
    let text = std::fs::read(validators_path(path)).ok()?;
    serde_json::from_slice(&text).ok()
}

fn write_validators(path: &Path, validators: &Validators) {
    if let Ok(json) = serde_json::to_vec(validators) {
        let target = validators_path(path);
        let partial = partial_path(&target);
        if std::fs::write(&partial, json).is_ok() {
            let _ = std::fs::rename(&partial, &target);
        }
    }
}

fn file_digest(path: &Path) -> Option<Vec<u8>> {
    let mut file = std::fs::File::open(path).ok()?;
    let mut digest = sha2::Sha256::new();
    let mut buffer = vec![0u8; 1 << 16];
    loop {
        let n = file.read(&mut buffer).ok()?;
        if n == 0 {
            break;
        }
        digest.update(&buffer[..n]);
    }
    Some(digest.finalize().to_vec())
}

/// The file name a URL points at (its last path segment, without query or fragment).
pub fn file_name_of(url: &str) -> Option<String> {
    let path = url.split(['?', '#']).next()?;
    let name = path.rsplit('/').next()?;
    let safe = !name.is_empty()
        && name != "."
        && name != ".."
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '.' | '-' | '_'));
    safe.then(|| name.to_string())
}

/// True for the URLs the fetcher downloads (`http://` and `https://`).
pub fn is_url(text: &str) -> bool {
    text.starts_with("http://") || text.starts_with("https://")
}

/// The URL and file name of an SRTM cell from a template with `{lat}` (`N43`), `{lon}`
/// (`E007`) or `{name}` (`N43E007`), e.g. `https://example.org/srtm/{lat}{lon}.hgt.zip`.
/// The file is named after the cell, whatever the URL calls it (`N43E007.SRTMGL1.hgt.zip`,
/// `…/N43/E007.hgt`): `N43E007.hgt.zip` when the URL names a zip file, `N43E007.hgt.gz` a
/// gzip file, else `N43E007.hgt`.
pub fn srtm_download(template: &str, cell_name: &str) -> (String, String) {
    let (lat, lon) = cell_name.split_at(3.min(cell_name.len()));
    let url = template
        .replace("{name}", cell_name)
        .replace("{lat}", lat)
        .replace("{lon}", lon);
    let path = url.split(['?', '#']).next().unwrap_or("");
    let lower = path.to_ascii_lowercase();
    let packed = if lower.ends_with(".zip") {
        ".zip"
    } else if lower.ends_with(".gz") {
        ".gz"
    } else {
        ""
    };
    let name = format!("{cell_name}.hgt{packed}");
    (url, name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_come_from_the_last_segment_and_stay_inside_the_directory() {
        assert_eq!(
            file_name_of("https://a.org/x/monaco-latest.osm.pbf?x=1").as_deref(),
            Some("monaco-latest.osm.pbf")
        );
        assert_eq!(file_name_of("https://a.org/x/"), None);
        assert_eq!(file_name_of("https://a.org/x/.."), None);
        let (url, name) = srtm_download("http://h/srtm/{lat}/{lat}{lon}.hgt.zip", "N43E007");
        assert_eq!(url, "http://h/srtm/N43/N43E007.hgt.zip");
        assert_eq!(name, "N43E007.hgt.zip");
        // Named after the cell, whatever the URL calls the file.
        let (_, name) = srtm_download("http://h/{lat}/{lon}.hgt", "S12W071");
        assert_eq!(name, "S12W071.hgt");
        let (_, name) = srtm_download("https://m/skadi/{lat}/{name}.hgt.gz", "N43E007");
        assert_eq!(name, "N43E007.hgt.gz");
        let (_, name) = srtm_download("http://h/{name}.SRTMGL1.hgt.ZIP?x=1", "N43E007");
        assert_eq!(name, "N43E007.hgt.zip");
    }
}
