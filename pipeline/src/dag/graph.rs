//! The stage graph's node type: one stage, one type.
//!
//! A stage is a struct that [`super::plan::Plan::of`] builds from the scene once, holding
//!
//! - its key struct (e.g. `BasisKey`, `GeneralizationKey`: the settings its compute uses) and
//!   the key spec made of it and its inputs' keys ([`KeySpec`]), computed at plan time and
//!   never again: the run writes the artifact under the spec it was planned with;
//! - its inputs as named fields ([`Input`]: the node that makes each and that node's key), so a
//!   stage reads `self.train`, not "input 0"; where it reads an input with that input's own
//!   settings, it holds the input stage's key struct too (the compactness holds the basis'
//!   `BasisKey`), which that input's key hashes;
//! - its [`Labels`](super::Labels): the scene's and the parameter's names, which label tables
//!   and change no number.
//!
//! The run's context ([`Ctx`]) does not carry the scene, so a stage cannot read a setting that
//! its key does not hold: "every setting a stage uses is in its key" holds by construction.
//! The one door left is the high-fidelity model ([`super::LazyPhysics`]), built from the
//! scene's model, which is the mesh's key and so every snapshot's.
//!
//! It implements [`StageDef`]: its artifact kind (declared once, with its schema version and its
//! timing files, as an `ArtifactKind` constant), its key, the nodes it reads, where it runs, the
//! names a finished study publishes its files under, and its compute. The executor ([`super::execute`]) is one loop over the plan's nodes that
//! calls [`StageDef::run`]; dry-run, status, Slurm and the run summary read the same nodes.
//! Adding a stage is one type in one file plus one `add` line in `Plan::of`.

use std::fmt::Debug;

use crom_schemas::artifact::ArtifactKind;

use super::ctx::Ctx;
use super::shared::Shared;
use crate::cache::Key;
use crate::error::CromError;

/// One input of a stage: the plan node that makes it, and that node's key.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Input {
    /// The node's name in the plan.
    pub node: String,
    /// Its artifact's key.
    pub key: Key,
}

impl Input {
    /// The input made by the node `node` with key `key`.
    pub(crate) fn new(node: impl Into<String>, key: &Key) -> Self {
        Self { node: node.into(), key: key.clone() }
    }
}

/// A name under which a finished study publishes one of a stage's files
/// (`STORE/scenes/<scene>/<name>`, see `crate::store::published`).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Published {
    /// The published name, e.g. `basis.h5`, `nested/level-2.h5`.
    pub name: String,
    /// The artifact's file it stands for (`None`: the artifact's directory).
    pub file: Option<String>,
    /// An XDMF file, copied with its references relocated (ParaView does not resolve links).
    pub relocate: bool,
}

impl Published {
    /// `name` for the artifact's file `file`.
    pub(crate) fn file(name: impl Into<String>, file: &str) -> Self {
        Self { name: name.into(), file: Some(file.to_string()), relocate: false }
    }

    /// `name` for the artifact's XDMF file `file` (copied, its references relocated).
    pub(crate) fn xdmf(name: impl Into<String>, file: &str) -> Self {
        Self { relocate: true, ..Self::file(name, file) }
    }
}

/// Where a stage runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Placement {
    /// In the executor's loop.
    Main,
    /// On the one worker beside it ([`super::beside`]): light, one core, no numerics.
    Beside,
}

/// A stage of the study, as data.
pub(crate) trait StageDef: Debug + Send + Sync {
    /// The kind of artifact it makes.
    fn kind(&self) -> ArtifactKind;
    /// Its artifact's key (for a snapshot sweep: its column family's).
    fn key(&self) -> Key;
    /// The inputs it reads, in the order they are shown.
    fn inputs(&self) -> Vec<&Input>;
    /// Where it runs.
    fn placement(&self) -> Placement {
        Placement::Main
    }
    /// Whether it times solves against each other (a speed-up): then nothing runs beside it,
    /// so that a job on the other core does not slow one of the timed solves more than the
    /// other.
    fn times_solves(&self) -> bool {
        false
    }
    /// The names a finished study gives its files; none by default (its artifact is then
    /// reached through the catalog and the artifacts that read it).
    fn published(&self) -> Vec<Published> {
        Vec::new()
    }
    /// Make its artifact, or find it in the store; returns its key.
    fn run(&self, ctx: &mut Ctx<'_>, shared: &mut Shared<'_>) -> Result<Key, CromError>;
}
