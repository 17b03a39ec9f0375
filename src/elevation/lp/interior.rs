//! An interior-point solver made for the elevation programs: Mehrotra's predictor–corrector
//! on the program's own shape.
//!
//! Every term of a component's objective is one of three kinds over a sparse row `a·x` of its
//! free variables: a charged distance `|a·x − b|` (a variable's distance to its target, a
//! smoothness term, a soft equality), a charged shortfall `max(0, b − a·x)` (a soft bound) or
//! nothing at all with a hard bound `a·x ≥ b`. Each charged term has one auxiliary variable `u`
//! (`u ≥ |a·x − b|`, or `u ≥ b − a·x` and `u ≥ 0`), which appears in its own two rows only: the
//! Newton system eliminates it on the spot, so what is factorised is a matrix over the free
//! variables and the hard equalities only ([`super::kkt`]: dense for a small component, banded
//! for a large one). A general solver (clarabel) pays for a sparse factorisation of the whole
//! split program instead, several times the size.
//!
//! Like clarabel it follows the central path to a gap of about 1e-9, so where the optimum is
//! not a single point both end near the same point of the optimal face. It gives up (and the
//! caller turns to clarabel) on what it is not made for: hard constraints among fixed values
//! only, a negative weight, or no convergence within its iterations.

use super::kkt::Kkt;
use super::{dot, shortfall, Problem, Relation, VIOLATION_EPS};
use crate::elevation::solutions::Solved;

/// Primal and dual residuals, relative to the size of the data, at which a point is feasible.
const FEASIBLE: f64 = 1e-9;
/// Duality gap, absolute or relative to the objective, at which a feasible point is optimal
/// (the gap cannot close much below the rounding of `cost · x`, about 1e-9 here).
const GAP_ABSOLUTE: f64 = 1e-8;
const GAP_RELATIVE: f64 = 1e-9;
const MAX_ITERATIONS: usize = 80;
/// Fraction of the way to the boundary a step goes.
const STEP: f64 = 0.99;

#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    /// `u ≥ |a·x − b|`, `cost · u` charged.
    Distance,
    /// `u ≥ b − a·x`, `u ≥ 0`, `cost · u` charged.
    Shortfall,
    /// `a·x ≥ b`, no auxiliary variable.
    Bound,
}

/// One term of the program: a sparse row over the free variables and what it asks of it.
#[derive(Debug)]
struct Term {
    a: Vec<(usize, f64)>,
    b: f64,
    kind: Kind,
    cost: f64,
}

impl Term {
    /// The term's rows as `(coefficient of u, coefficient of a·x, constant)`: each row reads
    /// `cu·u + cx·(a·x) − h ≥ 0`. A bound has one row; the second is unused.
    fn rows(&self) -> [(f64, f64, f64); 2] {
        match self.kind {
            Kind::Distance => [(1.0, -1.0, -self.b), (1.0, 1.0, self.b)],
            Kind::Shortfall => [(1.0, 1.0, self.b), (1.0, 0.0, 0.0)],
            Kind::Bound => [(0.0, 1.0, self.b), (0.0, 0.0, 0.0)],
        }
    }

    fn row_count(&self) -> usize {
        if self.kind == Kind::Bound {
            1
        } else {
            2
        }
    }

    fn dot(&self, x: &[f64]) -> f64 {
        dot(&self.a, x)
    }
}

/// A component over its free variables: charged terms and hard bounds, and hard equalities.
#[derive(Debug, Default)]
struct Program {
    /// The component's variable behind each free variable, which is measured from that
    /// variable's target (so the numbers the solver works on are metres of change, not
    /// elevations, and its residuals round far less).
    free: Vec<usize>,
    terms: Vec<Term>,
    equalities: Vec<(Vec<(usize, f64)>, f64)>,
}

