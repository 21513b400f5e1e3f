//! The linearisation of a Type-2 query: the state a query carries between linearisations
//! ([`LinState`]: positions, pairings, gap rows, and the budgets and certificates that prove a
//! pairing unchanged without a search), the re-pairing itself
//! ([`ReducedModel::linearize_with`]) and the assembly of the gap rows.

use super::switches::Switches;
use super::{ReducedModel, RomWork, SurfaceData};
use crate::contact::pairing::{vertex_pair, Certificate, Feature, GapRow, MasterIndex, Pair, PairKind};
use crate::contact::vertex::VertexTies;
use crate::rom::la::{axpy, combine_rows, dot};

/// `xc = base + Phi_c û` (`Phi_c` row-major `n_cd x r`) at the contact nodes `nodes`; at
/// `û = 0` (the first linearisation) the positions are the lifted reference itself.
pub(super) fn set_positions(
    phi_c: &[f64],
    r: usize,
    u_hat: &[f64],
    base: &[f64],
    xc: &mut [f64],
    nodes: impl Iterator<Item = usize>,
) {
    let zero = u_hat.iter().all(|&v| v == 0.0);
    for c in nodes {
        for cd in [2 * c, 2 * c + 1] {
            let d = if zero { 0.0 } else { dot(&phi_c[cd * r..(cd + 1) * r], u_hat) };
            xc[cd] = base[cd] + d;
        }
    }
}

/// Euclidean distance of two points.
pub(super) fn distance(a: [f64; 2], b: [f64; 2]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
}

/// The path length of `y` up to which a pairing proved with radius `r` at path length
/// `travel` holds, for a slave and masters moving at most `speed` per unit of path.
fn budget_until(travel: f64, r: f64, speed: f64) -> f64 {
    if speed > 0.0 {
        travel + r / speed
    } else {
        f64::INFINITY
    }
}

/// The largest dual basis whose reduced rows [`ReducedModel::assemble`] sums at each
/// linearisation instead of keeping one row per slave.
pub(super) const SUMMED_MAX_RL: usize = 3;

/// Linearisation state of a Type-2 query.
#[derive(Debug, Clone, Default)]
pub(super) struct LinState {
    /// Reference position plus lift on the contact dofs.
    pub(super) base: Vec<f64>,
    /// Current positions of the contact dofs (only the needed nodes are up to date).
    pub(super) xc: Vec<f64>,
    pub(super) xm: Vec<[f64; 2]>,
    pub(super) index: MasterIndex,
    pub(super) ties: VertexTies,
    pub(super) pairs: Vec<Pair>,
    /// 3-D: the pairs of the slaves, and the masters' positions ([`super::nts3`]).
    pub(super) pairs3: Vec<crate::contact3d::surface::Pair3>,
    pub(super) xm3: Vec<[f64; 3]>,
    /// 3-D: per slave what its last search proved, the distance the slave and the masters
    /// moved since (a bound), and its position at the last linearisation; the masters'
    /// positions at the last linearisation ([`ReducedModel::linearize3`]).
    pub(super) located3: Vec<Option<crate::contact3d::surface::Located>>,
    pub(super) moved3: Vec<f64>,
    pub(super) last3: Vec<[f64; 3]>,
    pub(super) xm3_prev: Vec<[f64; 3]>,
    /// Paired supported slaves, their `C Phi` rows (row-major) and constant parts.
    pub(super) ps: Vec<usize>,
    pub(super) ps_of: Vec<usize>,
    pub(super) cphi: Vec<f64>,
    pub(super) g0: Vec<f64>,
    /// The reduced rows `Ĉ` (row-major `r_l x r_u`) and offsets `ĝ0` where the model sums its
    /// rows ([`ReducedModel::sums_rows`]), and the
    /// weights `θ_as w_s` of the slaves' rows in them (`r_l x ps.len()`).
    pub(super) chat: Vec<f64>,
    pub(super) ghat0: Vec<f64>,
    pub(super) slave_weight: Vec<f64>,
    /// The Newton correction's buffers: forces per slave (zero between uses), the step and
    /// `H` times it.
    pub(super) force: Vec<f64>,
    pub(super) step: Vec<f64>,
    pub(super) hv: Vec<f64>,
    /// Contact forces on the contact dofs (indicator).
    pub(super) fc: Vec<f64>,
    /// Type-1: `ĝ0(mu)` of the query.
    pub(super) g_mu: Vec<f64>,
    /// No linearisation yet in this query: every supported slave is searched.
    pub(super) fresh: bool,
    /// `xc` holds every contact dof's position at `û` (the warm start's, placed from the
    /// samples' displacements by [`ReducedModel::seed_warm`]); cleared by the next linearisation.
    pub(super) placed_at_start: bool,
    /// Path length of `y` over the linearisations of this query, and `y` at the last one.
    pub(super) travel: f64,
    pub(super) last_u: Vec<f64>,
    /// Path length up to which each slave's pairing kind is known (see
    /// [`ReducedModel::linearize_with`]).
    pub(super) budget: Vec<f64>,
    /// Linearisations computed.
    pub(super) count: usize,
    /// Whether `xm` and `index` hold every master at the last linearisation (else only the
    /// masters next to the pairings, see [`ReducedModel::linearize_with`]).
    pub(super) masters_all: bool,
    /// Per master the `stamp` of the linearisation that placed it last.
    pub(super) placed: Vec<usize>,
    pub(super) stamp: usize,
    /// Each slave's certificate from its last search, its position then and `master_path`
    /// then (see [`ReducedModel::linearize_with`]).
    pub(super) cert: Vec<Certificate>,
    pub(super) cert_x: Vec<[f64; 2]>,
    pub(super) cert_path: Vec<f64>,
    /// Bound of the path length of the largest master displacement over this query's
    /// linearisations, and the masters at the last linearisation that placed them all.
    pub(super) master_path: f64,
    pub(super) xm_prev: Vec<[f64; 2]>,
    pub(super) prev_full: bool,
    /// Test-only switches (see [`Switches`]; an empty type outside tests).
    pub(super) switches: Switches,
}

