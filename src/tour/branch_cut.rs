//! Exact asymmetric TSP by branch-and-cut on the Dantzig-Fulkerson-Johnson formulation
//! (Dantzig, Fulkerson and Johnson 1954; Fischetti, Lodi and Toth 2002, "Exact methods for the
//! asymmetric traveling salesman problem", in Gutin and Punnen, The TSP and its Variations).
//!
//! - Variables `x_ij` in [0, 1] for the arcs that can be in a tour better than the incumbent:
//!   arcs whose assignment reduced cost exceeds `incumbent - assignment bound` are dropped first
//!   ([`super::assignment`]), which keeps the LP small (all of it on instances whose AP bound is
//!   tight, such as TSPLIB's rbg family).
//! - Out-degree and in-degree of every node equal one.
//! - Subtour elimination constraints `x(delta+(S)) >= 1` for node sets `S` holding the origin,
//!   added lazily: connected components of the LP's support graph first, then exact separation
//!   by minimum cut (a maximum flow from the origin to every other node, Dinic 1970; Padberg and
//!   Rinaldi 1990 for the scheme). Each cut is written in whichever equivalent form has the fewest
//!   nonzeros (arcs leaving S, entering S, inside S or inside its complement).
//! - Depth-first branching on the most fractional arc (arc in first), with one live LP that
//!   moves between nodes by fixing and releasing variables, so each node's LP is re-solved from
//!   its neighbour's basis (microlp's dual simplex). Cuts stay valid everywhere and are kept.
//!
//! The LP is microlp (pure Rust, maintained, measured workable on these instances).
//! Every node's LP value is a lower bound for its subtree, so a run cut short by the time limit
//! still reports a proven lower bound: the least bound among the open nodes.

use std::collections::HashSet;
use std::time::{Duration, Instant};

use microlp::{ComparisonOp, LinearExpr, OptimizationDirection, Problem, Solution, Variable};

use super::progress::{self, Event};
use super::subtour::violated_sides;
use super::{assignment, CostMatrix, PlanError, Tour};

/// Limits of a branch-and-cut run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Options {
    /// Wall-clock budget; when it runs out the best tour and a proven lower bound are returned.
    pub time_limit: Duration,
    /// How the tree below the root is searched.
    pub tree: TreeSearch,
}

/// The search below the root LP.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TreeSearch {
    /// Our depth-first branch-and-cut: subtour cuts separated at every node.
    Own,
    /// microlp's MIP branch-and-bound (pseudocost branching) over the root's cuts, with subtour
    /// cuts added for the subtours of each integral optimum and the MIP solved again.
    Milp,
    /// Our tree first (fast where the LP bound is close), the MIP with every cut found so far
    /// when the tree grows past a share of the time or a node budget.
    Hybrid,
}

/// Share of the time limit the hybrid search gives its own tree.
const HYBRID_OWN_SHARE: f64 = 0.25;
/// Nodes the hybrid search gives its own tree.
const HYBRID_OWN_NODES: u64 = 3000;

impl Default for Options {
    fn default() -> Self {
        Options {
            time_limit: Duration::from_secs(60),
            tree: TreeSearch::Hybrid,
        }
    }
}

/// What a branch-and-cut run found and proved.
#[derive(Debug, Clone, PartialEq)]
pub struct Outcome {
    /// The best tour; `optimal` when the search finished, `lower_bound` always proven.
    pub tour: Tour,
    /// The assignment-problem bound.
    pub assignment_bound: f64,
    /// The DFJ LP bound at the root (all subtour cuts satisfied).
    pub root_bound: f64,
    /// Arcs kept after reduced-cost elimination (of n(n-1)).
    pub arcs: usize,
    /// Branch-and-bound nodes whose LP was solved.
    pub nodes: u64,
    /// Subtour cuts added.
    pub cuts: usize,
    /// Wall-clock seconds.
    pub seconds: f64,
}

/// Values within this distance of 0 or 1 count as integral; LP feasibility is 1e-7.
const INTEGRAL_TOL: f64 = 1e-6;
/// Relative optimality tolerance for real-valued costs (the LP solver's own accuracy is about
/// 1e-9 relative): a tour within this of the lower bound is called optimal.
const REL_GAP: f64 = 1e-7;
/// Minimum cuts separated per round (components are all taken).
const MAX_CUTS_PER_ROUND: usize = 50;
/// Cut rounds at a node other than the root before branching anyway.
const MAX_NODE_ROUNDS: usize = 30;

