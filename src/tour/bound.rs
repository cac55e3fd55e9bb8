//! A strong lower bound for asymmetric TSPs too large for branch-and-cut: the LP bound of the
//! Dantzig-Fulkerson-Johnson formulation (degree equations plus subtour elimination; Dantzig,
//! Fulkerson and Johnson 1954), computed on a sparse set of candidate arcs and made valid for
//! the whole graph by relaxing its cuts in Lagrangian fashion over the dense assignment problem
//! (Held and Karp 1970 for the Lagrangian; Balas and Christofides 1981 and Fischetti and Toth
//! 1992 for bounding the ATSP additively on top of the assignment relaxation).
//!
//! Why the reported bound is valid whatever the LP did: take any cut multipliers `y`, `y_c >= 0`
//! for a `>=` cut and `y_c <= 0` for a `<=` cut. A tour `x` is an assignment that meets every
//! subtour cut, so `c x >= c x - sum_c y_c (a_c x - rhs_c) = (c - sum_c y_c a_c) x + sum_c y_c
//! rhs_c >= AP(c - sum_c y_c a_c) + sum_c y_c rhs_c =: L(y)`, the assignment problem taken over
//! all n(n-1) arcs with the diagonal forbidden. The LP only chooses `y`; a sparse LP, a missing
//! cut or an inexact dual can only make `L(y)` weaker, never invalid. The assignment value is
//! itself certified by potentials: for any `u`, `v`, every assignment costs at least `sum u +
//! sum v + sum_i min_j (c'_ij - u_i - v_j)`, and that is what is reported (with the AP's own
//! potentials, and with the LP's), so a slightly suboptimal floating-point AP cannot overstate
//! the bound either. Integer matrices (TSPLIB) round the bound up, as every tour costs an
//! integer.
//!
//! How `y` is found, in rounds of column generation (as in Fischetti and Toth 1997's ATSP
//! branch-and-cut):
//! 1. The AP over the full matrix gives the assignment bound and reduced costs. The candidate
//!    arcs are the [`CANDIDATES_PER_NODE`] cheapest out- and in-arcs of every node by reduced
//!    cost, the AP's arcs and the given tour's arcs (so the restricted LP is feasible).
//! 2. The DFJ LP on the candidates is solved with microlp and its violated subtour cuts added
//!    until none is left (or the gain tails off): a quick look at the components of the heavy
//!    arcs first, then exact separation (`subtour::violated_sides`: components, then
//!    minimum cuts from the origin) on the support with its paths of arcs at one shrunk.
//! 3. microlp reports no duals, so the dual LP (`max sum u + sum v + sum_c y_c rhs_c` subject to
//!    `u_i + v_j + sum_c y_c a_c,ij <= c_ij` on the candidates) is solved explicitly, over the
//!    cuts the primal optimum makes tight, by row generation from the rows of the primal
//!    support (equations, by complementary slackness) and of the cheapest arcs.
//! 4. The Lagrangian costs of the duals' `y` are priced over the full matrix: `L(y)` by the
//!    dense AP is this round's bound, and the most negative few arcs of each row outside the
//!    candidates join them for the next round. With none left the duals are feasible for the
//!    full LP, and the bound is (at least) the DFJ LP bound of the whole graph.
//!
//! The time limit stops the LP work early enough to leave room for a round's dense AP (timed by
//! the first); a run out of time returns the best bound of the rounds done, at worst the
//! assignment bound, which is always computed.

use std::collections::{HashMap, HashSet};
use std::time::{Duration, Instant};

use microlp::{ComparisonOp, LinearExpr, OptimizationDirection, Problem, Variable};
use serde::Serialize;

use super::subtour::{components, violated_sides, UnionFind, CUT_TOL};
use super::{assignment, CostMatrix, PlanError};

/// A proven lower bound on every tour and how it was obtained.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Bound {
    /// The bound: at least the assignment bound, never above the optimum.
    pub lower_bound: f64,
    /// The assignment-problem bound.
    pub assignment_bound: f64,
    /// Subtour cuts found.
    pub cuts: usize,
    /// Candidate arcs in the last LP (of n(n-1)).
    pub arcs: usize,
    /// LP rounds (each: cut loop, dual, pricing).
    pub rounds: usize,
    /// Why the search stopped.
    pub stop: Stop,
    /// Wall-clock seconds.
    pub seconds: f64,
}

/// Why [`dfj_bound`] stopped improving its bound.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Stop {
    /// No arc prices out: the bound is (at least) the DFJ LP bound of the full graph, up to the
    /// cuts a tailed-off loop left out.
    Converged,
    /// The time limit came first.
    TimeLimit,
    /// The LP solver failed; the bound is the best one before the failure.
    LpFailure(String),
    /// The bound meets the tour's cost (at most three nodes, or the tour is optimal).
    Optimal,
}

/// Candidate out-arcs and in-arcs per node, cheapest by assignment reduced cost.
pub const CANDIDATES_PER_NODE: usize = 8;
/// Of those, the cheapest out- and in-arcs per node whose dual rows are written from the start
/// (the others join when they price out).
const CORE_PER_NODE: usize = 3;
/// Arcs with negative reduced cost added per row and pricing round.
const PRICED_PER_ROW: usize = 5;
/// LP values above this count as support for separation.
const SUPPORT_TOL: f64 = 1e-6;
/// A cut counts as tight when its slack is below this.
const TIGHT_TOL: f64 = 1e-5;
/// An arc prices out when its reduced cost is below `-PRICE_TOL * (1 + |c_ij|)`.
const PRICE_TOL: f64 = 1e-9;
/// Minimum cuts separated per LP solve (the components of the support are all taken).
const MAX_CUTS_PER_ROUND: usize = 100;
/// New cuts from which the LP is rebuilt rather than edited one cut at a time (an edit costs
/// a few hundredths of a second at 1000 nodes, a rebuild about a second and a half).
const REBUILD_CUTS: usize = 40;
/// Share of the LP time left that a round's cut loop may take before the duals are computed.
const PRIMAL_SHARE: f64 = 0.6;
/// Time kept for a round's dense assignment, as a multiple of the slowest one so far.
const AP_RESERVE: f64 = 1.5;
/// The cut loop of a round stops when its last [`TAILOFF_ITERATIONS`] LP solves raised the
/// value by less than this share (the cuts still missing are worth less than the solves).
const TAILOFF_REL: f64 = 1e-5;
const TAILOFF_ITERATIONS: usize = 3;

