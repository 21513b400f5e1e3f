//! The curvature of the node-to-segment gaps in the reduced coordinates, for a Newton step of the
//! Type-2 re-pairing (docs/design-notes.md#newton-corrected-re-pairing-steps).
//!
//! The exact online solve linearises every paired slave's gap at the current iterate `y_k` and
//! solves the QP `min |y|^2 / 2  s.t.  Ĉ_k y + ĝ0_k >= 0` exactly. The gap rows are the gaps'
//! exact gradients (the projection's `ξ` and the normal frozen at `y_k` change the gap only to
//! second order), so this is sequential quadratic programming with the Lagrangian's Hessian
//! `I - Σ_a λ̂_a ∇²ŝ_a` replaced by `I`: it converges linearly, at the rate of the dropped term
//! `H = -Σ_s p_s ∇²g_s` (`p_s` the force on slave `s`, its pressure times its tributary
//! length), about 1e-2 on ironing-fine — a steady 1e-2 per linearisation.
//!
//! **What is dropped.** The QP's row of slave `s` is `r_s(y) = ∂g_s/∂y` with the normal (and
//! `ξ`) of the pairing at `y`; its force balance `y = Σ_s p_s r_s(y)` changes with the
//! linearisation point through `∂r_s/∂y`, which the fixed-point iteration ignores. Newton's
//! matrix is `I + H`, `H = -Σ_s p_s ∂r_s/∂y`:
//!
//! - a slave paired with segment `[x_a, x_b]` (length `L`, unit tangent `t`, normal `n`,
//!   projection `ξ`, gap `g = n · (x_s - x_a)`): the row is the gap's exact gradient (the
//!   projection makes `∂g/∂ξ = 0`), so `∂r/∂y = ∇²g`, and from `∂n/∂e = -t nᵀ / L`,
//!   `∂ξ/∂e = (-ξ L t + g n) / L²` (`e = x_b - x_a`):
//!
//!   ```text
//!   ∇²g = -(A Bᵀ + B Aᵀ) - g A Aᵀ,   A·δ = n · (δx_b - δx_a) / L   (the segment's rotation),
//!                                    B·δ = t · (δx_s - (1 - ξ) δx_a - ξ δx_b)   (the slip);
//!   ```
//!
//! - a slave tied to (or paired with) interior vertex `v` has the row `n̄ · (δx_s - δx_v)`
//!   with the averaged normal `n̄ = m / |m|`, `m = n_1 + n_2` over the segments `v - 1` and
//!   `v`, held fixed (the tie's model: its force acts along `n̄` on the slave and on `x_v`).
//!   Only `n̄` moves the row: `δn̄ = -t̄ (A·δ)`, `A·δ = Σ_i (t̄ · t_i) n_i · δe_i / (L_i |m|)`,
//!   so `∂r/∂y = -B Aᵀ` with `B·δ = t̄ · (δx_s - δx_v)` — one of the two cross terms;
//! - a slave tied to an end of the master (docs/design-notes.md#end-ties) gets no term.
//!
//! Each `A`, `B` is a combination of at most four contact nodes' rows of `Psi_c`, so
//!
//! ```text
//! H v = Σ_segments p_s [A_s (B_s·v) + B_s (A_s·v) + g_s A_s (A_s·v)] + Σ_ties p_s B_s (A_s·v)
//! ```
//!
//! costs, term by term, two row products and two row updates per node of each slave with
//! pressure, `O(r_u)` each; no `r_u x r_u` matrix is formed. Where `H` is applied several times
//! at one state (the exact step's Krylov iterations), [`CurvatureOp`] forms each term's `A` and
//! `B` as rows over the reduced coordinates once, and each product is then two row products and
//! two row updates per term.

use super::la::{axpy, combine_rows, dot};
use crate::contact::pairing::{dot as dot2, segment_normal, sub, GapRow, Pair, PairKind};
use crate::kernels::{add_row_pairs, dot_pair};

/// One slave's term of `H`: `p [A (B·v) + B (A·v) + gamma A (A·v)]` on a segment, `p B (A·v)`
/// at a tie (`symmetric` false), with `A` and `B` as coefficients on the two rows of up to four
/// contact nodes.
#[derive(Debug, Clone, Copy)]
pub(super) struct GapCurvature {
    nodes: [usize; 4],
    a: [[f64; 2]; 4],
    b: [[f64; 2]; 4],
    len: usize,
    gamma: f64,
    symmetric: bool,
}

