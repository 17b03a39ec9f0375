//! Accepting connections with bounds a public server needs: a client gets so long to send a
//! request's head (and an idle kept-alive connection is closed after as long), so many
//! connections are open at once (past that, one more is answered `503` and closed at once, never
//! left hanging), and after the shutdown signal the connections get a grace period to finish
//! before whatever is left is closed.
//!
//! A request hyper cannot read (a URI past its 64 KiB, too many or too large header fields, a
//! request line that is not ASCII) never reaches the routes: hyper answers it itself, with a
//! status and an empty body, and closes. [`JsonErrors`] gives those answers a JSON body like
//! every other error's.

use std::future::Future;
use std::pin::Pin;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::task::{Context, Poll};
use std::time::Duration;

use axum::Router;
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::service::TowerToHyperService;
use tokio::io::{AsyncRead, AsyncWrite, AsyncWriteExt, ReadBuf};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{watch, OwnedSemaphorePermit, Semaphore};

use super::metrics::Metrics;

/// The bounds on connections.
#[derive(Debug, Clone, Copy)]
pub struct Limits {
    /// Longest a client may take to send a request's head, and longest a kept-alive connection
    /// may stay idle.
    pub head: Duration,
    /// Connections open at once.
    pub connections: usize,
    /// Longest the open connections are given to finish after the shutdown signal.
    pub grace: Duration,
}

/// How long a refusal may take to write before the connection is dropped.
const REFUSAL_WRITE: Duration = Duration::from_secs(1);

