//! Errors of scene construction ([`ModelError`]) and of the contact solve ([`ContactError`]).

use crate::fem::AssemblyError;
use crate::mesh::MeshError;
use crate::mu::Mu;

/// A scene cannot be built or factored.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ModelError {
    /// A scene parameter is out of range.
    #[error("bad scene parameter `{field}`: {msg}")]
    BadParameter {
        /// The offending field (as in the scene file).
        field: &'static str,
        /// What is wrong and what is allowed.
        msg: String,
    },
    /// Mesh generation failed, e.g. a non-positive Jacobian (names element and Gauss point).
    #[error("mesh: {0}")]
    Mesh(#[from] MeshError),
    /// Element integration failed.
    #[error("stiffness assembly: {0}")]
    Assembly(#[from] AssemblyError),
    /// `K_FF` is singular / not positive definite (a body without enough Dirichlet support).
    #[error("the stiffness matrix of the free dofs is singular or not positive definite ({0}); does every body have Dirichlet support?")]
    Singular(String),
    /// faer could not build a sparse matrix (out of memory, index overflow).
    #[error("sparse matrix construction: {0}")]
    Sparse(String),
}

/// A contact solve failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ContactError {
    /// The parameter is not finite.
    #[error("contact solve: parameter {0} is not finite")]
    BadParameter(Mu),
    /// The active-set / re-pairing loop did not reach the tolerance within the iteration budget.
    #[error(
        "contact solve at parameter {param} did not converge: {iterations} active-set iterations \
         over {repairings} pairings, last relative KKT residual {residual:e} \
         (raise max_iter or loosen rel_tol)"
    )]
    NoConvergence {
        /// Parameter value of the solve.
        param: Mu,
        /// Active-set iterations spent.
        iterations: usize,
        /// Pairings computed.
        repairings: usize,
        /// Last relative KKT residual (equilibrium and complementarity, max of the two).
        residual: f64,
    },
    /// The condensed operator on the active set is not positive definite (dependent
    /// constraints, e.g. two slaves acting on the same dofs).
    #[error("contact solve at parameter {param}: condensed contact operator not positive definite (pivot {pivot:e})")]
    Singular {
        /// Parameter value.
        param: Mu,
        /// The failing Cholesky pivot.
        pivot: f64,
    },
    /// A deformed position became non-finite, so no closest point exists.
    #[error("contact solve at parameter {param}: pairing failed for slave {slave} (non-finite position)")]
    Pairing {
        /// Parameter value.
        param: Mu,
        /// Slave index (position in `slave_nodes`).
        slave: usize,
    },
}
