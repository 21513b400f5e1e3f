//! The bilinear quadrilateral (Q1) element kernel: shape functions, Jacobian, and the
//! plane-strain stiffness `K_e = sum_gp B^T D B det(J) w` with 2x2 Gauss quadrature, or with the
//! volumetric part at the centre only ([`stiffness_selective`], the remedy for locking).
//!
//! Reference square `[-1, 1]^2`, nodes counter-clockwise:
//!
//! ```text
//!   3 (-1, 1) ---- 2 (1, 1)
//!   |                 |        N_a = (1 + xi xi_a)(1 + eta eta_a) / 4
//!   0 (-1,-1) ---- 1 (1,-1)
//! ```
//!
//! Element dofs are interleaved: `[u_x0, u_y0, u_x1, u_y1, ...]`.
//!
//! Below both `mesh` (which checks every element's Jacobian when it builds a mesh) and `fem`
//! (which assembles with it), so neither depends on the other for it.

/// `1 / sqrt(3)`, the 2-point Gauss abscissa.
const G: f64 = 0.577_350_269_189_625_8;

/// The 2x2 Gauss points `(xi, eta)` (all weights 1), ordered like the element nodes.
pub const GAUSS_2X2: [[f64; 2]; 4] = [[-G, -G], [G, -G], [G, G], [-G, G]];

const XI_A: [[f64; 2]; 4] = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];

/// Shape function values at `(xi, eta)`.
pub fn shape(xi: f64, eta: f64) -> [f64; 4] {
    let mut n = [0.0; 4];
    for (a, [xa, ya]) in XI_A.iter().enumerate() {
        n[a] = 0.25 * (1.0 + xi * xa) * (1.0 + eta * ya);
    }
    n
}

/// Shape function derivatives `[dN_a/dxi, dN_a/deta]` at `(xi, eta)`.
pub fn shape_derivatives(xi: f64, eta: f64) -> [[f64; 2]; 4] {
    let mut d = [[0.0; 2]; 4];
    for (a, [xa, ya]) in XI_A.iter().enumerate() {
        d[a] = [0.25 * xa * (1.0 + eta * ya), 0.25 * ya * (1.0 + xi * xa)];
    }
    d
}

/// The isoparametric map's Jacobian at a point and the physical shape-function gradients.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Jacobian {
    /// `det(dx/dxi)`.
    pub det: f64,
    /// `[dN_a/dx, dN_a/dy]`; meaningless when `det <= 0`.
    pub dn_dx: [[f64; 2]; 4],
}

/// Jacobian of the element with corner coordinates `xe` at `(xi, eta)`.
pub fn jacobian(xe: &[[f64; 2]; 4], xi: f64, eta: f64) -> Jacobian {
    let dn = shape_derivatives(xi, eta);
    // J = [[dx/dxi, dx/deta], [dy/dxi, dy/deta]]
    let mut j = [[0.0; 2]; 2];
    for a in 0..4 {
        for r in 0..2 {
            for c in 0..2 {
                j[r][c] += xe[a][r] * dn[a][c];
            }
        }
    }
    let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
    // inverse of J: [[dxi/dx, dxi/dy], [deta/dx, deta/dy]]
    let inv = [[j[1][1] / det, -j[0][1] / det], [-j[1][0] / det, j[0][0] / det]];
    let mut dn_dx = [[0.0; 2]; 4];
    for a in 0..4 {
        dn_dx[a] = [dn[a][0] * inv[0][0] + dn[a][1] * inv[1][0], dn[a][0] * inv[0][1] + dn[a][1] * inv[1][1]];
    }
    Jacobian { det, dn_dx }
}

/// A non-positive Jacobian met while integrating an element.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BadJacobian {
    /// Index into [`GAUSS_2X2`].
    pub gauss_point: usize,
    /// The determinant found.
    pub det: f64,
}

/// Plane-strain Q1 stiffness `8 x 8` (unit thickness) with 2x2 Gauss quadrature.
pub fn stiffness(xe: &[[f64; 2]; 4], d: &[[f64; 3]; 3]) -> Result<[[f64; 8]; 8], BadJacobian> {
    let mut k = [[0.0; 8]; 8];
    for (gp, &[xi, eta]) in GAUSS_2X2.iter().enumerate() {
        add_point(&mut k, xe, d, xi, eta, 1.0).map_err(|det| BadJacobian { gauss_point: gp, det })?;
    }
    Ok(k)
}

