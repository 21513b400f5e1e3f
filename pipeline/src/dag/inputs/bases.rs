//! Reading a stored basis artifact: the bases the metrics use, and the singular values and
//! ranks the report shows. The basis stage (`basis.rs`) writes these files.

use crom_schemas::artifact::{basis as names, ArtifactKind};

use crate::cache::Key;
use crate::error::CromError;
use crate::io::h5::{ColMatrix, H5In};

/// The bases of one training set, as stored.
#[derive(Debug, Clone)]
pub(crate) struct Bases {
    pub primal_pod: ColMatrix,
    pub dual_pod: ColMatrix,
    pub dual_cpg: ColMatrix,
}

/// Load the untruncated-tolerance bases used by the metrics.
pub(crate) fn load_from(store: &crate::store::Store, key: &Key) -> Result<Bases, CromError> {
    let f = H5In::open(&store.dir(ArtifactKind::BASIS, key).join(names::FILE))?;
    let m = |g: &str| f.matrix(&format!("{g}/{}", names::MODES));
    Ok(Bases { primal_pod: m(names::PRIMAL_POD)?, dual_pod: m(names::DUAL_POD)?, dual_cpg: m(names::DUAL_CPG)? })
}

/// Singular values and ranks, for the report.
#[derive(Debug, Clone)]
pub(crate) struct BasisFacts {
    pub primal_sv: Vec<f64>,
    pub dual_sv: Vec<f64>,
    /// primal POD, dual POD, dual CPG, truncated dual CPG.
    pub ranks: [usize; 4],
}

/// Singular values and ranks of a stored basis artifact.
pub(crate) fn load_full(store: &crate::store::Store, key: &Key) -> Result<BasisFacts, CromError> {
    let f = H5In::open(&store.dir(ArtifactKind::BASIS, key).join(names::FILE))?;
    let sv = |g: &str| f.vec_f64(&format!("{g}/{}", names::SINGULAR_VALUES));
    let rank = |g: &str| f.attr_u64_at(g, "rank").map(|r| r as usize);
    Ok(BasisFacts {
        primal_sv: sv(names::PRIMAL_POD)?,
        dual_sv: sv(names::DUAL_POD)?,
        ranks: [
            rank(names::PRIMAL_POD)?,
            rank(names::DUAL_POD)?,
            rank(names::DUAL_CPG)?,
            rank(names::DUAL_CPG_TRUNCATED)?,
        ],
    })
}
