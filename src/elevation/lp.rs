//! The linear program that settles elevations (thesis §4.3), made robust.
//!
//! Every variable is an elevation with a target (the approximated terrain) and a weight: the
//! objective charges `weight · |x − target|` through a positive and a negative part (§4.3.2).
//! Beyond the thesis, it also charges `weight · |a·x + b·y + c·z|` for smoothness terms (the
//! change of slope between consecutive segments of a way), so ramps and bridge decks come out
//! smooth instead of peaked (§4.3.3, figure 4.9). Constraints are linear (in)equalities over a
//! few variables; those that come from tags and defaults are *soft*: a slack, charged at a
//! large penalty, lets a contradiction bend only the variables involved instead of making the
//! whole problem infeasible, and every slack used is reported.
//!
//! The problem is split into independent components (union-find over constraints and
//! smoothness terms); a variable in no constraint keeps its target without entering an LP.
//! Each component is solved by [`interior`], an interior-point solver made for these programs
//! (its Newton system dense for a small component, banded for a large one); one it gives up on,
//! by clarabel ([`reference`]), a general interior-point solver. Both hold equalities to about
//! 1e-9: two-variable equalities are snapped exactly afterwards. The integration test `lp`
//! holds the first to the second's optimum on components recorded from the bundled tiles
//! ([`text`]).

use std::collections::HashMap;

use super::solutions::{self, Key, KeyWriter, Solutions};

mod envelope;
pub mod interior;
mod kkt;
pub mod reference;
pub mod text;

/// A linear relation over some variables: `Σ coefficient · x (kind) rhs`.
#[derive(Debug, Clone, PartialEq)]
pub struct Constraint {
    pub terms: Vec<(usize, f64)>,
    pub kind: Relation,
    pub rhs: f64,
    /// `None` for a hard constraint; else the penalty per metre of violation.
    pub penalty: Option<f64>,
    /// What the constraint stands for, for reports (an index into the caller's list).
    pub label: u32,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Relation {
    Equal,
    AtLeast,
    AtMost,
}

/// A penalised linear combination: `weight · |Σ coefficient · x|`.
#[derive(Debug, Clone, PartialEq)]
pub struct Smoothness {
    pub terms: Vec<(usize, f64)>,
    pub weight: f64,
}

/// The whole problem: one target, weight and optional fixed value per variable.
#[derive(Debug, Clone, Default)]
pub struct Problem {
    pub targets: Vec<f64>,
    pub weights: Vec<f64>,
    /// A fixed variable takes this value whatever else asks (a vertex on a tile edge).
    pub fixed: Vec<Option<f64>>,
    pub constraints: Vec<Constraint>,
    pub smoothness: Vec<Smoothness>,
}

impl Problem {
    /// Adds a variable; returns its index.
    pub fn variable(&mut self, target: f64, weight: f64) -> usize {
        self.targets.push(target);
        self.weights.push(weight);
        self.fixed.push(None);
        self.targets.len() - 1
    }

    pub fn fix(&mut self, variable: usize, value: f64) {
        self.fixed[variable] = Some(value);
    }
}

/// A soft constraint that had to give way.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Violation {
    pub label: u32,
    /// How far the constraint is from holding, metres.
    pub amount: f64,
}

/// The solution and what it took.
#[derive(Debug, Clone, Default)]
pub struct Outcome {
    pub values: Vec<f64>,
    pub violations: Vec<Violation>,
    /// Components solved as LPs, and the largest one's variable and constraint counts.
    pub components: usize,
    pub largest: (usize, usize),
    /// Components the solver could not solve (they keep their targets; hard constraints
    /// among fixed values that contradict each other, say).
    pub failed: usize,
}

/// Slack below this (metres) is rounding, not a violation.
pub const VIOLATION_EPS: f64 = 1e-4;

