//! Components of the linear program already solved, kept by what the solver is given.
//!
//! A bridge group or a road stretch is one component of its tile's LP, and every tile it
//! reaches builds the same component again: the same variables with the same targets, the same
//! constraints, in the same order. The solver is deterministic, so a component's solution is a
//! function of that input alone; this memo keeps it by a SHA-256 digest of the input (labels
//! aside: they only name constraints for reports), and a tile that meets a component another
//! tile solved takes its solution instead of solving again. The bytes of a tile are the same
//! whether a component was solved or found here.
//!
//! A memo is made once by whoever renders (one for a server or a seed, kept across reloads of
//! the sources) and handed to every render; it is bounded in bytes, least recently used first
//! out, and may also be filled from and written to a durable store (see [`Solutions::remember`] and
//! [`Solutions::take_unsaved`]), so the components a tile cache's tiles were made from are
//! found again after a restart or a diff.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use sha2::{Digest, Sha256};

/// Bytes a memo keeps of solved components, at most, unless told otherwise.
pub const MEMO_BYTES: u64 = 64 << 20;

/// The digest a component is kept by.
pub type Key = [u8; 32];

/// A component solved: its variables' values in member order, and its soft constraints that
/// gave way, by position among the component's constraints, with how far. `None` when the
/// solver failed.
#[derive(Debug, Clone, PartialEq)]
pub struct Solved {
    pub values: Vec<f64>,
    pub violations: Vec<(u32, f64)>,
}

/// A memo of solved components.
pub struct Solutions {
    cache: moka::sync::Cache<Key, Arc<Option<Solved>>>,
    /// Components found here, and solved afresh.
    found: AtomicU64,
    solved: AtomicU64,
    /// Components solved afresh and not yet taken for a durable store.
    unsaved: Mutex<Vec<Key>>,
    /// When recording, the input of each component solved afresh, as its solver's caller
    /// writes it (for fixtures that hold a solver to another).
    recorded: Option<Mutex<Vec<String>>>,
}

impl Default for Solutions {
    fn default() -> Solutions {
        Solutions::new(MEMO_BYTES)
    }
}

impl std::fmt::Debug for Solutions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (found, solved) = self.counts();
        f.debug_struct("Solutions")
            .field("found", &found)
            .field("solved", &solved)
            .finish_non_exhaustive()
    }
}

/// Format of an encoded entry and version of the solvers behind it (2: small components by
/// the interior-point solver made for them); a change makes stored entries unreadable, not wrong.
const ENCODING: u8 = 2;

impl Solutions {
    /// A memo keeping at most `bytes` of solutions.
    pub fn new(bytes: u64) -> Solutions {
        Solutions {
            cache: moka::sync::Cache::builder()
                .max_capacity(bytes)
                .weigher(|_, solved: &Arc<Option<Solved>>| {
                    let size = solved
                        .as_ref()
                        .as_ref()
                        .map_or(0, |s| s.values.len() * 8 + s.violations.len() * 16);
                    u32::try_from(size + 64).unwrap_or(u32::MAX)
                })
                .build(),
            found: AtomicU64::new(0),
            solved: AtomicU64::new(0),
            unsaved: Mutex::new(Vec::new()),
            recorded: None,
        }
    }

    /// A memo of the usual size that also keeps the input of every component solved afresh.
    pub fn recording() -> Solutions {
        Solutions {
            recorded: Some(Mutex::new(Vec::new())),
            ..Solutions::default()
        }
    }

    pub fn records(&self) -> bool {
        self.recorded.is_some()
    }

    /// Keeps a component's input, when recording.
    pub fn record(&self, input: String) {
        if let Some(recorded) = &self.recorded {
            recorded
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .push(input);
        }
    }

    /// The inputs recorded since the last call.
    pub fn take_recorded(&self) -> Vec<String> {
        self.recorded.as_ref().map_or_else(Vec::new, |recorded| {
            std::mem::take(&mut *recorded.lock().unwrap_or_else(|p| p.into_inner()))
        })
    }

    /// The component kept by `key` when `sound` accepts it, else `solve`'s answer, then kept
    /// (an entry read from a damaged store is solved again, not used).
    pub fn get_or_solve(
        &self,
        key: Key,
        sound: impl Fn(&Option<Solved>) -> bool,
        solve: impl FnOnce() -> Option<Solved>,
    ) -> Arc<Option<Solved>> {
        if let Some(solved) = self.cache.get(&key).filter(|s| sound(s)) {
            self.found.fetch_add(1, Ordering::Relaxed);
            return solved;
        }
        self.solved.fetch_add(1, Ordering::Relaxed);
        let solved = Arc::new(solve());
        self.cache.insert(key, Arc::clone(&solved));
        self.unsaved
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .push(key);
        solved
    }

    fn insert(&self, key: Key, solved: Option<Solved>) {
        self.cache.insert(key, Arc::new(solved));
    }

    /// Components found here and solved afresh since the process started.
    pub fn counts(&self) -> (u64, u64) {
        (
            self.found.load(Ordering::Relaxed),
            self.solved.load(Ordering::Relaxed),
        )
    }

