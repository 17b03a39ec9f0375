//! Sorting more records than memory should hold: fixed-size records of `K` integers are
//! gathered up to a bound, sorted and written out as a run when the bound is reached, and the
//! runs merged when read back. Memory holds one run's records while they come and one block
//! of each run while they are merged, whatever their number.
//!
//! Run files are made beside a path the caller names and unlinked at once: the open handle
//! keeps them, and nothing is left behind when the process stops.

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

/// Records held before a run is written (32 MiB of pairs).
pub const RUN_RECORDS: usize = 1 << 21;

/// Records of `K` integers, sorted in the order of their integers (the first, then the next).
pub struct ExternalSort<const K: usize> {
    beside: PathBuf,
    held: Vec<[i64; K]>,
    limit: usize,
    runs: Vec<File>,
}

impl<const K: usize> ExternalSort<K> {
    /// A sort whose runs are written beside `beside`, holding up to `limit` records at once.
    pub fn new(beside: &Path, limit: usize) -> ExternalSort<K> {
        ExternalSort {
            beside: beside.to_path_buf(),
            held: Vec::new(),
            limit: limit.max(1),
            runs: Vec::new(),
        }
    }

    pub fn push(&mut self, record: [i64; K]) -> std::io::Result<()> {
        self.held.push(record);
        if self.held.len() >= self.limit {
            self.spill()?;
        }
        Ok(())
    }

    /// The records held, sorted, written as a run.
    fn spill(&mut self) -> std::io::Result<()> {
        self.held.sort_unstable();
        let path =
            self.beside
                .with_extension(format!("sort-{}-{}", std::process::id(), self.runs.len()));
        let file = File::options()
            .read(true)
            .write(true)
            .create(true)
            .truncate(true)
            .open(&path)?;
        std::fs::remove_file(&path)?;
        let mut out = BufWriter::with_capacity(1 << 20, file);
        for record in &self.held {
            for value in record {
                out.write_all(&value.to_le_bytes())?;
            }
        }
        let mut file = out.into_inner().map_err(|e| e.into_error())?;
        file.seek(SeekFrom::Start(0))?;
        self.runs.push(file);
        self.held.clear();
        Ok(())
    }

    /// Every record pushed, in order.
    pub fn sorted(mut self) -> std::io::Result<Sorted<K>> {
        if self.runs.is_empty() {
            self.held.sort_unstable();
            return Ok(Sorted::Held(self.held.into_iter()));
        }
        if !self.held.is_empty() {
            self.spill()?;
        }
        let mut readers: Vec<BufReader<File>> = self
            .runs
            .into_iter()
            .map(|file| BufReader::with_capacity(1 << 16, file))
            .collect();
        let mut heap = BinaryHeap::with_capacity(readers.len());
        for (run, reader) in readers.iter_mut().enumerate() {
            if let Some(record) = read_record(reader)? {
                heap.push(Reverse((record, run)));
            }
        }
        Ok(Sorted::Merged { readers, heap })
    }
}

fn read_record<const K: usize>(reader: &mut impl Read) -> std::io::Result<Option<[i64; K]>> {
    let mut record = [0i64; K];
    let mut bytes = [0u8; 8];
    for (k, value) in record.iter_mut().enumerate() {
        match reader.read_exact(&mut bytes) {
            Ok(()) => *value = i64::from_le_bytes(bytes),
            Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof && k == 0 => return Ok(None),
            Err(e) => return Err(e),
        }
    }
    Ok(Some(record))
}

/// The records of an [`ExternalSort`], in order.
pub enum Sorted<const K: usize> {
    /// All of them were held in memory.
    Held(std::vec::IntoIter<[i64; K]>),
    Merged {
        readers: Vec<BufReader<File>>,
        heap: BinaryHeap<Reverse<([i64; K], usize)>>,
    },
}

impl<const K: usize> Iterator for Sorted<K> {
    type Item = std::io::Result<[i64; K]>;

    fn next(&mut self) -> Option<Self::Item> {
        match self {
            Sorted::Held(records) => records.next().map(Ok),
            Sorted::Merged { readers, heap } => {
                let Reverse((record, run)) = heap.pop()?;
                match read_record(&mut readers[run]) {
                    Ok(Some(next)) => heap.push(Reverse((next, run))),
                    Ok(None) => {}
                    Err(e) => return Some(Err(e)),
                }
                Some(Ok(record))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sorted_by<const K: usize>(name: &str, records: &[[i64; K]], limit: usize) -> Vec<[i64; K]> {
        let dir = std::env::temp_dir().join(format!("{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut sort = ExternalSort::<K>::new(&dir.join("records"), limit);
        for &r in records {
            sort.push(r).unwrap();
        }
        let out = sort
            .sorted()
            .unwrap()
            .collect::<Result<Vec<_>, _>>()
            .unwrap();
        // The runs were unlinked as they were made.
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
        std::fs::remove_dir(&dir).unwrap();
        out
    }

    fn scrambled(n: i64) -> Vec<[i64; 2]> {
        (0..n)
            .map(|i| [(i * 7919) % 1013 - 500, (i * 104_729) % 97])
            .collect()
    }

    #[test]
    fn records_held_in_memory_come_out_in_order() {
        let records = scrambled(1000);
        let mut expected = records.clone();
        expected.sort();
        assert_eq!(sorted_by("held", &records, 10_000), expected);
    }

    #[test]
    fn records_spilled_in_many_runs_merge_in_order_with_every_duplicate() {
        let mut records = scrambled(1000);
        records.extend(scrambled(300));
        let mut expected = records.clone();
        expected.sort();
        // 1,300 records in runs of 64: 21 runs merged, the last one partly filled.
        assert_eq!(sorted_by("spilled", &records, 64), expected);
    }

    #[test]
    fn records_order_by_their_first_integer_then_the_next() {
        let records = vec![[2, 1, 0], [1, 5, 9], [1, 5, 3], [-4, 0, 0], [1, 2, 8]];
        assert_eq!(
            sorted_by("lexicographic", &records, 2),
            vec![[-4, 0, 0], [1, 2, 8], [1, 5, 3], [1, 5, 9], [2, 1, 0]]
        );
    }

    #[test]
    fn nothing_pushed_gives_nothing() {
        assert!(sorted_by::<2>("empty", &[], 4).is_empty());
    }
}