/// The DFJ LP lower bound of the tour problem of `m` (node 0 = origin), via sparse candidate
/// arcs, pricing and the Lagrangian argument of the module documentation. `tour` is any tour
/// (every node 1..n-1 once); its arcs keep the restricted LP feasible. Always computes the
/// assignment bound, even with a zero `time_limit`; beyond it, returns the best bound proven
/// when the time runs out.
pub fn dfj_bound(m: &CostMatrix, tour: &[usize], time_limit: Duration) -> Result<Bound, PlanError> {
    let started = Instant::now();
    // Capped so that the deadline cannot overflow (a year is as good as forever here).
    let deadline = started + time_limit.min(Duration::from_secs(365 * 24 * 3600));
    let n = m.len();
    m.check_tour_order(tour)?;
    let ap = assignment::solve(m)?;
    let ap_seconds = started.elapsed().as_secs_f64();
    tracing::debug!(seconds = ap_seconds, bound = ap.cost, "assignment bound");
    let tour_cost = if n == 0 { 0.0 } else { m.tour_cost(tour) };
    let assignment_bound = ap.cost.min(tour_cost);
    let integer = m.has_integer_costs();
    let finish = |bound: f64, cuts, arcs, rounds, stop| {
        let mut lower_bound = bound.max(assignment_bound);
        if integer {
            lower_bound = (lower_bound - 1e-9 * lower_bound.abs() - 1e-6).ceil();
        }
        Bound {
            lower_bound: lower_bound.max(assignment_bound).min(tour_cost),
            assignment_bound,
            cuts,
            arcs,
            rounds,
            stop,
            seconds: started.elapsed().as_secs_f64(),
        }
    };
    if n <= 3 {
        // Every assignment of at most three nodes without fixed points is a tour.
        return Ok(finish(assignment_bound, 0, 0, 0, Stop::Optimal));
    }

    let proves_tour = |bound: f64| {
        if integer {
            (bound - 1e-9 * bound.abs() - 1e-6).ceil() >= tour_cost
        } else {
            bound >= tour_cost
        }
    };
    if proves_tour(assignment_bound) {
        return Ok(finish(assignment_bound, 0, 0, 0, Stop::Optimal));
    }
    let mut candidates = Candidates::new(m, &ap, tour);
    let mut cuts: Vec<Vec<bool>> = Vec::new();
    let mut keys: HashSet<Vec<bool>> = HashSet::new();
    let mut best = assignment_bound;
    let mut rounds = 0;
    // The slowest dense assignment so far: the LP work stops early enough to leave room for one.
    let mut ap_seconds = ap_seconds;
    let stop = loop {
        let now = Instant::now();
        let lp_deadline = deadline
            .checked_sub(Duration::from_secs_f64(AP_RESERVE * ap_seconds))
            .unwrap_or(started);
        if now >= lp_deadline || super::cancel::requested() {
            break Stop::TimeLimit;
        }
        let soft_deadline = now
            + lp_deadline
                .saturating_duration_since(now)
                .mul_f64(PRIMAL_SHARE);
        let primal = match solve_primal(
            m,
            &candidates.arcs,
            &mut cuts,
            &mut keys,
            soft_deadline,
            lp_deadline,
        ) {
            Ok(Some(p)) => p,
            Ok(None) => break Stop::TimeLimit,
            Err(e) => break Stop::LpFailure(e.to_string()),
        };
        rounds += 1;
        let duals = match solve_dual(
            m,
            &candidates.arcs,
            &cuts,
            &primal,
            lp_deadline,
            &candidates.core,
        ) {
            Ok(Some(d)) => d,
            Ok(None) => break Stop::TimeLimit,
            Err(e) => break Stop::LpFailure(e.to_string()),
        };
        let lagrangian = Lagrangian::new(m, &cuts, &duals.multipliers);
        let pricing = lagrangian.price(m, &duals, &candidates);
        // The LP deadline left room for the dense assignment, unless this one is slower.
        let dense_started = Instant::now();
        let dense = if dense_started + Duration::from_secs_f64(ap_seconds) <= deadline {
            match lagrangian.assignment_value(m) {
                Ok(value) => value,
                Err(e) => {
                    break Stop::LpFailure(format!("assignment of the lagrangian costs: {e}"))
                }
            }
        } else {
            f64::NEG_INFINITY
        };
        ap_seconds = ap_seconds.max(dense_started.elapsed().as_secs_f64());
        best = best.max(pricing.bound).max(dense);
        tracing::debug!(
            round = rounds,
            arcs = candidates.arcs.len(),
            cuts = cuts.len(),
            tight = duals.multipliers.len(),
            primal = primal.value,
            dual = duals.value,
            priced_bound = pricing.bound,
            dense_bound = dense,
            priced = pricing.columns.len(),
            seconds = started.elapsed().as_secs_f64(),
            "dfj bound round"
        );
        if proves_tour(best) {
            break Stop::Optimal;
        }
        if pricing.columns.is_empty() {
            break Stop::Converged;
        }
        candidates.extend(pricing.columns);
    };
    Ok(finish(
        best,
        cuts.len(),
        candidates.arcs.len(),
        rounds,
        stop,
    ))
}

/// The candidate arcs of the restricted LP, each one's index, and the core arcs (the cheapest
/// few per node) whose dual rows are written from the start.
struct Candidates {
    arcs: Vec<(usize, usize)>,
    index: HashMap<(usize, usize), usize>,
    core: HashSet<(usize, usize)>,
}

