//! The lower Cholesky factor `L` of the passive set's Gram matrix `G[P, P]`, row-major with a
//! leading dimension `ld`, shared by the Gram solver [`Nnls`](super::Nnls) and the Gram-free
//! [`WideNnls`](super::WideNnls): appending a column (one forward substitution), deleting one
//! (Givens rotations restore the triangle) and solving `L L^T z = rhs`.

/// Append row p of `L` for a column whose inner products with the passive columns (in factor
/// order) are `cross(i)` and whose own squared norm is `gtt`; false (factor unchanged) when its
/// squared pivot `gtt - ||l||^2` is at most `pivot_tol * gtt` (numerically dependent).
pub(crate) fn append(
    chol: &mut [f64],
    ld: usize,
    p: usize,
    cross: impl Fn(usize) -> f64,
    gtt: f64,
    pivot_tol: f64,
) -> bool {
    let mut norm2 = 0.0;
    for i in 0..p {
        let mut s = cross(i);
        for j in 0..i {
            s -= chol[i * ld + j] * chol[p * ld + j];
        }
        let l = s / chol[i * ld + i];
        chol[p * ld + i] = l;
        norm2 += l * l;
    }
    let d2 = gtt - norm2;
    if !(d2 > pivot_tol * gtt && d2 > 0.0) {
        return false;
    }
    chol[p * ld + p] = d2.sqrt();
    true
}

/// Delete row (and column) q of the p x p factor: shift the rows below up and restore the
/// lower triangle with Givens rotations on columns (j, j+1), j = q..p-2.
pub(crate) fn remove(chol: &mut [f64], ld: usize, p: usize, q: usize) {
    for i in q..p - 1 {
        chol.copy_within((i + 1) * ld..(i + 1) * ld + p, i * ld);
    }
    for j in q..p - 1 {
        let a = chol[j * ld + j];
        let b = chol[j * ld + j + 1];
        let r = a.hypot(b);
        let (c, s) = (a / r, b / r);
        for i in j..p - 1 {
            let u = chol[i * ld + j];
            let v = chol[i * ld + j + 1];
            chol[i * ld + j] = c * u + s * v;
            chol[i * ld + j + 1] = c * v - s * u;
        }
        chol[j * ld + j] = r;
        chol[j * ld + j + 1] = 0.0;
    }
}

/// `z <- (L L^T)^{-1} z` on the first p entries (forward, then backward substitution).
pub(crate) fn solve(chol: &[f64], ld: usize, p: usize, z: &mut [f64]) {
    for i in 0..p {
        let s: f64 = (0..i).map(|j| chol[i * ld + j] * z[j]).sum();
        z[i] = (z[i] - s) / chol[i * ld + i];
    }
    for i in (0..p).rev() {
        let s: f64 = (i + 1..p).map(|j| chol[j * ld + i] * z[j]).sum();
        z[i] = (z[i] - s) / chol[i * ld + i];
    }
}
