//! What the two elevation LPs, bridges and tunnels ([`super::structures`]) and roads on the
//! ground ([`super::road_profiles`]), ask alike of the [`lp`]: soft constraints, each with a
//! report of what it stood for and how far it is from holding; a way's grade, no steeper than
//! its steepest either way and as `incline=*` tags it; and smoothness, the change of slope at
//! a station. Both build their problems through one [`ConstraintBuilder`], so a grade or a
//! change of slope is written the same way, to the bit, in either.

use super::lp::{self, Constraint, Outcome, Problem, Relation, Smoothness};
use super::solutions::Solutions;
use crate::features::structures::{Incline, Slope};
use crate::geometry::Point;

/// Penalties per metre of violation of a grade: a tagged grade is worth as much as the
/// class's steepest.
const MAX_INCLINE_PENALTY: f64 = 1_000.0;
const TAGGED_INCLINE_PENALTY: f64 = 1_000.0;

/// What a soft constraint stood for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ConstraintKind {
    /// A bridge's underside over what it crosses.
    Clearance,
    /// A bridge's deck above the ground.
    AboveGround,
    /// A tunnel's roof under the ground.
    Cover,
    /// A tunnel's roof under the foundations of a building or the roots of a tree over it.
    Foundations,
    /// A tunnel above another.
    TunnelOverTunnel,
    /// The steepest grade of the way's class.
    MaxIncline,
    /// `incline=*`.
    TaggedIncline,
}

impl ConstraintKind {
    pub fn as_str(self) -> &'static str {
        match self {
            ConstraintKind::Clearance => "clearance",
            ConstraintKind::AboveGround => "above_ground",
            ConstraintKind::Cover => "cover",
            ConstraintKind::Foundations => "foundations",
            ConstraintKind::TunnelOverTunnel => "tunnel_over_tunnel",
            ConstraintKind::MaxIncline => "max_incline",
            ConstraintKind::TaggedIncline => "tagged_incline",
        }
    }
}

/// One soft constraint of a settled problem: what it was, on which way, where, and how far it
/// is from holding (0 when it holds).
#[derive(Debug, Clone, PartialEq)]
pub struct ConstraintReport {
    pub kind: ConstraintKind,
    /// The OSM way the constraint belongs to.
    pub way: i64,
    /// Where (global tile units).
    pub at: Point,
    /// What was asked, as written in reports (`>= 12.30`).
    pub bound: f64,
    pub violation: f64,
}

/// What a way's tags ask of its grade, along a run in its direction or, `reversed`, against
/// it: the steepest grade either way (the tagged grade's size, else the class's) and the
/// direction the tags give (`incline=up`, `down`, or a grade's sign) as a relation on the rise
/// per metre.
pub(crate) struct GradeAsked {
    pub steepest: Option<f64>,
    pub tagged: Option<(Relation, f64)>,
}

impl GradeAsked {
    pub fn of(slope: Slope, reversed: bool) -> GradeAsked {
        let incline = slope.incline;
        // A tagged grade is the steepest the way gets (OSM and the thesis read it so), in place
        // of its class's, and says which way it rises; `0%` holds it level.
        let steepest = match incline {
            Some(Incline::Grade(g)) => Some(g.abs()),
            _ => slope.max_incline,
        };
        let (up, down) = if reversed {
            (Relation::AtMost, Relation::AtLeast)
        } else {
            (Relation::AtLeast, Relation::AtMost)
        };
        let tagged = match incline {
            Some(Incline::Grade(g)) if g > 0.0 => Some((up, 0.0)),
            Some(Incline::Grade(g)) if g < 0.0 => Some((down, 0.0)),
            Some(Incline::Up) => Some((up, 0.0)),
            Some(Incline::Down) => Some((down, 0.0)),
            Some(Incline::Grade(_)) | None => None,
        };
        GradeAsked { steepest, tagged }
    }
}

/// An elevation LP in the making, with a report for each of its soft constraints (a
/// constraint's label is its report's index).
#[derive(Debug, Clone, Default)]
pub(crate) struct ConstraintBuilder {
    pub problem: Problem,
    pub reports: Vec<ConstraintReport>,
}

impl ConstraintBuilder {
    /// A soft constraint `terms (relation) rhs`, reported as what it stands for, on which way
    /// and where.
    pub fn soft(
        &mut self,
        (kind, way, at): (ConstraintKind, i64, Point),
        terms: Vec<(usize, f64)>,
        relation: Relation,
        rhs: f64,
        penalty: f64,
    ) {
        self.problem.constraints.push(Constraint {
            terms,
            kind: relation,
            rhs,
            penalty: Some(penalty),
            label: self.reports.len() as u32,
        });
        self.reports.push(ConstraintReport {
            kind,
            way,
            at,
            bound: rhs,
            violation: 0.0,
        });
    }

    /// The grade `asked` of the rise from variable `from` to variable `to` over `run` metres,
    /// on `way` at `at`: the steepest grade down and up, then the tagged grade. A run of no
    /// length has no grade.
    pub fn grade(
        &mut self,
        asked: &GradeAsked,
        (way, at): (i64, Point),
        [from, to]: [usize; 2],
        run: f64,
    ) {
        if run <= 0.0 {
            return;
        }
        let rise = vec![(to, 1.0), (from, -1.0)];
        if let Some(max) = asked.steepest {
            for (relation, bound) in [
                (Relation::AtMost, max * run),
                (Relation::AtLeast, -max * run),
            ] {
                self.soft(
                    (ConstraintKind::MaxIncline, way, at),
                    rise.clone(),
                    relation,
                    bound,
                    MAX_INCLINE_PENALTY,
                );
            }
        }
        if let Some((relation, per_metre)) = asked.tagged {
            self.soft(
                (ConstraintKind::TaggedIncline, way, at),
                rise,
                relation,
                per_metre * run,
                TAGGED_INCLINE_PENALTY,
            );
        }
    }

    /// Charges `weight` per unit of change of slope (rise per run) at the middle of three
    /// consecutive variables, the runs between them `before` and `after` metres long. Where a
    /// run has no length there is no slope to change.
    pub fn smoothness(
        &mut self,
        [previous, middle, next]: [usize; 3],
        [before, after]: [f64; 2],
        weight: f64,
    ) {
        if before <= 0.0 || after <= 0.0 {
            return;
        }
        self.problem.smoothness.push(Smoothness {
            terms: vec![
                (previous, 1.0 / before),
                (middle, -1.0 / before - 1.0 / after),
                (next, 1.0 / after),
            ],
            weight,
        });
    }

    /// Solves the problem (components `memo` holds are found there); each report takes the
    /// violation of its constraint.
    pub fn solve(&mut self, memo: &Solutions) -> Outcome {
        let outcome = lp::solve(&self.problem, memo);
        for violation in &outcome.violations {
            if let Some(report) = self.reports.get_mut(violation.label as usize) {
                report.violation = violation.amount;
            }
        }
        outcome
    }
}