/// Solves the ATSP of `m` exactly, starting from the `incumbent` order (every node 1..n-1 once;
/// a good heuristic tour makes the search far smaller).
pub fn solve(m: &CostMatrix, incumbent: &[usize], options: &Options) -> Result<Outcome, PlanError> {
    let started = Instant::now();
    let n = m.len();
    m.check_tour_order(incumbent)?;
    let mut best_order = incumbent.to_vec();
    let mut best_cost = m.tour_cost(&best_order);
    if n <= 3 {
        // One tour (or two mirror tours for n = 3): enumerate.
        if n == 3 {
            let other = vec![incumbent[1], incumbent[0]];
            if m.tour_cost(&other) < best_cost {
                best_cost = m.tour_cost(&other);
                best_order = other;
            }
        }
        return Ok(Outcome {
            tour: Tour {
                order: best_order,
                cost: best_cost,
                lower_bound: best_cost,
                optimal: true,
            },
            assignment_bound: best_cost,
            root_bound: best_cost,
            arcs: n * n.saturating_sub(1),
            nodes: 0,
            cuts: 0,
            seconds: started.elapsed().as_secs_f64(),
        });
    }
    let integer = m.has_integer_costs();
    let ap = assignment::solve(m)?;
    let assignment_bound = ap.cost;

    // Keep the arcs that can lie on a tour no worse than the incumbent.
    let slack = best_cost - ap.cost;
    let keep_tol = 1e-9 * best_cost.abs().max(1.0);
    let mut arcs = Vec::new();
    for i in 0..n {
        for j in 0..n {
            if i != j && ap.reduced_cost(m, i, j) <= slack + keep_tol {
                arcs.push((i, j));
            }
        }
    }
    let mut search = Search {
        m,
        n,
        integer,
        arcs,
        cuts: Vec::new(),
        cut_keys: HashSet::new(),
        live: None,
        live_fixed: Vec::new(),
        deadline: started + options.time_limit,
    };
    search.live_fixed = vec![None; search.arcs.len()];

    let mut nodes = 0u64;
    let mut root_bound = f64::NEG_INFINITY;
    let mut pseudo = PseudoCosts::new(search.arcs.len());
    let mut stack = vec![Open {
        fixings: Vec::new(),
        bound: ap.cost,
        branched: None,
    }];
    let mut timed_out = false;
    // The own tree's share of the time before the MIP takes over (hybrid search).
    let own_deadline = match options.tree {
        TreeSearch::Own => search.deadline,
        TreeSearch::Milp => started,
        TreeSearch::Hybrid => started + options.time_limit.mul_f64(HYBRID_OWN_SHARE),
    };
    while let Some(open) = stack.pop() {
        if search.prunes(open.bound, best_cost) {
            continue;
        }
        if Instant::now() >= search.deadline || super::cancel::requested() {
            stack.push(open);
            timed_out = true;
            break;
        }
        let hand_over = nodes > 0
            && options.tree != TreeSearch::Own
            && (Instant::now() >= own_deadline || nodes >= HYBRID_OWN_NODES);
        if hand_over {
            // The MIP restarts from the root with every cut found so far.
            stack.push(open);
            let open_bound = stack.iter().map(|o| o.bound).fold(f64::INFINITY, f64::min);
            let milp = search.milp(&mut best_order, &mut best_cost)?;
            nodes += milp.nodes;
            stack.clear();
            if !milp.proven {
                stack.push(Open {
                    fixings: Vec::new(),
                    bound: milp.lower_bound.max(open_bound.min(best_cost)),
                    branched: None,
                });
                timed_out = true;
            }
            break;
        }
        nodes += 1;
        let is_root = nodes == 1;
        if nodes % 32 == 1 {
            // The best bound of the tree: the least over the open nodes and this one.
            let open_bound = stack.iter().map(|o| o.bound).fold(open.bound, f64::min);
            progress::report(Event::Bound(open_bound.min(best_cost)));
        }
        let (bound, first, x) = match search.evaluate(&open.fixings, is_root, best_cost)? {
            Evaluated::Infeasible => continue,
            Evaluated::TimedOut(bound) => {
                stack.push(Open {
                    bound: bound.max(open.bound),
                    ..open
                });
                timed_out = true;
                break;
            }
            Evaluated::Bound { bound, first, x } => (bound, first, x),
        };
        if let Some((var, up, moved)) = open.branched {
            pseudo.record(var, up, (first - open.bound).max(0.0) / moved.max(1e-6));
        }
        if is_root {
            root_bound = bound;
        }
        if search.prunes(bound, best_cost) {
            continue;
        }
        match pseudo.choose(&x) {
            None => {
                // Integral and no subtour: a tour.
                if let Some(order) = search.tour_of(&x) {
                    let cost = m.tour_cost(&order);
                    if cost < best_cost {
                        best_cost = cost;
                        best_order = order;
                        progress::report(Event::Incumbent(best_cost));
                    }
                }
            }
            Some(var) => {
                let mut zero = open.fixings.clone();
                zero.push((var, false));
                let mut one = open.fixings;
                one.push((var, true));
                stack.push(Open {
                    fixings: zero,
                    bound,
                    branched: Some((var, false, x[var])),
                });
                stack.push(Open {
                    fixings: one,
                    bound,
                    branched: Some((var, true, 1.0 - x[var])),
                });
            }
        }
    }
    let open_bound = stack.iter().map(|o| o.bound).fold(f64::INFINITY, f64::min);
    let mut lower_bound = if timed_out {
        open_bound.min(best_cost)
    } else {
        best_cost
    };
    lower_bound = lower_bound.max(assignment_bound).min(best_cost);
    if integer && lower_bound < best_cost {
        lower_bound = (lower_bound - 1e-6).ceil().min(best_cost);
    }
    if root_bound == f64::NEG_INFINITY {
        root_bound = lower_bound;
    }
    let optimal = !timed_out || search.prunes(lower_bound, best_cost);
    Ok(Outcome {
        tour: Tour {
            order: best_order,
            cost: best_cost,
            lower_bound: if optimal { best_cost } else { lower_bound },
            optimal,
        },
        assignment_bound,
        root_bound,
        arcs: search.arcs.len(),
        nodes,
        cuts: search.cuts.len(),
        seconds: started.elapsed().as_secs_f64(),
    })
}

