//! The Newton system of [`super::interior`]: `[H Eᵀ; E 0]` over a component's free variables
//! and its hard equalities, `H` a sum of weighted outer products of the terms' rows. A small
//! system is factorised dense (LU with partial pivoting); a large one keeps `H` by its envelope
//! in a banded order and takes the equalities through their Schur complement
//! `E·H⁻¹·Eᵀ`, a few columns wide.

use super::dot;
use super::envelope::Envelope;

/// Systems up to this size (free variables and equalities) are factorised dense; larger ones
/// by their envelope, whose cost grows with the size times the band squared, not the size
/// cubed. On the bundled tiles' components (`examples/lp_compare`, each against clarabel's
/// time in the same run) the two are even from 30 to 60 variables, and the band wins above.
pub const DENSE_MAX: usize = 60;

/// Most entries of an envelope, and most equalities beside one, this solver takes on.
const MAX_ENVELOPE: usize = 1 << 22;
const MAX_BANDED_EQUALITIES: usize = 400;

/// A sparse row: `(free variable, coefficient)`.
pub type Row = [(usize, f64)];

pub enum Kkt {
    Dense {
        n: usize,
        free: usize,
        assembled: Vec<f64>,
        matrix: Vec<f64>,
        pivots: Vec<usize>,
    },
    Banded {
        /// `H` as assembled, and its factors.
        h: Box<Envelope>,
        factors: Box<Envelope>,
        /// `H⁻¹·Eᵀ`, a column per equality, and the LU factors of `E·H⁻¹·Eᵀ`.
        columns: Vec<Vec<f64>>,
        schur: Vec<f64>,
        pivots: Vec<usize>,
    },
}

impl Kkt {
    /// The system over `free` variables and `equalities`, whose `H` has nonzeros where the
    /// variables of one of `cliques` meet.
    /// `None` when the envelope would be too large to be worth it (a component that is no
    /// network of chains).
    pub fn new(
        free: usize,
        equalities: &[(Vec<(usize, f64)>, f64)],
        cliques: impl Iterator<Item = Vec<usize>>,
    ) -> Option<Kkt> {
        let m = equalities.len();
        if free + m <= DENSE_MAX {
            let n = free + m;
            return Some(Kkt::Dense {
                n,
                free,
                assembled: vec![0.0; n * n],
                matrix: vec![0.0; n * n],
                pivots: vec![0; n],
            });
        }
        let cliques: Vec<Vec<usize>> = cliques.collect();
        let h = Box::new(Envelope::new(free, cliques.iter().map(Vec::as_slice)));
        if h.entries() > MAX_ENVELOPE || m > MAX_BANDED_EQUALITIES {
            return None;
        }
        Some(Kkt::Banded {
            factors: h.clone(),
            h,
            columns: vec![vec![0.0; free]; m],
            schur: vec![0.0; m * m],
            pivots: vec![0; m],
        })
    }

    pub fn clear(&mut self) {
        match self {
            Kkt::Dense { assembled, .. } => assembled.iter_mut().for_each(|x| *x = 0.0),
            Kkt::Banded { h, .. } => h.clear(),
        }
    }

    /// Adds `weight · a·aᵀ` to `H`.
    pub fn add_outer(&mut self, a: &Row, weight: f64) {
        match self {
            Kkt::Dense { n, assembled, .. } => {
                for &(i, ci) in a {
                    for &(j, cj) in a {
                        assembled[i * *n + j] += weight * ci * cj;
                    }
                }
            }
            Kkt::Banded { h, .. } => {
                for (p, &(i, ci)) in a.iter().enumerate() {
                    h.add(i, i, weight * ci * ci);
                    for &(j, cj) in &a[p + 1..] {
                        // A variable twice in one row meets itself on the diagonal twice.
                        let twice = if i == j { 2.0 } else { 1.0 };
                        h.add(i, j, twice * weight * ci * cj);
                    }
                }
            }
        }
    }

    /// Factorises the system assembled, with the least regularisation of `H` that makes it
    /// solvable; `None` if none of those tried does. Residuals are computed exactly, so the
    /// regularisation slows convergence at most, never moves the optimum.
    pub fn factorise(&mut self, equalities: &[(Vec<(usize, f64)>, f64)]) -> Option<()> {
        if let Kkt::Dense {
            n, free, assembled, ..
        } = self
        {
            for (e, (a, _)) in equalities.iter().enumerate() {
                for &(j, c) in a {
                    assembled[(*free + e) * *n + j] += c;
                    assembled[j * *n + *free + e] += c;
                }
            }
        }
        for relative in [1e-17, 1e-14, 1e-11] {
            if self.try_factorise(equalities, relative).is_some() {
                return Some(());
            }
        }
        None
    }