impl LinState {
    /// Whether re-pairing steps are Newton-corrected (always, but in tests that compare
    /// against plain steps).
    pub(super) fn newton(&self) -> bool {
        self.switches.newton()
    }

    /// Whether pairings may be proved unchanged instead of searched (always, but in tests that
    /// compare against searching every slave).
    fn proofs(&self) -> bool {
        self.switches.proofs()
    }

    /// Whether slave `s`'s budget still proves its natural pairing kind at the path length
    /// `path` of `y` (proof 1 of [`ReducedModel::linearize_with`]).
    fn budget_holds(&self, s: usize, path: Option<f64>) -> bool {
        self.proofs() && path.is_some_and(|t| t <= self.budget[s])
    }

    /// Slave `s`'s natural pairing at `xs` when its budget proves it: unpaired, or projected
    /// on its segment again (the search's arithmetic; `None` if the projection is invalid).
    pub(super) fn budget_pair(&self, s: usize, xs: [f64; 2], path: Option<f64>) -> Option<Pair> {
        if !self.budget_holds(s, path) {
            return None;
        }
        match self.cert[s].feature {
            Feature::End(_) => Some(Pair::NONE),
            Feature::Segment(k) => MasterIndex::segment_pair(xs, &self.xm, k),
            _ => None,
        }
    }

    /// Slave `s`'s pairing at `xs` by the vertex-tie rule without recording it: from its
    /// natural pairing where its budget still proves it (`supported` slaves only), else from a
    /// search.
    pub(super) fn peek_pair(&self, s: usize, xs: [f64; 2], path: Option<f64>, supported: bool) -> Pair {
        let nat = if supported { self.budget_pair(s, xs, path) } else { None };
        match nat {
            Some(nat) => self.ties.peek_known(s, nat, xs, &self.xm),
            None => self.ties.pair_peek(s, xs, &self.xm, &self.index),
        }
    }

    /// The path length of `y` up to `u` (the linearisations' path plus the step from the last
    /// one to `u`); `None` before the first linearisation of the query.
    pub(super) fn travel_to(&self, u: &[f64]) -> Option<f64> {
        (!self.fresh)
            .then(|| self.travel + u.iter().zip(&self.last_u).map(|(a, b)| (a - b) * (a - b)).sum::<f64>().sqrt())
    }