/// Length of segment `k` of the polyline `m`.
fn length(m: &[[f64; 2]], k: usize) -> f64 {
    let e = sub(m[k + 1], m[k]);
    dot2(e, e).sqrt()
}

/// The unit tangent `t` of a segment with normal `n = (t_y, -t_x)` ([`segment_normal`]).
fn tangent(n: [f64; 2]) -> [f64; 2] {
    [-n[1], n[0]]
}

impl GapCurvature {
    /// The term of supported slave `s` (of `ns`; masters are contact nodes `ns..`) for its
    /// pairing `p` at the master positions `xm` it was computed at; `None` for an unpaired
    /// slave, an end tie, or a vertex at an end of the master.
    pub(super) fn new(s: usize, ns: usize, p: &Pair, xm: &[[f64; 2]]) -> Option<Self> {
        let mut c =
            GapCurvature { nodes: [s; 4], a: [[0.0; 2]; 4], b: [[0.0; 2]; 4], len: 0, gamma: 0.0, symmetric: true };
        match p.kind {
            PairKind::Segment(k) => {
                let (n, xi) = (p.normal, p.xi);
                let t = tangent(n);
                let l = length(xm, k);
                c.len = 3;
                c.nodes[1] = ns + k;
                c.nodes[2] = ns + k + 1;
                c.a[1] = [-n[0] / l, -n[1] / l];
                c.a[2] = [n[0] / l, n[1] / l];
                c.b[0] = t;
                c.b[1] = [-(1.0 - xi) * t[0], -(1.0 - xi) * t[1]];
                c.b[2] = [-xi * t[0], -xi * t[1]];
                c.gamma = p.gap;
            }
            PairKind::Tied(v) | PairKind::Vertex(v) if v >= 1 && v + 1 < xm.len() => {
                let tb = tangent(p.normal);
                let (n1, n2) = (segment_normal(xm, v - 1), segment_normal(xm, v));
                let sum = [n1[0] + n2[0], n1[1] + n2[1]];
                let m = dot2(sum, sum).sqrt();
                let c1 = dot2(tb, tangent(n1)) / (length(xm, v - 1) * m);
                let c2 = dot2(tb, tangent(n2)) / (length(xm, v) * m);
                c.len = 4;
                c.nodes[1] = ns + v - 1;
                c.nodes[2] = ns + v;
                c.nodes[3] = ns + v + 1;
                c.a[1] = [-c1 * n1[0], -c1 * n1[1]];
                c.a[2] = [c1 * n1[0] - c2 * n2[0], c1 * n1[1] - c2 * n2[1]];
                c.a[3] = [c2 * n2[0], c2 * n2[1]];
                c.b[0] = tb;
                c.b[2] = [-tb[0], -tb[1]];
                c.symmetric = false;
            }
            _ => return None,
        }
        Some(c)
    }

    /// `side` (this term's `a` or `b`) as a row over the contact dofs, skipping the nodes it
    /// does not touch (a segment's `A` the slave; a tie's `B` the vertex's neighbours): four or
    /// six entries.
    fn side(&self, side: &[[f64; 2]; 4]) -> GapRow {
        let mut row = GapRow { dof: [0; 6], coef: [0.0; 6], len: 0 };
        for (&c, k) in self.nodes.iter().zip(side).take(self.len) {
            if k[0] == 0.0 && k[1] == 0.0 {
                continue;
            }
            for (i, &coef) in k.iter().enumerate() {
                row.dof[row.len] = 2 * c + i;
                row.coef[row.len] = coef;
                row.len += 1;
            }
        }
        row
    }

    /// `out += ` this term times `v`, `psi_c` the contact-dof rows (row-major, `r` columns).
    pub(super) fn apply(&self, p: f64, psi_c: &[f64], r: usize, v: &[f64], out: &mut [f64]) {
        let row = |cd: usize| &psi_c[cd * r..(cd + 1) * r];
        let (mut alpha, mut beta) = (0.0, 0.0);
        for ((&c, a), b) in self.nodes.iter().zip(&self.a).zip(&self.b).take(self.len) {
            let d = [dot(row(2 * c), v), dot(row(2 * c + 1), v)];
            alpha += a[0] * d[0] + a[1] * d[1];
            beta += b[0] * d[0] + b[1] * d[1];
        }
        let fa = if self.symmetric { p * (beta + self.gamma * alpha) } else { 0.0 };
        let fb = p * alpha;
        for ((&c, a), b) in self.nodes.iter().zip(&self.a).zip(&self.b).take(self.len) {
            for i in 0..2 {
                let f = fa * a[i] + fb * b[i];
                if f != 0.0 {
                    axpy(f, row(2 * c + i), out);
                }
            }
        }
    }
}