impl Candidates {
    fn new(m: &CostMatrix, ap: &assignment::Assignment, tour: &[usize]) -> Candidates {
        let n = m.len();
        let mut c = Candidates {
            arcs: Vec::new(),
            index: HashMap::new(),
            core: HashSet::new(),
        };
        let k = CANDIDATES_PER_NODE.min(n.saturating_sub(1));
        let mut row: Vec<(f64, usize)> = Vec::with_capacity(n);
        for out in [true, false] {
            for a in 0..n {
                row.clear();
                row.extend((0..n).filter(|&b| b != a).map(|b| {
                    let (i, j) = if out { (a, b) } else { (b, a) };
                    (ap.reduced_cost(m, i, j), b)
                }));
                if k < row.len() {
                    row.select_nth_unstable_by(k, |p, q| p.0.total_cmp(&q.0));
                }
                row.truncate(k);
                row.sort_unstable_by(|p, q| p.0.total_cmp(&q.0));
                for (rank, &(_, b)) in row.iter().enumerate() {
                    let arc = if out { (a, b) } else { (b, a) };
                    c.insert(arc);
                    if rank < CORE_PER_NODE {
                        c.core.insert(arc);
                    }
                }
            }
        }
        for i in 0..n {
            c.insert((i, ap.successor[i]));
        }
        for arc in tour_arcs(tour) {
            c.insert(arc);
        }
        c
    }

    fn insert(&mut self, arc: (usize, usize)) {
        if arc.0 != arc.1 && !self.index.contains_key(&arc) {
            self.index.insert(arc, self.arcs.len());
            self.arcs.push(arc);
        }
    }

    fn extend(&mut self, arcs: Vec<(usize, usize)>) {
        for arc in arcs {
            self.insert(arc);
        }
    }
}

/// The arcs of the closed tour through the origin that visits `order`.
fn tour_arcs(order: &[usize]) -> impl Iterator<Item = (usize, usize)> + '_ {
    let heads = order.iter().copied().chain(std::iter::once(0));
    std::iter::once(0).chain(order.iter().copied()).zip(heads)
}

/// Which of the equivalent forms of a subtour cut (`S` holds the origin, `T` is the rest) a
/// constraint uses; with the degree equations they agree on every assignment.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Form {
    /// `x(S -> T) >= 1`.
    Leaving,
    /// `x(T -> S) >= 1`.
    Entering,
    /// `x(S -> S) <= |S| - 1`.
    InsideS,
    /// `x(T -> T) <= |T| - 1`.
    InsideT,
}

impl Form {
    const ALL: [Form; 4] = [Form::Leaving, Form::Entering, Form::InsideS, Form::InsideT];

    /// Whether arc `i -> j` is in the cut's left side.
    #[cfg(test)]
    fn has(self, in_s: &[bool], i: usize, j: usize) -> bool {
        match self {
            Form::Leaving => in_s[i] && !in_s[j],
            Form::Entering => !in_s[i] && in_s[j],
            Form::InsideS => in_s[i] && in_s[j],
            Form::InsideT => !in_s[i] && !in_s[j],
        }
    }

    fn op(self) -> ComparisonOp {
        match self {
            Form::Leaving | Form::Entering => ComparisonOp::Ge,
            Form::InsideS | Form::InsideT => ComparisonOp::Le,
        }
    }

    fn rhs(self, in_s: &[bool]) -> f64 {
        let size_s = in_s.iter().filter(|&&b| b).count() as f64;
        match self {
            Form::Leaving | Form::Entering => 1.0,
            Form::InsideS => size_s - 1.0,
            Form::InsideT => in_s.len() as f64 - size_s - 1.0,
        }
    }

    /// The multiplier's sign range in the dual: `>= 0` for `>=` cuts, `<= 0` for `<=` cuts.
    fn dual_bounds(self) -> (f64, f64) {
        match self.op() {
            ComparisonOp::Ge => (0.0, f64::INFINITY),
            _ => (f64::NEG_INFINITY, 0.0),
        }
    }

    fn clamp(self, y: f64) -> f64 {
        let (lo, hi) = self.dual_bounds();
        y.clamp(lo, hi)
    }
}

/// The sparsest form of the cut `in_s` over `arcs`, with the indices of its arcs.
fn sparsest(in_s: &[bool], arcs: &[(usize, usize)]) -> (Form, Vec<usize>) {
    let mut members: [Vec<usize>; 4] = Default::default();
    for (k, &(i, j)) in arcs.iter().enumerate() {
        let f = match (in_s[i], in_s[j]) {
            (true, false) => 0,
            (false, true) => 1,
            (true, true) => 2,
            (false, false) => 3,
        };
        members[f].push(k);
    }
    let f = (0..4).min_by_key(|&f| members[f].len()).unwrap_or(0);
    (Form::ALL[f], std::mem::take(&mut members[f]))
}

/// The restricted LP's optimum: arc values, objective, and the form each cut was written in.
struct Primal {
    x: Vec<f64>,
    value: f64,
    forms: Vec<(Form, Vec<usize>)>,
}

/// A solved restricted LP: the solution, its arc variables, and the form of every cut.
type Built = (microlp::Solution, Vec<Variable>, Vec<(Form, Vec<usize>)>);

/// The restricted LP with every cut so far, solved from scratch; `Ok(None)` on time out.
fn solve_built(
    m: &CostMatrix,
    arcs: &[(usize, usize)],
    cuts: &[Vec<bool>],
    deadline: Instant,
) -> Result<Option<Built>, microlp::Error> {
    let n = m.len();
    let mut problem = Problem::new(OptimizationDirection::Minimize);
    let vars: Vec<Variable> = arcs
        .iter()
        .map(|&(i, j)| problem.add_var(m.cost(i, j), (0.0, 1.0)))
        .collect();
    let mut out: Vec<LinearExpr> = (0..n).map(|_| LinearExpr::empty()).collect();
    let mut inn: Vec<LinearExpr> = (0..n).map(|_| LinearExpr::empty()).collect();
    for (k, &(i, j)) in arcs.iter().enumerate() {
        out[i].add(vars[k], 1.0);
        inn[j].add(vars[k], 1.0);
    }
    for expr in out.into_iter().chain(inn) {
        problem.add_constraint(expr, ComparisonOp::Eq, 1.0);
    }
    let mut forms = Vec::with_capacity(cuts.len());
    for in_s in cuts {
        let (form, members) = sparsest(in_s, arcs);
        problem.add_constraint(
            members.iter().map(|&k| (vars[k], 1.0)),
            form.op(),
            form.rhs(in_s),
        );
        forms.push((form, members));
    }
    problem.set_time_limit(deadline.saturating_duration_since(Instant::now()));
    match problem.solve()?.into_solution() {
        Ok(solution) => Ok(Some((solution, vars, forms))),
        Err(_) => Ok(None),
    }
}