    /// A new round of the vertex-zone rule: `forced` slaves tied, pairing history cleared.
    /// The budgets stay: they bound the natural pairing kinds, which do not depend on ties.
    pub(super) fn restart(&mut self, forced: &[Option<usize>]) {
        self.ties.force(forced);
        self.count = 0;
    }

    /// The positions at `y` of the contact `nodes` into `xc`, unless `xc` already holds every
    /// position at `y` (the warm start's, placed by [`ReducedModel::seed_warm`]).
    fn place(&mut self, phi_c: &[f64], r: usize, y: &[f64], nodes: impl Iterator<Item = usize>) {
        if !self.placed_at_start {
            set_positions(phi_c, r, y, &self.base, &mut self.xc, nodes);
        }
    }

    /// Every master's position at `y` (contact nodes `ns..ns + nm`, into `xc` and `xm`) and
    /// the search index over them.
    pub(super) fn all_masters(&mut self, phi_c: &[f64], r: usize, y: &[f64], ns: usize, nm: usize) {
        self.place(phi_c, r, y, ns..ns + nm);
        self.index_masters(ns, nm);
        self.masters_all = true;
    }

    /// The positions at `y` of the masters in `range` not yet placed at this linearisation
    /// (`stamp`), into `xc` and `xm`; the index is left as it was.
    pub(super) fn window(&mut self, phi_c: &[f64], r: usize, y: &[f64], ns: usize, range: std::ops::Range<usize>) {
        for k in range {
            if self.placed[k] != self.stamp {
                self.placed[k] = self.stamp;
                self.place(phi_c, r, y, std::iter::once(ns + k));
                self.xm[k] = [self.xc[2 * (ns + k)], self.xc[2 * (ns + k) + 1]];
            }
        }
    }

    /// Copy the masters' positions (contact nodes `ns..ns + nm`) into `xm` and rebuild the
    /// search index over them.
    pub(super) fn index_masters(&mut self, ns: usize, nm: usize) {
        for k in 0..nm {
            self.xm[k] = [self.xc[2 * (ns + k)], self.xc[2 * (ns + k) + 1]];
        }
        self.index.build(&self.xm);
    }

    /// The masters slave `s` needs placed when its pairing is known without a search: those
    /// next to its forced vertex or its pairing, and next to its certificate's feature. A
    /// tie's averaged normal reads v - 1..=v + 1, an end tie v and its segment, a segment k its
    /// ends (and a tie on them up to k + 2).
    fn window_anchors(&self, s: usize) -> [Option<usize>; 2] {
        let lo = match (self.ties.forced(s), self.pairs[s].kind) {
            (Some(v), _) | (None, PairKind::Tied(v) | PairKind::End(v) | PairKind::Vertex(v)) => Some(v),
            (None, PairKind::Segment(k)) => Some(k),
            (None, PairKind::None) => None,
        };
        let cert = match self.cert[s].feature {
            Feature::Segment(k) | Feature::End(k) => Some(k),
            _ => None,
        };
        [lo, cert]
    }

    /// Proof 2 of [`ReducedModel::linearize_with`]: slave `s`'s natural pairing at `xs`
    /// re-derived from its certificate while it and the masters moved less than its radius,
    /// with a new budget from path length `travel` (`node_norm`, `master_norm`: the speeds of
    /// the slaves and of the masters); `None` if the certificate does not decide.
    fn certified_pair(
        &mut self,
        s: usize,
        xs: [f64; 2],
        travel: f64,
        node_norm: &[f64],
        master_norm: f64,
    ) -> Option<Pair> {
        let (x0, at) = (self.cert_x[s], self.cert_path[s]);
        self.switches.check_master_path(s, &self.xm, self.master_path, at);
        let moved = distance(xs, x0) + (self.master_path - at);
        if let Some((p, r)) = MasterIndex::recheck(xs, &self.xm, &self.cert[s], moved) {
            // a new budget from here (proof 1 again)
            self.budget[s] = budget_until(travel, r, node_norm[s] + master_norm);
            return Some(p);
        }
        None
    }

