//! Dictionary-sparse approximation (the paper's first *Perspective*; Kollepara et al. 2024):
//! every non-zero training snapshot, scaled to unit norm, is an atom `d_j`, and a pressure `s`
//! is approximated by a non-negative combination of at most m atoms, chosen greedily by the
//! Lawson–Hanson rule:
//!
//! ```text
//! r_0 = s;  t = 1, 2, ..: j_t = argmax_{j not chosen} d_j^T r_{t-1}  (stop if <= 0),
//!           alpha = argmin_{a >= 0} ||s - D_{j_1..j_t} a||,  r_t = s - D_{j_1..j_t} alpha
//! ```
//!
//! The error with at most m atoms is `||r_m||` (atoms whose coefficient the NNLS sets to zero
//! stay chosen and count). Without a limit the loop ends when no atom correlates positively
//! with the residual: the KKT conditions of the NNLS over all atoms, so `||r||` is the
//! distance from s to the cone of the whole dictionary. Each step costs one correlation per
//! atom (`O(N n)` here; `O(N)` online with the atoms' Gram rows precomputed) and one NNLS on the
//! chosen atoms.

use faer::{Mat, MatRef};

use super::{DualApprox, DualError, Fact};
use crate::cone::{norm2, ConeProjector, NnlsParams};

/// A correlation at most this fraction of `||s||` is no ascent direction (round-off of the
/// residual's inner products).
const ASCENT_REL: f64 = 1e-12;

/// The training snapshots as atoms.
#[derive(Debug, Clone)]
pub struct Dictionary {
    atoms: Mat<f64>,
}

/// The non-zero columns of `s` scaled to unit norm: their indices, and the atoms column-major.
fn unit_atoms(s: MatRef<'_, f64>) -> (Vec<usize>, Vec<f64>) {
    let mut kept = Vec::new();
    let mut atoms = Vec::new();
    for j in 0..s.ncols() {
        let norm = s.col(j).iter().map(|v| v * v).sum::<f64>().sqrt();
        if norm > 0.0 {
            kept.push(j);
            atoms.extend(s.col(j).iter().map(|v| v / norm));
        }
    }
    (kept, atoms)
}

/// One greedy approximation.
#[derive(Debug, Clone, PartialEq)]
pub struct Sparse {
    /// Atoms in the order they entered.
    pub chosen: Vec<usize>,
    /// Their coefficients (>= 0).
    pub coeffs: Vec<f64>,
    /// `||r_t||` after each step t = 1..
    pub residuals: Vec<f64>,
}

impl Dictionary {
    /// Atoms from the non-zero columns of `s` (n x N), each scaled to unit norm.
    pub fn new(s: MatRef<'_, f64>) -> Self {
        let (kept, atoms) = unit_atoms(s);
        Self { atoms: MatRef::from_column_major_slice(&atoms, s.nrows(), kept.len()).to_owned() }
    }

    /// Number of atoms.
    pub fn len(&self) -> usize {
        self.atoms.ncols()
    }

    /// True without atoms.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The greedy approximation of `s` with at most `max_atoms` atoms.
    pub fn approximate(&self, s: &[f64], max_atoms: usize) -> Result<Sparse, DualError> {
        let n = self.atoms.nrows();
        let mut cone = ConeProjector::empty(n, NnlsParams::default());
        let mut out = Sparse { chosen: Vec::new(), coeffs: Vec::new(), residuals: Vec::new() };
        let mut r = s.to_vec();
        let scale = norm2(s);
        let mut chosen = vec![false; self.len()];
        while out.chosen.len() < max_atoms {
            let mut best: Option<(usize, f64)> = None;
            for j in (0..self.len()).filter(|&j| !chosen[j]) {
                let d = self.atoms.col(j).try_as_col_major().expect("contiguous column").as_slice();
                let c: f64 = d.iter().zip(&r).map(|(a, b)| a * b).sum();
                if best.is_none_or(|(_, b)| c > b) {
                    best = Some((j, c));
                }
            }
            let Some((j, c)) = best else { break };
            if c <= ASCENT_REL * scale {
                break;
            }
            chosen[j] = true;
            out.chosen.push(j);
            let d = self.atoms.col(j).try_as_col_major().expect("contiguous column").as_slice();
            cone.push_column(d);
            out.coeffs.push(0.0);
            let norm = cone.project_warm(s, &mut out.coeffs)?;
            r.copy_from_slice(s);
            for (k, &a) in out.chosen.iter().enumerate() {
                let col = self.atoms.col(a).try_as_col_major().expect("contiguous column").as_slice();
                r.iter_mut().zip(col).for_each(|(x, v)| *x -= out.coeffs[k] * v);
            }
            out.residuals.push(norm);
        }
        Ok(out)
    }
}

