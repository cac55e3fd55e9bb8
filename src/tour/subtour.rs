//! Subtour separation for the DFJ formulation, shared by the branch-and-cut solver and the LP
//! lower bound: given a fractional point `x` on the arcs, find node sets `S` holding the origin
//! whose cut `x(delta+(S)) >= 1` it violates. Weakly connected components first (every one
//! without the origin is violated), then minimum cuts from the origin by Dinic's maximum flow
//! (Dinic 1970) on the support graph; and the union-find both use to group nodes.

/// A cut is violated when its flow falls this far below one.
pub(crate) const CUT_TOL: f64 = 1e-4;

/// Node sets `S` holding the origin whose subtour cuts `x(delta+(S)) >= 1` the fractional point
/// `support` (arcs `(i, j, x_ij)` with `x_ij > 0`) violates: every weakly connected component
/// without the origin when there are several, else the source sides of the minimum cuts from
/// the origin below one (at most `max_cuts` per call). `S` is given as membership per node.
pub(crate) fn violated_sides(
    n: usize,
    support: &[(usize, usize, f64)],
    max_cuts: usize,
) -> Vec<Vec<bool>> {
    let mut sides: Vec<Vec<bool>> = Vec::new();
    // Weakly connected components: every one without the origin is a violated cut.
    let component = components(n, support);
    let count = component.iter().copied().max().map_or(0, |c| c + 1);
    if count > 1 {
        for c in 0..count {
            if c != component[0] {
                sides.push(component.iter().map(|&k| k != c).collect());
            }
        }
    } else {
        let mut flow = MaxFlow::new(n, support);
        let mut covered = vec![false; n];
        for t in 1..n {
            if covered[t] {
                continue;
            }
            let (value, source_side) = flow.min_cut(0, t);
            if value < 1.0 - CUT_TOL {
                for v in 0..n {
                    if !source_side[v] {
                        covered[v] = true;
                    }
                }
                sides.push(source_side);
                if sides.len() >= max_cuts {
                    break;
                }
            }
        }
    }
    sides
}

/// Weakly connected component of every node in the graph of `arcs`, numbered in order of
/// their lowest node (so the origin's component is 0).
pub(crate) fn components(n: usize, arcs: &[(usize, usize, f64)]) -> Vec<usize> {
    let mut sets = UnionFind::new(n);
    for &(i, j, _) in arcs {
        sets.union(i, j);
    }
    sets.labels()
}

/// Disjoint sets of nodes with path halving (Tarjan 1975).
pub(crate) struct UnionFind {
    parent: Vec<usize>,
}

impl UnionFind {
    /// `n` singleton sets.
    pub(crate) fn new(n: usize) -> UnionFind {
        UnionFind {
            parent: (0..n).collect(),
        }
    }

    /// The representative of `a`'s set.
    pub(crate) fn find(&mut self, mut a: usize) -> usize {
        while self.parent[a] != a {
            self.parent[a] = self.parent[self.parent[a]];
            a = self.parent[a];
        }
        a
    }

    /// Merges the sets of `a` and `b`.
    pub(crate) fn union(&mut self, a: usize, b: usize) {
        let (a, b) = (self.find(a), self.find(b));
        if a != b {
            self.parent[a] = b;
        }
    }

    /// The set of every node, numbered 0, 1, ... in order of each set's lowest node.
    pub(crate) fn labels(&mut self) -> Vec<usize> {
        let n = self.parent.len();
        let mut label = vec![usize::MAX; n];
        let mut next = 0;
        (0..n)
            .map(|v| {
                let r = self.find(v);
                if label[r] == usize::MAX {
                    label[r] = next;
                    next += 1;
                }
                label[r]
            })
            .collect()
    }
}

/// Dinic's maximum flow on a small graph with real capacities.
pub(crate) struct MaxFlow {
    n: usize,
    head: Vec<usize>,
    next: Vec<usize>,
    to: Vec<usize>,
    capacity: Vec<f64>,
    flow: Vec<f64>,
    level: Vec<i32>,
    cursor: Vec<usize>,
}

const NONE: usize = usize::MAX;
const FLOW_EPS: f64 = 1e-9;