/// Solves the problem component by component; a component `memo` holds is found there, one
/// solved is kept in it.
pub fn solve(problem: &Problem, memo: &Solutions) -> Outcome {
    let n = problem.targets.len();
    let mut values: Vec<f64> = (0..n)
        .map(|i| problem.fixed[i].unwrap_or(problem.targets[i]))
        .collect();
    let mut sets = UnionFind::new(n);
    let term_lists = problem
        .constraints
        .iter()
        .map(|c| &c.terms)
        .chain(problem.smoothness.iter().map(|s| &s.terms));
    for terms in term_lists {
        for pair in terms.windows(2) {
            sets.union(pair[0].0, pair[1].0);
        }
    }
    // Members and constraints of each component with at least one constraint or term.
    let mut component_of = vec![usize::MAX; n];
    let mut count = 0;
    let mut id_of = |v: usize, sets: &mut UnionFind| {
        let root = sets.find(v);
        if component_of[root] == usize::MAX {
            component_of[root] = count;
            count += 1;
        }
        component_of[root]
    };
    let constraint_ids: Vec<Option<usize>> = problem
        .constraints
        .iter()
        .map(|c| c.terms.first().map(|&(v, _)| id_of(v, &mut sets)))
        .collect();
    let smooth_ids: Vec<Option<usize>> = problem
        .smoothness
        .iter()
        .map(|s| s.terms.first().map(|&(v, _)| id_of(v, &mut sets)))
        .collect();
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); count];
    let mut constraints: Vec<Vec<usize>> = vec![Vec::new(); count];
    let mut smooth: Vec<Vec<usize>> = vec![Vec::new(); count];
    for (k, id) in constraint_ids.into_iter().enumerate() {
        if let Some(id) = id {
            constraints[id].push(k);
        }
    }
    for (k, id) in smooth_ids.into_iter().enumerate() {
        if let Some(id) = id {
            smooth[id].push(k);
        }
    }
    for v in 0..n {
        let root = sets.find(v);
        if component_of[root] != usize::MAX {
            members[component_of[root]].push(v);
        }
    }
    let mut outcome = Outcome::default();
    let solved = solve_all(problem, memo, &members, &constraints, &smooth);
    for (id, solution) in solved.into_iter().enumerate() {
        outcome.components += 1;
        let size = (members[id].len(), constraints[id].len());
        if size.0 > outcome.largest.0 {
            outcome.largest = size;
        }
        match solution {
            Some((solved, violations)) => {
                // A fixed variable keeps its value to the bit (tile edges must match).
                for (&v, x) in members[id].iter().zip(solved) {
                    values[v] = problem.fixed[v].unwrap_or(x);
                }
                outcome.violations.extend(violations);
            }
            None => outcome.failed += 1,
        }
    }
    snap_equalities(problem, &mut values);
    outcome.values = values;
    outcome
}

/// Components below this many are solved on the calling thread.
const COMPONENTS_PER_THREAD: usize = 16;
/// Most threads one problem's components are spread over.
const MAX_THREADS: usize = 4;

type Solved = Option<(Vec<f64>, Vec<Violation>)>;

/// Solves every component, spread over a few threads when there are many: each component is
/// solved alone, so the result does not depend on how they are spread. Threads take the
/// largest components first, the next one as they come free, so one large component does not
/// hold up a share of small ones.
fn solve_all(
    problem: &Problem,
    memo: &Solutions,
    members: &[Vec<usize>],
    constraints: &[Vec<usize>],
    smooth: &[Vec<usize>],
) -> Vec<Solved> {
    let solve_one =
        |id: usize| solve_component(problem, memo, &members[id], &constraints[id], &smooth[id]);
    let count = members.len();
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(MAX_THREADS)
        .min(count / COMPONENTS_PER_THREAD)
        .max(1);
    if threads == 1 {
        return (0..count).map(solve_one).collect();
    }
    let mut order: Vec<usize> = (0..count).collect();
    order.sort_by_key(|&id| std::cmp::Reverse(members[id].len() + constraints[id].len()));
    let next = std::sync::atomic::AtomicUsize::new(0);
    let shares: Vec<Vec<(usize, Solved)>> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..threads)
            .map(|_| {
                scope.spawn(|| {
                    let mut share = Vec::new();
                    loop {
                        let at = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        let Some(&id) = order.get(at) else {
                            return share;
                        };
                        share.push((id, solve_one(id)));
                    }
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| {
                h.join()
                    .unwrap_or_else(|payload| std::panic::resume_unwind(payload))
            })
            .collect()
    });
    let mut out: Vec<Solved> = (0..count).map(|_| None).collect();
    for (id, solution) in shares.into_iter().flatten() {
        out[id] = solution;
    }
    out
}

/// One component as an LP; `None` if the solver fails. A component solved before (in this
/// tile or another) is taken from `memo`.
fn solve_component(
    problem: &Problem,
    memo: &Solutions,
    members: &[usize],
    constraints: &[usize],
    smooth: &[usize],
) -> Option<(Vec<f64>, Vec<Violation>)> {
    let component = component(problem, members, constraints, smooth);
    let key = component_key(&component);
    // A solution with a value for each member, each finite: anything else was damaged on
    // its way through a durable store.
    let sound = |kept: &Option<solutions::Solved>| {
        kept.as_ref().is_none_or(|s| {
            s.values.len() == members.len() && s.values.iter().all(|v| v.is_finite())
        })
    };
    let solved = memo.get_or_solve(key, sound, || {
        if memo.records() {
            memo.record(text::write(&component));
        }
        solve_afresh(&component)
    });
    let solved = Option::as_ref(&solved)?;
    let violations = solved
        .violations
        .iter()
        .filter_map(|&(at, amount)| {
            let k = *constraints.get(at as usize)?;
            Some(Violation {
                label: problem.constraints[k].label,
                amount,
            })
        })
        .collect();
    Some((solved.values.clone(), violations))
}