    /// The components solved afresh since the last call (those still kept), encoded, for a
    /// durable store.
    pub fn take_unsaved(&self) -> Vec<(Key, Vec<u8>)> {
        let keys = std::mem::take(&mut *self.unsaved.lock().unwrap_or_else(|p| p.into_inner()));
        keys.into_iter()
            .filter_map(|key| {
                let solved = self.cache.get(&key)?;
                Some((key, encode(solved.as_ref().as_ref())))
            })
            .collect()
    }

    /// Keeps components read from a durable store; those this version cannot read are
    /// skipped. Returns how many were kept.
    pub fn remember(&self, entries: impl IntoIterator<Item = (Key, Vec<u8>)>) -> usize {
        let mut kept = 0;
        for (key, bytes) in entries {
            if let Some(solved) = decode(&bytes) {
                self.insert(key, solved);
                kept += 1;
            }
        }
        kept
    }
}

/// Digests a component's input as the solver sees it, in order.
#[derive(Default)]
pub struct KeyWriter {
    hash: Sha256,
}

impl KeyWriter {
    pub fn new() -> KeyWriter {
        let mut writer = KeyWriter::default();
        writer.hash.update([ENCODING]);
        writer
    }

    pub fn count(&mut self, n: usize) -> &mut Self {
        self.hash.update((n as u64).to_le_bytes());
        self
    }

    pub fn number(&mut self, x: f64) -> &mut Self {
        self.hash.update(x.to_bits().to_le_bytes());
        self
    }

    pub fn optional(&mut self, x: Option<f64>) -> &mut Self {
        match x {
            Some(x) => {
                self.hash.update([1]);
                self.number(x)
            }
            None => {
                self.hash.update([0]);
                self
            }
        }
    }

    pub fn tag(&mut self, tag: u8) -> &mut Self {
        self.hash.update([tag]);
        self
    }

    pub fn finish(self) -> Key {
        self.hash.finalize().into()
    }
}

pub(crate) fn encode(solved: Option<&Solved>) -> Vec<u8> {
    let mut out = vec![ENCODING];
    let Some(solved) = solved else {
        out.push(0);
        return out;
    };
    out.push(1);
    out.extend((solved.values.len() as u32).to_le_bytes());
    for v in &solved.values {
        out.extend(v.to_bits().to_le_bytes());
    }
    out.extend((solved.violations.len() as u32).to_le_bytes());
    for &(at, amount) in &solved.violations {
        out.extend(at.to_le_bytes());
        out.extend(amount.to_bits().to_le_bytes());
    }
    out
}

fn decode(bytes: &[u8]) -> Option<Option<Solved>> {
    let mut rest = bytes;
    let mut take = |n: usize| -> Option<&[u8]> {
        let (head, tail) = rest.split_at_checked(n)?;
        rest = tail;
        Some(head)
    };
    let u32_of = |b: &[u8]| b.try_into().ok().map(u32::from_le_bytes);
    let f64_of = |b: &[u8]| {
        b.try_into()
            .ok()
            .map(|b| f64::from_bits(u64::from_le_bytes(b)))
    };
    if take(1)? != [ENCODING] {
        return None;
    }
    if take(1)? == [0] {
        return Some(None);
    }
    let n = u32_of(take(4)?)? as usize;
    let mut values = Vec::with_capacity(n.min(1 << 16));
    for _ in 0..n {
        values.push(f64_of(take(8)?)?);
    }
    let m = u32_of(take(4)?)? as usize;
    let mut violations = Vec::with_capacity(m.min(1 << 16));
    for _ in 0..m {
        let at = u32_of(take(4)?)?;
        violations.push((at, f64_of(take(8)?)?));
    }
    if !rest.is_empty() {
        return None;
    }
    Some(Some(Solved { values, violations }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_encoded_solution_reads_back_the_same_and_a_cut_one_does_not() {
        let solved = Solved {
            values: vec![1.5, -0.25, f64::MAX],
            violations: vec![(2, 0.125)],
        };
        let bytes = encode(Some(&solved));
        assert_eq!(decode(&bytes), Some(Some(solved)));
        assert_eq!(decode(&encode(None)), Some(None));
        assert_eq!(decode(&bytes[..bytes.len() - 1]), None);
        let mut longer = bytes.clone();
        longer.push(0);
        assert_eq!(decode(&longer), None);
    }

    #[test]
    fn remembered_components_are_found_and_only_those_solved_afresh_are_saved() {
        let bytes = encode(Some(&Solved {
            values: vec![2.0],
            violations: Vec::new(),
        }));
        let memo = Solutions::new(1 << 20);
        let kept = memo.remember([([7; 32], bytes.clone()), ([8; 32], vec![ENCODING + 1])]);
        assert_eq!(kept, 1);
        let any = |_: &Option<Solved>| true;
        assert_eq!(
            memo.get_or_solve([7; 32], any, || None).as_ref(),
            &decode(&bytes).flatten()
        );
        assert_eq!(memo.counts(), (1, 0));
        // Remembered components are not saved again; one solved afresh is, once.
        assert!(memo.take_unsaved().is_empty());
        memo.get_or_solve([9; 32], any, || None);
        assert_eq!(memo.take_unsaved(), vec![([9; 32], encode(None))]);
        assert!(memo.take_unsaved().is_empty());
        // An entry its reader finds unsound is solved again and replaced.
        let solved = memo.get_or_solve([7; 32], |_| false, || None);
        assert_eq!(solved.as_ref(), &None);
        assert_eq!(memo.counts(), (1, 2));
    }
}
