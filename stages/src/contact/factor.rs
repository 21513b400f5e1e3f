//! `ContactModel::factor`: everything parameter-independent that the solves share.
//!
//! - sparse Cholesky `K_FF = L L^T` (faer, fill-reducing ordering), done once per scene;
//! - the unconstrained responses `u^(k) = K_FF^{-1} (-K_FD u_Dk)`, `k = 0..=p`, so that
//!   without contact `u_F(mu) = u^(0) + sum_k mu_k u^(k)` (the imposed displacement is affine
//!   in the p parameter components);
//! - the Delassus operator `W` on the contact dofs ([`super::delassus`]).

use super::delassus::compliance;
use super::error::ModelError;
use super::model::ContactModel;
use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::Llt;
use faer::{MatMut, Side};

/// A factored contact model: solve it at any parameter with [`FactoredModel::solve`]. It is
/// `Sync` and immutable, so many threads may solve different parameters concurrently.
#[derive(Debug, Clone)]
pub struct FactoredModel {
    pub(crate) model: ContactModel,
    pub(crate) llt: Llt<usize, f64>,
    /// Unconstrained free-dof responses to `u_D0`, `u_D1`, … (one per affine term).
    pub(crate) resp: Vec<Vec<f64>>,
    /// Lifted loads `-K_FD u_Dk` (free dofs), for the residual scale.
    pub(crate) lift: Vec<Vec<f64>>,
    /// Contact nodes: slaves, then masters (global ids).
    pub(crate) cnodes: Vec<usize>,
    /// Reference coordinates of the contact nodes.
    pub(crate) x_ref: Vec<[f64; 2]>,
    /// Free index of every contact dof (`2 local + component`), `None` if Dirichlet.
    pub(crate) cfree: Vec<Option<usize>>,
    /// Contact-dof displacement without contact: `a_c(mu) = a[0] + sum_k mu_k a[k + 1]`
    /// (Dirichlet values included).
    pub(crate) a: Vec<Vec<f64>>,
    /// Delassus operator, row-major `n_cd x n_cd`.
    pub(crate) w: Vec<f64>,
    /// Slaves whose two dofs are both Dirichlet (never paired).
    pub(crate) slave_fixed: Vec<bool>,
    /// The H1 Gram matrix, assembled on first use (error evaluation).
    pub(crate) h1: std::sync::OnceLock<crate::fem::CsrMatrix>,
    /// The estimate of `K_FF`'s extreme eigenvalues ([`stiffness_condition`]): computed beside
    /// the Delassus operator by [`ContactModel::factor_with_condition`], else on first read.
    pub(crate) condition: std::sync::OnceLock<Option<crate::condition::Condition>>,
}

/// `K_FF`'s extreme eigenvalues ([`crate::condition::estimate`]) by products of `K` on free-dof
/// vectors (zero on the Dirichlet dofs) and solves with the solver's own sparse Cholesky
/// factor.
pub(super) fn stiffness_condition(model: &ContactModel, llt: &Llt<usize, f64>) -> Option<crate::condition::Condition> {
    let free = model.split.free();
    let n = model.n_dof();
    let mul = |x: &[f64], y: &mut [f64]| {
        let mut full = vec![0.0; n];
        for (&d, v) in free.iter().zip(x) {
            full[d] = *v;
        }
        let mut out = vec![0.0; n];
        model.k.matvec_into(&full, &mut out);
        for (&d, v) in free.iter().zip(y.iter_mut()) {
            *v = out[d];
        }
    };
    let solve = |x: &mut [f64]| {
        let b = MatMut::from_column_major_slice_mut(x, free.len(), 1);
        llt.solve_in_place(b);
    };
    crate::condition::estimate(free.len(), crate::condition::ITERATIONS, &mul, &solve)
}

impl ContactModel {
    /// Factor `K_FF` (sparse Cholesky), compute the unconstrained responses and the Delassus
    /// operator. Done once per scene; the result is shared by every solve. The stiffness's
    /// condition estimate is left for its first read ([`FactoredModel`]'s
    /// `stiffness_condition`): only the mesh artifact states it.
    pub fn factor(&self) -> Result<FactoredModel, ModelError> {
        self.factor_with(false)
    }

    /// [`Self::factor`] with the stiffness's condition estimate computed beside the Delassus
    /// operator: its inverse iteration is a chain of solves that kept one core of two busy after
    /// the operator (90 ms on ironing-fine). Each is computed as alone, so both are the same
    /// whatever runs beside them, and the same as a later first read.
    pub fn factor_with_condition(&self) -> Result<FactoredModel, ModelError> {
        self.factor_with(true)
    }