/// Solves the DFJ LP on `arcs` with every cut so far, separating new subtour cuts until none is
/// violated or `soft_deadline` passes (the LP then misses some cuts, which only weakens the
/// bound). Many new cuts at once rebuild the LP, few are added to it warm. `Ok(None)`: the
/// hard `deadline` came first.
fn solve_primal(
    m: &CostMatrix,
    arcs: &[(usize, usize)],
    cuts: &mut Vec<Vec<bool>>,
    keys: &mut HashSet<Vec<bool>>,
    soft_deadline: Instant,
    deadline: Instant,
) -> Result<Option<Primal>, microlp::Error> {
    let n = m.len();
    let built = Instant::now();
    let Some((mut solution, mut vars, mut forms)) = solve_built(m, arcs, cuts, deadline)? else {
        return Ok(None);
    };
    tracing::trace!(
        arcs = arcs.len(),
        cuts = cuts.len(),
        seconds = built.elapsed().as_secs_f64(),
        "restricted lp built and solved"
    );
    let mut values: Vec<f64> = Vec::new();
    loop {
        values.push(solution.objective());
        let tailed_off = values.len() > TAILOFF_ITERATIONS && {
            let last = values[values.len() - 1];
            let before = values[values.len() - 1 - TAILOFF_ITERATIONS];
            last - before < TAILOFF_REL * last.abs()
        };
        let x: Vec<f64> = vars.iter().map(|&v| solution.var_value(v)).collect();
        let support: Vec<(usize, usize, f64)> = x
            .iter()
            .zip(arcs)
            .filter(|(&v, _)| v > SUPPORT_TOL)
            .map(|(&v, &(i, j))| (i, j, v))
            .collect();
        let sep_started = Instant::now();
        let fresh: Vec<Vec<bool>> = if Instant::now() < soft_deadline && !tailed_off {
            separate(n, &support)
                .into_iter()
                .filter(|side| keys.insert(side.clone()))
                .collect()
        } else {
            Vec::new()
        };
        tracing::trace!(
            fresh = fresh.len(),
            value = solution.objective(),
            separation_s = sep_started.elapsed().as_secs_f64(),
            "subtour separation"
        );
        if fresh.is_empty() {
            let value = solution.objective();
            return Ok(Some(Primal { x, value, forms }));
        }
        if fresh.len() >= REBUILD_CUTS {
            cuts.extend(fresh);
            match solve_built(m, arcs, cuts, deadline)? {
                Some((s, v, f)) => {
                    solution = s;
                    vars = v;
                    forms = f;
                }
                None => return Ok(None),
            }
            continue;
        }
        for in_s in fresh {
            if Instant::now() >= deadline {
                return Ok(None);
            }
            let (form, members) = sparsest(&in_s, arcs);
            let expr: Vec<(Variable, f64)> = members.iter().map(|&k| (vars[k], 1.0)).collect();
            let rhs = form.rhs(&in_s);
            solution = match solution
                .add_constraint(expr, form.op(), rhs)?
                .into_solution()
            {
                Ok(s) => s,
                Err(_) => return Ok(None),
            };
            cuts.push(in_s);
            forms.push((form, members));
        }
    }
}

/// Arc values from which an arc counts as one: its ends are shrunk into one node.
const ONE_TOL: f64 = 1e-6;

/// Violated subtour cuts of the LP point `support` (arcs `(i, j, x_ij)`, `x_ij > 0`), as node
/// sets holding the origin. The paths of arcs at one are shrunk first (the shrinking of Padberg
/// and Rinaldi 1990, for the directed cut): if `x_uv = 1` and a violated set `S` holds `u` but
/// not `v`, then `S + v` is violated too (`x(S -> v)` is all of `v`'s in-flow, so
/// `x(delta+(S + v)) = x(delta+(S)) - x(v -> S)`), and symmetrically `S + u` when it holds `v`
/// but not `u`; so some violated set never splits such a path whenever one exists. The quick
/// [`heavy_components`] go first; only when they find nothing does the exact separation of
/// `violated_sides` run, on the shrunk graph (at 1000 nodes, about 700 remain).
fn separate(n: usize, support: &[(usize, usize, f64)]) -> Vec<Vec<bool>> {
    let mut sets = UnionFind::new(n);
    for &(i, j, x) in support {
        if x >= 1.0 - ONE_TOL {
            sets.union(i, j);
        }
    }
    // Shrunk node of every node, the origin's being 0.
    let shrunk = sets.labels();
    let count = shrunk.iter().copied().max().map_or(0, |c| c + 1);
    let arcs: Vec<(usize, usize, f64)> = support
        .iter()
        .filter(|&&(i, j, _)| shrunk[i] != shrunk[j])
        .map(|&(i, j, x)| (shrunk[i], shrunk[j], x))
        .collect();
    let heuristic = heavy_components(count, &arcs);
    tracing::trace!(
        nodes = count,
        arcs = arcs.len(),
        heuristic = heuristic.len(),
        "shrunk support"
    );
    let sides = if heuristic.is_empty() {
        violated_sides(count, &arcs, MAX_CUTS_PER_ROUND)
    } else {
        heuristic
    };
    sides
        .into_iter()
        .map(|side| {
            (0..n)
                .map(|v| side.get(shrunk[v]).copied().unwrap_or(true))
                .collect()
        })
        .collect()
}

/// Arc values from which [`heavy_components`] keeps an arc, heaviest first.
const HEAVY_THRESHOLDS: [f64; 3] = [0.5, 0.3, 0.1];

/// A quick search for violated subtour cuts before the exact one: the weakly connected
/// components of the arcs at [`HEAVY_THRESHOLDS`] or more, those without the origin whose
/// in-flow falls short of one (complements of `S`, returned as `S`).
fn heavy_components(n: usize, arcs: &[(usize, usize, f64)]) -> Vec<Vec<bool>> {
    let mut found: Vec<Vec<bool>> = Vec::new();
    let mut seen: HashSet<Vec<bool>> = HashSet::new();
    for threshold in HEAVY_THRESHOLDS {
        let heavy: Vec<(usize, usize, f64)> =
            arcs.iter().copied().filter(|a| a.2 >= threshold).collect();
        let component = components(n, &heavy);
        let count = component.iter().copied().max().map_or(0, |c| c + 1);
        let mut inflow = vec![0.0; count];
        for &(i, j, x) in arcs {
            if component[i] != component[j] {
                inflow[component[j]] += x;
            }
        }
        let origin = component.first().copied().unwrap_or(0);
        for (c, &flow) in inflow.iter().enumerate() {
            if c != origin && flow < 1.0 - CUT_TOL {
                let side: Vec<bool> = component.iter().map(|&k| k != c).collect();
                if seen.insert(side.clone()) {
                    found.push(side);
                }
            }
        }
    }
    found
}

