//! The online solve with every atom of a dictionary ([`crate::dual::dictionary`]) as a dual basis
//! vector, by a working set of atoms (column generation; [`WorkingSet`]). It lives with the
//! online solve, which it drives, so that `dual` (the offline approximations) never imports
//! `rom`: `rom` depends on `dual`, not the other way round.

use faer::MatRef;

use super::{ReducedModel, RomOutcome, RomParams, RomWork, SolveInfo};
use crate::dual::dictionary::unit_atoms;

/// Relative tolerance of the working set's check: an atom outside the working set is violated
/// when its reduced gap is below `-WS_TOL` times its weight on the largest nodal gap (two orders
/// above the re-linearisation's own consistency, `RomParams::u_tol` = 1e-10).
const WS_TOL: f64 = 1e-8;

/// Size of the first working set: the atoms nearest to the query's parameter. Measured on
/// ironing-fine (`bench_dictionary`, docs/design-notes.md#dual-approximations): with 16 a 4 097-atom dictionary needs a
/// second round at most test points (its 16 nearest atoms span a fraction of one node spacing
/// of travel, and atoms up to one node spacing away are violated), with 32 one round suffices
/// at the median and the 128-atom dictionary pays about 20 % more per query.
pub const WS_START: usize = 32;

/// Atoms added to the working set per round, most violated first.
const WS_ADD: usize = 16;

/// Rounds of the working set before it gives up (the query is then reported as not converged).
const WS_MAX_ROUNDS: usize = 64;

/// The online solve with every atom of a dictionary as a dual basis vector, by a working set
/// (column generation): the reduced problem with all N atoms has one constraint
/// `ĝ_a = sum_i theta_ia w_i g_i(û) >= 0` per atom. Start from the `start` atoms nearest to
/// `mu` in the first parameter, solve the reduced problem on them
/// ([`ReducedModel::solve_in`]), then compute the gap `g_i` of every paired node
/// ([`ReducedModel::node_gaps`]) and the reduced gap of the atoms outside the set that touch a
/// node with a negative gap (an atom whose nodes all have `g >= 0` cannot be violated, since
/// `theta >= 0`); add the most violated ones and solve again, until none is violated. The
/// answer then satisfies the KKT conditions of the problem over all atoms (the atoms outside
/// the set have multiplier 0 and are feasible), so it is the all-atom solution, at a cost that
/// grows with the working set and the nodes near the contact, not with N (the nearest atoms are
/// found by bisection in the sorted parameters).
#[derive(Debug, Clone)]
pub struct WorkingSet {
    n: usize,
    /// Unit atoms, column-major `n x N`.
    atoms: Vec<f64>,
    /// Non-zeros of each atom (CSC): starts, nodes, values.
    by_atom: (Vec<usize>, Vec<usize>, Vec<f64>),
    /// Atoms touching each node (CSR): starts, atoms.
    by_node: (Vec<usize>, Vec<usize>),
    /// Atom indices sorted by their first parameter, and those parameters.
    order: Vec<usize>,
    keys: Vec<f64>,
    weights: Vec<f64>,
    start: usize,
}

/// Buffers of [`WorkingSet::solve`], one per thread.
#[derive(Debug, Clone, Default)]
pub struct WorkingSetScratch {
    set: Vec<usize>,
    /// `stamp[a] == generation`: atom a is in the working set of this query.
    stamp: Vec<u32>,
    generation: u32,
    /// `seen[a] == round`: atom a was checked in this round.
    seen: Vec<u32>,
    round: u32,
    theta: Vec<f64>,
    gaps: Vec<(usize, f64)>,
    node_gap: Vec<f64>,
    candidates: Vec<(f64, usize)>,
}

/// How a working-set solve went.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorkingSetInfo {
    /// The last reduced solve.
    pub info: SolveInfo,
    /// Rounds (reduced solves).
    pub rounds: usize,
    /// Atoms in the final working set.
    pub atoms: usize,
}

impl WorkingSet {
    /// The non-zero columns of `s` (n x N) as unit atoms, with their parameters `params`, the
    /// nodes' tributary weights and the size of the first working set.
    pub fn new(s: MatRef<'_, f64>, params: &[Vec<f64>], weights: &[f64], start: usize) -> Self {
        let n = s.nrows();
        let (kept, atoms) = unit_atoms(s);
        let count = kept.len();
        let mut by_atom = (vec![0], Vec::new(), Vec::new());
        let mut node_atoms: Vec<Vec<usize>> = vec![Vec::new(); n];
        for a in 0..count {
            for i in 0..n {
                let v = atoms[a * n + i];
                if v != 0.0 {
                    by_atom.1.push(i);
                    by_atom.2.push(v);
                    node_atoms[i].push(a);
                }
            }
            by_atom.0.push(by_atom.1.len());
        }
        let mut by_node = (vec![0], Vec::new());
        for list in &node_atoms {
            by_node.1.extend_from_slice(list);
            by_node.0.push(by_node.1.len());
        }
        let first = |a: usize| params[kept[a]].first().copied().unwrap_or(0.0);
        let mut order: Vec<usize> = (0..count).collect();
        order.sort_by(|&a, &b| first(a).total_cmp(&first(b)).then(a.cmp(&b)));
        let keys = order.iter().map(|&a| first(a)).collect();
        Self { n, atoms, by_atom, by_node, order, keys, weights: weights.to_vec(), start: start.max(1) }
    }