impl Program {
    /// Indices of the rows in use (a bound's second row is not).
    fn rows(&self) -> impl Iterator<Item = usize> + '_ {
        self.terms
            .iter()
            .enumerate()
            .flat_map(|(k, t)| (0..t.row_count()).map(move |r| 2 * k + r))
    }

    /// `f` of each row in use, 0 for the others.
    fn per_row(&self, f: impl Fn(usize) -> f64) -> Vec<f64> {
        let mut out = vec![0.0; 2 * self.terms.len()];
        for i in self.rows() {
            out[i] = f(i);
        }
        out
    }

    /// The longest step along `d` that keeps every used entry of `v` positive.
    fn step(&self, v: &[f64], d: &[f64]) -> f64 {
        self.rows()
            .filter(|&i| d[i] < 0.0)
            .map(|i| -v[i] / d[i])
            .fold(f64::INFINITY, f64::min)
    }
}

/// Solves a component; `None` when it is not one this solver takes or it does not converge.
/// Violations name soft constraints by their position, as clarabel's answer does.
pub fn solve(component: &Problem) -> Option<Solved> {
    let program = program(component)?;
    let x = if program.free.is_empty() {
        Vec::new()
    } else {
        Iterate::start(&program).run(&program)?
    };
    let mut values: Vec<f64> = (0..component.targets.len())
        .map(|v| component.fixed[v].unwrap_or(component.targets[v]))
        .collect();
    for (j, &v) in program.free.iter().enumerate() {
        values[v] += x[j];
    }
    if values.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let violations = violations(component, &values);
    Some(Solved { values, violations })
}

/// How far each soft constraint is from holding at `values`, where that is more than
/// rounding.
fn violations(component: &Problem, values: &[f64]) -> Vec<(u32, f64)> {
    component
        .constraints
        .iter()
        .enumerate()
        .filter(|(_, c)| c.penalty.is_some())
        .filter_map(|(at, c)| {
            let amount = shortfall(c, dot(&c.terms, values));
            (amount > VIOLATION_EPS).then_some((at as u32, amount))
        })
        .collect()
}

/// The component in this solver's shape; `None` for what it does not take.
fn program(component: &Problem) -> Option<Program> {
    let n = component.targets.len();
    let mut index = vec![usize::MAX; n];
    let mut p = Program::default();
    for (v, fixed) in component.fixed.iter().enumerate() {
        if fixed.is_none() {
            index[v] = p.free.len();
            p.free.push(v);
        }
    }
    // A row over the free variables, and the constant the fixed values and the free
    // variables' targets add to it.
    let split = |terms: &[(usize, f64)]| -> (Vec<(usize, f64)>, f64) {
        let mut a = Vec::with_capacity(terms.len());
        let mut constant = 0.0;
        for &(v, c) in terms {
            match component.fixed[v] {
                Some(value) => constant += c * value,
                None => {
                    a.push((index[v], c));
                    constant += c * component.targets[v];
                }
            }
        }
        (a, constant)
    };
    for (j, &v) in p.free.iter().enumerate() {
        let weight = component.weights[v];
        if weight < 0.0 || !weight.is_finite() {
            return None;
        }
        if weight > 0.0 {
            p.terms.push(Term {
                a: vec![(j, 1.0)],
                b: 0.0,
                kind: Kind::Distance,
                cost: weight,
            });
        }
    }
    for s in &component.smoothness {
        let (a, constant) = split(&s.terms);
        if s.weight < 0.0 || !s.weight.is_finite() {
            return None;
        }
        if s.weight > 0.0 && !a.is_empty() {
            p.terms.push(Term {
                a,
                b: -constant,
                kind: Kind::Distance,
                cost: s.weight,
            });
        }
    }
    for c in &component.constraints {
        let (a, constant) = split(&c.terms);
        let b = c.rhs - constant;
        if a.is_empty() {
            // Among fixed values only: a soft one is reported as it stands, a hard one must
            // hold (else the component is infeasible, which clarabel reports).
            let holds = shortfall(c, constant) <= FEASIBLE * (1.0 + c.rhs.abs());
            if c.penalty.is_none() && !holds {
                return None;
            }
            continue;
        }
        let negated = || a.iter().map(|&(j, x)| (j, -x)).collect();
        let (a, b, kind, cost) = match (c.penalty, c.kind) {
            (None, Relation::Equal) => {
                p.equalities.push((a, b));
                continue;
            }
            (None, Relation::AtLeast) => (a, b, Kind::Bound, 0.0),
            (None, Relation::AtMost) => (negated(), -b, Kind::Bound, 0.0),
            (Some(penalty), _) if penalty <= 0.0 || !penalty.is_finite() => return None,
            (Some(penalty), Relation::Equal) => (a, b, Kind::Distance, penalty),
            (Some(penalty), Relation::AtLeast) => (a, b, Kind::Shortfall, penalty),
            (Some(penalty), Relation::AtMost) => (negated(), -b, Kind::Shortfall, penalty),
        };
        p.terms.push(Term { a, b, kind, cost });
    }
    Some(p)
}