/// Optimal duals of the restricted LP: row and column potentials, and a multiplier for every
/// cut `(index, form, y)` (zero for the cuts left out).
struct Duals {
    u: Vec<f64>,
    v: Vec<f64>,
    multipliers: Vec<(usize, Form, f64)>,
    value: f64,
}

/// Solves the dual of the restricted LP over the cuts `primal` makes tight (every optimal dual
/// is zero on the others), by row generation: the rows of the primal optimum's support first
/// (written as equations: complementary slackness makes them tight at every optimal dual, and
/// microlp then solves several times faster), then every candidate arc whose reduced cost is
/// negative, a few at a time into the live LP, many by a rebuild. Should round-off make the
/// equations inconsistent, the dual is solved again with inequalities only. `Ok(None)`: the
/// deadline came first.
fn solve_dual(
    m: &CostMatrix,
    arcs: &[(usize, usize)],
    cuts: &[Vec<bool>],
    primal: &Primal,
    deadline: Instant,
    core: &HashSet<(usize, usize)>,
) -> Result<Option<Duals>, microlp::Error> {
    match solve_dual_with(m, arcs, cuts, primal, deadline, true, core) {
        Ok(found) => Ok(found),
        Err(e) => {
            tracing::debug!("dual with support equations failed ({e}); inequalities only");
            solve_dual_with(m, arcs, cuts, primal, deadline, false, core)
        }
    }
}

/// Rows added to the live dual LP one by one below this count; from it, the LP is rebuilt.
const DUAL_WARM_ROWS: usize = 200;

fn solve_dual_with(
    m: &CostMatrix,
    arcs: &[(usize, usize)],
    cuts: &[Vec<bool>],
    primal: &Primal,
    deadline: Instant,
    support_equations: bool,
    core: &HashSet<(usize, usize)>,
) -> Result<Option<Duals>, microlp::Error> {
    // The cuts in the dual and, for every arc, the cuts (indices into `tight`) it is in.
    let mut tight: Vec<(usize, Form, f64)> = Vec::new();
    let mut arc_cuts: Vec<Vec<usize>> = vec![Vec::new(); arcs.len()];
    for (c, (in_s, (form, members))) in cuts.iter().zip(&primal.forms).enumerate() {
        let lhs: f64 = members
            .iter()
            .map(|&k| primal.x.get(k).copied().unwrap_or(0.0))
            .sum();
        let rhs = form.rhs(in_s);
        if (lhs - rhs).abs() > TIGHT_TOL {
            continue;
        }
        for &k in members {
            if let Some(list) = arc_cuts.get_mut(k) {
                list.push(tight.len());
            }
        }
        tight.push((c, *form, rhs));
    }
    let mut in_rows: Vec<bool> = primal
        .x
        .iter()
        .zip(arcs)
        .map(|(&x, a)| x > SUPPORT_TOL || core.contains(a))
        .collect();
    let mut live: Option<DualLp> = None;
    loop {
        if Instant::now() >= deadline {
            return Ok(None);
        }
        let lp = match live.take() {
            Some(lp) => lp,
            None => {
                let rows: Vec<usize> = (0..arcs.len()).filter(|&k| in_rows[k]).collect();
                match DualLp::build(
                    m,
                    arcs,
                    &tight,
                    &arc_cuts,
                    primal,
                    &rows,
                    support_equations,
                    deadline,
                )? {
                    Some(lp) => lp,
                    None => return Ok(None),
                }
            }
        };
        let duals = lp.duals();
        let violated: Vec<usize> = (0..arcs.len())
            .filter(|&k| {
                !in_rows[k] && {
                    let (i, j) = arcs[k];
                    let y: f64 = arc_cuts[k].iter().map(|&t| duals.multipliers[t].2).sum();
                    let r = m.cost(i, j) - duals.u[i] - duals.v[j] - y;
                    r < -PRICE_TOL * (1.0 + m.cost(i, j).abs())
                }
            })
            .collect();
        tracing::trace!(violated = violated.len(), value = duals.value, "dual rows");
        if violated.is_empty() {
            return Ok(Some(duals));
        }
        for &k in &violated {
            in_rows[k] = true;
        }
        if violated.len() < DUAL_WARM_ROWS {
            match lp.add_rows(m, arcs, &arc_cuts, &violated, deadline)? {
                Some(lp) => live = Some(lp),
                None => return Ok(None),
            }
        }
    }
}

/// The live dual LP: `max sum u + sum v + sum_c y_c rhs_c` subject to `u_i + v_j + sum_c y_c
/// a_c,ij <= c_ij` (`=` on the primal support) on some candidate arcs.
struct DualLp {
    solution: microlp::Solution,
    u: Vec<Variable>,
    v: Vec<Variable>,
    y: Vec<Variable>,
    tight: Vec<(usize, Form)>,
}

impl DualLp {
    #[allow(clippy::too_many_arguments)]
    fn build(
        m: &CostMatrix,
        arcs: &[(usize, usize)],
        tight: &[(usize, Form, f64)],
        arc_cuts: &[Vec<usize>],
        primal: &Primal,
        rows: &[usize],
        support_equations: bool,
        deadline: Instant,
    ) -> Result<Option<DualLp>, microlp::Error> {
        let n = m.len();
        let mut problem = Problem::new(OptimizationDirection::Maximize);
        let free = (f64::NEG_INFINITY, f64::INFINITY);
        let u: Vec<Variable> = (0..n).map(|_| problem.add_var(1.0, free)).collect();
        let v: Vec<Variable> = (0..n).map(|_| problem.add_var(1.0, free)).collect();
        let y: Vec<Variable> = tight
            .iter()
            .map(|&(_, form, rhs)| problem.add_var(rhs, form.dual_bounds()))
            .collect();
        for &k in rows {
            let (i, j) = arcs[k];
            let op = if support_equations && primal.x[k] > SUPPORT_TOL {
                ComparisonOp::Eq
            } else {
                ComparisonOp::Le
            };
            problem.add_constraint(row_expr(&u, &v, &y, arcs, arc_cuts, k), op, m.cost(i, j));
        }
        problem.set_time_limit(deadline.saturating_duration_since(Instant::now()));
        let Ok(solution) = problem.solve()?.into_solution() else {
            return Ok(None);
        };
        Ok(Some(DualLp {
            solution,
            u,
            v,
            y,
            tight: tight.iter().map(|&(c, form, _)| (c, form)).collect(),
        }))
    }

