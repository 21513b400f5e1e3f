//! What stages read of each other's artifacts, and the run's cache of it: a stored training set
//! whole ([`sets`]) or with its primal snapshots left in the store ([`streamed`]), a stored
//! basis ([`bases`]), and [`loaded::Loaded`], which reads each of them once per run.
//!
//! A stage's own file writes its artifact; the readers that other stages share live here, under
//! the run context that caches them, so that no stage file is imported by the context.

pub(crate) mod bases;
pub(crate) mod loaded;
pub(crate) mod sets;
pub(crate) mod streamed;
