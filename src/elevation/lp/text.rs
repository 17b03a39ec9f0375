//! Components written as text, one line per variable, smoothness term and constraint, numbers
//! exactly as they were: how recorded components are kept as fixtures.
//!
//! ```text
//! component
//! v <target> <weight> <fixed value or ->
//! s <weight> <variable>:<coefficient> …
//! c <= or > or <> <rhs> <penalty or -> <label> <variable>:<coefficient> …
//! end
//! ```

use super::{Constraint, Problem, Relation, Smoothness};

pub fn write(component: &Problem) -> String {
    let mut out = String::from("component\n");
    let optional = |x: Option<f64>| x.map_or("-".to_string(), |x| format!("{x:?}"));
    let terms = |out: &mut String, terms: &[(usize, f64)]| {
        for &(v, a) in terms {
            out.push_str(&format!(" {v}:{a:?}"));
        }
    };
    for v in 0..component.targets.len() {
        out.push_str(&format!(
            "v {:?} {:?} {}\n",
            component.targets[v],
            component.weights[v],
            optional(component.fixed[v])
        ));
    }
    for s in &component.smoothness {
        out.push_str(&format!("s {:?}", s.weight));
        terms(&mut out, &s.terms);
        out.push('\n');
    }
    for c in &component.constraints {
        let kind = match c.kind {
            Relation::Equal => "=",
            Relation::AtLeast => ">",
            Relation::AtMost => "<",
        };
        out.push_str(&format!(
            "c {kind} {:?} {} {}",
            c.rhs,
            optional(c.penalty),
            c.label
        ));
        terms(&mut out, &c.terms);
        out.push('\n');
    }
    out.push_str("end\n");
    out
}

/// Every component in `text`; an error names the first line that is not one.
pub fn read(text: &str) -> Result<Vec<Problem>, String> {
    let mut components = Vec::new();
    let mut current: Option<Problem> = None;
    for (at, line) in text.lines().enumerate() {
        let fail = |what: &str| format!("line {}: {what}: {line:?}", at + 1);
        let mut words = line.split_whitespace();
        match (words.next(), current.as_mut()) {
            (None, _) => {}
            (Some("component"), None) => current = Some(Problem::default()),
            (Some("end"), Some(_)) => components.extend(current.take()),
            (Some("v"), Some(p)) => {
                let target = number(words.next()).ok_or_else(|| fail("target"))?;
                let weight = number(words.next()).ok_or_else(|| fail("weight"))?;
                let fixed = optional(words.next()).ok_or_else(|| fail("fixed value"))?;
                let v = p.variable(target, weight);
                p.fixed[v] = fixed;
            }
            (Some("s"), Some(p)) => {
                let weight = number(words.next()).ok_or_else(|| fail("weight"))?;
                let terms = terms(words, p.targets.len()).ok_or_else(|| fail("terms"))?;
                p.smoothness.push(Smoothness { terms, weight });
            }
            (Some("c"), Some(p)) => {
                let kind = match words.next() {
                    Some("=") => Relation::Equal,
                    Some(">") => Relation::AtLeast,
                    Some("<") => Relation::AtMost,
                    _ => return Err(fail("relation")),
                };
                let rhs = number(words.next()).ok_or_else(|| fail("rhs"))?;
                let penalty = optional(words.next()).ok_or_else(|| fail("penalty"))?;
                let label = words
                    .next()
                    .and_then(|w| w.parse().ok())
                    .ok_or_else(|| fail("label"))?;
                let terms = terms(words, p.targets.len()).ok_or_else(|| fail("terms"))?;
                p.constraints.push(Constraint {
                    terms,
                    kind,
                    rhs,
                    penalty,
                    label,
                });
            }
            _ => return Err(fail("unexpected")),
        }
    }
    match current {
        Some(_) => Err("the last component has no end".to_string()),
        None => Ok(components),
    }
}

fn number(word: Option<&str>) -> Option<f64> {
    word?.parse().ok().filter(|x: &f64| x.is_finite())
}

fn optional(word: Option<&str>) -> Option<Option<f64>> {
    match word? {
        "-" => Some(None),
        w => number(Some(w)).map(Some),
    }
}

/// `variable:coefficient` pairs over `n` variables.
fn terms<'a>(words: impl Iterator<Item = &'a str>, n: usize) -> Option<Vec<(usize, f64)>> {
    words
        .map(|w| {
            let (v, a) = w.split_once(':')?;
            let v: usize = v.parse().ok().filter(|&v| v < n)?;
            Some((v, number(Some(a))?))
        })
        .collect()
}