/// Selective reduced integration: `K_e = sum_2x2 B^T D_dev B det J + B_0^T D_vol B_0 det J_0 * 4`
/// with `B_0`, `J_0` at the element centre (weight 4). Under-integrating only the volumetric
/// (`lambda`) term removes Q1's volumetric locking as `nu -> 1/2` (Hughes, *The Finite Element
/// Method*, sec. 4.5; B-bar of the same element is equivalent to it on parallelograms); the
/// fully integrated deviatoric term keeps every non-rigid mode stiff (no hourglass). A
/// constant strain is integrated exactly by both terms, so the patch test holds.
pub fn stiffness_selective(
    xe: &[[f64; 2]; 4],
    d_dev: &[[f64; 3]; 3],
    d_vol: &[[f64; 3]; 3],
) -> Result<[[f64; 8]; 8], BadJacobian> {
    let mut k = stiffness(xe, d_dev)?;
    add_point(&mut k, xe, d_vol, 0.0, 0.0, 4.0).map_err(|det| BadJacobian { gauss_point: 0, det })?;
    Ok(k)
}

/// Add `w B^T D B det J` at `(xi, eta)` to `k`; `Err(det)` for a non-positive Jacobian.
fn add_point(
    k: &mut [[f64; 8]; 8],
    xe: &[[f64; 2]; 4],
    d: &[[f64; 3]; 3],
    xi: f64,
    eta: f64,
    weight: f64,
) -> Result<(), f64> {
    let jac = jacobian(xe, xi, eta);
    if jac.det.is_nan() || jac.det <= 0.0 {
        return Err(jac.det);
    }
    // B (3 x 8): strain = B u_e, rows xx, yy, xy (engineering).
    let mut b = [[0.0; 8]; 3];
    for a in 0..4 {
        let [nx, ny] = jac.dn_dx[a];
        b[0][2 * a] = nx;
        b[1][2 * a + 1] = ny;
        b[2][2 * a] = ny;
        b[2][2 * a + 1] = nx;
    }
    // DB (3 x 8)
    let mut db = [[0.0; 8]; 3];
    for r in 0..3 {
        for c in 0..8 {
            db[r][c] = d[r][0] * b[0][c] + d[r][1] * b[1][c] + d[r][2] * b[2][c];
        }
    }
    let w = jac.det * weight;
    for r in 0..8 {
        for c in 0..8 {
            k[r][c] += w * (b[0][r] * db[0][c] + b[1][r] * db[1][c] + b[2][r] * db[2][c]);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::Material;
    use crate::float_cmp::Tol;
    use crate::{assert_all_close, assert_close};

    fn skewed() -> [[f64; 2]; 4] {
        [[0.0, 0.0], [2.0, 0.3], [2.4, 1.7], [-0.2, 1.2]]
    }

    fn energy(k: &[[f64; 8]; 8], u: &[f64; 8]) -> f64 {
        (0..8).map(|r| (0..8).map(|c| u[r] * k[r][c] * u[c]).sum::<f64>()).sum::<f64>()
    }

    /// With nu = 0 there is no volumetric term (lambda = 0): selective integration is the full
    /// one. Sums of the same products in another order: 1e-14 relative.
    #[test]
    fn selective_equals_full_without_lambda() {
        let m = Material::new(2.0, 0.0);
        let (dev, vol) = m.plane_strain_split();
        let full = stiffness(&skewed(), &m.plane_strain()).expect("full");
        let sri = stiffness_selective(&skewed(), &dev, &vol).expect("selective");
        for r in 0..8 {
            assert_all_close!(&sri[r], &full[r], Tol { abs: 1e-14, rel: 1e-14 });
        }
    }

    /// Patch test: a linear displacement field (constant strain) has the exact energy
    /// `eps^T D eps * area` under selective integration too (both terms integrate a constant
    /// exactly), for nu near 1/2 where the volumetric term dominates; rigid motions have none;
    /// the two hourglass modes keep positive energy (the deviatoric term is fully integrated).
    #[test]
    fn selective_passes_the_patch_test_and_has_no_spurious_zero_mode() {
        let m = Material::new(3.0, 0.4999);
        let (dev, vol) = m.plane_strain_split();
        let xe = skewed();
        let k = stiffness_selective(&xe, &dev, &vol).expect("selective");
        let area: f64 = GAUSS_2X2.iter().map(|&[xi, eta]| jacobian(&xe, xi, eta).det).sum();
        let a = [[0.3, -0.7], [0.2, 0.5]]; // u = A x + c
        let mut u = [0.0; 8];
        for (n, x) in xe.iter().enumerate() {
            u[2 * n] = a[0][0] * x[0] + a[0][1] * x[1] + 0.1;
            u[2 * n + 1] = a[1][0] * x[0] + a[1][1] * x[1] - 0.4;
        }
        let eps = [a[0][0], a[1][1], a[0][1] + a[1][0]];
        let d = m.plane_strain();
        let exact: f64 = (0..3).map(|r| (0..3).map(|c| eps[r] * d[r][c] * eps[c]).sum::<f64>()).sum::<f64>() * area;
        // lambda ~ 5000: the energies are O(1e4); 1e-12 relative is round-off.
        assert_close!(energy(&k, &u), exact, Tol::rel(1e-12));
        let rotation: [f64; 8] = std::array::from_fn(|i| if i % 2 == 0 { -xe[i / 2][1] } else { xe[i / 2][0] });
        let translation: [f64; 8] = std::array::from_fn(|i| (i % 2) as f64);
        for rigid in [rotation, translation] {
            assert_close!(energy(&k, &rigid), 0.0, Tol::abs(1e-9));
        }
        for dir in 0..2 {
            let h: [f64; 8] = std::array::from_fn(|i| if i % 2 == dir { [1.0, -1.0, 1.0, -1.0][i / 2] } else { 0.0 });
            assert!(energy(&k, &h) > 1e-3 * m.lame().1, "hourglass mode {dir} has no stiffness");
        }
    }

    /// Shape functions form a partition of unity and reproduce x (isoparametric).
    #[test]
    fn shape_functions_partition_of_unity() {
        for &[xi, eta] in &[[0.3, -0.7], [-1.0, 1.0], [0.0, 0.0]] {
            let n = shape(xi, eta);
            // Sums of four products of numbers <= 1: rounding only.
            assert_close!(n.iter().sum::<f64>(), 1.0, Tol::abs(1e-15));
            let d = shape_derivatives(xi, eta);
            assert_close!(d.iter().map(|x| x[0]).sum::<f64>(), 0.0, Tol::abs(1e-15));
            assert_close!(d.iter().map(|x| x[1]).sum::<f64>(), 0.0, Tol::abs(1e-15));
        }
    }

    /// The element stiffness is symmetric, has exactly the three rigid-body modes in its kernel,
    /// and a constant strain state gives the exact strain energy `area * eps^T D eps`
    /// (Q1 integrates constant-strain fields exactly with 2x2 Gauss).
    #[test]
    fn stiffness_symmetric_rigid_modes_and_energy() {
        let xe = skewed();
        let mat = Material::new(3.0, 0.3);
        let d = mat.plane_strain();
        let k = stiffness(&xe, &d).expect("valid element");
        let scale = k.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
        for (r, row) in k.iter().enumerate() {
            for (c, &krc) in row.iter().enumerate() {
                // Symmetric by construction up to the summation order: 1e-14 relative.
                assert_close!(krc, k[c][r], Tol::abs(1e-14 * scale));
            }
        }
        // rigid modes: tx, ty, rotation about origin
        let modes: [Vec<f64>; 3] = [
            (0..4).flat_map(|_| [1.0, 0.0]).collect(),
            (0..4).flat_map(|_| [0.0, 1.0]).collect(),
            xe.iter().flat_map(|p| [-p[1], p[0]]).collect(),
        ];
        for m in &modes {
            let km: Vec<f64> = (0..8).map(|r| (0..8).map(|c| k[r][c] * m[c]).sum()).collect();
            // K m = 0 up to rounding in sums of 8 terms of size `scale`.
            assert_all_close!(km, vec![0.0; 8], Tol::abs(1e-13 * scale));
        }
        // constant strain u = (a x + b y, c x + e y): eps = (a, e, b + c)
        let (a, b, c, e) = (0.01, -0.02, 0.005, 0.03);
        let u: Vec<f64> = xe.iter().flat_map(|p| [a * p[0] + b * p[1], c * p[0] + e * p[1]]).collect();
        let energy: f64 = (0..8).map(|r| (0..8).map(|cc| u[r] * k[r][cc] * u[cc]).sum::<f64>()).sum();
        let eps = [a, e, b + c];
        let mut ede = 0.0;
        for r in 0..3 {
            for cc in 0..3 {
                ede += eps[r] * d[r][cc] * eps[cc];
            }
        }
        // area of the quad (shoelace)
        let area = 0.5
            * (0..4)
                .map(|i| {
                    let (p, q) = (xe[i], xe[(i + 1) % 4]);
                    p[0] * q[1] - q[0] * p[1]
                })
                .sum::<f64>();
        // Exact for constant strain; 1e-12 relative covers rounding.
        assert_close!(energy, area * ede, Tol::rel(1e-12));
    }

    #[test]
    fn inverted_element_is_an_error() {
        let mut xe = skewed();
        xe.swap(1, 3); // clockwise
        let d = Material::new(1.0, 0.3).plane_strain();
        assert!(matches!(stiffness(&xe, &d), Err(BadJacobian { gauss_point: 0, .. })));
    }
}