/// A subtour cut over arc variables: `sum x_k (op) rhs`.
#[derive(Debug, Clone)]
struct Cut {
    vars: Vec<usize>,
    op: ComparisonOp,
    rhs: f64,
}

/// An open node: its fixings from the root, its parent's bound, and the branching that made
/// it (arc, up or down, how far the LP value had to move).
struct Open {
    fixings: Vec<(usize, bool)>,
    bound: f64,
    branched: Option<(usize, bool, f64)>,
}

/// Pseudocosts (Benichou et al. 1971): the observed bound increase per unit of change of each
/// arc variable, up and down; unobserved arcs take the average. Branching picks the arc with
/// the best product score of its estimated increases (Achterberg, Koch and Martin 2005).
struct PseudoCosts {
    sum: [Vec<f64>; 2],
    count: [Vec<u32>; 2],
    total: [f64; 2],
    observed: [u32; 2],
}

impl PseudoCosts {
    fn new(arcs: usize) -> PseudoCosts {
        PseudoCosts {
            sum: [vec![0.0; arcs], vec![0.0; arcs]],
            count: [vec![0; arcs], vec![0; arcs]],
            total: [0.0; 2],
            observed: [0; 2],
        }
    }

    fn record(&mut self, var: usize, up: bool, per_unit: f64) {
        let d = usize::from(up);
        self.sum[d][var] += per_unit;
        self.count[d][var] += 1;
        self.total[d] += per_unit;
        self.observed[d] += 1;
    }

    fn estimate(&self, var: usize, up: bool) -> f64 {
        let d = usize::from(up);
        if self.count[d][var] > 0 {
            self.sum[d][var] / f64::from(self.count[d][var])
        } else if self.observed[d] > 0 {
            self.total[d] / f64::from(self.observed[d])
        } else {
            1.0
        }
    }

