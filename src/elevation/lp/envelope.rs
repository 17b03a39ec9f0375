//! A sparse symmetric positive definite matrix stored by its envelope (each row from its first
//! nonzero to the diagonal) in reverse Cuthill–McKee order, and its LDLᵀ factorisation, which
//! fills nothing outside the envelope.
//!
//! A large LP component is roads and ramps as chains of stations with a few joints between
//! them: in that order its Newton matrix is a band a few dozen wide, and factorising it costs
//! the size times the band squared, where a dense factorisation costs the size cubed.

/// The shape of a matrix over `n` variables whose nonzeros are the cliques it is given.
#[derive(Debug, Clone)]
pub struct Envelope {
    /// Position of each variable in the order, and the variable at each position.
    position: Vec<usize>,
    variable: Vec<usize>,
    /// Per row (in the order): its first column, and where its entries start in `values`.
    first: Vec<usize>,
    start: Vec<usize>,
    values: Vec<f64>,
    diagonal: Vec<f64>,
}

impl Envelope {
    /// The envelope of a matrix over `n` variables in which each clique's variables meet.
    pub fn new<'a>(n: usize, cliques: impl Iterator<Item = &'a [usize]> + Clone) -> Envelope {
        let position = reverse_cuthill_mckee(n, cliques.clone());
        let mut variable = vec![0; n];
        for (v, &p) in position.iter().enumerate() {
            variable[p] = v;
        }
        let mut first: Vec<usize> = (0..n).collect();
        for clique in cliques {
            let lowest = clique.iter().map(|&v| position[v]).min().unwrap_or(0);
            for &v in clique {
                let p = position[v];
                first[p] = first[p].min(lowest);
            }
        }
        let mut start = Vec::with_capacity(n + 1);
        let mut size = 0;
        for (row, &f) in first.iter().enumerate() {
            start.push(size);
            size += row - f + 1;
        }
        start.push(size);
        Envelope {
            position,
            variable,
            first,
            start,
            values: vec![0.0; size],
            diagonal: vec![0.0; n],
        }
    }

    /// Variables of the matrix.
    pub fn size(&self) -> usize {
        self.first.len()
    }

    /// Entries kept: the envelope's size.
    pub fn entries(&self) -> usize {
        self.values.len()
    }

    /// Takes the entries of `other`, a matrix of the same envelope.
    pub fn copy_values(&mut self, other: &Envelope) {
        self.values.copy_from_slice(&other.values);
    }

    pub fn clear(&mut self) {
        self.values.iter_mut().for_each(|v| *v = 0.0);
    }

    /// Adds `x` to the entry of variables `i` and `j`, which is also that of `j` and `i` (the
    /// matrix is symmetric): a pair is added once. The two must share a clique.
    pub fn add(&mut self, i: usize, j: usize, x: f64) {
        let (pi, pj) = (self.position[i], self.position[j]);
        let (row, col) = (pi.max(pj), pi.min(pj));
        self.values[self.start[row] + col - self.first[row]] += x;
    }

    /// Adds `x` to every diagonal entry.
    pub fn shift(&mut self, x: f64) {
        for row in 0..self.first.len() {
            self.values[self.start[row + 1] - 1] += x;
        }
    }

    /// The largest diagonal entry.
    pub fn largest_diagonal(&self) -> f64 {
        (0..self.first.len()).fold(0.0f64, |m, row| m.max(self.values[self.start[row + 1] - 1]))
    }

    /// `A·x` for the matrix as assembled (not factorised), `x` indexed by variable.
    pub fn multiply(&self, x: &[f64]) -> Vec<f64> {
        let n = self.first.len();
        let mut out = vec![0.0; n];
        for row in 0..n {
            let (f, s) = (self.first[row], self.start[row]);
            let i = self.variable[row];
            for (&j, &a) in self.variable[f..row]
                .iter()
                .zip(&self.values[s..s + row - f])
            {
                out[i] += a * x[j];
                out[j] += a * x[i];
            }
            out[i] += self.values[s + row - f] * x[i];
        }
        out
    }

    /// Factorises in place as `L·D·Lᵀ`; `None` when a pivot is not clearly positive (the
    /// matrix is not positive definite to working precision).
    pub fn factorise(&mut self) -> Option<()> {
        let n = self.first.len();
        let largest = self.largest_diagonal();
        let tiny = 1e-300_f64.max(largest * 1e-16);
        for i in 0..n {
            let (fi, si) = (self.first[i], self.start[i]);
            for j in fi..i {
                let (fj, sj) = (self.first[j], self.start[j]);
                let from = fi.max(fj);
                let mut sum = self.values[si + j - fi];
                for k in from..j {
                    sum -= self.values[si + k - fi] * self.values[sj + k - fj] * self.diagonal[k];
                }
                self.values[si + j - fi] = sum / self.diagonal[j];
            }
            let mut pivot = self.values[si + i - fi];
            for k in fi..i {
                let l = self.values[si + k - fi];
                pivot -= l * l * self.diagonal[k];
            }
            if !pivot.is_finite() || pivot <= tiny {
                return None;
            }
            self.diagonal[i] = pivot;
        }
        Some(())
    }

    /// Solves the factorised system for `b` (indexed by variable), in place.
    pub fn solve(&self, b: &mut [f64]) {
        let n = self.first.len();
        let mut z = vec![0.0; n];
        for (v, &p) in self.position.iter().enumerate() {
            z[p] = b[v];
        }
        for i in 0..n {
            let (fi, si) = (self.first[i], self.start[i]);
            let sum: f64 = (fi..i).map(|k| self.values[si + k - fi] * z[k]).sum();
            z[i] -= sum;
        }
        for (zi, d) in z.iter_mut().zip(&self.diagonal) {
            *zi /= d;
        }
        for i in (0..n).rev() {
            let (fi, si) = (self.first[i], self.start[i]);
            let x = z[i];
            for (zk, l) in z[fi..i].iter_mut().zip(&self.values[si..si + i - fi]) {
                *zk -= l * x;
            }
        }
        for (v, &p) in self.position.iter().enumerate() {
            b[v] = z[p];
        }
    }
}