    /// Search slave `s` at `xs` (every master placed; `ns` slaves) with the vertex-tie rule,
    /// and record its new proofs: the budget from path length `travel` (`node_norm`,
    /// `master_norm`: the speeds of the slaves and of the masters), the certificate, the
    /// slave's position and the masters' path length.
    fn search(&mut self, s: usize, xs: [f64; 2], ns: usize, travel: f64, node_norm: &[f64], master_norm: f64) -> Pair {
        let (p, r, cert) = self.ties.pair_proved(s, xs, &self.xm, &self.index, self.count);
        self.budget[s] = budget_until(travel, r, node_norm[s] + master_norm);
        self.cert[s] = cert;
        self.cert_x[s] = xs;
        self.cert_path[s] = self.master_path;
        self.switches.record_search(s, ns, &self.xm);
        p
    }

    /// The end of a linearisation: the next one measures the masters' displacement from here
    /// if all are placed.
    fn close(&mut self) {
        self.prev_full = self.masters_all;
        if self.masters_all {
            self.xm_prev.clear();
            self.xm_prev.extend_from_slice(&self.xm);
        }
        self.count += 1;
        self.fresh = false;
        self.placed_at_start = false;
    }

    /// FNV-1a hash of the discrete pairing of every slave.
    pub(super) fn pairing_hash(&self) -> u64 {
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        for p in &self.pairs {
            let (tag, v) = match p.kind {
                PairKind::None => (0u64, 0u64),
                PairKind::Segment(k) => (1, k as u64),
                PairKind::Vertex(v) => (2, v as u64),
                PairKind::Tied(v) => (3, v as u64),
                PairKind::End(v) => (4, v as u64),
            };
            for x in [tag, v] {
                h ^= x;
                h = h.wrapping_mul(0x0000_0100_0000_01b3);
            }
        }
        for p in &self.pairs3 {
            h ^= p.feature.id();
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
        h
    }
}

impl ReducedModel {
    /// Type-2: positions of the needed contact nodes at `y = w.u_hat`, re-pair the supported
    /// slaves (recording the pairing history for vertex ties) and rebuild their gap rows.
    /// Returns whether a pairing kind changed. Type-1: nothing to do.
    pub(super) fn linearize(&self, w: &mut RomWork) -> bool {
        self.linearize_with(w, true)
    }