/// `H` over the slaves with pressure at one corrected step, applied by term through each
/// term's two rows over the reduced coordinates, `a = Aᵀ Psi_c` and `b = Bᵀ Psi_c`:
///
/// ```text
/// H v = Σ_terms p [a (b·v) + b (a·v) + gamma a (a·v)]     (a tie: p b (a·v))
/// ```
///
/// The rows are formed once per corrected step, at its first product (each a combination of
/// four or six rows of `Psi_c`), and each product is then two dot products and two row
/// updates per term. By contact node it would be two of each per node of the terms: on
/// ironing-fine about 57 nodes against 23 terms, the node rows streamed from the L2 cache at
/// each of the exact step's three products (docs/design-notes.md#an-exact-corrected-step).
#[derive(Debug, Clone, Default)]
pub(crate) struct CurvatureOp {
    terms: Vec<(GapCurvature, f64)>,
    /// `a` and `b` of each term, `2 r` per term, for the first `formed` terms.
    rows: Vec<f64>,
    formed: usize,
    /// Each term's coefficients of `a` and `b` in the product being formed.
    coef: Vec<[f64; 2]>,
}

impl CurvatureOp {
    /// Start an operator with no term.
    pub(super) fn clear(&mut self) {
        self.terms.clear();
        self.formed = 0;
    }

    /// Add the term `c` with force `p`.
    pub(super) fn push(&mut self, c: GapCurvature, p: f64) {
        self.terms.push((c, p));
    }

    /// Whether no term was added.
    pub(super) fn is_empty(&self) -> bool {
        self.terms.is_empty()
    }

    /// `out += H v` term by term, in the order the terms were pushed (each term's
    /// [`GapCurvature::apply`]): the first-order corrected step's sum.
    pub(super) fn apply_by_term(&self, psi_c: &[f64], r: usize, v: &[f64], out: &mut [f64]) {
        for (c, p) in &self.terms {
            c.apply(*p, psi_c, r, v, out);
        }
    }

    /// Form the rows `a` and `b` of the terms added since the last product.
    fn form(&mut self, psi_c: &[f64], r: usize) {
        self.rows.resize(2 * r * self.terms.len(), 0.0);
        for (t, (c, _)) in self.terms.iter().enumerate().skip(self.formed) {
            let (a, b) = self.rows[2 * r * t..2 * r * (t + 1)].split_at_mut(r);
            combine_rows(&c.side(&c.a), psi_c, r, a);
            combine_rows(&c.side(&c.b), psi_c, r, b);
        }
        self.formed = self.terms.len();
    }