    /// Adds the rows of `ks` (inequalities) to the live LP, re-solving warm after each.
    fn add_rows(
        mut self,
        m: &CostMatrix,
        arcs: &[(usize, usize)],
        arc_cuts: &[Vec<usize>],
        ks: &[usize],
        deadline: Instant,
    ) -> Result<Option<DualLp>, microlp::Error> {
        for &k in ks {
            if Instant::now() >= deadline {
                return Ok(None);
            }
            let (i, j) = arcs[k];
            let expr = row_expr(&self.u, &self.v, &self.y, arcs, arc_cuts, k);
            self.solution = match self
                .solution
                .add_constraint(expr, ComparisonOp::Le, m.cost(i, j))?
                .into_solution()
            {
                Ok(s) => s,
                Err(_) => return Ok(None),
            };
        }
        Ok(Some(self))
    }

    fn duals(&self) -> Duals {
        let s = &self.solution;
        Duals {
            u: self.u.iter().map(|&x| s.var_value(x)).collect(),
            v: self.v.iter().map(|&x| s.var_value(x)).collect(),
            multipliers: self
                .tight
                .iter()
                .zip(&self.y)
                .map(|(&(c, form), &y)| (c, form, form.clamp(s.var_value(y))))
                .collect(),
            value: s.objective(),
        }
    }
}

/// The dual row of candidate arc `k`: `u_i + v_j + sum of its cuts' multipliers`.
fn row_expr(
    u: &[Variable],
    v: &[Variable],
    y: &[Variable],
    arcs: &[(usize, usize)],
    arc_cuts: &[Vec<usize>],
    k: usize,
) -> LinearExpr {
    let (i, j) = arcs[k];
    let mut e = LinearExpr::empty();
    e.add(u[i], 1.0);
    e.add(v[j], 1.0);
    for &t in &arc_cuts[k] {
        e.add(y[t], 1.0);
    }
    e
}

/// A row or column term of a cut rewritten for the dense matrix: the nodes it covers (those in
/// `S`, or those in `T`) and its sign.
type SideTerm = Option<(bool, f64)>;

/// What pricing found.
struct Pricing {
    /// The valid bound of the duals.
    bound: f64,
    /// New candidate arcs.
    columns: Vec<(usize, usize)>,
}

/// The Lagrangian costs `c'_ij = c_ij - sum_c y_c a_c,ij` over the full matrix, stored as
/// `base_ij - alpha_i - beta_j` (each cut is rewritten in the equivalent form touching the
/// fewest pairs, which moves the rest into row and column shifts), and `sum_c y_c rhs_c`.
struct Lagrangian {
    n: usize,
    base: Vec<f64>,
    alpha: Vec<f64>,
    beta: Vec<f64>,
    constant: f64,
}

impl Lagrangian {
    fn new(m: &CostMatrix, cuts: &[Vec<bool>], multipliers: &[(usize, Form, f64)]) -> Lagrangian {
        let n = m.len();
        let mut base = Vec::with_capacity(n * n);
        for i in 0..n {
            for j in 0..n {
                base.push(m.cost(i, j));
            }
        }
        let mut l = Lagrangian {
            n,
            base,
            alpha: vec![0.0; n],
            beta: vec![0.0; n],
            constant: 0.0,
        };
        for &(c, form, y) in multipliers {
            if y != 0.0 {
                if let Some(in_s) = cuts.get(c) {
                    l.subtract(in_s, form, y);
                }
            }
        }
        l
    }

    /// Subtracts `y a_ij` of the cut `in_s` written in `form`, adding `y rhs` to the constant.
    ///
    /// With `s`, `t` the indicators of `S` and `T` (`s + t = 1`), each form is an inside form
    /// plus row and column terms: `s_i t_j = s_i - s_i s_j = t_j - t_i t_j`, `t_i s_j = s_j -
    /// s_i s_j = t_i - t_i t_j`, `s_i s_j = s_i - t_j + t_i t_j`, `t_i t_j = t_i - s_j + s_i
    /// s_j`. The inside form of the smaller side is applied to the matrix.
    fn subtract(&mut self, in_s: &[bool], form: Form, y: f64) {
        let n = self.n;
        self.constant += y * form.rhs(in_s);
        let size_s = in_s.iter().filter(|&&b| b).count();
        let x_is_s = size_s <= n - size_s;
        // (row term, column term, inside coefficient); a term is (on S?, sign).
        let (row, col, kappa): (SideTerm, SideTerm, f64) = match (form, x_is_s) {
            (Form::Leaving, true) => (Some((true, 1.0)), None, -1.0),
            (Form::Leaving, false) => (None, Some((false, 1.0)), -1.0),
            (Form::Entering, true) => (None, Some((true, 1.0)), -1.0),
            (Form::Entering, false) => (Some((false, 1.0)), None, -1.0),
            (Form::InsideS, true) | (Form::InsideT, false) => (None, None, 1.0),
            (Form::InsideS, false) => (Some((true, 1.0)), Some((false, -1.0)), 1.0),
            (Form::InsideT, true) => (Some((false, 1.0)), Some((true, -1.0)), 1.0),
        };
        if let Some((on_s, sign)) = row {
            for (alpha, &s) in self.alpha.iter_mut().zip(in_s) {
                if s == on_s {
                    *alpha += y * sign;
                }
            }
        }
        if let Some((on_s, sign)) = col {
            for (beta, &s) in self.beta.iter_mut().zip(in_s) {
                if s == on_s {
                    *beta += y * sign;
                }
            }
        }
        let members: Vec<usize> = (0..n).filter(|&k| in_s[k] == x_is_s).collect();
        for &i in &members {
            let row = &mut self.base[i * n..(i + 1) * n];
            for &j in &members {
                row[j] -= y * kappa;
            }
        }
    }