    /// [`Self::linearize`], rebuilding the gap rows only if `assemble`.
    ///
    /// A slave searched ([`MasterIndex::closest_point_proved`]) gets two proofs that its
    /// natural pairing holds while the slave and the masters move little:
    ///
    /// 1. a radius `R_s` within which the pairing kind cannot change at all. The slave and the
    ///    masters move by at most `(|Psi_s| + max_m |Psi_m|) |Δy|` per change `Δy` of the
    ///    coordinates, so with `T` the path length of `y` over the linearisations of this
    ///    query, the kind is known while `T <= T_s + R_s / (|Psi_s| + max_m |Psi_m|)` (its
    ///    budget), `T_s` the path length when it was searched. Then an unpaired slave keeps its
    ///    pairing without even being placed, and a slave paired with segment `k` is projected
    ///    on `k` again (the search's own arithmetic).
    /// 2. a [`Certificate`], for when the budget is spent: the natural pairing is re-derived
    ///    from the neighbourhood of the certified feature alone ([`MasterIndex::recheck`])
    ///    while the slave's actual displacement since its search plus the masters' largest
    ///    displacement (summed over the linearisations since, each measured when every master
    ///    was placed at it and the previous one, else bounded by `max_m |Psi_m| |Δy|`) is
    ///    below the certificate's radius. Unlike 1 it reads positions, so it needs them; it
    ///    spares the searches of the slaves far from the master (unpaired, barely moving)
    ///    and of those that slide along a segment.
    ///
    /// Slaves forced to a vertex by the zone rule are never searched; every other slave is
    /// searched and gets new proofs. Without `assemble` (the check after convergence), a
    /// pairing known unchanged by 1 returns at once: positions, pairs and rows stay those of
    /// the last linearisation, `|Δy| <= u_tol |y|` away.
    pub(super) fn linearize_with(&self, w: &mut RomWork, assemble: bool) -> bool {
        if let SurfaceData::Nts3(d) = &self.surf {
            return self.linearize3(d, w, assemble);
        }
        let SurfaceData::Nts { ns, nm, supp, node_norm, master_norm, phi_c, .. } = &self.surf else {
            w.lin.count = 1;
            return false;
        };
        let (ns, nm) = (*ns, *nm);
        let l = &mut w.lin;
        let path = l.travel_to(&w.u_hat);
        let travel = path.unwrap_or(0.0);
        let known = |l: &LinState, s: usize| l.budget_holds(s, path);
        if !assemble && supp.iter().all(|&s| known(l, s) || l.ties.forced(s).is_some()) {
            return false;
        }
        let step = travel - l.travel;
        l.travel = travel;
        l.last_u.clear();
        l.last_u.extend_from_slice(&w.u_hat);
        let (pairs, first) = (&l.pairs, l.fresh);
        let budget = &l.budget;
        let slaves = supp.iter().copied().filter(|&s| first || travel > budget[s] || pairs[s].kind.is_paired());
        // as [`LinState::place`] (the slaves' filter borrows the state it would take)
        if !l.placed_at_start {
            set_positions(phi_c, self.r_u, &w.u_hat, &l.base, &mut l.xc, slaves);
        }
        // Every slave known by its budget on a segment or unpaired, or forced to a vertex,
        // needs the masters next to its pairing only; any other needs every master (for its
        // certificate or its search).
        let everything = supp.iter().any(|&s| {
            l.ties.forced(s).is_none()
                && !(known(l, s) && matches!(l.cert[s].feature, Feature::Segment(_) | Feature::End(_)))
        });
        let measured = l.prev_full && !first;
        l.masters_all = false;
        if everything {
            l.all_masters(phi_c, self.r_u, &w.u_hat, ns, nm);
            // the masters' largest displacement since the last linearisation, measured when
            // that one placed them all too
            let moved = if measured {
                l.xm.iter().zip(&l.xm_prev).map(|(&a, &b)| distance(a, b)).fold(0.0f64, f64::max)
            } else {
                master_norm * step
            };
            l.master_path += moved;
        } else {
            l.master_path += master_norm * step;
            l.stamp += 1;
            for &s in supp {
                for v in l.window_anchors(s).into_iter().flatten() {
                    l.window(phi_c, self.r_u, &w.u_hat, ns, v.saturating_sub(1)..(v + 3).min(nm));
                }
            }
        }
        let mut changed = false;
        for &s in supp {
            let xs = [l.xc[2 * s], l.xc[2 * s + 1]];
            if let Some(v) = l.ties.forced(s) {
                let p = vertex_pair(xs, &l.xm, v, PairKind::Tied(v));
                changed |= p.kind != l.pairs[s].kind;
                l.pairs[s] = p;
                continue;
            }
            // the natural pairing from proof 1, else proof 2
            let mut nat = l.budget_pair(s, xs, path);
            if nat.is_none() && l.masters_all && !first && l.proofs() {
                nat = l.certified_pair(s, xs, travel, node_norm, *master_norm);
            }
            // Tests only (`verifies` is a constant false otherwise): a proved pairing against a
            // search at the same positions, with every master in place.
            if let (Some(q), true) = (nat, l.switches.verifies()) {
                if !l.masters_all {
                    l.all_masters(phi_c, self.r_u, &w.u_hat, ns, nm);
                }
                assert_eq!(q, l.index.closest_point(xs, &l.xm), "slave {s}: proved pairing is not the search's");
            }
            let p = match nat {
                Some(nat) => l.ties.pair_known(s, nat, xs, &l.xm, l.count),
                None => {
                    if !l.masters_all {
                        l.all_masters(phi_c, self.r_u, &w.u_hat, ns, nm);
                    }
                    l.search(s, xs, ns, travel, node_norm, *master_norm)
                }
            };
            changed |= p.kind != l.pairs[s].kind;
            l.pairs[s] = p;
        }
        l.close();
        if assemble {
            self.assemble(w);
        }
        changed
    }

