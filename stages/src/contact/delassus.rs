//! The Delassus (compliance) operator on the potential-contact dofs, computed once per scene.
//!
//! With `E_c` the injection of the contact dofs (slave and master node dofs) into the free dofs,
//! the contact dofs respond to contact forces `F_c` as `u_c = a_c(mu) + W F_c` with
//!
//! ```text
//! W = E_c^T K_FF^{-1} E_c        (n_cd x n_cd, symmetric positive semi-definite),
//! ```
//!
//! zero rows/columns for contact dofs that are Dirichlet. Column `j` of `W` is the contact-dof
//! part of `K_FF^{-1} e_j`; the columns are solved in blocks of [`BLOCK`] right-hand sides with
//! the sparse Cholesky factor. For a frozen pairing with constraint matrix `B` (gaps
//! `g = B x`), the condensed operator of the LCP is `D = B W B^T` ([`super::active_set`]).

use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::Llt;
use faer::Mat;

/// Right-hand sides per block solve.
pub const BLOCK: usize = 64;

/// `W` (row-major `n_cd x n_cd`) from the factor of `K_FF`. `cfree[cd]` is the free index of
/// contact dof `cd`, or `None` if it is Dirichlet. The blocks of right-hand sides are spread
/// over up to `threads` scoped threads (the factor is shared read-only).
pub fn compliance(llt: &Llt<usize, f64>, n_free: usize, cfree: &[Option<usize>], threads: usize) -> Vec<f64> {
    compliance_in_blocks(llt, n_free, cfree, threads, BLOCK)
}

/// [`compliance`] with `block` right-hand sides per solve.
pub fn compliance_in_blocks(
    llt: &Llt<usize, f64>,
    n_free: usize,
    cfree: &[Option<usize>],
    threads: usize,
    block: usize,
) -> Vec<f64> {
    let ncd = cfree.len();
    let cols: Vec<(usize, usize)> = cfree.iter().enumerate().filter_map(|(cd, f)| f.map(|fi| (cd, fi))).collect();
    let chunks: Vec<&[(usize, usize)]> = cols.chunks(block.max(1)).collect();
    let threads = threads.clamp(1, chunks.len().max(1));
    // each worker returns, for its chunks, the contact-dof rows of K^{-1} e_j: (cd_j, column)
    let work = |first: usize| -> Vec<(usize, Vec<f64>)> {
        let mut out = Vec::new();
        for chunk in chunks.iter().skip(first).step_by(threads) {
            let mut rhs = Mat::<f64>::zeros(n_free, chunk.len());
            for (j, &(_, fi)) in chunk.iter().enumerate() {
                rhs[(fi, j)] = 1.0;
            }
            llt.solve_in_place(rhs.as_mut());
            for (j, &(cdj, _)) in chunk.iter().enumerate() {
                out.push((cdj, cols.iter().map(|&(_, fi)| rhs[(fi, j)]).collect()));
            }
        }
        out
    };
    let parts: Vec<Vec<(usize, Vec<f64>)>> = if threads == 1 {
        vec![work(0)]
    } else {
        std::thread::scope(|sc| {
            let hs: Vec<_> = (0..threads).map(|t| sc.spawn(move || work(t))).collect();
            hs.into_iter().map(|h| h.join().unwrap_or_else(|e| std::panic::resume_unwind(e))).collect()
        })
    };
    let mut w = vec![0.0; ncd * ncd];
    for (cdj, col) in parts.into_iter().flatten() {
        for (&(cdi, _), v) in cols.iter().zip(col) {
            w[cdi * ncd + cdj] = v;
        }
    }
    // symmetrise away the solve's rounding (W is symmetric in exact arithmetic)
    for i in 0..ncd {
        for j in 0..i {
            let m = 0.5 * (w[i * ncd + j] + w[j * ncd + i]);
            w[i * ncd + j] = m;
            w[j * ncd + i] = m;
        }
    }
    w
}
