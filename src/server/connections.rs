//! Accepting connections with bounds a public server needs: a client gets so long to send a
//! request's head (and an idle kept-alive connection is closed after as long), so many
//! connections are open at once (past that, one more is answered `503` and closed at once, never
//! left hanging), and after the shutdown signal the connections get a grace period to finish
//! before whatever is left is closed.

use std::future::Future;
use std::sync::Arc;
use std::time::Duration;

use axum::Router;
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::service::TowerToHyperService;
use tokio::io::AsyncWriteExt;
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{watch, OwnedSemaphorePermit, Semaphore};

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
                open.spawn(connection(
                    stream,
                    router.clone(),
                    limits,
                    permit,
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

/// Serves one connection (HTTP/1.1 with keep-alive) until it closes, the head timeout passes,
/// or the server shuts down.
async fn connection(
    stream: TcpStream,
    router: Router,
    limits: Limits,
    _permit: OwnedSemaphorePermit,
    mut closed: watch::Receiver<()>,
) {
    let _ = stream.set_nodelay(true);
    let service = TowerToHyperService::new(router);
    let mut builder = hyper::server::conn::http1::Builder::new();
    builder
        .timer(TokioTimer::new())
        .header_read_timeout(limits.head)
        .keep_alive(true);
    let mut served = std::pin::pin!(builder.serve_connection(TokioIo::new(stream), service));
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