    /// Whether [`Self::assemble`] also sums the rows under the dual basis: for a basis of at
    /// most [`SUMMED_MAX_RL`] columns.
    pub(super) fn sums_rows(&self) -> bool {
        self.r_l <= SUMMED_MAX_RL
    }

    /// Gap rows of the paired supported slaves: their `C Phi` rows (`cphi`) and constant
    /// parts, and for a dual basis of at most [`SUMMED_MAX_RL`] columns the reduced rows
    /// themselves (`chat`, and `ĝ0` in `ghat0`).
    ///
    /// Summed: reduced row `a` is `Σ_k t_ak cphi_k` with `t_ak = θ_a,s w_s` over the paired
    /// supported slaves `s = ps[k]` (gap weight `w_s`), four rows per pass over the output. The
    /// QP then evaluates `r_l` dot products per call instead of one per slave, and a row is a
    /// copy instead of a sum over the slaves of its column.
    pub(super) fn assemble(&self, w: &mut RomWork) {
        let SurfaceData::Nts { ns, supp, phi_c, .. } = &self.surf else { return };
        let ru = self.r_u;
        let l = &mut w.lin;
        l.ps.clear();
        l.g0.clear();
        for &s in supp {
            l.ps_of[s] = usize::MAX;
            if !l.pairs[s].kind.is_paired() {
                continue;
            }
            let row = GapRow::new(s, *ns, &l.pairs[s]);
            // row k of `cphi` (the buffer only grows: every row below `ps.len()` is written
            // here before it is read)
            let at = l.ps.len() * ru;
            l.ps_of[s] = l.ps.len();
            l.ps.push(s);
            if l.cphi.len() < at + ru {
                l.cphi.resize(at + ru, 0.0);
            }
            combine_rows(&row, phi_c, ru, &mut l.cphi[at..at + ru]);
            l.g0.push(row.apply(&l.base));
        }
        self.sum_rows(w);
    }

