//! What every high-fidelity contact solve returns: the primal field, the dual field (as contact
//! pressure, one value per potential-contact node) and the evidence that it converged.

/// Convergence evidence of one high-fidelity solve. Stored with every snapshot.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SolveStats {
    /// Active-set (semismooth Newton) iterations, re-pairings included.
    pub iterations: usize,
    /// Number of active contact constraints at the solution.
    pub active: usize,
    /// Largest penetration `max(0, -gap)` over potential-contact nodes (length units).
    pub max_penetration: f64,
    /// Smallest contact pressure over potential-contact nodes (should be >= 0).
    pub min_lambda: f64,
    /// Relative complementarity residual `||min(lambda, gap)|| / scale`.
    pub complementarity: f64,
    /// Relative residual of the equilibrium equation `||K u - f + C^T lambda|| / ||f_ref||`.
    pub kkt_residual: f64,
    /// Number of slave nodes that had to be tied to a master vertex (averaged normal) because the
    /// closest-point pairing kept flipping between two segments. 0 for the rope.
    pub vertex_ties: usize,
}

/// One high-fidelity solution at one parameter value.
#[derive(Debug, Clone, PartialEq)]
pub struct Snapshot {
    /// Displacement, all dofs including Dirichlet ones; shape `n_dof`.
    pub u: Vec<f64>,
    /// Contact pressure (force per unit length) at each potential-contact node, `>= 0`;
    /// shape `n_contact`.
    pub pressure: Vec<f64>,
    /// Convergence evidence.
    pub stats: SolveStats,
}
