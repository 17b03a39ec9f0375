//! The connections to one PostgreSQL database that a process keeps: a small pool of our own
//! over the blocking `postgres` client, opened as needed; a connection that broke is dropped,
//! not given back.

use std::sync::Mutex;

use postgres::{Client, NoTls};

use crate::cache::store::StoreError;

/// Connections kept open when idle, at most.
const IDLE_CONNECTIONS: usize = 8;

pub struct Connections {
    /// Where the database is, without its password (for errors and logs).
    place: String,
    url: String,
    idle: Mutex<Vec<Client>>,
}

impl std::fmt::Debug for Connections {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Connections")
            .field("place", &self.place)
            .finish()
    }
}

/// A connection taken from the pool, given back when dropped unless it broke.
pub struct Pooled<'a> {
    connections: &'a Connections,
    client: Option<Client>,
}

impl std::ops::Deref for Pooled<'_> {
    type Target = Client;
    fn deref(&self) -> &Client {
        self.client
            .as_ref()
            .expect("a pooled connection until dropped")
    }
}

impl std::ops::DerefMut for Pooled<'_> {
    fn deref_mut(&mut self) -> &mut Client {
        self.client
            .as_mut()
            .expect("a pooled connection until dropped")
    }
}

impl Drop for Pooled<'_> {
    fn drop(&mut self) {
        let Some(client) = self.client.take() else {
            return;
        };
        if !client.is_closed() {
            let mut idle = self.connections.lock();
            if idle.len() < IDLE_CONNECTIONS {
                idle.push(client);
                return;
            }
        }
        close(vec![client]);
    }
}

impl Drop for Connections {
    fn drop(&mut self) {
        close(std::mem::take(&mut *self.lock()));
    }
}

/// Closes blocking clients wherever they are dropped. Each client drives its connection on a
/// runtime of its own, which cannot run on a thread that drives async tasks (it panics, and a
/// panic there while the server stops aborts the process): there the clients are closed on a
/// thread of their own.
pub fn close(clients: Vec<Client>) {
    if clients.is_empty() {
        return;
    }
    if tokio::runtime::Handle::try_current().is_err() {
        drop(clients);
        return;
    }
    // Should no thread start, the clients are left to the operating system, not dropped here.
    let clients = std::mem::ManuallyDrop::new(clients);
    let closing = std::thread::Builder::new()
        .name("postgres-close".into())
        .spawn(move || drop(std::mem::ManuallyDrop::into_inner(clients)));
    if let Ok(thread) = closing {
        let _ = thread.join();
    }
}

impl Connections {
    /// Connections to the database at `url`; none is opened yet.
    pub fn new(url: &str) -> Connections {
        Connections {
            place: redacted(url),
            url: url.to_string(),
            idle: Mutex::new(Vec::new()),
        }
    }

    /// Where the database is, without its password.
    pub fn place(&self) -> &str {
        &self.place
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Vec<Client>> {
        self.idle.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// A store error naming the database.
    pub fn error(&self, source: postgres::Error) -> StoreError {
        StoreError::Postgres {
            place: self.place.clone(),
            source,
        }
    }

    /// A connection from the pool, or a new one.
    pub fn client(&self) -> Result<Pooled<'_>, StoreError> {
        let kept = self.lock().pop();
        let client = match kept {
            Some(client) => client,
            None => self.connect()?,
        };
        Ok(Pooled {
            connections: self,
            client: Some(client),
        })
    }

    /// A connection of its own, outside the pool (one that listens for notifications).
    pub fn connect(&self) -> Result<Client, StoreError> {
        Client::connect(&self.url, NoTls).map_err(|e| self.error(e))
    }
}

/// `url` without the password it may hold, in every form PostgreSQL takes one: `user:password@`
/// in a URL, a `password=` parameter of its query, a `password=` setting of the key–value form
/// (quoted or not, spaces around `=` or not); and in a URL whose scheme is mistyped, whatever
/// stands between its first `:` and its last `@`. Hiding too much is harmless; too little
/// is not.
pub fn redacted(url: &str) -> String {
    let hidden = match (url.find("://"), url.rfind('@')) {
        (Some(scheme), Some(at)) if at > scheme => {
            let credentials = &url[scheme + 3..at];
            match credentials.split_once(':') {
                Some((user, _)) => format!("{}{user}:***{}", &url[..scheme + 3], &url[at..]),
                None => url.to_string(),
            }
        }
        (None, Some(at)) => match url[..at].find(':') {
            Some(colon) => format!("{}:***{}", &url[..colon], &url[at..]),
            None => url.to_string(),
        },
        _ => url.to_string(),
    };
    hide_password_settings(&hidden)
}

/// Every `password=VALUE` (any case, `sslpassword` too) with its value hidden: a value runs to
/// the next space or `&`, or is quoted with `'` (a quote inside escaped with `\`).
fn hide_password_settings(text: &str) -> String {
    let lower = text.to_ascii_lowercase();
    let mut out = String::with_capacity(text.len());
    let mut from = 0;
    while let Some(found) = lower[from..].find("password") {
        let key_end = from + found + "password".len();
        let Some(value_and_more) = text[key_end..].trim_start().strip_prefix('=') else {
            out.push_str(&text[from..key_end]);
            from = key_end;
            continue;
        };
        let value_start = text.len() - value_and_more.trim_start().len();
        let value = &text[value_start..];
        let value_len = match value.strip_prefix('\'') {
            Some(quoted) => {
                let mut escaped = false;
                let close = quoted.char_indices().find(|&(_, c)| {
                    let closes = c == '\'' && !escaped;
                    escaped = c == '\\' && !escaped;
                    closes
                });
                close.map_or(value.len(), |(i, _)| i + 2)
            }
            None => value
                .find(|c: char| c.is_whitespace() || c == '&')
                .unwrap_or(value.len()),
        };
        out.push_str(&text[from..value_start]);
        out.push_str("***");
        from = value_start + value_len;
    }
    out.push_str(&text[from..]);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_database_url_is_named_without_its_password() {
        assert_eq!(
            redacted("postgres://tiles:secret@db.example:5432/tiles"),
            "postgres://tiles:***@db.example:5432/tiles"
        );
        assert_eq!(
            redacted("postgres://tiles@db/tiles"),
            "postgres://tiles@db/tiles"
        );
        assert_eq!(
            redacted("host=/run/postgresql dbname=tiles password=secret"),
            "host=/run/postgresql dbname=tiles password=***"
        );
    }

    #[test]
    fn every_form_of_a_password_is_hidden() {
        let forms = [
            (
                "postgres://tiles@host/db?password=S3cret",
                "postgres://tiles@host/db?password=***",
            ),
            (
                "postgres://tiles@host/db?sslmode=disable&PASSWORD=S3cret&x=1",
                "postgres://tiles@host/db?sslmode=disable&PASSWORD=***&x=1",
            ),
            (
                "postgresql://tiles:S3c/r@t@host/db",
                "postgresql://tiles:***@host/db",
            ),
            (
                "host=db password = 'S3 cr\\'et' dbname=tiles",
                "host=db password = *** dbname=tiles",
            ),
            ("password=S3cret", "password=***"),
            (
                "postgress://tiles:S3cret@host/db",
                "postgress://tiles:***@host/db",
            ),
            ("postgres:/tiles:S3cret@host/db", "postgres:***@host/db"),
            ("host=db sslpassword=S3cret", "host=db sslpassword=***"),
        ];
        for (url, shown) in forms {
            let hidden = redacted(url);
            assert_eq!(hidden, shown, "{url}");
            assert!(!hidden.contains("S3"), "{url}");
        }
    }
}