    fn factor_with(&self, with_condition: bool) -> Result<FactoredModel, ModelError> {
        let split = &self.split;
        let nf = split.n_free();
        let kff = split.free_block(&self.k).map_err(ModelError::Sparse)?;
        let llt = kff.sp_cholesky(Side::Lower).map_err(|e| ModelError::Singular(format!("{e:?}")))?;
        let (lift, resp) = split.responses(&self.k, &self.u_d, |rhs| llt.solve_in_place(rhs));
        let resp = resp.ok_or_else(|| ModelError::Singular("non-finite unconstrained response".into()))?;
        let terms = lift.len();
        let cnodes: Vec<usize> = self.slaves.iter().chain(&self.masters).copied().collect();
        let x_ref: Vec<[f64; 2]> = cnodes.iter().map(|&n| self.mesh.nodes[n]).collect();
        let cfree: Vec<Option<usize>> =
            cnodes.iter().flat_map(|&n| [split.free_index(2 * n), split.free_index(2 * n + 1)]).collect();
        let a: Vec<Vec<f64>> = (0..terms)
            .map(|k| {
                let (ud, r) = (&self.u_d[k], &resp[k]);
                cnodes
                    .iter()
                    .flat_map(|&n| [2 * n, 2 * n + 1])
                    .map(|d| split.free_index(d).map_or(ud[d], |fi| r[fi]))
                    .collect::<Vec<f64>>()
            })
            .collect();
        let threads = std::thread::available_parallelism().map_or(1, |n| n.get()).min(4);
        let condition = std::sync::OnceLock::new();
        let w = if with_condition {
            let (w, c) = rayon::join(|| compliance(&llt, nf, &cfree, threads), || stiffness_condition(self, &llt));
            let _ = condition.set(c);
            w
        } else {
            compliance(&llt, nf, &cfree, threads)
        };
        let slave_fixed =
            (0..self.slaves.len()).map(|s| cfree[2 * s].is_none() && cfree[2 * s + 1].is_none()).collect();
        Ok(FactoredModel {
            model: self.clone(),
            llt,
            resp,
            lift,
            cnodes,
            x_ref,
            cfree,
            a,
            w,
            slave_fixed,
            h1: std::sync::OnceLock::new(),
            condition,
        })
    }
}

impl FactoredModel {
    /// The model this factor belongs to.
    pub fn model(&self) -> &ContactModel {
        &self.model
    }

    /// Solve `K_FF x = b` in place with the stored factor (one forward/backward substitution).
    pub fn solve_free_in_place(&self, b: &mut [f64]) {
        let nf = self.model.split.n_free();
        assert_eq!(b.len(), nf, "right-hand side length");
        self.llt.solve_in_place(MatMut::from_column_major_slice_mut(b, nf, 1));
    }

    /// The displacement `v` (all dofs, zero on the Dirichlet ones) under the nodal forces `f`
    /// (all dofs; the entries on Dirichlet dofs are reactions and are ignored) with the
    /// Dirichlet dofs held at zero: `K_FF v_F = f_F`. A contact response `u - u0(mu)` is this
    /// map applied to the contact forces.
    pub fn response(&self, f: &[f64]) -> Vec<f64> {
        let split = &self.model.split;
        assert_eq!(f.len(), split.n_dof(), "force length");
        let mut b: Vec<f64> = split.free().iter().map(|&d| f[d]).collect();
        self.solve_free_in_place(&mut b);
        let mut v = vec![0.0; split.n_dof()];
        for (&d, x) in split.free().iter().zip(b) {
            v[d] = x;
        }
        v
    }

    /// Potential-contact nodes: the slaves, then the master polyline (global ids).
    pub fn contact_nodes(&self) -> &[usize] {
        &self.cnodes
    }

    /// Number of potential-contact dofs (size of the Delassus operator).
    pub fn n_contact_dof(&self) -> usize {
        self.cfree.len()
    }
}

#[cfg(test)]
mod tests {
    use crate::float_cmp::Tol;
    use crate::rom::ContactOperator;
    use crate::testing::ironing_coarse;
    use crate::{assert_all_close, assert_close};

    /// `response` solves `K_FF v_F = f_F` with zero Dirichlet values: checked against the
    /// assembled stiffness itself (not the factor), on ironing-coarse under random forces on
    /// every dof. The residual of a backward-stable Cholesky solve is a few rounding errors of
    /// `K v`'s terms, so `|K v - f|` is held to 1e-12 of `max_i sum_j |K_ij v_j|`; the
    /// Dirichlet entries of `v` are exactly zero, and the forces given there change nothing.
    #[test]
    fn response_solves_the_free_block_with_zero_dirichlet_values() {
        let fm = ironing_coarse();
        let n = fm.n_dof();
        let mut rng = crate::rng::Rng::new(7);
        let f: Vec<f64> = (0..n).map(|_| rng.uniform_in(-1.0, 1.0)).collect();
        let v = fm.response(&f);
        let split = &fm.model.split;
        assert!(!split.fixed().is_empty(), "the check needs Dirichlet dofs");
        for &d in split.fixed() {
            assert_close!(v[d], 0.0, Tol::abs(0.0));
        }
        let mut kv = vec![0.0; n];
        fm.stiffness_mul(&v, &mut kv);
        let abs: Vec<f64> = v.iter().map(|x| x.abs()).collect();
        let mut scale = vec![0.0; n];
        let k = &fm.model.k;
        let abs_k = crate::fem::CsrMatrix { val: k.val.iter().map(|x| x.abs()).collect(), ..k.clone() };
        abs_k.matvec_into(&abs, &mut scale);
        let bound = 1e-12 * scale.iter().fold(0.0f64, |m, &x| m.max(x));
        for &d in split.free() {
            assert_close!(kv[d], f[d], Tol::abs(bound));
        }
        // the forces on Dirichlet dofs are ignored
        let mut g = f.clone();
        for &d in split.fixed() {
            g[d] = 1e3;
        }
        assert_all_close!(&fm.response(&g), &v, Tol::abs(0.0));
    }
}