/// The reverse Cuthill–McKee order of the graph in which each clique's variables are joined:
/// the position of each variable. Ties go to the lower degree, then the lower index, so the
/// order is a function of the graph alone.
fn reverse_cuthill_mckee<'a>(n: usize, cliques: impl Iterator<Item = &'a [usize]>) -> Vec<usize> {
    let mut neighbours: Vec<Vec<usize>> = vec![Vec::new(); n];
    for clique in cliques {
        for &a in clique {
            neighbours[a].extend(clique.iter().copied().filter(|&b| b != a));
        }
    }
    for list in &mut neighbours {
        list.sort_unstable();
        list.dedup();
    }
    let degree: Vec<usize> = neighbours.iter().map(Vec::len).collect();
    let mut by_degree: Vec<usize> = (0..n).collect();
    by_degree.sort_by_key(|&v| (degree[v], v));
    let mut order = Vec::with_capacity(n);
    let mut seen = vec![false; n];
    for &root in &by_degree {
        if seen[root] {
            continue;
        }
        seen[root] = true;
        let mut head = order.len();
        order.push(root);
        while head < order.len() {
            let v = order[head];
            head += 1;
            let mut next: Vec<usize> = neighbours[v]
                .iter()
                .copied()
                .filter(|&w| !seen[w])
                .collect();
            next.sort_by_key(|&w| (degree[w], w));
            for w in next {
                seen[w] = true;
                order.push(w);
            }
        }
    }
    let mut position = vec![0; n];
    for (p, &v) in order.iter().rev().enumerate() {
        position[v] = p;
    }
    position
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_factorised_envelope_solves_what_its_dense_matrix_solves() {
        // Two chains joined at one station, in an order that scatters them.
        let chains: Vec<[usize; 2]> = vec![[0, 5], [5, 2], [2, 7], [7, 1], [3, 6], [6, 4], [4, 2]];
        let cliques: Vec<Vec<usize>> = chains.iter().map(|c| c.to_vec()).collect();
        let n = 8;
        let mut envelope = Envelope::new(n, cliques.iter().map(Vec::as_slice));
        let mut dense = vec![vec![0.0; n]; n];
        for (k, c) in chains.iter().enumerate() {
            let w = 1.0 + k as f64;
            for &(i, j, x) in &[(c[0], c[0], w), (c[1], c[1], w), (c[0], c[1], -w)] {
                envelope.add(i, j, x);
                dense[i][j] += x;
                if i != j {
                    dense[j][i] += x;
                }
            }
        }
        for (v, row) in dense.iter_mut().enumerate() {
            let d = 0.5 + v as f64 / 10.0;
            row[v] += d;
            envelope.add(v, v, d);
        }
        envelope.factorise().unwrap();
        let b: Vec<f64> = (0..n).map(|v| (v as f64 * 1.7).sin()).collect();
        let mut x = b.clone();
        envelope.solve(&mut x);
        for (i, row) in dense.iter().enumerate() {
            let ax: f64 = row.iter().zip(&x).map(|(a, x)| a * x).sum();
            assert!((ax - b[i]).abs() < 1e-12, "row {i}: {ax} against {}", b[i]);
        }
    }

    #[test]
    fn a_matrix_that_is_not_positive_definite_is_refused() {
        let cliques = [vec![0, 1]];
        let mut envelope = Envelope::new(2, cliques.iter().map(Vec::as_slice));
        envelope.add(0, 0, 1.0);
        envelope.add(1, 1, 1.0);
        envelope.add(0, 1, 2.0);
        assert!(envelope.factorise().is_none());
    }

    #[test]
    fn chains_in_any_numbering_get_a_narrow_band() {
        // A chain of 200 numbered in a scattered order: its envelope is one entry a row.
        let order: Vec<usize> = (0..200).map(|k| (k * 77) % 200).collect();
        let cliques: Vec<Vec<usize>> = order.windows(2).map(|w| w.to_vec()).collect();
        let envelope = Envelope::new(200, cliques.iter().map(Vec::as_slice));
        assert_eq!(envelope.values.len(), 200 + 199);
    }
}