impl MaxFlow {
    pub(crate) fn new(n: usize, arcs: &[(usize, usize, f64)]) -> MaxFlow {
        let mut g = MaxFlow {
            n,
            head: vec![NONE; n],
            next: Vec::new(),
            to: Vec::new(),
            capacity: Vec::new(),
            flow: Vec::new(),
            level: vec![0; n],
            cursor: vec![0; n],
        };
        for &(i, j, c) in arcs {
            g.edge(i, j, c);
            g.edge(j, i, 0.0);
        }
        g
    }

    fn edge(&mut self, from: usize, to: usize, capacity: f64) {
        self.to.push(to);
        self.capacity.push(capacity);
        self.flow.push(0.0);
        self.next.push(self.head[from]);
        self.head[from] = self.to.len() - 1;
    }

    fn residual(&self, e: usize) -> f64 {
        self.capacity[e] - self.flow[e]
    }

    fn bfs(&mut self, s: usize, t: usize) -> bool {
        self.level.fill(-1);
        self.level[s] = 0;
        let mut queue = std::collections::VecDeque::from([s]);
        while let Some(v) = queue.pop_front() {
            let mut e = self.head[v];
            while e != NONE {
                let w = self.to[e];
                if self.level[w] < 0 && self.residual(e) > FLOW_EPS {
                    self.level[w] = self.level[v] + 1;
                    queue.push_back(w);
                }
                e = self.next[e];
            }
        }
        self.level[t] >= 0
    }

    fn dfs(&mut self, v: usize, t: usize, pushed: f64) -> f64 {
        if v == t {
            return pushed;
        }
        while self.cursor[v] != NONE {
            let e = self.cursor[v];
            let w = self.to[e];
            if self.level[w] == self.level[v] + 1 && self.residual(e) > FLOW_EPS {
                let got = self.dfs(w, t, pushed.min(self.residual(e)));
                if got > FLOW_EPS {
                    self.flow[e] += got;
                    self.flow[e ^ 1] -= got;
                    return got;
                }
            }
            self.cursor[v] = self.next[e];
        }
        0.0
    }

    /// The maximum flow from `s` to `t` (capped at 1, all a subtour cut needs) and the source
    /// side of a minimum cut.
    pub(crate) fn min_cut(&mut self, s: usize, t: usize) -> (f64, Vec<bool>) {
        self.flow.fill(0.0);
        let mut total = 0.0;
        while total < 1.0 && self.bfs(s, t) {
            self.cursor.clone_from(&self.head);
            loop {
                let got = self.dfs(s, t, f64::INFINITY);
                if got <= FLOW_EPS {
                    break;
                }
                total += got;
            }
        }
        let _ = self.bfs(s, t);
        let side = (0..self.n).map(|v| self.level[v] >= 0).collect();
        (total, side)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_max_flow_finds_the_bottleneck_of_a_small_graph() {
        // 0 -> 1 (0.4) -> 3, 0 -> 2 (0.5) -> 3, 1 -> 2 (1).
        let arcs = [
            (0, 1, 0.4),
            (0, 2, 0.5),
            (1, 3, 1.0),
            (2, 3, 1.0),
            (1, 2, 1.0),
        ];
        let mut f = MaxFlow::new(4, &arcs);
        let (value, side) = f.min_cut(0, 3);
        assert!((value - 0.9).abs() < 1e-12);
        assert_eq!(side, vec![true, false, false, false]);
    }

    #[test]
    fn components_are_numbered_from_the_origin_and_every_one_without_it_is_a_violated_side() {
        // Two cycles: 0 -> 1 -> 0 and 2 -> 3 -> 2.
        let arcs = [(0, 1, 1.0), (1, 0, 1.0), (2, 3, 1.0), (3, 2, 1.0)];
        assert_eq!(components(4, &arcs), vec![0, 0, 1, 1]);
        assert_eq!(
            violated_sides(4, &arcs, 10),
            vec![vec![true, true, false, false]]
        );
    }

    #[test]
    fn one_connected_support_with_a_weak_cut_is_separated_by_minimum_cut() {
        // Connected, but only 0.5 leaves {0, 1}.
        let arcs = [
            (0, 1, 1.0),
            (1, 0, 0.5),
            (1, 2, 0.5),
            (2, 3, 1.0),
            (3, 2, 0.5),
            (3, 0, 0.5),
        ];
        let sides = violated_sides(4, &arcs, 10);
        assert_eq!(sides, vec![vec![true, true, false, false]]);
    }
}