    /// For a dual basis of at most [`SUMMED_MAX_RL`] columns, the reduced rows `chat` and
    /// offsets `ghat0` summed from the paired slaves' rows (`cphi`, `g0`) under the basis.
    pub(super) fn sum_rows(&self, w: &mut RomWork) {
        if !self.sums_rows() {
            return;
        }
        let (ru, rl) = (self.r_u, self.r_l);
        let l = &mut w.lin;
        let np = l.ps.len();
        l.slave_weight.clear();
        l.slave_weight.resize(rl * np, 0.0);
        l.ghat0.clear();
        l.ghat0.resize(rl, 0.0);
        for (k, &s) in l.ps.iter().enumerate() {
            let gw = self.gap_weight(s);
            for e in self.by_node.0[s]..self.by_node.0[s + 1] {
                let (a, t) = (self.by_node.1[e], self.by_node.2[e] * gw);
                l.slave_weight[a * np + k] = t;
                l.ghat0[a] += t * l.g0[k];
            }
        }
        l.chat.clear();
        l.chat.resize(rl * ru, 0.0);
        for (a, out) in l.chat.chunks_exact_mut(ru).enumerate() {
            let t = &l.slave_weight[a * np..(a + 1) * np];
            let mut k = 0;
            while k + 4 <= np {
                let r = |i: usize| &l.cphi[(k + i) * ru..(k + i + 1) * ru];
                let (r0, r1, r2, r3) = (r(0), r(1), r(2), r(3));
                let (c0, c1, c2, c3) = (t[k], t[k + 1], t[k + 2], t[k + 3]);
                for (j, o) in out.iter_mut().enumerate() {
                    *o += c0 * r0[j] + c1 * r1[j] + c2 * r2[j] + c3 * r3[j];
                }
                k += 4;
            }
            for (kk, &c) in t.iter().enumerate().skip(k) {
                axpy(c, &l.cphi[kk * ru..(kk + 1) * ru], out);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::SUMMED_MAX_RL;
    use crate::assert_all_close;
    use crate::float_cmp::Tol;
    use crate::rom::reduced::test_support::{coarse_mus, coarse_tests, full_rom, points};
    use crate::rom::{RomParams, RomWork};
    use crate::testing::ironing_coarse;

    /// The reduced rows a small dual basis sums at each linearisation are its slaves' rows
    /// summed under it: on ironing-coarse (full primal rank, the leading 1, 2 and 3 CPG
    /// generators), re-linearised at each test point's answer, `chat` and `ghat0` against
    /// `Σ_s θ_as w_s cphi_s` and `Σ_s θ_as w_s g0_s` summed here from the per-slave rows. The
    /// two add the same terms in other orders, so they agree to rounding: 1e-13 of the largest
    /// term's magnitude times the number of terms. A basis of `SUMMED_MAX_RL + 1` columns is
    /// not summed.
    #[test]
    fn summed_rows_are_the_slave_rows_summed() {
        let fm = ironing_coarse();
        let mus = coarse_mus();
        let (rom, _, _) = full_rom(fm, &mus);
        let p = RomParams::default();
        let mut checked = 0;
        for rl in 1..=SUMMED_MAX_RL + 1 {
            let model = rom.leading(17, rl);
            let ru = model.r_u;
            for d in coarse_tests() {
                let mut w = RomWork::default();
                model.solve(&[d], &p, &mut w);
                model.linearize(&mut w);
                let l = &w.lin;
                // a fresh work's `chat` is formed only where the rows are summed
                assert_eq!(l.chat.len(), if rl <= SUMMED_MAX_RL { rl * ru } else { 0 }, "r_l {rl}");
                if rl > SUMMED_MAX_RL || l.ps.is_empty() {
                    continue;
                }
                let (mut chat, mut ghat0) = (vec![0.0; rl * ru], vec![0.0; rl]);
                let mut largest = 0.0f64;
                for (k, &s) in l.ps.iter().enumerate() {
                    for e in model.by_node.0[s]..model.by_node.0[s + 1] {
                        let (a, t) = (model.by_node.1[e], model.by_node.2[e] * model.gap_weight(s));
                        for (o, c) in chat[a * ru..(a + 1) * ru].iter_mut().zip(&l.cphi[k * ru..(k + 1) * ru]) {
                            *o += t * c;
                            largest = largest.max((t * c).abs());
                        }
                        ghat0[a] += t * l.g0[k];
                        largest = largest.max((t * l.g0[k]).abs());
                    }
                }
                let tol = Tol::abs(1e-13 * largest * l.ps.len() as f64);
                assert_all_close!(&l.chat, &chat, tol);
                assert_all_close!(&l.ghat0, &ghat0, tol);
                assert!(chat.iter().any(|&v| v != 0.0), "r_l {rl} d_x {d}: rows under the basis");
                checked += 1;
            }
        }
        assert!(checked >= 3 * coarse_tests().len() / 2, "summed rows checked at {checked} states");
    }

    /// The proofs that spare searches in a linearisation (budgets and certificates,
    /// `ReducedModel::linearize_with`) change nothing: on ironing-coarse, 17 training points,
    /// at full and truncated ranks, cold and warm-started, every one of 48 test points gets
    /// the same outcome and the same answer, to the last bit, as with every slave searched at
    /// every linearisation (each proof returns what the search would, bit for bit — checked
    /// at every proof — and records the same pairing history).
    #[test]
    fn search_proofs_change_nothing() {
        let fm = ironing_coarse();
        let mus = coarse_mus();
        let (rom, _, _) = full_rom(fm, &mus);
        let p = RomParams::default();
        let samples = points(&mus);
        for (ru, rl) in [(17, 17), (17, 4), (6, 8), (3, 2)] {
            let cold = rom.leading(ru, rl);
            let warm = cold.clone().with_warm_starts(&samples, &p);
            for model in [&cold, &warm] {
                let (mut proved, mut searched) = (RomWork::verifying_proofs(), RomWork::searching_always());
                for d in coarse_tests() {
                    let a = model.solve(&[d], &p, &mut proved);
                    let b = model.solve(&[d], &p, &mut searched);
                    assert_eq!(a.outcome, b.outcome, "({ru}, {rl}) d_x {d}");
                    assert_eq!((&a.u_hat, &a.lambda_hat), (&b.u_hat, &b.lambda_hat), "({ru}, {rl}) d_x {d}");
                }
            }
        }
    }
}
