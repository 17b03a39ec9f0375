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
//! Each component is solved with clarabel, an interior-point solver whose equalities hold to
//! about 1e-8: two-variable equalities are snapped exactly afterwards.

use std::collections::HashMap;

use good_lp::{clarabel, variable, Expression, ProblemVariables, Solution, SolverModel};

use super::solutions::{self, Key, KeyWriter, Solutions};

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
const VIOLATION_EPS: f64 = 1e-4;

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
/// solved alone, so the result does not depend on how they are spread.
fn solve_all(
    problem: &Problem,
    memo: &Solutions,
    members: &[Vec<usize>],
    constraints: &[Vec<usize>],
    smooth: &[Vec<usize>],
) -> Vec<Solved> {
    let solve_range = |range: std::ops::Range<usize>| -> Vec<Solved> {
        range
            .map(|id| solve_component(problem, memo, &members[id], &constraints[id], &smooth[id]))
            .collect()
    };
    let count = members.len();
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(MAX_THREADS)
        .min(count / COMPONENTS_PER_THREAD)
        .max(1);
    if threads == 1 {
        return solve_range(0..count);
    }
    // Interleaved shares: components of similar size sit together in the list.
    let shares: Vec<Vec<Solved>> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..threads)
            .map(|t| {
                scope.spawn(move || {
                    (t..count)
                        .step_by(threads)
                        .map(|id| {
                            solve_component(
                                problem,
                                memo,
                                &members[id],
                                &constraints[id],
                                &smooth[id],
                            )
                        })
                        .collect::<Vec<Solved>>()
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
    for (t, share) in shares.into_iter().enumerate() {
        for (k, solution) in share.into_iter().enumerate() {
            out[t + k * threads] = solution;
        }
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
    // Each member's position in the component.
    let local: HashMap<usize, usize> = members.iter().enumerate().map(|(k, &v)| (v, k)).collect();
    let key = component_key(problem, members, &local, constraints, smooth);
    // A solution with a value for each member, each finite: anything else was damaged on
    // its way through a durable store.
    let sound = |kept: &Option<solutions::Solved>| {
        kept.as_ref().is_none_or(|s| {
            s.values.len() == members.len() && s.values.iter().all(|v| v.is_finite())
        })
    };
    let solved = memo.get_or_solve(key, sound, || {
        solve_afresh(problem, members, &local, constraints, smooth)
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

/// The digest of a component as [`solve_afresh`] reads it: variables in member order, then
/// smoothness terms and constraints in order, over the members' positions.
fn component_key(
    problem: &Problem,
    members: &[usize],
    local: &HashMap<usize, usize>,
    constraints: &[usize],
    smooth: &[usize],
) -> Key {
    let mut key = KeyWriter::new();
    key.count(members.len());
    for &v in members {
        key.optional(problem.fixed[v])
            .number(problem.weights[v])
            .number(problem.targets[v]);
    }
    let terms = |key: &mut KeyWriter, terms: &[(usize, f64)]| {
        key.count(terms.len());
        for &(v, a) in terms {
            key.count(local.get(&v).copied().unwrap_or(usize::MAX))
                .number(a);
        }
    };
    key.count(smooth.len());
    for &k in smooth {
        let s = &problem.smoothness[k];
        key.number(s.weight);
        terms(&mut key, &s.terms);
    }
    key.count(constraints.len());
    for &k in constraints {
        let c = &problem.constraints[k];
        terms(&mut key, &c.terms);
        key.tag(c.kind as u8).number(c.rhs).optional(c.penalty);
    }
    key.finish()
}

/// One component solved by clarabel; violations name the constraint by its position in
/// `constraints`.
fn solve_afresh(
    problem: &Problem,
    members: &[usize],
    local: &HashMap<usize, usize>,
    constraints: &[usize],
    smooth: &[usize],
) -> Option<solutions::Solved> {
    let mut vars = ProblemVariables::new();
    let x: Vec<good_lp::Variable> = members.iter().map(|_| vars.add(variable())).collect();
    let mut objective = Expression::from(0.0);
    let mut rows: Vec<good_lp::Constraint> = Vec::new();
    for (k, &v) in members.iter().enumerate() {
        match problem.fixed[v] {
            Some(value) => rows.push(Expression::from(x[k]).eq(value)),
            None if problem.weights[v] > 0.0 => {
                // x − target = above − below, both parts charged.
                let above = vars.add(variable().min(0.0));
                let below = vars.add(variable().min(0.0));
                objective += problem.weights[v] * (above + below);
                rows.push((x[k] - above + below).eq(problem.targets[v]));
            }
            None => {}
        }
    }
    let expression = |terms: &[(usize, f64)]| -> Expression {
        terms
            .iter()
            .fold(Expression::from(0.0), |e, &(v, a)| e + a * x[local[&v]])
    };
    for &k in smooth {
        let s = &problem.smoothness[k];
        let (up, down) = (vars.add(variable().min(0.0)), vars.add(variable().min(0.0)));
        objective += s.weight * (up + down);
        rows.push((expression(&s.terms) - up + down).eq(0.0));
    }
    let mut slacks: Vec<(u32, good_lp::Variable, Option<good_lp::Variable>)> = Vec::new();
    for (at, &k) in constraints.iter().enumerate() {
        let at = at as u32;
        let c = &problem.constraints[k];
        let mut lhs = expression(&c.terms);
        if let Some(penalty) = c.penalty {
            let slack = vars.add(variable().min(0.0));
            objective += penalty * slack;
            match c.kind {
                Relation::AtLeast => lhs += slack,
                Relation::AtMost => lhs -= slack,
                Relation::Equal => {
                    let other = vars.add(variable().min(0.0));
                    objective += penalty * other;
                    lhs += slack - other;
                    slacks.push((at, slack, Some(other)));
                }
            }
            if c.kind != Relation::Equal {
                slacks.push((at, slack, None));
            }
        }
        rows.push(match c.kind {
            Relation::Equal => lhs.eq(c.rhs),
            Relation::AtLeast => lhs.geq(c.rhs),
            Relation::AtMost => lhs.leq(c.rhs),
        });
    }
    let mut model = vars.minimise(objective).using(clarabel);
    for row in rows {
        model = model.with(row);
    }
    let solution = model.solve().ok()?;
    let values: Vec<f64> = x.iter().map(|&v| solution.value(v)).collect();
    if values.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let violations = slacks
        .iter()
        .filter_map(|&(at, slack, other)| {
            let amount = solution.value(slack) + other.map_or(0.0, |o| solution.value(o));
            (amount > VIOLATION_EPS).then_some((at, amount))
        })
        .collect();
    Some(solutions::Solved { values, violations })
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
mod tests {
    use super::*;

    fn at_least(a: usize, b: usize, gap: f64, penalty: Option<f64>, label: u32) -> Constraint {
        // x_a − x_b ≥ gap
        Constraint {
            terms: vec![(a, 1.0), (b, -1.0)],
            kind: Relation::AtLeast,
            rhs: gap,
            penalty,
            label,
        }
    }

    #[test]
    fn unconstrained_variables_keep_their_targets_and_components_split() {
        let mut p = Problem::default();
        let v: Vec<usize> = [10.0, 20.0, 30.0, 40.0, 50.0]
            .iter()
            .map(|&t| p.variable(t, 1.0))
            .collect();
        // A bridge (v1) at least 5 m above what it crosses (v0); v2 and v3 at one height.
        p.constraints.push(at_least(v[1], v[0], 15.0, None, 0));
        p.constraints.push(Constraint {
            terms: vec![(v[2], 1.0), (v[3], -1.0)],
            kind: Relation::Equal,
            rhs: 0.0,
            penalty: None,
            label: 1,
        });
        let out = solve(&p, &Solutions::default());
        assert_eq!(out.components, 2);
        assert_eq!(out.failed, 0);
        assert!(
            out.values[1] - out.values[0] >= 15.0 - 1e-6,
            "{:?}",
            out.values
        );
        // Least total change: 5 m shared between the two, somewhere.
        let moved = (out.values[0] - 10.0).abs() + (out.values[1] - 20.0).abs();
        assert!((moved - 5.0).abs() < 1e-5, "{moved}");
        // The equal pair is snapped to exactly one value within the targets.
        assert_eq!(out.values[2], out.values[3]);
        assert!((30.0..=40.0).contains(&out.values[2]));
        assert_eq!(out.values[4], 50.0);
        assert!(out.violations.is_empty());
    }

    #[test]
    fn a_contradiction_bends_only_what_it_involves_and_is_reported() {
        let mut p = Problem::default();
        let a = p.variable(0.0, 1.0);
        let b = p.variable(0.0, 1.0);
        let c = p.variable(7.0, 1.0);
        let d = p.variable(3.0, 1.0);
        // a above b by 10 and b above a by 10: impossible together.
        p.constraints.push(at_least(a, b, 10.0, Some(100.0), 7));
        p.constraints.push(at_least(b, a, 10.0, Some(100.0), 8));
        // An unrelated, satisfiable constraint elsewhere.
        p.constraints.push(at_least(c, d, 2.0, Some(100.0), 9));
        let out = solve(&p, &Solutions::default());
        assert_eq!(out.failed, 0);
        let total: f64 = out.violations.iter().map(|v| v.amount).sum();
        assert!((total - 20.0).abs() < 1e-3, "{:?}", out.violations);
        assert!(out.violations.iter().all(|v| v.label == 7 || v.label == 8));
        assert!((out.values[c] - 7.0).abs() < 1e-5 && (out.values[d] - 3.0).abs() < 1e-5);
    }

    #[test]
    fn fixed_variables_hold_and_smoothness_rounds_a_peak_into_a_deck() {
        // Five stations of a bridge over a valley: the ends fixed on the banks at 10 m, the
        // terrain below at 0 m, the middle station at least 8 m above the valley floor.
        let mut p = Problem::default();
        let targets = [10.0, 0.0, 0.0, 0.0, 10.0];
        let x: Vec<usize> = targets.iter().map(|&t| p.variable(t, 0.01)).collect();
        p.fix(x[0], 10.0);
        p.fix(x[4], 10.0);
        let floor = p.variable(0.0, 1.0);
        p.constraints
            .push(at_least(x[2], floor, 8.0, Some(1000.0), 0));
        for k in 1..4 {
            p.smoothness.push(Smoothness {
                terms: vec![(x[k - 1], 1.0), (x[k], -2.0), (x[k + 1], 1.0)],
                weight: 10.0,
            });
        }
        let out = solve(&p, &Solutions::default());
        assert_eq!((out.values[x[0]], out.values[x[4]]), (10.0, 10.0));
        assert!(out.values[x[2]] - out.values[floor] >= 8.0 - 1e-6);
        // A straight deck from bank to bank: no peak at the middle, no sag either side.
        for &station in &x[1..4] {
            assert!(
                (out.values[station] - 10.0).abs() < 1e-4,
                "{:?}",
                out.values
            );
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(200))]
        /// Random soft "at least" constraints, contradictions included: the LP never fails,
        /// every shortfall in the values is reported, and free variables keep their targets.
        #[test]
        fn every_shortfall_is_reported(
            targets in proptest::collection::vec(-20.0f64..20.0, 2..30),
            pairs in proptest::collection::vec((0usize..30, 0usize..30, -10.0f64..10.0), 0..40),
            hard in proptest::collection::vec(proptest::bool::ANY, 40),
        ) {
            let mut p = Problem::default();
            for &t in &targets {
                p.variable(t, 1.0);
            }
            let n = targets.len();
            for (k, &(a, b, gap)) in pairs.iter().enumerate() {
                let (a, b) = (a % n, b % n);
                if a == b {
                    continue;
                }
                // Hard ones only along increasing indices: they can always hold together.
                let penalty = if hard[k] && a > b { None } else { Some(50.0) };
                p.constraints.push(at_least(a, b, gap, penalty, k as u32));
            }
            let out = solve(&p, &Solutions::default());
            proptest::prop_assert_eq!(out.failed, 0);
            let mut reported = vec![0.0; pairs.len()];
            for v in &out.violations {
                reported[v.label as usize] += v.amount;
            }
            let mut constrained = vec![false; n];
            for c in &p.constraints {
                let (a, b) = (c.terms[0].0, c.terms[1].0);
                constrained[a] = true;
                constrained[b] = true;
                let shortfall = c.rhs - (out.values[a] - out.values[b]);
                let allowed = if c.penalty.is_some() { reported[c.label as usize] } else { 0.0 };
                proptest::prop_assert!(shortfall <= allowed + 1e-4, "{} > {}", shortfall, allowed);
            }
            for v in 0..n {
                if !constrained[v] {
                    proptest::prop_assert_eq!(out.values[v], targets[v]);
                }
            }
        }
    }

    /// A contradiction (labels `label`, `label + 1`) among two variables placed after
    /// `before` unrelated ones, with a target that differs by `target`.
    fn contradiction(before: usize, label: u32, target: f64) -> (Problem, [usize; 2]) {
        let mut p = Problem::default();
        for k in 0..before {
            let v = p.variable(k as f64, 1.0);
            let w = p.variable(0.0, 1.0);
            p.constraints.push(at_least(v, w, 1.0, None, 100));
        }
        let a = p.variable(target, 1.0);
        let b = p.variable(0.0, 1.0);
        p.constraints.push(at_least(a, b, 10.0, Some(100.0), label));
        p.constraints
            .push(at_least(b, a, 3.0, Some(50.0), label + 1));
        (p, [a, b])
    }

    #[test]
    fn a_component_solved_once_is_found_again_wherever_it_sits_with_its_own_labels() {
        let memo = Solutions::default();
        let target = 1234.5678;
        let (first, [a, b]) = contradiction(0, 7, target);
        let solved = solve(&first, &memo);
        let (found, solved_afresh) = memo.counts();
        assert_eq!((found, solved_afresh), (0, 1), "a new memo finds nothing");
        // The same contradiction after three components of its own.
        let (second, [c, d]) = contradiction(3, 40, target);
        let again = solve(&second, &memo);
        assert_eq!(
            memo.counts(),
            (1, 4),
            "the contradiction is found, not solved"
        );
        assert_eq!(
            [solved.values[a], solved.values[b]],
            [again.values[c], again.values[d]]
        );
        let labels = |o: &Outcome| -> Vec<(u32, u64)> {
            o.violations
                .iter()
                .filter(|v| v.label != 100)
                .map(|v| (v.label, v.amount.to_bits()))
                .collect()
        };
        let shifted: Vec<(u32, u64)> = labels(&solved)
            .into_iter()
            .map(|(label, amount)| (label + 33, amount))
            .collect();
        assert!(!shifted.is_empty());
        assert_eq!(labels(&again), shifted);
        // A component that differs in one number is solved, not found.
        let (other, [e, _]) = contradiction(0, 7, target + 1.0);
        assert_ne!(solve(&other, &memo).values[e], solved.values[a]);
        assert_eq!(memo.counts(), (1, 5), "a component that differs is solved");
    }

    #[test]
    fn a_damaged_solution_read_back_is_solved_again() {
        let target = 4321.0;
        let (p, [a, b]) = contradiction(0, 3, target);
        // One value for two members: not a solution of this component.
        let damaged = solutions::encode(Some(&solutions::Solved {
            values: vec![-7.0],
            violations: Vec::new(),
        }));
        let local = HashMap::from([(a, 0), (b, 1)]);
        let key = component_key(&p, &[a, b], &local, &[0, 1], &[]);
        let memo = Solutions::default();
        assert_eq!(memo.remember([(key, damaged)]), 1);
        let out = solve(&p, &memo);
        assert_eq!(out.failed, 0);
        // The damaged entry would give a −7 m and leave b at its target, 17 m short of a ≥ b + 10.
        assert!(
            out.values[a] - out.values[b] >= 10.0 - 1e-6,
            "{:?}",
            out.values
        );
    }
}