impl DualApprox for Dictionary {
    fn residuals(&self, s: &[f64], _mu: &[f64], ms: &[usize], out: &mut [f64]) -> Result<(), DualError> {
        let max = ms.iter().copied().max().unwrap_or(0);
        let sparse = self.approximate(s, max)?;
        let norm = norm2(s);
        for (o, &m) in out.iter_mut().zip(ms) {
            *o = match m.min(sparse.residuals.len()) {
                0 => norm,
                k => sparse.residuals[k - 1],
            };
        }
        Ok(())
    }

    fn size(&self) -> usize {
        self.len()
    }

    fn facts(&self) -> Vec<Fact> {
        vec![Fact::new("atoms", None, self.len() as f64)]
    }

    fn cone_basis(&self, _mu: &[f64], _m: usize) -> Option<Mat<f64>> {
        Some(self.atoms.clone())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assert_close;
    use crate::cone::nnls_reference;
    use crate::float_cmp::Tol;
    use crate::rng::Rng;

    /// Unlimited, the greedy loop ends at the NNLS over every atom (dense Lawson–Hanson
    /// reference); limited, its error is never below that and never grows with m.
    #[test]
    fn unlimited_it_is_the_nnls_over_all_atoms() {
        let mut rng = Rng::new(31);
        let (n, count) = (40, 25);
        let s = Mat::from_fn(n, count, |i, j| {
            let c = 1.0 + j as f64;
            (-((i as f64 - c) / 3.0).powi(2)).exp() * rng.uniform_in(0.5, 1.5)
        });
        let dict = Dictionary::new(s.as_ref());
        for trial in 0..5 {
            let b: Vec<f64> = (0..n).map(|i| (-((i as f64 - 10.0 - 3.3 * trial as f64) / 4.0).powi(2)).exp()).collect();
            let full = dict.approximate(&b, count).expect("greedy");
            let reference = nnls_reference(dict.atoms.as_ref(), &b, NnlsParams::default()).expect("reference");
            // 1e-9 relative: two NNLS solvers on a cone of 25 overlapping bumps (condition
            // ~1e3); the residuals agree to round-off times the condition.
            assert_close!(
                *full.residuals.last().expect("steps"),
                reference.residual_norm,
                Tol { abs: 1e-12, rel: 1e-9 }
            );
            assert!(full.residuals.windows(2).all(|w| w[1] <= w[0] * (1.0 + 1e-12)));
            assert!(full.coeffs.iter().all(|&c| c >= 0.0));
            let few = dict.approximate(&b, 2).expect("two atoms");
            assert!(few.chosen.len() <= 2);
            assert!(few.residuals.last().copied().unwrap_or(norm2(&b)) >= reference.residual_norm * (1.0 - 1e-12));
        }
    }

    /// A snapshot of the dictionary is reproduced by one atom; zero snapshots are no atoms.
    #[test]
    fn a_training_snapshot_is_one_atom() {
        let mut rng = Rng::new(32);
        let mut s = Mat::from_fn(12, 6, |_, _| rng.uniform());
        for i in 0..12 {
            s[(i, 5)] = 0.0;
        }
        let dict = Dictionary::new(s.as_ref());
        assert_eq!(dict.len(), 5);
        let col: Vec<f64> = (0..12).map(|i| 3.0 * s[(i, 2)]).collect();
        let a = dict.approximate(&col, 3).expect("approximate");
        assert_eq!(a.chosen[0], 2);
        assert!(a.residuals[0] <= 1e-12 * norm2(&col));
    }
}

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
/// ([`crate::rom::ReducedModel::solve_in`]), then compute the gap `g_i` of every paired node
/// ([`crate::rom::ReducedModel::node_gaps`]) and the reduced gap of the atoms outside the set that touch a
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
    pub info: crate::rom::SolveInfo,
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
        rom: &mut crate::rom::ReducedModel,
        mu: &[f64],
        p: &crate::rom::RomParams,
        w: &mut crate::rom::RomWork,
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
            if info.outcome != crate::rom::RomOutcome::Converged || rounds >= WS_MAX_ROUNDS {
                let mut out = done(info);
                if info.outcome == crate::rom::RomOutcome::Converged {
                    out.info.outcome = crate::rom::RomOutcome::NotConverged;
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