/// Serves `router` on `listener` until `shutdown` completes, then gives the open connections
/// the grace period and closes the rest.
pub async fn serve(
    listener: TcpListener,
    router: Router,
    limits: Limits,
    metrics: Arc<Metrics>,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> std::io::Result<()> {
    let permits = Arc::new(Semaphore::new(limits.connections.max(1)));
    // Dropped at shutdown: every connection then finishes the request it is serving and closes.
    let (closing, closed) = watch::channel(());
    let mut open = tokio::task::JoinSet::new();
    let mut shutdown = std::pin::pin!(shutdown);
    loop {
        let accepted = tokio::select! {
            accepted = listener.accept() => accepted,
            () = &mut shutdown => break,
        };
        while open.try_join_next().is_some() {}
        let stream = match accepted {
            Ok((stream, _)) => stream,
            Err(error) => {
                // Out of file descriptors, or the peer gave up: wait a little, go on.
                tracing::warn!(%error, "accepting a connection failed");
                tokio::time::sleep(Duration::from_millis(50)).await;
                continue;
            }
        };
        match permits.clone().try_acquire_owned() {
            Ok(permit) => {
                let counted = Open::on(metrics.clone());
                open.spawn(connection(
                    stream,
                    router.clone(),
                    limits,
                    (permit, counted),
                    closed.clone(),
                ));
            }
            Err(_) => {
                tokio::spawn(refuse(stream, limits.connections));
            }
        }
    }
    drop(closing);
    drop(listener);
    let drained = tokio::time::timeout(limits.grace, async {
        while open.join_next().await.is_some() {}
    })
    .await;
    if drained.is_err() {
        tracing::warn!(
            left = open.len(),
            grace_s = limits.grace.as_secs_f64(),
            "closing the connections still open after the shutdown grace period"
        );
        open.abort_all();
        while open.join_next().await.is_some() {}
    }
    Ok(())
}

/// A connection counted in the metrics' open connections for as long as it lives.
struct Open(Arc<Metrics>);

impl Open {
    fn on(metrics: Arc<Metrics>) -> Open {
        metrics.connections_open.fetch_add(1, Ordering::Relaxed);
        Open(metrics)
    }
}

impl Drop for Open {
    fn drop(&mut self) {
        self.0.connections_open.fetch_sub(1, Ordering::Relaxed);
    }
}

/// Serves one connection (HTTP/1.1 with keep-alive) until it closes, the head timeout passes,
/// or the server shuts down.
async fn connection(
    stream: TcpStream,
    router: Router,
    limits: Limits,
    _held: (OwnedSemaphorePermit, Open),
    mut closed: watch::Receiver<()>,
) {
    let _ = stream.set_nodelay(true);
    let service = TowerToHyperService::new(router);
    let mut builder = hyper::server::conn::http1::Builder::new();
    builder
        .timer(TokioTimer::new())
        .header_read_timeout(limits.head)
        .keep_alive(true);
    let io = TokioIo::new(JsonErrors::new(stream));
    let mut served = std::pin::pin!(builder.serve_connection(io, service));
    let mut shutting_down = false;
    loop {
        tokio::select! {
            result = served.as_mut() => {
                if let Err(error) = result {
                    tracing::debug!(%error, "connection ended");
                }
                return;
            }
            changed = closed.changed(), if !shutting_down => {
                let _: Result<(), _> = changed;
                shutting_down = true;
                served.as_mut().graceful_shutdown();
            }
        }
    }
}

/// Answers a connection past the limit with `503` and closes it.
async fn refuse(mut stream: TcpStream, limit: usize) {
    let body = serde_json::json!({
        "error": format!("the server has {limit} connections open, its most; retry shortly")
    })
    .to_string();
    let response = format!(
        "HTTP/1.1 503 Service Unavailable\r\ncontent-type: application/json\r\n\
         retry-after: {}\r\nconnection: close\r\ncontent-length: {}\r\n\r\n{body}",
        super::RETRY_AFTER_S,
        body.len()
    );
    let written = tokio::time::timeout(REFUSAL_WRITE, async {
        stream.write_all(response.as_bytes()).await?;
        stream.shutdown().await
    })
    .await;
    if !matches!(written, Ok(Ok(()))) {
        tracing::debug!("a refused connection could not be told");
    }
    tracing::warn!(limit, "connection refused: too many open");
}

/// hyper's refusals are a status line and three short headers.
const MAX_REFUSAL_HEAD: usize = 512;

/// A connection whose answers to requests hyper could not read carry a JSON body.
///
/// hyper writes such an answer as a head alone (`HTTP/1.1 431 …`, `connection: close`,
/// `content-length: 0`) in one write, and then closes; every answer of the routes to a client
/// error has a body. A write that is such a head is replaced by the same status with a JSON
/// body saying what was wrong.
pub struct JsonErrors<T> {
    inner: T,
    /// A replacement being written, how much of it is written, and the length of the write it
    /// stands for.
    replacing: Option<(Vec<u8>, usize, usize)>,
}

impl<T> JsonErrors<T> {
    pub fn new(inner: T) -> JsonErrors<T> {
        JsonErrors {
            inner,
            replacing: None,
        }
    }
}

/// The answer with a JSON body for `written`, when it is hyper's bodiless answer to a request
/// it could not read.
fn with_json_body(written: &[u8]) -> Option<Vec<u8>> {
    // Cheap tests first: this sees every write of every answer.
    let error_head = written.len() <= MAX_REFUSAL_HEAD
        && (written.starts_with(b"HTTP/1.1 4") || written.starts_with(b"HTTP/1.1 5"))
        && written.ends_with(b"\r\n\r\n");
    if !error_head {
        return None;
    }
    let head = std::str::from_utf8(written)
        .ok()?
        .strip_suffix("\r\n\r\n")?;
    let status = head.strip_prefix("HTTP/1.1 ")?.get(..3)?;
    let lines: Vec<&str> = head.lines().map(str::trim).collect();
    let bodiless = lines.contains(&"content-length: 0") && lines.contains(&"connection: close");
    if !(status.starts_with('4') || status.starts_with('5'))
        || !bodiless
        || head.contains("\r\n\r\n")
    {
        return None;
    }
    let why = match status {
        "414" => "the request's URI is longer than the server reads (64 KiB)",
        "431" => "the request's header fields are too many (at most 100) or too large",
        "400" => {
            "the request is not HTTP/1.1 the server can read: a request line or header field \
             is malformed (a URI must be ASCII, with other bytes percent-encoded)"
        }
        _ => "the request is not HTTP/1.1 the server can read",
    };
    let body = serde_json::json!({ "error": why }).to_string();
    let status_line = head.lines().next()?;
    let kept: String = lines[1..]
        .iter()
        .filter(|l| !l.starts_with("content-length:"))
        .map(|l| format!("{l}\r\n"))
        .collect();
    Some(
        format!(
            "{status_line}\r\n{kept}content-type: application/json\r\ncontent-length: {}\r\n\r\n{body}",
            body.len()
        )
        .into_bytes(),
    )
}

impl<T: AsyncRead + Unpin> AsyncRead for JsonErrors<T> {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<std::io::Result<()>> {
        Pin::new(&mut self.inner).poll_read(cx, buf)
    }
}

impl<T: AsyncWrite + Unpin> AsyncWrite for JsonErrors<T> {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<std::io::Result<usize>> {
        if self.replacing.is_none() {
            match with_json_body(buf) {
                Some(answer) => self.replacing = Some((answer, 0, buf.len())),
                None => return Pin::new(&mut self.inner).poll_write(cx, buf),
            }
        }
        self.write_replacement(cx)
    }

    /// Vectored writes go on as they are (answers with bodies are written as head and body
    /// slices, without a copy); a lone slice that is a refusal is replaced.
    fn poll_write_vectored(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[std::io::IoSlice<'_>],
    ) -> Poll<std::io::Result<usize>> {
        let mut slices = bufs.iter().filter(|b| !b.is_empty());
        let lone = match (slices.next(), slices.next()) {
            (Some(only), None) => Some(&only[..]),
            _ => None,
        };
        if self.replacing.is_none() {
            match lone.and_then(with_json_body) {
                Some(answer) => self.replacing = Some((answer, 0, lone.map_or(0, <[u8]>::len))),
                None => return Pin::new(&mut self.inner).poll_write_vectored(cx, bufs),
            }
        }
        self.write_replacement(cx)
    }

    fn is_write_vectored(&self) -> bool {
        self.inner.is_write_vectored()
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        Pin::new(&mut self.inner).poll_flush(cx)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        Pin::new(&mut self.inner).poll_shutdown(cx)
    }
}

impl<T: AsyncWrite + Unpin> JsonErrors<T> {
    /// Writes the replacement under way; once it is out, the bytes it stands for are said to
    /// have gone.
    fn write_replacement(&mut self, cx: &mut Context<'_>) -> Poll<std::io::Result<usize>> {
        let this = self;
        while let Some((answer, done, stands_for)) = &mut this.replacing {
            if *done == answer.len() {
                let stands_for = *stands_for;
                this.replacing = None;
                return Poll::Ready(Ok(stands_for));
            }
            match Pin::new(&mut this.inner).poll_write(cx, &answer[*done..]) {
                Poll::Ready(Ok(0)) => {
                    return Poll::Ready(Err(std::io::ErrorKind::WriteZero.into()))
                }
                Poll::Ready(Ok(n)) => *done += n,
                other => return other,
            }
        }
        Poll::Ready(Ok(0))
    }
}

/// Raises this process's soft limit of open files to its hard limit (so connections are not
/// bounded by a low default), and returns the connections to allow: at most `wanted`, and at most
/// three quarters of the open-file limit, leaving the rest to the store, caches and data files.
pub fn connections_to_allow(wanted: usize) -> usize {
    let mut limit = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: getrlimit writes into the struct it is given.
    if unsafe { libc::getrlimit(libc::RLIMIT_NOFILE, &mut limit) } != 0 {
        return wanted;
    }
    if limit.rlim_cur < limit.rlim_max {
        let raised = libc::rlimit {
            rlim_cur: limit.rlim_max,
            rlim_max: limit.rlim_max,
        };
        // SAFETY: setrlimit reads the struct it is given.
        if unsafe { libc::setrlimit(libc::RLIMIT_NOFILE, &raised) } == 0 {
            limit = raised;
        }
    }
    let files = usize::try_from(limit.rlim_cur).unwrap_or(usize::MAX);
    wanted.min(files / 4 * 3).max(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hypers_bodiless_refusals_get_a_json_body() {
        let head = "HTTP/1.1 431 Request Header Fields Too Large\r\nconnection: close\r\n\
                    content-length: 0\r\ndate: Fri, 27 Nov 2026 15:21:57 GMT\r\n\r\n";
        let answer = String::from_utf8(with_json_body(head.as_bytes()).unwrap()).unwrap();
        let (head, body) = answer.split_once("\r\n\r\n").unwrap();
        assert!(head.starts_with("HTTP/1.1 431 Request Header Fields Too Large\r\n"));
        assert!(head.contains("content-type: application/json"), "{head}");
        assert!(
            head.contains(&format!("content-length: {}", body.len())),
            "{head}"
        );
        assert!(!head.contains("content-length: 0"), "{head}");
        let parsed: serde_json::Value = serde_json::from_str(body).unwrap();
        assert!(parsed["error"].as_str().unwrap().contains("too many"));
    }

    #[test]
    fn answers_with_bodies_and_answers_that_go_on_are_left_alone() {
        let with_body = "HTTP/1.1 404 Not Found\r\ncontent-type: application/json\r\n\
                         content-length: 12\r\n\r\n{\"error\":\"\"}";
        assert_eq!(with_json_body(with_body.as_bytes()), None);
        let kept_alive = "HTTP/1.1 400 Bad Request\r\ncontent-length: 0\r\n\r\n";
        assert_eq!(with_json_body(kept_alive.as_bytes()), None);
        let success = "HTTP/1.1 200 OK\r\nconnection: close\r\ncontent-length: 0\r\n\r\n";
        assert_eq!(with_json_body(success.as_bytes()), None);
        assert_eq!(with_json_body(&[0xff, 0xfe]), None);
    }
}
