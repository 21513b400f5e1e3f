//! Symmetry planes as roller conditions, and the check that the Dirichlet and roller
//! conditions together hold every body.
//!
//! A symmetry plane `x_c = at` (`c` one of the axes) holds the normal component `u_c` of every
//! node on it at zero: a quarter or half model is the whole body's solution restricted to one
//! side when loads and geometry are mirror-symmetric. A body that no condition holds in some
//! rigid motion makes `K_FF` singular; [`free_rigid_modes`] finds that before any
//! factorisation, from the fixed dofs alone: the six rigid modes of a body restricted to its
//! fixed dofs, `R` (`n_fixed x 6`), leave a mode free exactly when `R^T R` is singular.

/// A plane `x[axis] = at`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plane {
    /// 0, 1 or 2 (x, y, z).
    pub axis: usize,
    /// Where it lies.
    pub at: f64,
}

/// The roller dofs (`3 n + axis`) of the nodes within `tol` of each plane, ascending, no
/// duplicates.
pub fn roller_dofs(nodes: &[[f64; 3]], planes: &[Plane], tol: f64) -> Vec<usize> {
    let mut out: Vec<usize> = planes
        .iter()
        .flat_map(|p| {
            nodes
                .iter()
                .enumerate()
                .filter(move |(_, x)| (x[p.axis] - p.at).abs() <= tol)
                .map(move |(n, _)| 3 * n + p.axis)
        })
        .collect();
    out.sort_unstable();
    out.dedup();
    out
}

/// The rigid motions of each body that its fixed dofs leave free: for body `b` (nodes with
/// `node_body[n] == b`), the dimension of the null space of `R_b^T R_b`, `R_b` the six rigid
/// modes (three translations, three rotations about the body's centroid) on the body's fixed
/// dofs. Returns `(body, free modes)` for every body with at least one; empty when every body
/// is held. The Gram matrix is scaled to unit diagonal entries where they are non-zero and an
/// eigenvalue below 1e-10 of the largest counts as free (a held mode's eigenvalue is O(1) on
/// any mesh whose fixed nodes are not nearly collinear).
pub fn free_rigid_modes(nodes: &[[f64; 3]], node_body: &[usize], fixed: &[usize]) -> Vec<(usize, usize)> {
    let bodies = node_body.iter().copied().max().map_or(0, |b| b + 1);
    let mut out = Vec::new();
    for b in 0..bodies {
        let members: Vec<usize> = (0..nodes.len()).filter(|&n| node_body[n] == b).collect();
        if members.is_empty() {
            continue;
        }
        let mut c = [0.0; 3];
        for &n in &members {
            for k in 0..3 {
                c[k] += nodes[n][k] / members.len() as f64;
            }
        }
        let mut g = faer::Mat::<f64>::zeros(6, 6);
        for &d in fixed {
            let (n, comp) = (d / 3, d % 3);
            if node_body.get(n) != Some(&b) {
                continue;
            }
            let x = [nodes[n][0] - c[0], nodes[n][1] - c[1], nodes[n][2] - c[2]];
            // component `comp` of the six modes at x: translations e_k, rotations e_k x x
            let mut r = [0.0; 6];
            r[comp] = 1.0;
            let rot = [[0.0, -x[2], x[1]], [x[2], 0.0, -x[0]], [-x[1], x[0], 0.0]];
            for k in 0..3 {
                r[3 + k] = rot[k][comp];
            }
            for i in 0..6 {
                for j in 0..6 {
                    g[(i, j)] += r[i] * r[j];
                }
            }
        }
        let scale: Vec<f64> = (0..6).map(|i| if g[(i, i)] > 0.0 { 1.0 / g[(i, i)].sqrt() } else { 1.0 }).collect();
        let gs = faer::Mat::from_fn(6, 6, |i, j| g[(i, j)] * scale[i] * scale[j]);
        let eig = gs.self_adjoint_eigenvalues(faer::Side::Lower).unwrap_or_else(|_| vec![0.0; 6]);
        let top = eig.iter().fold(0.0f64, |m, &l| m.max(l));
        let free = eig.iter().filter(|&&l| l <= 1e-10 * top.max(f64::MIN_POSITIVE)).count();
        if free > 0 {
            out.push((b, free));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solid::shapes::cuboid;

    /// A box clamped on its bottom face is held, and so is a box on rollers at the three
    /// planes `x = 0`, `y = 0`, `z = 0` (each plane holds its normal translation and, having
    /// extent, the two rotations that tilt it). On the planes `x = 0` and `y = 0` alone the
    /// translation along z is free (nothing holds `u_z`), one mode; with no condition, six.
    #[test]
    fn free_rigid_modes_are_counted() {
        let b = cuboid([0.0; 3], [1.0, 2.0, 1.0], [2, 2, 2]);
        let body = vec![0; b.nodes.len()];
        let bottom: Vec<usize> = (0..b.nodes.len())
            .filter(|&n| b.nodes[n][2].abs() < 1e-12)
            .flat_map(|n| [3 * n, 3 * n + 1, 3 * n + 2])
            .collect();
        assert!(free_rigid_modes(&b.nodes, &body, &bottom).is_empty());
        let planes = |axes: &[usize]| axes.iter().map(|&axis| Plane { axis, at: 0.0 }).collect::<Vec<_>>();
        let three = roller_dofs(&b.nodes, &planes(&[0, 1, 2]), 1e-12);
        assert!(free_rigid_modes(&b.nodes, &body, &three).is_empty());
        let two = roller_dofs(&b.nodes, &planes(&[0, 1]), 1e-12);
        assert_eq!(free_rigid_modes(&b.nodes, &body, &two), vec![(0, 1)]);
        assert_eq!(free_rigid_modes(&b.nodes, &body, &[]), vec![(0, 6)]);
    }
}
