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
    /// Backward error of the equilibrium equation, `||K u - f + C^T lambda||_inf` over the
    /// largest of the contact forces and the row sums `|K| |u| + |f|` (`contact::solve` docs).
    /// The rope's is `||K u - f + lambda|| / ||f_ref||`.
    pub kkt_residual: f64,
    /// Number of slave nodes that had to be tied to a master vertex (averaged normal) because the
    /// closest-point pairing kept flipping between two segments, or because it sits in a
    /// vertex's zone (the vertex-zone rule, `contact::vertex`). 0 for the rope.
    pub vertex_ties: usize,
    /// The tied slaves as `slave:vertex` pairs (slave and master-vertex indices along the slave
    /// and master lists), space-separated, ascending; empty for none and for the rope.
    pub vertex_nodes: String,
    /// Cold re-solves the vertex-zone rule needed after the first solve (0 for the rope).
    pub vertex_rounds: usize,
    /// Geometric check (`contact::check`): smallest signed distance of a slave to the deformed
    /// master (negative: penetration); for the rope `min (u - g)` over the obstacle.
    pub min_gap: f64,
    /// Geometric check: largest `|signed distance|` of a slave with pressure (rope: `|u - g|`
    /// where the obstacle pushes).
    pub active_gap: f64,
    /// Geometric check: largest angle (rad) by which an active slave's force lies outside the
    /// normal cone of the feature it touches (0 for the rope, where every force is vertical).
    pub cone_angle: f64,
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
