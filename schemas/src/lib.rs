//! The contracts of crom: what a scene file may say ([`scene`]), how it is checked
//! ([`SceneError`]), and what every artifact on disk is called and contains ([`artifact`]).
//!
//! Parse and validate a scene, then ask it for its point sets:
//!
//! ```
//! use crom_schemas::{Model, SceneConfig, SceneError};
//! use std::path::Path;
//!
//! let text = r#"
//! [scene]
//! name = "rope-small"
//! description = "a rope on a sloped obstacle"
//!
//! [model.rope]
//! length = 1.0
//! n_elements = 20
//! nu = 30.0
//! f = 250.0
//! obstacle = { modes = [1.0, 3.0], amplitudes = [-0.2, 0.2], offset = -0.5 }
//!
//! [parameter]
//! name = "gamma"
//! description = "slope of the obstacle"
//! min = -0.5
//! max = 0.5
//! n_train = 5
//!
//! [solver]
//! rel_tol = 1e-10
//! max_iter = 100
//!
//! [study]
//! primal_tol = 0.0
//! dual_orth_tol = 0.0
//! dual_cone_tol = 0.0
//! dual_cone_tol_truncated = 0.2
//! specificity_samples = 100
//! seed = 1
//! "#;
//! let scene = SceneConfig::from_toml_str(text, Path::new("rope-small.toml"))?;
//! assert!(matches!(scene.model, Model::Rope(_)));
//! // Five equidistant training points, both ends included; the test points are the midpoints.
//! assert_eq!(scene.parameter.train(), [-0.5, -0.25, 0.0, 0.25, 0.5]);
//! assert_eq!(scene.parameter.test(), [-0.375, -0.125, 0.125, 0.375]);
//!
//! // A value out of range is refused, naming the field and the fix.
//! let bad = text.replace("n_train = 5", "n_train = 1");
//! match SceneConfig::from_toml_str(&bad, Path::new("bad.toml")) {
//!     Err(SceneError::Invalid { field, .. }) => assert_eq!(field, "parameter.n_train"),
//!     other => panic!("expected a refusal, got {other:?}"),
//! }
//! // So is a key the format does not have.
//! let typo = text.replace("nu = 30.0", "nu = 30.0\ntension = 1.0");
//! assert!(matches!(SceneConfig::from_toml_str(&typo, Path::new("typo.toml")), Err(SceneError::Parse { .. })));
//! # Ok::<(), SceneError>(())
//! ```
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
