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

    /// blake3 of the canonical JSON.
    pub fn key(&self) -> Key {
        let bytes = serde_json::to_vec(self).unwrap_or_default();
        Key(blake3::hash(&bytes).to_hex().to_string())
    }
}

/// Serialise stage parameters for a [`KeySpec`]; serde_json cannot fail on the plain data structs
/// crom passes here (no maps with non-string keys), `Null` otherwise.
pub fn params<T: Serialize>(value: &T) -> serde_json::Value {
    serde_json::to_value(value).unwrap_or(serde_json::Value::Null)
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn key_changes_with_every_ingredient() {
        let base = KeySpec::new(ArtifactKind::Snapshot, 1, json!({"p": 0.5}));
        let k = base.key();
        assert_eq!(k, base.clone().key(), "deterministic");
        assert_eq!(k.0.len(), 64);
        assert_ne!(k, KeySpec::new(ArtifactKind::Snapshot, 2, json!({"p": 0.5})).key());
        assert_ne!(k, KeySpec::new(ArtifactKind::Basis, 1, json!({"p": 0.5})).key());
        assert_ne!(k, KeySpec::new(ArtifactKind::Snapshot, 1, json!({"p": 0.5000000000000001})).key());
        assert_ne!(k, base.clone().input("mesh", &Key("ab".into())).key());
        let mut other_schema = base.clone();
        other_schema.schema_version += 1;
        assert_ne!(k, other_schema.key());
    }
}
