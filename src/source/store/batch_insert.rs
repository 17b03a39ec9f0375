//! Rows inserted many to a statement: most of what SQLite spends on a small row is spent on
//! its statement (binding, stepping, resetting), so rows are held and written [`ROWS`] at a
//! time.

use rusqlite::types::Value;
use rusqlite::{Connection, Statement};

/// Rows a statement.
pub const ROWS: usize = 128;

/// Inserts rows of a fixed number of columns into one table. Rows are held until [`ROWS`]
/// have come: [`BatchInsert::flush`] writes the rest, and must be called before the
/// transaction commits.
pub struct BatchInsert<'a> {
    columns: usize,
    many: Statement<'a>,
    one: Statement<'a>,
    held: Vec<Value>,
}

impl<'a> BatchInsert<'a> {
    /// `insert` names the table and its columns (`INSERT [OR IGNORE] INTO t (a, b)`), of
    /// which there are `columns`.
    pub fn new(db: &'a Connection, insert: &str, columns: usize) -> rusqlite::Result<Self> {
        let sql = |rows: usize| {
            let row = format!("({})", vec!["?"; columns].join(", "));
            format!("{insert} VALUES {}", vec![row; rows].join(", "))
        };
        Ok(BatchInsert {
            columns,
            many: db.prepare(&sql(ROWS))?,
            one: db.prepare(&sql(1))?,
            held: Vec::with_capacity(columns * ROWS),
        })
    }

    /// Adds a row of as many values as the table's columns named.
    pub fn push<const N: usize>(&mut self, row: [Value; N]) -> rusqlite::Result<()> {
        if N != self.columns {
            return Err(rusqlite::Error::InvalidParameterCount(N, self.columns));
        }
        self.held.extend(row);
        if self.held.len() == self.columns * ROWS {
            self.many
                .execute(rusqlite::params_from_iter(self.held.drain(..)))?;
        }
        Ok(())
    }

    /// Writes the rows held.
    pub fn flush(&mut self) -> rusqlite::Result<()> {
        let held = std::mem::take(&mut self.held);
        for row in held.chunks(self.columns) {
            self.one.execute(rusqlite::params_from_iter(row))?;
        }
        self.held = held;
        self.held.clear();
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table() -> Connection {
        let db = Connection::open_in_memory().unwrap();
        db.execute_batch("CREATE TABLE t (id INTEGER PRIMARY KEY, name TEXT, data BLOB)")
            .unwrap();
        db
    }

    fn rows(db: &Connection) -> Vec<(i64, String, Vec<u8>)> {
        let mut s = db
            .prepare("SELECT id, name, data FROM t ORDER BY id")
            .unwrap();
        s.query_map([], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)))
            .unwrap()
            .collect::<Result<_, _>>()
            .unwrap()
    }

    fn row(id: i64) -> [Value; 3] {
        [
            Value::Integer(id),
            Value::Text(format!("row {id}")),
            Value::Blob(vec![id as u8; 3]),
        ]
    }

    #[test]
    fn every_row_pushed_is_written_once_flushed_whether_a_batch_is_full_or_not() {
        let db = table();
        let mut insert = BatchInsert::new(&db, "INSERT INTO t (id, name, data)", 3).unwrap();
        let count = 2 * ROWS as i64 + 5;
        for id in 0..count {
            insert.push(row(id)).unwrap();
        }
        // Two statements' worth are written as they come, the rest held.
        assert_eq!(rows(&db).len(), 2 * ROWS);
        insert.flush().unwrap();
        let written = rows(&db);
        assert_eq!(written.len() as i64, count);
        for (k, (id, name, data)) in written.into_iter().enumerate() {
            assert_eq!(id, k as i64);
            assert_eq!(name, format!("row {id}"));
            assert_eq!(data, vec![id as u8; 3]);
        }
    }

    #[test]
    fn a_row_of_the_wrong_width_is_refused() {
        let db = table();
        let mut insert = BatchInsert::new(&db, "INSERT INTO t (id, name, data)", 3).unwrap();
        assert!(insert.push([Value::Integer(1)]).is_err());
    }

    #[test]
    fn or_ignore_skips_each_conflicting_row_alone() {
        let db = table();
        db.execute(
            "INSERT INTO t (id, name, data) VALUES (3, 'first', x'00')",
            [],
        )
        .unwrap();
        let mut insert =
            BatchInsert::new(&db, "INSERT OR IGNORE INTO t (id, name, data)", 3).unwrap();
        for id in 0..ROWS as i64 {
            insert.push(row(id)).unwrap();
        }
        insert.flush().unwrap();
        let written = rows(&db);
        assert_eq!(written.len(), ROWS);
        assert_eq!(written[3].1, "first");
    }
}