    /// The arc to branch on, or None when `x` is integral.
    fn choose(&self, x: &[f64]) -> Option<usize> {
        let mut best: Option<(usize, f64)> = None;
        for (k, &v) in x.iter().enumerate() {
            if v.min(1.0 - v) <= INTEGRAL_TOL {
                continue;
            }
            let down = (self.estimate(k, false) * v).max(1e-6);
            let up = (self.estimate(k, true) * (1.0 - v)).max(1e-6);
            let score = down * up;
            if best.is_none_or(|(_, s)| score > s) {
                best = Some((k, score));
            }
        }
        best.map(|(k, _)| k)
    }
}

struct Milp {
    proven: bool,
    lower_bound: f64,
    nodes: u64,
}

enum Edit {
    Done(Solution),
    Infeasible,
    Failed,
}

enum Evaluated {
    Infeasible,
    TimedOut(f64),
    /// The node's LP bound after its cuts, its LP value before them, and the LP point.
    Bound {
        bound: f64,
        first: f64,
        x: Vec<f64>,
    },
}

struct Search<'a> {
    m: &'a CostMatrix,
    n: usize,
    integer: bool,
    arcs: Vec<(usize, usize)>,
    cuts: Vec<Cut>,
    cut_keys: HashSet<Vec<bool>>,
    /// The live LP and its variables, or None after an infeasible edit.
    live: Option<(Solution, Vec<Variable>)>,
    /// What the live LP has each variable fixed to.
    live_fixed: Vec<Option<bool>>,
    deadline: Instant,
}

