//! Cache keys: blake3 of a canonical serialisation of everything that affects a stage's output
//! (its parameters, its inputs' keys, the stage's algorithm version and the artifact kind's
//! schema version), as in just's `cache.rs`.
//!
//! The serialisation is `serde_json` of a struct with a fixed field order and `BTreeMap`s, so it
//! is canonical; floats print as their shortest round-trip decimal, so two parameter values share
//! a key exactly when their bits agree.

use std::collections::BTreeMap;

use crom_schemas::artifact::ArtifactKind;
use serde::Serialize;

/// The content-hash name of an artifact.
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, serde::Deserialize)]
#[serde(transparent)]
pub struct Key(pub String);

impl std::fmt::Display for Key {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl Key {
    /// First 12 hex digits, for humans.
    pub fn short(&self) -> &str {
        &self.0[..12.min(self.0.len())]
    }
}

/// Everything that determines one artifact.
#[derive(Debug, Clone, Serialize)]
pub struct KeySpec {
    /// The artifact kind (its name and schema version are the fields below).
    #[serde(skip)]
    pub kind: ArtifactKind,
    /// Stage / artifact kind name.
    pub stage: &'static str,
    /// Version of the stage's algorithm: bump when the numbers it produces change.
    pub algorithm_version: u32,
    /// Layout version of the artifact kind.
    pub schema_version: u32,
    /// The stage's own parameters.
    pub params: serde_json::Value,
    /// Keys of the input artifacts, by role.
    pub inputs: BTreeMap<String, Key>,
}

impl KeySpec {
    /// A key spec for `kind` with the given parameters and inputs.
    pub fn new(kind: ArtifactKind, algorithm_version: u32, params: serde_json::Value) -> Self {
        Self {
            kind,
            stage: kind.name(),
            algorithm_version,
            schema_version: kind.schema_version(),
            params,
            inputs: BTreeMap::new(),
        }
    }

    /// Add an input artifact's key under `role`.
    pub fn input(mut self, role: &str, key: &Key) -> Self {
        self.inputs.insert(role.to_string(), key.clone());
        self
    }

    /// blake3 of the canonical JSON. A `KeySpec` is strings, integers, a JSON value and a map
    /// with string keys: its serialisation cannot fail.
    pub fn key(&self) -> Key {
        let bytes = serde_json::to_vec(self).expect("a KeySpec (strings, integers, JSON, string-keyed map) serialises");
        Key(blake3::hash(&bytes).to_hex().to_string())
    }

    /// The key spec of a typed stage key (inputs are added with [`KeySpec::input`]).
    pub fn of<K: StageKey>(key: &K) -> Self {
        Self::new(K::KIND, K::ALGORITHM_VERSION, params(key))
    }
}

/// A stage's cache key as a type: exactly the settings that determine its output (its inputs'
/// keys are added to the [`KeySpec`]), so that a setting the stage uses cannot be left out of
/// its key, nor a setting it does not use (a timing constant) be put in.
pub trait StageKey: Serialize {
    /// The artifact kind the stage writes.
    const KIND: ArtifactKind;
    /// Version of the stage's algorithm: bump when the numbers it produces change.
    const ALGORITHM_VERSION: u32;
}

/// The NNLS settings of every cone computation (CPG, cone projections): part of the key of
/// each stage that solves NNLS problems. crom uses `NnlsParams::default()` throughout, so a
/// change of those defaults changes these keys.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct NnlsKey {
    /// Outer iteration cap (`None`: `3 k + 10`).
    pub max_iter: Option<usize>,
    /// Relative KKT tolerance.
    pub tol: f64,
    /// Relative pivot tolerance.
    pub pivot_tol: f64,
}

impl NnlsKey {
    /// The settings crom's stages use.
    pub fn used() -> Self {
        let p = crom_stages::cone::NnlsParams::default();
        Self { max_iter: p.max_iter, tol: p.tol, pivot_tol: p.pivot_tol }
    }
}

/// Serialise typed key fields for a [`KeySpec`]. Key structs hold numbers, strings, options,
/// vectors and string-keyed maps, which serde_json always serialises (a non-finite float
/// becomes `null`); a map with non-string keys would be a programming error, caught by the
/// tests of every key type.
pub fn params<T: Serialize>(value: &T) -> serde_json::Value {
    serde_json::to_value(value).expect("a stage key (numbers, strings, options, vectors) serialises")
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn key_changes_with_every_ingredient() {
        let base = KeySpec::new(ArtifactKind::SNAPSHOT, 1, json!({"p": 0.5}));
        let k = base.key();
        assert_eq!(k, base.clone().key(), "deterministic");
        assert_eq!(k.0.len(), 64);
        assert_ne!(k, KeySpec::new(ArtifactKind::SNAPSHOT, 2, json!({"p": 0.5})).key());
        assert_ne!(k, KeySpec::new(ArtifactKind::BASIS, 1, json!({"p": 0.5})).key());
        assert_ne!(k, KeySpec::new(ArtifactKind::SNAPSHOT, 1, json!({"p": 0.5000000000000001})).key());
        assert_ne!(k, base.clone().input("mesh", &Key("ab".into())).key());
        let mut other_schema = base.clone();
        other_schema.schema_version += 1;
        assert_ne!(k, other_schema.key());
    }

    #[derive(Serialize)]
    struct Example {
        tol: f64,
        nnls: NnlsKey,
    }

    impl StageKey for Example {
        const KIND: ArtifactKind = ArtifactKind::BASIS;
        const ALGORITHM_VERSION: u32 = 7;
    }

    #[test]
    fn a_typed_key_carries_its_kind_version_and_every_field() {
        let spec = KeySpec::of(&Example { tol: 0.5, nnls: NnlsKey::used() });
        assert_eq!((spec.stage, spec.algorithm_version), ("basis", 7));
        assert_eq!(spec.schema_version, ArtifactKind::BASIS.schema_version());
        assert_eq!(spec.params["tol"], json!(0.5));
        // The NNLS settings the stages use are in the key: a change of them changes it.
        let p = crom_stages::cone::NnlsParams::default();
        assert_eq!(spec.params["nnls"], json!({ "max_iter": p.max_iter, "tol": p.tol, "pivot_tol": p.pivot_tol }));
        let other = KeySpec::of(&Example { tol: 0.5, nnls: NnlsKey { tol: 2.0 * p.tol, ..NnlsKey::used() } });
        assert_ne!(spec.key(), other.key());
    }
}