/// The component over `members` as a problem of its own: variables in member order, then its
/// smoothness terms and constraints in order, over the members' positions. Labels are kept.
fn component(
    problem: &Problem,
    members: &[usize],
    constraints: &[usize],
    smooth: &[usize],
) -> Problem {
    let local: HashMap<usize, usize> = members.iter().enumerate().map(|(k, &v)| (v, k)).collect();
    let terms = |terms: &[(usize, f64)]| -> Vec<(usize, f64)> {
        terms.iter().map(|&(v, a)| (local[&v], a)).collect()
    };
    Problem {
        targets: members.iter().map(|&v| problem.targets[v]).collect(),
        weights: members.iter().map(|&v| problem.weights[v]).collect(),
        fixed: members.iter().map(|&v| problem.fixed[v]).collect(),
        constraints: constraints
            .iter()
            .map(|&k| {
                let c = &problem.constraints[k];
                Constraint {
                    terms: terms(&c.terms),
                    ..c.clone()
                }
            })
            .collect(),
        smoothness: smooth
            .iter()
            .map(|&k| Smoothness {
                terms: terms(&problem.smoothness[k].terms),
                weight: problem.smoothness[k].weight,
            })
            .collect(),
    }
}

/// The digest of a component as the solvers read it (labels aside: they only name
/// constraints for reports).
fn component_key(component: &Problem) -> Key {
    let mut key = KeyWriter::new();
    key.count(component.targets.len());
    for v in 0..component.targets.len() {
        key.optional(component.fixed[v])
            .number(component.weights[v])
            .number(component.targets[v]);
    }
    let terms = |key: &mut KeyWriter, terms: &[(usize, f64)]| {
        key.count(terms.len());
        for &(v, a) in terms {
            key.count(v).number(a);
        }
    };
    key.count(component.smoothness.len());
    for s in &component.smoothness {
        key.number(s.weight);
        terms(&mut key, &s.terms);
    }
    key.count(component.constraints.len());
    for c in &component.constraints {
        terms(&mut key, &c.terms);
        key.tag(c.kind as u8).number(c.rhs).optional(c.penalty);
    }
    key.finish()
}

/// One component solved afresh: by [`interior`] when it converges, else by clarabel.
/// Violations name the constraint by its position in the component.
fn solve_afresh(component: &Problem) -> Option<solutions::Solved> {
    interior::solve(component).or_else(|| reference::solve(component))
}

/// What `values` cost in `problem`'s objective: each free variable's weighted distance to its
/// target, each smoothness term, and each soft constraint's penalty for its shortfall.
pub fn objective(problem: &Problem, values: &[f64]) -> f64 {
    let dot = |terms: &[(usize, f64)]| dot(terms, values);
    let targets: f64 = (0..values.len())
        .filter(|&v| problem.fixed[v].is_none())
        .map(|v| problem.weights[v] * (values[v] - problem.targets[v]).abs())
        .sum();
    let smooth: f64 = problem
        .smoothness
        .iter()
        .map(|s| s.weight * dot(&s.terms).abs())
        .sum();
    let penalties: f64 = problem
        .constraints
        .iter()
        .map(|c| c.penalty.unwrap_or(0.0) * shortfall(c, dot(&c.terms)))
        .sum();
    targets + smooth + penalties
}

/// `Σ coefficient · value` over `terms`.
pub fn dot(terms: &[(usize, f64)], values: &[f64]) -> f64 {
    terms.iter().map(|&(v, a)| a * values[v]).sum()
}

/// How far a constraint with left-hand side `lhs` is from holding.
pub fn shortfall(c: &Constraint, lhs: f64) -> f64 {
    match c.kind {
        Relation::AtLeast => (c.rhs - lhs).max(0.0),
        Relation::AtMost => (lhs - c.rhs).max(0.0),
        Relation::Equal => (lhs - c.rhs).abs(),
    }
}

/// Makes hard two-variable equalities (`x − y = d`) hold exactly: each group follows the
/// variable in it that comes first, or a fixed one.
fn snap_equalities(problem: &Problem, values: &mut [f64]) {
    for c in &problem.constraints {
        if c.penalty.is_some() || c.kind != Relation::Equal {
            continue;
        }
        if let [(a, ca), (b, cb)] = c.terms[..] {
            // ca·x_a + cb·x_b = rhs: the later variable follows the earlier one.
            let (keep, follow, ck, cf) =
                if problem.fixed[b].is_some() || (a > b && problem.fixed[a].is_none()) {
                    (b, a, cb, ca)
                } else {
                    (a, b, ca, cb)
                };
            if problem.fixed[follow].is_none() && cf != 0.0 {
                values[follow] = (c.rhs - ck * values[keep]) / cf;
            }
        }
    }
}

/// Disjoint sets of variables.
struct UnionFind {
    parent: Vec<usize>,
}

impl UnionFind {
    fn new(n: usize) -> UnionFind {
        UnionFind {
            parent: (0..n).collect(),
        }
    }

    fn find(&mut self, mut v: usize) -> usize {
        while self.parent[v] != v {
            self.parent[v] = self.parent[self.parent[v]];
            v = self.parent[v];
        }
        v
    }

    fn union(&mut self, a: usize, b: usize) {
        let (a, b) = (self.find(a), self.find(b));
        if a != b {
            self.parent[a.max(b)] = a.min(b);
        }
    }
}

#[cfg(test)]
mod tests;