impl Search<'_> {
    /// Whether a subtree whose LP bound is `bound` cannot hold a tour better than `best`.
    fn prunes(&self, bound: f64, best: f64) -> bool {
        if self.integer {
            (bound - 1e-6).ceil() >= best
        } else {
            bound >= best - REL_GAP * best.abs().max(1.0)
        }
    }

    /// The degree equations (one successor and one predecessor per node) and every cut so far.
    fn add_rows(&self, problem: &mut Problem, vars: &[Variable]) {
        let mut out: Vec<LinearExpr> = (0..self.n).map(|_| LinearExpr::empty()).collect();
        let mut inn: Vec<LinearExpr> = (0..self.n).map(|_| LinearExpr::empty()).collect();
        for (k, &(i, j)) in self.arcs.iter().enumerate() {
            out[i].add(vars[k], 1.0);
            inn[j].add(vars[k], 1.0);
        }
        for expr in out.into_iter().chain(inn) {
            problem.add_constraint(expr, ComparisonOp::Eq, 1.0);
        }
        for cut in &self.cuts {
            problem.add_constraint(cut.vars.iter().map(|&k| (vars[k], 1.0)), cut.op, cut.rhs);
        }
    }

    /// A fresh LP with every cut so far and `fixed` applied as bounds.
    fn build(
        &self,
        fixed: &[Option<bool>],
    ) -> Result<Option<(Solution, Vec<Variable>)>, PlanError> {
        let mut problem = Problem::new(OptimizationDirection::Minimize);
        let vars: Vec<Variable> = self
            .arcs
            .iter()
            .zip(fixed)
            .map(|(&(i, j), f)| {
                let bounds = match f {
                    Some(true) => (1.0, 1.0),
                    Some(false) => (0.0, 0.0),
                    None => (0.0, 1.0),
                };
                problem.add_var(self.m.cost(i, j), bounds)
            })
            .collect();
        self.add_rows(&mut problem, &vars);
        problem.set_time_limit(self.remaining());
        match problem.solve() {
            Ok(outcome) => match outcome.into_solution() {
                Ok(solution) => Ok(Some((solution, vars))),
                Err(_) => Err(PlanError::Lp("time limit inside an LP solve".to_string())),
            },
            Err(microlp::Error::Infeasible) => Ok(None),
            Err(e) => Err(PlanError::Lp(e.to_string())),
        }
    }

    fn remaining(&self) -> Duration {
        self.deadline.saturating_duration_since(Instant::now())
    }

    /// Moves the live LP to the node with `fixings`; false when that node is infeasible.
    fn move_to(&mut self, fixings: &[(usize, bool)]) -> Result<bool, PlanError> {
        let mut target = vec![None; self.arcs.len()];
        for &(k, v) in fixings {
            target[k] = Some(v);
        }
        if let Some((sol, vars)) = self.live.take() {
            match self.edit(sol, &vars, &target) {
                Edit::Done(sol) => {
                    self.live = Some((sol, vars));
                    return Ok(true);
                }
                Edit::Infeasible => {
                    // The LP is gone; the next node rebuilds it.
                    self.live_fixed = vec![None; self.arcs.len()];
                    return Ok(false);
                }
                Edit::Failed => {}
            }
        }
        // No live LP (first node, after an infeasible edit or a numerical failure): rebuild.
        let built = self.build(&target)?;
        self.live_fixed = target;
        match built {
            Some(live) => {
                self.live = Some(live);
                Ok(true)
            }
            None => Ok(false),
        }
    }

    /// Releases the fixings the target drops (never infeasible), then applies its new ones.
    fn edit(&mut self, mut sol: Solution, vars: &[Variable], target: &[Option<bool>]) -> Edit {
        for k in 0..self.arcs.len() {
            if self.live_fixed[k].is_some() && target[k].is_none() {
                match sol.unfix_var(vars[k]).map(|(o, _)| o.into_solution()) {
                    Ok(Ok(s)) => sol = s,
                    _ => return Edit::Failed,
                }
                self.live_fixed[k] = None;
            }
        }
        for k in 0..self.arcs.len() {
            if target[k].is_some() && self.live_fixed[k] != target[k] {
                let value = if target[k] == Some(true) { 1.0 } else { 0.0 };
                match sol.fix_var(vars[k], value).map(|o| o.into_solution()) {
                    Ok(Ok(s)) => sol = s,
                    Err(microlp::Error::Infeasible) => return Edit::Infeasible,
                    _ => return Edit::Failed,
                }
                self.live_fixed[k] = target[k];
            }
        }
        Edit::Done(sol)
    }

    /// Solves the node's LP, adding violated subtour cuts until none is left (or the node
    /// cannot beat `best`).
    fn evaluate(
        &mut self,
        fixings: &[(usize, bool)],
        is_root: bool,
        best: f64,
    ) -> Result<Evaluated, PlanError> {
        if !self.move_to(fixings)? {
            return Ok(Evaluated::Infeasible);
        }
        let mut rounds = 0;
        let mut first = None;
        loop {
            let Some((sol, vars)) = self.live.as_ref() else {
                return Ok(Evaluated::Infeasible);
            };
            let bound = sol.objective();
            let x: Vec<f64> = vars.iter().map(|&v| sol.var_value(v)).collect();
            let first = *first.get_or_insert(bound);
            if self.prunes(bound, best) {
                return Ok(Evaluated::Bound { bound, first, x });
            }
            if Instant::now() >= self.deadline {
                return Ok(Evaluated::TimedOut(bound));
            }
            let found = self.separate(&x);
            if found.is_empty() || (!is_root && rounds >= MAX_NODE_ROUNDS) {
                return Ok(Evaluated::Bound { bound, first, x });
            }
            rounds += 1;
            for cut in found {
                self.cuts.push(cut.clone());
                let Some((sol, vars)) = self.live.take() else {
                    continue;
                };
                let expr: Vec<(Variable, f64)> = cut.vars.iter().map(|&k| (vars[k], 1.0)).collect();
                match sol.add_constraint(expr, cut.op, cut.rhs) {
                    Ok(outcome) => match outcome.into_solution() {
                        Ok(s) => self.live = Some((s, vars)),
                        Err(_) => return Ok(Evaluated::TimedOut(bound)),
                    },
                    Err(microlp::Error::Infeasible) => {
                        self.live_fixed = vec![None; self.arcs.len()];
                        return Ok(Evaluated::Infeasible);
                    }
                    Err(_) => {
                        // Numerical trouble: rebuild with every cut from scratch.
                        if !self.move_to(fixings)? {
                            return Ok(Evaluated::Infeasible);
                        }
                        break;
                    }
                }
            }
        }
    }

    /// microlp's MIP over the current cuts, warm-started from the incumbent; subtours of its
    /// integral optima are cut off and the MIP solved again until its optimum is a tour or time
    /// runs out.
    fn milp(
        &mut self,
        best_order: &mut Vec<usize>,
        best_cost: &mut f64,
    ) -> Result<Milp, PlanError> {
        self.live = None;
        let mut nodes = 0;
        loop {
            let mut problem = Problem::new(OptimizationDirection::Minimize);
            let vars: Vec<Variable> = self
                .arcs
                .iter()
                .map(|&(i, j)| problem.add_binary_var(self.m.cost(i, j)))
                .collect();
            self.add_rows(&mut problem, &vars);
            let mut successor = vec![usize::MAX; self.n];
            let mut prev = 0;
            for &node in best_order.iter() {
                successor[prev] = node;
                prev = node;
            }
            successor[prev] = 0;
            let hint: Vec<(Variable, f64)> = self
                .arcs
                .iter()
                .enumerate()
                .map(|(k, &(i, j))| (vars[k], if successor[i] == j { 1.0 } else { 0.0 }))
                .collect();
            let mut options = microlp::SolveOptions::default();
            options.time_limit = Some(self.remaining());
            options.warm_start = Some(hint);
            let outcome = problem
                .solve_with(options)
                .map_err(|e| PlanError::Lp(e.to_string()))?;
            let stats = outcome.stats();
            nodes += stats.nodes_solved;
            let proven = outcome.is_optimal();
            let Ok(sol) = outcome.into_solution() else {
                return Ok(Milp {
                    proven: false,
                    lower_bound: stats.best_bound.unwrap_or(f64::NEG_INFINITY),
                    nodes,
                });
            };
            let x: Vec<f64> = vars.iter().map(|&v| sol.var_value(v)).collect();
            if let Some(order) = self.tour_of(&x) {
                let cost = self.m.tour_cost(&order);
                if cost < *best_cost {
                    *best_cost = cost;
                    *best_order = order;
                }
            }
            if !proven {
                return Ok(Milp {
                    proven: false,
                    lower_bound: stats.best_bound.unwrap_or(f64::NEG_INFINITY),
                    nodes,
                });
            }
            let found = self.separate(&x);
            if found.is_empty() {
                return Ok(Milp {
                    proven: true,
                    lower_bound: sol.objective(),
                    nodes,
                });
            }
            if self.prunes(sol.objective(), *best_cost) {
                return Ok(Milp {
                    proven: true,
                    lower_bound: sol.objective(),
                    nodes,
                });
            }
            self.cuts.extend(found);
        }
    }

    /// The tour of an integral `x`, if it is one cycle through every node.
    fn tour_of(&self, x: &[f64]) -> Option<Vec<usize>> {
        let mut successor = vec![usize::MAX; self.n];
        for (k, &v) in x.iter().enumerate() {
            if v > 0.5 {
                let (i, j) = self.arcs[k];
                successor[i] = j;
            }
        }
        let mut order = Vec::with_capacity(self.n - 1);
        let mut node = successor[0];
        while node != 0 && node < self.n && order.len() < self.n {
            order.push(node);
            node = successor[node];
        }
        (node == 0 && order.len() == self.n - 1).then_some(order)
    }

    /// Violated subtour cuts of `x`: components of the support graph, then minimum cuts.
    fn separate(&mut self, x: &[f64]) -> Vec<Cut> {
        let support: Vec<(usize, usize, f64)> = x
            .iter()
            .enumerate()
            .filter(|(_, &v)| v > INTEGRAL_TOL)
            .map(|(k, &v)| (self.arcs[k].0, self.arcs[k].1, v))
            .collect();
        let mut cuts = Vec::new();
        for side in violated_sides(self.n, &support, MAX_CUTS_PER_ROUND) {
            if self.cut_keys.insert(side.clone()) {
                cuts.push(self.cut_for(&side));
            }
        }
        cuts
    }

    /// The sparsest of the equivalent forms of the subtour cut of `in_s` (S holds the origin).
    fn cut_for(&self, in_s: &[bool]) -> Cut {
        let (mut leaving, mut entering, mut inside_s, mut inside_t) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for (k, &(i, j)) in self.arcs.iter().enumerate() {
            match (in_s[i], in_s[j]) {
                (true, false) => leaving.push(k),
                (false, true) => entering.push(k),
                (true, true) => inside_s.push(k),
                (false, false) => inside_t.push(k),
            }
        }
        let size_s = in_s.iter().filter(|&&b| b).count() as f64;
        let size_t = self.n as f64 - size_s;
        let forms = [
            (leaving, ComparisonOp::Ge, 1.0),
            (entering, ComparisonOp::Ge, 1.0),
            (inside_s, ComparisonOp::Le, size_s - 1.0),
            (inside_t, ComparisonOp::Le, size_t - 1.0),
        ];
        let (vars, op, rhs) = forms
            .into_iter()
            .min_by_key(|(vars, _, _)| vars.len())
            .unwrap_or((Vec::new(), ComparisonOp::Ge, 1.0));
        Cut { vars, op, rhs }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;
    use crate::tour::held_karp;

    fn identity_order(n: usize) -> Vec<usize> {
        (1..n).collect()
    }

    #[test]
    fn branch_and_cut_equals_held_karp_on_random_asymmetric_matrices() {
        let mut rng = Rng::new(11);
        for trial in 0..60 {
            let n = 2 + trial % 12;
            let m = CostMatrix::from_fn(n, |_, _| rng.below(1000) as f64);
            let hk = held_karp::solve(&m).unwrap();
            let bc = solve(&m, &identity_order(n), &Options::default()).unwrap();
            assert!(bc.tour.optimal, "trial {trial}");
            assert_eq!(bc.tour.cost, hk.cost, "trial {trial}");
            assert_eq!(m.tour_cost(&bc.tour.order), bc.tour.cost);
            assert_eq!(bc.tour.lower_bound, bc.tour.cost);
        }
    }

    #[test]
    fn branch_and_cut_equals_held_karp_on_real_valued_climb_averse_costs() {
        let mut rng = Rng::new(5);
        for trial in 0..20 {
            let n = 6 + trial % 10;
            let m = crate::tour::testing::drone(n, rng.next_u64());
            let hk = held_karp::solve(&m).unwrap();
            let bc = solve(&m, &identity_order(n), &Options::default()).unwrap();
            assert!(bc.tour.optimal);
            assert!(
                (bc.tour.cost - hk.cost).abs() <= 1e-6 * hk.cost,
                "trial {trial}"
            );
        }
    }

    #[test]
    fn every_tree_search_proves_the_held_karp_optimum() {
        let mut rng = Rng::new(17);
        for trial in 0..12 {
            let n = 8 + trial % 6;
            let m = crate::tour::testing::drone(n, rng.next_u64());
            let hk = held_karp::solve(&m).unwrap();
            for tree in [TreeSearch::Own, TreeSearch::Milp, TreeSearch::Hybrid] {
                let options = Options {
                    tree,
                    ..Default::default()
                };
                let out = solve(&m, &identity_order(n), &options).unwrap();
                assert!(out.tour.optimal, "{tree:?} trial {trial}");
                assert!(
                    (out.tour.cost - hk.cost).abs() <= 1e-6 * hk.cost,
                    "{tree:?} trial {trial}: {} vs {}",
                    out.tour.cost,
                    hk.cost
                );
            }
        }
    }

    #[test]
    fn a_starting_tour_that_is_not_a_permutation_is_refused() {
        let m = CostMatrix::from_fn(4, |_, _| 1.0);
        assert!(matches!(
            solve(&m, &[1, 1, 2], &Options::default()),
            Err(PlanError::Infeasible(_))
        ));
        assert!(solve(&m, &[1, 2], &Options::default()).is_err());
    }

    #[test]
    fn a_zero_time_limit_still_returns_the_incumbent_with_a_valid_lower_bound() {
        let mut rng = Rng::new(2);
        let m = CostMatrix::from_fn(12, |_, _| rng.below(1000) as f64);
        let hk = held_karp::solve(&m).unwrap();
        let out = solve(
            &m,
            &identity_order(12),
            &Options {
                time_limit: Duration::ZERO,
                ..Default::default()
            },
        )
        .unwrap();
        assert!(out.tour.lower_bound <= hk.cost);
        assert!(out.tour.cost >= hk.cost);
    }
}
