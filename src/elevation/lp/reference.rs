//! A component solved by clarabel, a general interior-point solver: the reference the
//! component solver is held to, and the solver of components too large for it.

use good_lp::{clarabel, variable, Expression, ProblemVariables, Solution, SolverModel};

use super::{Problem, Relation, VIOLATION_EPS};
use crate::elevation::solutions::Solved;

/// The component's solution; `None` if clarabel fails (hard constraints that contradict each
/// other, say). Violations name soft constraints by their position.
pub fn solve(component: &Problem) -> Option<Solved> {
    let mut vars = ProblemVariables::new();
    let x: Vec<good_lp::Variable> = component
        .targets
        .iter()
        .map(|_| vars.add(variable()))
        .collect();
    let mut objective = Expression::from(0.0);
    let mut rows: Vec<good_lp::Constraint> = Vec::new();
    for (k, &target) in component.targets.iter().enumerate() {
        match component.fixed[k] {
            Some(value) => rows.push(Expression::from(x[k]).eq(value)),
            None if component.weights[k] > 0.0 => {
                // x − target = above − below, both parts charged.
                let above = vars.add(variable().min(0.0));
                let below = vars.add(variable().min(0.0));
                objective += component.weights[k] * (above + below);
                rows.push((x[k] - above + below).eq(target));
            }
            None => {}
        }
    }
    let expression = |terms: &[(usize, f64)]| -> Expression {
        terms
            .iter()
            .fold(Expression::from(0.0), |e, &(v, a)| e + a * x[v])
    };
    for s in &component.smoothness {
        let (up, down) = (vars.add(variable().min(0.0)), vars.add(variable().min(0.0)));
        objective += s.weight * (up + down);
        rows.push((expression(&s.terms) - up + down).eq(0.0));
    }
    let mut slacks: Vec<(u32, good_lp::Variable, Option<good_lp::Variable>)> = Vec::new();
    for (at, c) in component.constraints.iter().enumerate() {
        let at = at as u32;
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
    Some(Solved { values, violations })
}