    /// Number of atoms.
    pub fn len(&self) -> usize {
        self.order.len()
    }

    /// True without atoms.
    pub fn is_empty(&self) -> bool {
        self.order.is_empty()
    }

    /// Solve at `mu` with the dual basis of `rom` replaced by the working set's atoms; the
    /// solution is in `w` (`λ̂` over the working set, in `scratch`'s order).
    pub fn solve(
        &self,
        rom: &mut ReducedModel,
        mu: &[f64],
        p: &RomParams,
        w: &mut RomWork,
        sc: &mut WorkingSetScratch,
    ) -> WorkingSetInfo {
        let count = self.len();
        if sc.stamp.len() != count {
            sc.stamp.clear();
            sc.stamp.resize(count, 0);
            sc.generation = 0;
            sc.seen.clear();
            sc.seen.resize(count, 0);
            sc.round = 0;
        }
        sc.generation = sc.generation.wrapping_add(1);
        if sc.generation == 0 {
            sc.stamp.iter_mut().for_each(|s| *s = 0);
            sc.generation = 1;
        }
        let gen = sc.generation;
        // The `start` atoms nearest to mu in the first parameter (bisection, then outwards).
        sc.set.clear();
        let x = mu.first().copied().unwrap_or(0.0);
        let mut hi = self.keys.partition_point(|&k| k < x);
        let mut lo = hi;
        while sc.set.len() < self.start.min(count) {
            let take_left = match (lo > 0, hi < count) {
                (true, true) => x - self.keys[lo - 1] <= self.keys[hi] - x,
                (true, false) => true,
                (false, _) => false,
            };
            let a = if take_left {
                lo -= 1;
                self.order[lo]
            } else {
                hi += 1;
                self.order[hi - 1]
            };
            sc.stamp[a] = gen;
            sc.set.push(a);
        }
        let n = self.n;
        let mut rounds = 0;
        loop {
            rounds += 1;
            sc.theta.clear();
            for &a in &sc.set {
                sc.theta.extend_from_slice(&self.atoms[a * n..(a + 1) * n]);
            }
            rom.set_dual(&sc.theta, sc.set.len());
            let info = rom.solve_in(mu, p, w);
            let done = |info| WorkingSetInfo { info, rounds, atoms: sc.set.len() };
            if info.outcome != RomOutcome::Converged || rounds >= WS_MAX_ROUNDS {
                let mut out = done(info);
                if info.outcome == RomOutcome::Converged {
                    out.info.outcome = RomOutcome::NotConverged;
                }
                return out;
            }
            rom.node_gaps(mu, w, &mut sc.gaps);
            sc.node_gap.clear();
            sc.node_gap.resize(n, 0.0);
            let mut gscale = 0.0f64;
            for &(i, g) in &sc.gaps {
                sc.node_gap[i] = g;
                gscale = gscale.max(g.abs());
            }
            // Candidates: atoms outside the set touching a node with a negative gap.
            sc.candidates.clear();
            sc.round = sc.round.wrapping_add(1);
            if sc.round == 0 {
                sc.seen.iter_mut().for_each(|s| *s = 0);
                sc.round = 1;
            }
            let round = sc.round;
            for &(i, g) in &sc.gaps {
                if g >= -WS_TOL * gscale {
                    continue;
                }
                for &a in &self.by_node.1[self.by_node.0[i]..self.by_node.0[i + 1]] {
                    if sc.stamp[a] == gen || sc.seen[a] == round {
                        continue;
                    }
                    sc.seen[a] = round;
                    let (mut ga, mut scale) = (0.0, 0.0);
                    for e in self.by_atom.0[a]..self.by_atom.0[a + 1] {
                        let (node, v) = (self.by_atom.1[e], self.by_atom.2[e]);
                        let tw = v * self.weights[node];
                        ga += tw * sc.node_gap[node];
                        scale += tw * gscale;
                    }
                    if ga < -WS_TOL * scale {
                        sc.candidates.push((ga / scale.max(f64::MIN_POSITIVE), a));
                    }
                }
            }
            if sc.candidates.is_empty() {
                return done(info);
            }
            sc.candidates.sort_by(|p, q| p.0.total_cmp(&q.0).then(p.1.cmp(&q.1)));
            for k in 0..sc.candidates.len().min(WS_ADD) {
                let a = sc.candidates[k].1;
                sc.stamp[a] = gen;
                sc.set.push(a);
            }
        }
    }
}