    /// `out = H v`.
    pub(super) fn apply(&mut self, psi_c: &[f64], r: usize, v: &[f64], out: &mut [f64]) {
        self.form(psi_c, r);
        self.coef.clear();
        for ((c, p), ab) in self.terms.iter().zip(self.rows.chunks_exact(2 * r)) {
            let (alpha, beta) = dot_pair(&ab[..r], &ab[r..], v);
            let fa = if c.symmetric { p * (beta + c.gamma * alpha) } else { 0.0 };
            self.coef.push([fa, p * alpha]);
        }
        out.iter_mut().for_each(|o| *o = 0.0);
        // four terms per pass over `out`, added term by term
        let row = |t: usize| {
            let ab = &self.rows[2 * r * t..2 * r * (t + 1)];
            [&ab[..r], &ab[r..]]
        };
        let mut t = 0;
        while t + 4 <= self.terms.len() {
            let f = [self.coef[t], self.coef[t + 1], self.coef[t + 2], self.coef[t + 3]];
            add_row_pairs(f, [row(t), row(t + 1), row(t + 2), row(t + 3)], out);
            t += 4;
        }
        for t in t..self.terms.len() {
            add_row_pairs([self.coef[t]], [row(t)], out);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::pairing::{closest_point, vertex_normal, vertex_pair, GapRow};

    impl GapCurvature {
        /// The bilinear form `δ'ᵀ (-∂r/∂y) δ` of this term (without `p`) for contact-dof
        /// displacements `delta` and `delta2` (tests).
        fn form(&self, delta: &[f64], delta2: &[f64]) -> f64 {
            let ab = |d: &[f64]| {
                let (mut alpha, mut beta) = (0.0, 0.0);
                for j in 0..self.len {
                    let c = self.nodes[j];
                    alpha += self.a[j][0] * d[2 * c] + self.a[j][1] * d[2 * c + 1];
                    beta += self.b[j][0] * d[2 * c] + self.b[j][1] * d[2 * c + 1];
                }
                (alpha, beta)
            };
            let ((a1, b1), (a2, b2)) = (ab(delta), ab(delta2));
            if self.symmetric {
                b2 * a1 + a2 * b1 + self.gamma * a2 * a1
            } else {
                b2 * a1
            }
        }
    }

    const MASTER: [[f64; 2]; 4] = [[0.0, 0.0], [1.0, 0.1], [2.0, 0.05], [3.1, -0.2]];

    /// The solver's own gap row of slave 0 (contact node 0; masters `1..`) at contact
    /// positions `x`, for a segment pairing (re-projected at `x`) or a tie at vertex 2, as a
    /// dense row over the contact dofs.
    fn row(tie: bool, x: &[f64]) -> Vec<f64> {
        let xs = [x[0], x[1]];
        let xm: Vec<[f64; 2]> = x[2..].chunks(2).map(|c| [c[0], c[1]]).collect();
        let p = if tie { vertex_pair(xs, &xm, 2, PairKind::Tied(2)) } else { closest_point(xs, &xm) };
        let mut out = vec![0.0; x.len()];
        for (cd, c) in GapRow::new(0, 1, &p).entries() {
            out[cd] += c;
        }
        out
    }

    /// `form` against a central difference of the solver's gap row: `-δ' · ∂r/∂y δ`, along
    /// random directions, for slaves on segments (off the surface, so the `g` term counts) and
    /// a slave tied at a vertex off its averaged normal. Tolerance 1e-6 relative: the
    /// difference's truncation error is `O(h²)` with `h = 1e-5` and its rounding `eps / h`
    /// ~ 1e-11. Fails with either cross term's sign flipped or `g` dropped.
    #[test]
    fn the_form_is_the_derivative_of_the_gap_row() {
        let xm = MASTER;
        let mut seed = 7u64;
        let mut rand = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let near_vertex = {
            let n = vertex_normal(&xm, 2);
            [xm[2][0] + 0.03 * n[0] + 0.004, xm[2][1] + 0.03 * n[1]]
        };
        for (xs, tie) in [([1.3, 0.4], false), ([1.7, 0.02], false), ([2.5, -0.3], false), (near_vertex, true)] {
            let p = if tie { vertex_pair(xs, &xm, 2, PairKind::Tied(2)) } else { closest_point(xs, &xm) };
            assert!(matches!(p.kind, PairKind::Segment(_) | PairKind::Tied(_)), "{:?}", p.kind);
            let c = GapCurvature::new(0, 1, &p, &xm).expect("a term");
            let x0: Vec<f64> = xs.iter().chain(xm.iter().flatten()).copied().collect();
            for _ in 0..5 {
                let d1: Vec<f64> = (0..x0.len()).map(|_| rand()).collect();
                let d2: Vec<f64> = (0..x0.len()).map(|_| rand()).collect();
                let h = 1e-5;
                let at = |t: f64| {
                    let r = row(tie, &x0.iter().zip(&d1).map(|(a, b)| a + t * b).collect::<Vec<_>>());
                    r.iter().zip(&d2).map(|(a, b)| a * b).sum::<f64>()
                };
                let fd = -(at(h) - at(-h)) / (2.0 * h);
                let exact = c.form(&d1, &d2);
                assert!((fd - exact).abs() <= 1e-6 * exact.abs().max(1.0), "{:?}: {fd} vs {exact}", p.kind);
            }
        }
    }

    /// The operator through its terms' rows applies the sum of its terms' `apply` (the rows
    /// of `Psi_c` of each term's nodes): two segment pairings and a tie on one master, sharing
    /// nodes, with forces 2, 0.5 and 1.5, so that both the groups of four terms and the rest
    /// are used (five terms: the three, then two added after a first product, which must form
    /// their rows too). Tolerance 1e-12 relative: the same products summed in another order.
    #[test]
    fn the_operator_is_the_sum_of_its_terms() {
        let xm = MASTER;
        let pairs = [
            (closest_point([1.3, 0.4], &xm), 2.0),
            (closest_point([1.7, 0.02], &xm), 0.5),
            (vertex_pair([2.01, 0.1], &xm, 2, PairKind::Tied(2)), 1.5),
            (closest_point([0.4, 0.3], &xm), 0.7),
            (vertex_pair([0.98, 0.2], &xm, 1, PairKind::Tied(1)), 1.1),
        ];
        let (ns, r) = (5, 5);
        let ncd = 2 * (ns + xm.len());
        let psi: Vec<f64> = (0..ncd * r).map(|k| ((k * 37 % 11) as f64 - 5.0) / 7.0).collect();
        let v: Vec<f64> = (0..r).map(|k| ((k * 3 % 5) as f64 - 2.0) / 2.0).collect();
        let check = |op: &mut CurvatureOp, want: &[f64]| {
            let mut got = vec![1.0; r];
            op.apply(&psi, r, &v, &mut got);
            let scale = want.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            assert!(scale > 0.0);
            for (a, b) in got.iter().zip(want) {
                assert!((a - b).abs() <= 1e-12 * scale, "{got:?} vs {want:?}");
            }
        };
        let mut op = CurvatureOp::default();
        op.clear();
        let mut want = vec![0.0; r];
        for (s, (p, force)) in pairs.iter().enumerate() {
            let c = GapCurvature::new(s, ns, p, &xm).expect("a term");
            c.apply(*force, &psi, r, &v, &mut want);
            op.push(c, *force);
            if s == 2 || s == 4 {
                check(&mut op, &want);
            }
        }
        // cleared, it starts again from no term: one term's rows are formed anew
        op.clear();
        assert!(op.is_empty());
        let c = GapCurvature::new(1, ns, &pairs[1].0, &xm).expect("a term");
        let mut want = vec![0.0; r];
        c.apply(pairs[1].1, &psi, r, &v, &mut want);
        op.push(c, pairs[1].1);
        check(&mut op, &want);
    }

    /// `apply` is the form's matrix with the force: `u · H v = p form(Psi_c v, Psi_c u)` on
    /// random rows, symmetric on a segment. Tolerance 1e-12 relative: sums of a few dozen
    /// products.
    #[test]
    fn apply_is_the_matrix_of_the_form() {
        let xm = MASTER;
        for p in [closest_point([1.3, 0.4], &xm), vertex_pair([2.01, 0.1], &xm, 2, PairKind::Tied(2))] {
            let c = GapCurvature::new(0, 1, &p, &xm).expect("a term");
            let (r, ncd) = (5, 2 * (1 + xm.len()));
            let psi: Vec<f64> = (0..ncd * r).map(|k| ((k * 37 % 11) as f64 - 5.0) / 7.0).collect();
            let u: Vec<f64> = (0..r).map(|k| (k as f64 - 1.5) / 3.0).collect();
            let v: Vec<f64> = (0..r).map(|k| ((k * 3 % 5) as f64 - 2.0) / 2.0).collect();
            let rows = |y: &[f64]| (0..ncd).map(|cd| dot(&psi[cd * r..(cd + 1) * r], y)).collect::<Vec<_>>();
            let (mut hu, mut hv) = (vec![0.0; r], vec![0.0; r]);
            c.apply(2.0, &psi, r, &u, &mut hu);
            c.apply(2.0, &psi, r, &v, &mut hv);
            let form = 2.0 * c.form(&rows(&v), &rows(&u));
            assert!((dot(&u, &hv) - form).abs() <= 1e-12 * form.abs().max(1.0), "{} vs {form}", dot(&u, &hv));
            if matches!(p.kind, PairKind::Segment(_)) {
                assert!((dot(&u, &hv) - dot(&v, &hu)).abs() <= 1e-12 * dot(&u, &hv).abs().max(1.0));
            }
        }
    }
}