    #[inline]
    fn cost(&self, i: usize, j: usize) -> f64 {
        self.base[i * self.n + j] - self.alpha[i] - self.beta[j]
    }

    /// Pricing under the LP duals: the bound `sum_c y_c rhs_c + sum u + sum v + sum_i min_j
    /// (c'_ij - u_i - v_j)` (valid for any `u`, `v`), and the arcs outside the candidates that
    /// price out, the most negative [`PRICED_PER_ROW`] of each row.
    fn price(&self, m: &CostMatrix, duals: &Duals, candidates: &Candidates) -> Pricing {
        let n = self.n;
        let mut bound = self.constant + duals.u.iter().sum::<f64>() + duals.v.iter().sum::<f64>();
        let mut columns = Vec::new();
        let mut row: Vec<(f64, usize)> = Vec::new();
        for i in 0..n {
            row.clear();
            let mut least = f64::INFINITY;
            for j in 0..n {
                if i == j {
                    continue;
                }
                let r = self.cost(i, j) - duals.u[i] - duals.v[j];
                least = least.min(r);
                if r < -PRICE_TOL * (1.0 + m.cost(i, j).abs())
                    && !candidates.index.contains_key(&(i, j))
                {
                    row.push((r, j));
                }
            }
            if least.is_finite() {
                bound += least;
            }
            if row.len() > PRICED_PER_ROW {
                row.select_nth_unstable_by(PRICED_PER_ROW, |p, q| p.0.total_cmp(&q.0));
                row.truncate(PRICED_PER_ROW);
            }
            columns.extend(row.iter().map(|&(_, j)| (i, j)));
        }
        Pricing { bound, columns }
    }