    fn try_factorise(
        &mut self,
        equalities: &[(Vec<(usize, f64)>, f64)],
        relative: f64,
    ) -> Option<()> {
        match self {
            Kkt::Dense {
                n,
                free,
                assembled,
                matrix,
                pivots,
            } => {
                let n = *n;
                let largest = (0..*free).fold(0.0f64, |m, i| m.max(assembled[i * n + i]));
                let delta = relative * (1.0 + largest);
                matrix.copy_from_slice(assembled);
                for i in 0..n {
                    matrix[i * n + i] += if i < *free { delta } else { -delta };
                }
                lu(matrix, pivots, n)
            }
            Kkt::Banded {
                h,
                factors,
                columns,
                schur,
                pivots,
            } => {
                let delta = relative * (1.0 + h.largest_diagonal());
                factors.copy_values(h);
                factors.shift(delta);
                factors.factorise()?;
                let m = equalities.len();
                for (column, (a, _)) in columns.iter_mut().zip(equalities) {
                    column.iter_mut().for_each(|x| *x = 0.0);
                    for &(j, c) in a {
                        column[j] += c;
                    }
                    factors.solve(column);
                }
                for (e, (a, _)) in equalities.iter().enumerate() {
                    for (f, column) in columns.iter().enumerate() {
                        schur[e * m + f] = dot(a, column);
                    }
                }
                lu(schur, pivots, m)
            }
        }
    }

    /// Solves the factorised system for `[r1; r2]` (free variables, then equalities), in
    /// place: `[Δx; w]` with `H·Δx + Eᵀ·w = r1`, `E·Δx = r2`.
    pub fn solve(&self, equalities: &[(Vec<(usize, f64)>, f64)], rhs: &mut [f64]) {
        match self {
            Kkt::Dense {
                n, matrix, pivots, ..
            } => lu_solve(matrix, pivots, *n, rhs),
            Kkt::Banded { h, .. } => {
                // The factors are of a regularised `H` and the Schur complement rounds: one
                // pass of refinement against `H` as assembled restores the digits the
                // interior point needs near the optimum.
                let b = rhs.to_vec();
                self.solve_banded(equalities, rhs);
                let free = h.size();
                let hx = h.multiply(&rhs[..free]);
                let mut residual = b;
                for (r, v) in residual.iter_mut().zip(hx) {
                    *r -= v;
                }
                for (e, (a, _)) in equalities.iter().enumerate() {
                    let w = rhs[free + e];
                    let mut ex = 0.0;
                    for &(j, c) in a {
                        residual[j] -= c * w;
                        ex += c * rhs[j];
                    }
                    residual[free + e] -= ex;
                }
                self.solve_banded(equalities, &mut residual);
                for (x, d) in rhs.iter_mut().zip(residual) {
                    *x += d;
                }
            }
        }
    }

    /// The banded system's answer from its factors alone.
    fn solve_banded(&self, equalities: &[(Vec<(usize, f64)>, f64)], rhs: &mut [f64]) {
        let Kkt::Banded {
            factors,
            columns,
            schur,
            pivots,
            ..
        } = self
        else {
            return;
        };
        let (x, w) = rhs.split_at_mut(factors.size());
        factors.solve(x);
        for (we, (a, _)) in w.iter_mut().zip(equalities) {
            *we = dot(a, x) - *we;
        }
        lu_solve(schur, pivots, equalities.len(), w);
        for (column, we) in columns.iter().zip(w.iter()) {
            for (xi, ci) in x.iter_mut().zip(column) {
                *xi -= ci * we;
            }
        }
    }
}

/// LU factorisation with partial pivoting of the `n × n` row-major `a`, in place; `None` when
/// a pivot is negligible against the matrix.
pub fn lu(a: &mut [f64], pivots: &mut [usize], n: usize) -> Option<()> {
    let largest = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let tiny = 1e-300_f64.max(largest * 1e-18);
    for col in 0..n {
        let pivot = (col..n)
            .max_by(|&i, &j| a[i * n + col].abs().total_cmp(&a[j * n + col].abs()))
            .unwrap_or(col);
        if a[pivot * n + col].abs() <= tiny || !a[pivot * n + col].is_finite() {
            return None;
        }
        pivots[col] = pivot;
        if pivot != col {
            for j in 0..n {
                a.swap(col * n + j, pivot * n + j);
            }
        }
        let p = a[col * n + col];
        for i in col + 1..n {
            let f = a[i * n + col] / p;
            if f == 0.0 {
                continue;
            }
            a[i * n + col] = f;
            for j in col + 1..n {
                a[i * n + j] -= f * a[col * n + j];
            }
        }
    }
    Some(())
}

pub fn lu_solve(a: &[f64], pivots: &[usize], n: usize, b: &mut [f64]) {
    for (col, &pivot) in pivots.iter().enumerate() {
        b.swap(col, pivot);
    }
    for i in 0..n {
        let sum: f64 = (0..i).map(|j| a[i * n + j] * b[j]).sum();
        b[i] -= sum;
    }
    for i in (0..n).rev() {
        let sum: f64 = (i + 1..n).map(|j| a[i * n + j] * b[j]).sum();
        b[i] = (b[i] - sum) / a[i * n + i];
    }
}
