//! The contracts of crom: what a scene file may say ([`scene`]), how it is checked
//! ([`SceneError`]), and what every artifact on disk is called and contains ([`artifact`]).
//!
//! Stages and the pipeline depend on this crate; it depends on nothing of theirs.

pub mod artifact;
pub mod comparison;
pub mod error;
pub mod external;
pub mod parameter;
pub mod scene;
mod validate;

pub use error::SceneError;
pub use parameter::ParameterSpec;
pub use scene::{Model, SceneConfig};