/// A primal–dual point: free variables `x`, each term's `u`, each row's slack `s` and dual
/// `y` (two rows a term, the second unused for a bound), each equality's dual `nu`.
struct Iterate {
    x: Vec<f64>,
    u: Vec<f64>,
    s: Vec<f64>,
    y: Vec<f64>,
    nu: Vec<f64>,
}

/// Residuals of an iterate: rows, equalities, dual over `x` and over each `u`.
struct Residuals {
    rows: Vec<f64>,
    equalities: Vec<f64>,
    dual_x: Vec<f64>,
    dual_u: Vec<f64>,
    /// Mean complementarity `s·y / rows`.
    mu: f64,
    /// The largest sum of magnitudes behind an entry of `dual_x`: the rounding it can hold.
    dual_size: f64,
}

/// A Newton direction.
struct Direction {
    x: Vec<f64>,
    u: Vec<f64>,
    s: Vec<f64>,
    y: Vec<f64>,
    nu: Vec<f64>,
}

impl Iterate {
    /// Starts at the targets (no change), every row's slack at least 1 and each charged term's cost shared
    /// between its two rows' duals.
    fn start(p: &Program) -> Iterate {
        let m = p.terms.len();
        let mut it = Iterate {
            x: vec![0.0; p.free.len()],
            u: vec![0.0; m],
            s: vec![1.0; 2 * m],
            y: vec![0.0; 2 * m],
            nu: vec![0.0; p.equalities.len()],
        };
        for (k, t) in p.terms.iter().enumerate() {
            let q = t.dot(&it.x);
            match t.kind {
                Kind::Distance => it.u[k] = (q - t.b).abs() + 1.0,
                Kind::Shortfall => it.u[k] = (t.b - q).max(0.0) + 1.0,
                Kind::Bound => {}
            }
            for (r, &(cu, cx, h)) in t.rows().iter().enumerate().take(t.row_count()) {
                it.s[2 * k + r] = (cu * it.u[k] + cx * q - h).max(1.0);
                it.y[2 * k + r] = if t.kind == Kind::Bound {
                    1.0
                } else {
                    t.cost / 2.0
                };
            }
        }
        it
    }

    /// Iterates to an optimum; `None` if it is not reached.
    fn run(mut self, p: &Program) -> Option<Vec<f64>> {
        let scale = Scale::of(p);
        let mut system = System::new(p)?;
        for _ in 0..MAX_ITERATIONS {
            let r = self.residuals(p);
            if self.converged(p, &r, &scale) {
                return Some(self.x);
            }
            system.factorise(p, &self)?;
            // Predictor: straight for the optimum.
            let comp = p.per_row(|i| -self.s[i] * self.y[i]);
            let affine = system.direction(p, &self, &r, &comp);
            let ap = p.step(&self.s, &affine.s).min(1.0);
            let ad = p.step(&self.y, &affine.y).min(1.0);
            let rows = p.rows().count() as f64;
            let mu_affine = p
                .rows()
                .map(|i| (self.s[i] + ap * affine.s[i]) * (self.y[i] + ad * affine.y[i]))
                .sum::<f64>()
                / rows;
            let sigma = (mu_affine / r.mu).clamp(0.0, 1.0).powi(3);
            // Corrector: back towards the central path, with the predictor's second order.
            let comp =
                p.per_row(|i| -self.s[i] * self.y[i] - affine.s[i] * affine.y[i] + sigma * r.mu);
            let d = system.direction(p, &self, &r, &comp);
            let ap = (STEP * p.step(&self.s, &d.s)).min(1.0);
            let ad = (STEP * p.step(&self.y, &d.y)).min(1.0);
            self.advance(p, &d, ap, ad);
        }
        None
    }

