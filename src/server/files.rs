//! The viewer's files, served at `/` from `server.static_dir`: `GET` and `HEAD` only, never a
//! dotfile, never a file a symbolic link leads to outside the directory.

use std::path::{Component, Path, PathBuf};

use axum::extract::{Request, State};
use axum::http::{header, HeaderValue, Method, StatusCode};
use axum::response::{IntoResponse, Response};
use tower::ServiceExt;

use super::error::ApiError;
use super::AppState;

pub async fn serve(State(state): State<AppState>, request: Request) -> Response {
    let dir = &state.http.static_dir;
    let path = request.uri().path().to_string();
    let Some(file) = inside(dir, &path) else {
        return not_found(&path);
    };
    if request.method() != Method::GET && request.method() != Method::HEAD {
        if file.exists() {
            let mut response = ApiError::new(
                StatusCode::METHOD_NOT_ALLOWED,
                format!(
                    "{} is not allowed on {path}: files are read with GET",
                    request.method()
                ),
            )
            .into_response();
            response
                .headers_mut()
                .insert(header::ALLOW, HeaderValue::from_static("GET, HEAD"));
            return response;
        }
        return not_found(&path);
    }
    let files = tower_http::services::ServeDir::new(dir).append_index_html_on_directories(true);
    match files.oneshot(request).await {
        Ok(response) if response.status() == StatusCode::NOT_FOUND => not_found(&path),
        Ok(response) => response.into_response(),
        Err(error) => {
            ApiError::internal(format!("{path} could not be read: {error}")).into_response()
        }
    }
}

fn not_found(path: &str) -> Response {
    ApiError::not_found(format!("no route or file for {path}")).into_response()
}

/// The file `path` (a URL path) names under `dir` when it may be served: no segment a dotfile
/// or `..`, and where it exists, its real place (links followed) still under `dir`.
fn inside(dir: &Path, path: &str) -> Option<PathBuf> {
    // Checked as the file server will read it: percent-decoded (`%2e` is a dot).
    let decoded = percent_decoded(path.trim_start_matches('/'))?;
    let relative = Path::new(&decoded);
    let mut file = dir.to_path_buf();
    for component in relative.components() {
        match component {
            Component::Normal(name) if !name.to_string_lossy().starts_with('.') => {
                file.push(name);
            }
            Component::CurDir => {}
            _ => return None,
        }
    }
    match (std::fs::canonicalize(&file), std::fs::canonicalize(dir)) {
        (Ok(real), Ok(root)) if !real.starts_with(&root) => None,
        _ => Some(file),
    }
}

/// `text` with its `%XX` escapes decoded; `None` when one is malformed.
fn percent_decoded(text: &str) -> Option<std::ffi::OsString> {
    use std::os::unix::ffi::OsStringExt;
    let bytes = text.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = std::str::from_utf8(bytes.get(i + 1..i + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    Some(std::ffi::OsString::from_vec(out))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dotfiles_parents_and_links_out_of_the_directory_are_not_served() {
        let root = tempfile::tempdir().unwrap();
        let dir = root.path().join("static");
        std::fs::create_dir(&dir).unwrap();
        std::fs::write(dir.join("index.html"), "<html>").unwrap();
        std::fs::write(dir.join(".env"), "secret").unwrap();
        std::fs::write(root.path().join("outside.txt"), "secret").unwrap();
        std::os::unix::fs::symlink(root.path().join("outside.txt"), dir.join("link.txt")).unwrap();
        std::os::unix::fs::symlink(dir.join("index.html"), dir.join("home.html")).unwrap();
        assert!(inside(&dir, "/index.html").is_some());
        assert!(
            inside(&dir, "/home.html").is_some(),
            "a link within is served"
        );
        assert!(
            inside(&dir, "/missing.html").is_some(),
            "a missing file is a 404 later"
        );
        for refused in [
            "/.env",
            "/%2eenv",
            "/link.txt",
            "/link%2etxt",
            "/%2e%2e/outside.txt",
            "/bad%zz",
            "/../outside.txt",
            "/a/../../outside.txt",
        ] {
            assert!(inside(&dir, refused).is_none(), "{refused}");
        }
    }
}