    /// `L(y)`: the constant plus the dense assignment of the Lagrangian costs, certified by the
    /// assignment's own potentials.
    fn assignment_value(&self, m: &CostMatrix) -> Result<f64, PlanError> {
        let costs = CostMatrix::from_fn(m.len(), |i, j| self.cost(i, j));
        let ap = assignment::solve(&costs)?;
        let n = self.n;
        let mut bound = self.constant + ap.u.iter().sum::<f64>() + ap.v.iter().sum::<f64>();
        for i in 0..n {
            let least = (0..n)
                .filter(|&j| j != i)
                .map(|j| costs.cost(i, j) - ap.u[i] - ap.v[j])
                .fold(f64::INFINITY, f64::min);
            if least.is_finite() {
                bound += least;
            }
        }
        Ok(bound)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;
    use crate::tour::testing::{drone, tsplib_instance};
    use crate::tour::{branch_cut, held_karp};

    fn identity_order(n: usize) -> Vec<usize> {
        (1..n).collect()
    }

    /// A random permutation of 0..n without fixed points (n >= 2).
    fn derangement(n: usize, rng: &mut Rng) -> Vec<usize> {
        loop {
            let mut p: Vec<usize> = (0..n).collect();
            for i in (1..n).rev() {
                p.swap(i, rng.below(i + 1));
            }
            if p.iter().enumerate().all(|(i, &j)| i != j) {
                return p;
            }
        }
    }

    #[test]
    fn the_bound_lies_between_the_assignment_bound_and_the_held_karp_optimum_on_small_instances() {
        let mut rng = Rng::new(7);
        let mut above_assignment = 0;
        let trials = 90;
        for trial in 0..trials {
            let n = 4 + trial % 9;
            let m = match trial % 3 {
                0 => CostMatrix::from_fn(n, |_, _| rng.below(1000) as f64),
                1 => drone(n, rng.next_u64()),
                // Two clusters: the assignment splits into subtours, the cuts must join them.
                _ => CostMatrix::from_fn(n, |i, j| {
                    let far = (i < n / 2) != (j < n / 2);
                    rng.below(100) as f64 + if far { 1000.0 } else { 0.0 }
                }),
            };
            let exact = held_karp::solve(&m).unwrap();
            let b = dfj_bound(&m, &identity_order(n), Duration::from_secs(10)).unwrap();
            let ap = assignment::solve(&m).unwrap();
            let tol = 1e-9 * exact.cost.abs().max(1.0);
            assert!(
                b.lower_bound <= exact.cost + tol,
                "trial {trial}: {b:?} above {exact:?}"
            );
            assert!(b.lower_bound >= b.assignment_bound, "trial {trial}");
            assert!((b.assignment_bound - ap.cost.min(exact.cost)).abs() <= tol);
            if b.lower_bound > b.assignment_bound + tol {
                above_assignment += 1;
            }
        }
        // The cuts must be doing something: most of these assignments have subtours.
        assert!(above_assignment >= trials / 3, "{above_assignment}");
    }

    #[test]
    fn the_bound_is_within_about_two_percent_of_the_optimum_on_ftv70_kro124p_and_ftv170() {
        // Optimum (TSPLIB) and the DFJ LP bound rounded up (published DFJ LP
        // values: 1909, 35999.1, 2715.2).
        for (name, optimum, dfj_lp) in [
            ("ftv70", 1950.0, 1909.0),
            ("kro124p", 36230.0, 36000.0),
            ("ftv170", 2755.0, 2716.0),
        ] {
            let m = tsplib_instance(name);
            let b = dfj_bound(&m, &identity_order(m.len()), Duration::from_secs(60)).unwrap();
            assert!(b.lower_bound <= optimum, "{name}: {b:?}");
            assert!(b.lower_bound >= dfj_lp, "{name}: {b:?}");
            assert!(
                (optimum - b.lower_bound) / optimum <= 0.022,
                "{name}: {b:?}"
            );
            assert_eq!(b.stop, Stop::Converged, "{name}");
            assert!(b.lower_bound > b.assignment_bound, "{name}");
        }
    }

    #[test]
    fn the_bound_is_within_two_percent_of_the_optimum_of_a_drone_mission() {
        let mut rng = Rng::new(40);
        let m = drone(40, rng.next_u64());
        let exact = branch_cut::solve(&m, &identity_order(40), &branch_cut::Options::default())
            .unwrap()
            .tour;
        assert!(exact.optimal);
        let b = dfj_bound(&m, &identity_order(40), Duration::from_secs(10)).unwrap();
        assert!(
            b.lower_bound <= exact.cost * (1.0 + 1e-9),
            "{b:?} {exact:?}"
        );
        // DFJ LP gaps on such costs run 0.1-2% (0.4% at N = 100, 2.1% on ftv70).
        assert!(b.lower_bound >= 0.98 * exact.cost, "{b:?} {exact:?}");
        // The assignment bound is several percent off on such costs.
        assert!(b.assignment_bound < 0.97 * exact.cost, "{b:?} {exact:?}");
    }

    #[test]
    fn a_zero_time_limit_returns_at_least_the_assignment_bound_and_never_more_than_the_optimum() {
        let mut rng = Rng::new(3);
        let m = CostMatrix::from_fn(12, |_, _| rng.below(1000) as f64);
        let exact = held_karp::solve(&m).unwrap();
        let b = dfj_bound(&m, &identity_order(12), Duration::ZERO).unwrap();
        assert!(b.lower_bound >= b.assignment_bound);
        assert!(b.lower_bound <= exact.cost);
        let ftv70 = tsplib_instance("ftv70");
        let b = dfj_bound(&ftv70, &identity_order(ftv70.len()), Duration::ZERO).unwrap();
        assert_eq!(b.stop, Stop::TimeLimit);
        assert_eq!(b.lower_bound, b.assignment_bound);
        assert!(b.lower_bound <= 1950.0);
    }

    #[test]
    fn every_form_of_a_cut_moved_onto_the_dense_matrix_keeps_the_lagrangian_costs() {
        let mut rng = Rng::new(9);
        for trial in 0..40 {
            let n = 5 + trial % 6;
            let m = CostMatrix::from_fn(n, |_, _| rng.below(100) as f64);
            // Random sets S holding the origin, small and large (both sides get rewritten).
            let cuts: Vec<Vec<bool>> = (0..4)
                .map(|c| {
                    let share = if c % 2 == 0 { 0.2 } else { 0.8 };
                    (0..n).map(|v| v == 0 || rng.next_f64() < share).collect()
                })
                .collect();
            let multipliers: Vec<(usize, Form, f64)> = (0..8)
                .map(|k| {
                    let form = Form::ALL[k % 4];
                    let (lo, hi) = form.dual_bounds();
                    let y = rng.uniform(0.0, 10.0) * if lo < 0.0 { -1.0 } else { 1.0 };
                    (k % cuts.len(), form, y.clamp(lo, hi))
                })
                .collect();
            let l = Lagrangian::new(&m, &cuts, &multipliers);
            let mut constant = 0.0;
            for &(c, form, y) in &multipliers {
                constant += y * form.rhs(&cuts[c]);
            }
            assert!((l.constant - constant).abs() < 1e-9, "trial {trial}");
            for i in 0..n {
                for j in 0..n {
                    if i == j {
                        continue;
                    }
                    let mut direct = m.cost(i, j);
                    for &(c, form, y) in &multipliers {
                        if form.has(&cuts[c], i, j) {
                            direct -= y;
                        }
                    }
                    assert!(
                        (l.cost(i, j) - direct).abs() < 1e-9,
                        "trial {trial} ({i},{j})"
                    );
                }
            }
        }
    }

    #[test]
    fn the_shrunk_separation_finds_a_violated_cut_exactly_when_the_full_one_does() {
        let mut rng = Rng::new(5);
        let mut violated = 0;
        for trial in 0..300 {
            let n = 4 + trial % 12;
            // A point of the assignment polytope: a convex combination of a few assignments.
            let parts = 1 + trial % 4;
            let mut x = vec![0.0; n * n];
            for p in 0..parts {
                let weight = if p + 1 == parts {
                    1.0 - (parts - 1) as f64 * (1.0 / parts as f64)
                } else {
                    1.0 / parts as f64
                };
                for (i, j) in derangement(n, &mut rng).into_iter().enumerate() {
                    x[i * n + j] += weight;
                }
            }
            let support: Vec<(usize, usize, f64)> = (0..n * n)
                .filter(|&k| x[k] > 0.0)
                .map(|k| (k / n, k % n, x[k]))
                .collect();
            let full = violated_sides(n, &support, 100);
            let shrunk = separate(n, &support);
            assert_eq!(full.is_empty(), shrunk.is_empty(), "trial {trial}");
            for side in &shrunk {
                assert!(side[0], "trial {trial}: the origin is in S");
                assert!(side.iter().any(|&b| !b), "trial {trial}: T is empty");
                let leaving: f64 = support
                    .iter()
                    .filter(|&&(i, j, _)| side[i] && !side[j])
                    .map(|a| a.2)
                    .sum();
                assert!(leaving < 1.0 - CUT_TOL, "trial {trial}: {leaving}");
            }
            violated += usize::from(!full.is_empty());
        }
        // Both outcomes are exercised.
        assert!(violated > 50 && violated < 250, "{violated}");
    }

    #[test]
    fn a_tour_that_is_not_a_permutation_and_a_non_finite_cost_are_typed_errors() {
        let m = CostMatrix::from_fn(5, |i, j| (i * 5 + j) as f64);
        assert!(matches!(
            dfj_bound(&m, &[1, 1, 2, 3], Duration::from_secs(1)),
            Err(PlanError::Infeasible(_))
        ));
        assert!(dfj_bound(&m, &[1, 2, 3], Duration::from_secs(1)).is_err());
        let nan = CostMatrix::from_fn(5, |i, j| if (i, j) == (3, 1) { f64::NAN } else { 1.0 });
        assert_eq!(
            dfj_bound(&nan, &[1, 2, 3, 4], Duration::from_secs(1)),
            Err(PlanError::NonFiniteCost { from: 3, to: 1 })
        );
    }

    #[test]
    fn tiny_instances_are_solved_by_the_assignment_alone() {
        for n in 0..=3 {
            let m = CostMatrix::from_fn(n, |i, j| (1 + i * 3 + j) as f64);
            let b = dfj_bound(&m, &identity_order(n.max(1)), Duration::from_secs(1)).unwrap();
            if n >= 2 {
                let exact = held_karp::solve(&m).unwrap();
                assert_eq!(b.lower_bound, exact.cost, "n = {n}");
            }
            assert_eq!(b.stop, Stop::Optimal);
        }
    }
}