    fn advance(&mut self, p: &Program, d: &Direction, ap: f64, ad: f64) {
        for (x, dx) in self.x.iter_mut().zip(&d.x) {
            *x += ap * dx;
        }
        for (u, du) in self.u.iter_mut().zip(&d.u) {
            *u += ap * du;
        }
        for i in p.rows() {
            self.s[i] += ap * d.s[i];
            self.y[i] += ad * d.y[i];
        }
        for (nu, dnu) in self.nu.iter_mut().zip(&d.nu) {
            *nu += ad * dnu;
        }
    }

    fn residuals(&self, p: &Program) -> Residuals {
        let m = p.terms.len();
        let mut r = Residuals {
            rows: vec![0.0; 2 * m],
            equalities: Vec::with_capacity(p.equalities.len()),
            dual_x: vec![0.0; self.x.len()],
            dual_u: vec![0.0; m],
            mu: 0.0,
            dual_size: 0.0,
        };
        let mut size = vec![0.0; self.x.len()];
        let mut used = 0;
        for (k, t) in p.terms.iter().enumerate() {
            let q = t.dot(&self.x);
            let mut along = 0.0;
            r.dual_u[k] = t.cost;
            for (i, &(cu, cx, h)) in t.rows().iter().enumerate().take(t.row_count()) {
                let row = 2 * k + i;
                r.rows[row] = cu * self.u[k] + cx * q - h - self.s[row];
                along += self.y[row] * cx;
                r.dual_u[k] -= self.y[row] * cu;
                r.mu += self.s[row] * self.y[row];
                used += 1;
            }
            for &(j, c) in &t.a {
                r.dual_x[j] -= along * c;
                size[j] += (along * c).abs();
            }
        }
        for ((a, b), nu) in p.equalities.iter().zip(&self.nu) {
            r.equalities.push(dot(a, &self.x) - b);
            for &(j, c) in a {
                r.dual_x[j] -= nu * c;
                size[j] += (nu * c).abs();
            }
        }
        r.mu /= used.max(1) as f64;
        r.dual_size = size.iter().fold(0.0, |m: f64, x| m.max(*x));
        r
    }

    fn converged(&self, p: &Program, r: &Residuals, scale: &Scale) -> bool {
        let worst = |v: &[f64]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let primal = worst(&r.rows) <= FEASIBLE * (1.0 + scale.rows)
            && worst(&r.equalities) <= FEASIBLE * (1.0 + scale.equalities);
        let dual = worst(&r.dual_x).max(worst(&r.dual_u))
            <= FEASIBLE * (1.0 + scale.costs.max(r.dual_size));
        if !(primal && dual) {
            return false;
        }
        let primal_objective: f64 = p.terms.iter().zip(&self.u).map(|(t, u)| t.cost * u).sum();
        let dual_objective: f64 = p
            .terms
            .iter()
            .enumerate()
            .flat_map(|(k, t)| {
                let y = &self.y;
                t.rows()
                    .into_iter()
                    .take(t.row_count())
                    .enumerate()
                    .map(move |(i, (_, _, h))| h * y[2 * k + i])
            })
            .chain(p.equalities.iter().zip(&self.nu).map(|((_, b), nu)| b * nu))
            .sum();
        let gap = (primal_objective - dual_objective).abs();
        gap <= GAP_ABSOLUTE || gap <= GAP_RELATIVE * primal_objective.abs()
    }
}

/// The size of a program's data, to which residuals are compared.
struct Scale {
    rows: f64,
    equalities: f64,
    costs: f64,
}

impl Scale {
    fn of(p: &Program) -> Scale {
        Scale {
            rows: p.terms.iter().fold(0.0, |m, t| m.max(t.b.abs())),
            equalities: p.equalities.iter().fold(0.0, |m, (_, b)| m.max(b.abs())),
            costs: p.terms.iter().fold(0.0, |m, t| m.max(t.cost)),
        }
    }
}

/// The Newton system over the free variables and the equalities' duals, with each term's
/// auxiliary variable eliminated, factorised once per iteration for both of its directions.
struct System {
    kkt: Kkt,
    /// Per term with an auxiliary variable: `Σ D·cu`, `Σ D·cu·cx` (with `D = y/s` over its
    /// rows), 0 for a bound.
    alpha: Vec<f64>,
    beta: Vec<f64>,
}

impl System {
    fn new(p: &Program) -> Option<System> {
        let cliques = p
            .terms
            .iter()
            .map(|t| t.a.iter().map(|&(j, _)| j).collect());
        Some(System {
            kkt: Kkt::new(p.free.len(), &p.equalities, cliques)?,
            alpha: vec![0.0; p.terms.len()],
            beta: vec![0.0; p.terms.len()],
        })
    }

    /// Assembles and factorises the system at `it`; `None` if it is singular even with the
    /// largest regularisation tried.
    fn factorise(&mut self, p: &Program, it: &Iterate) -> Option<()> {
        self.kkt.clear();
        for (k, t) in p.terms.iter().enumerate() {
            let [(_, cx1, _), (_, cx2, _)] = t.rows();
            let d1 = it.y[2 * k] / it.s[2 * k];
            let weight = if t.kind == Kind::Bound {
                (self.alpha[k], self.beta[k]) = (0.0, 0.0);
                d1 * cx1 * cx1
            } else {
                // Both rows have u's coefficient 1: eliminating u leaves
                // D1·D2·(cx1 − cx2)² / (D1 + D2), written so that it does not cancel.
                let d2 = it.y[2 * k + 1] / it.s[2 * k + 1];
                (self.alpha[k], self.beta[k]) = (d1 + d2, d1 * cx1 + d2 * cx2);
                d1 * d2 * (cx1 - cx2) * (cx1 - cx2) / (d1 + d2)
            };
            self.kkt.add_outer(&t.a, weight);
        }
        self.kkt.factorise(&p.equalities)
    }

    /// The direction for complementarity target `comp` (`S·Δy + Y·Δs = comp`).
    fn direction(&self, p: &Program, it: &Iterate, r: &Residuals, comp: &[f64]) -> Direction {
        let (free, m) = (p.free.len(), p.terms.len());
        let n = free + p.equalities.len();
        // v = S⁻¹·comp − W·r_p, per row.
        let mut rhs = vec![0.0; n];
        let mut rho_u = vec![0.0; m];
        for (j, d) in r.dual_x.iter().enumerate() {
            rhs[j] = -d;
        }
        for (k, t) in p.terms.iter().enumerate() {
            let mut along = 0.0;
            rho_u[k] = -r.dual_u[k];
            for (i, &(cu, cx, _)) in t.rows().iter().enumerate().take(t.row_count()) {
                let row = 2 * k + i;
                let v = (comp[row] - it.y[row] * r.rows[row]) / it.s[row];
                along += v * cx;
                rho_u[k] += v * cu;
            }
            if self.alpha[k] > 0.0 {
                along -= self.beta[k] / self.alpha[k] * rho_u[k];
            }
            for &(j, c) in &t.a {
                rhs[j] += along * c;
            }
        }
        for (e, residual) in r.equalities.iter().enumerate() {
            rhs[free + e] = -residual;
        }
        self.kkt.solve(&p.equalities, &mut rhs);
        let dx = rhs[..free].to_vec();
        let mut d = Direction {
            u: vec![0.0; m],
            s: vec![0.0; 2 * m],
            y: vec![0.0; 2 * m],
            nu: rhs[free..].iter().map(|w| -w).collect(),
            x: dx,
        };
        for (k, t) in p.terms.iter().enumerate() {
            let q = t.dot(&d.x);
            if self.alpha[k] > 0.0 {
                d.u[k] = (rho_u[k] - self.beta[k] * q) / self.alpha[k];
            }
            for (i, &(cu, cx, _)) in t.rows().iter().enumerate().take(t.row_count()) {
                let row = 2 * k + i;
                d.s[row] = cu * d.u[k] + cx * q + r.rows[row];
                d.y[row] = (comp[row] - it.y[row] * d.s[row]) / it.s[row];
            }
        }
        d
    }
}
