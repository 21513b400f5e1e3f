//! A stage added in one file (this one) and one line (`plan.add` in the test below), as a
//! developer adds one: its kind, schema version, key, inputs, published name and compute are
//! all declared here, and the plan, `crom run --dry-run`, `crom status`, the executor, the
//! catalog, the published names and the Python reader `crom_data` see it with no other change.
//!
//! The stage counts the rows of the study's compactness table and stores the count as
//! `throwaway.parquet`, published under that name.

use serde::Serialize;
use serde_json::json;

use crom_schemas::artifact::ArtifactKind;

use super::ctx::Ctx;
use super::graph::{Input, Published, StageDef};
use super::shared::Shared;
use crate::cache::{Key, KeySpec, StageKey};
use crate::error::CromError;
use crate::io::table::{read_parquet, Column, Table};

/// The kind, declared by the stage itself (not one of the shipped kinds).
const KIND: ArtifactKind = ArtifactKind::new("throwaway", 1);

/// Its file.
const FILE: &str = "throwaway.parquet";

/// Its key: no settings; the compactness artifact is its input.
#[derive(Debug, Serialize)]
struct ThrowawayKey {}

impl StageKey for ThrowawayKey {
    const KIND: ArtifactKind = KIND;
    const ALGORITHM_VERSION: u32 = 1;
}

/// The stage.
#[derive(Debug)]
struct ThrowawayStage {
    spec: KeySpec,
    compactness: Input,
}

impl ThrowawayStage {
    fn plan(compactness: Input) -> Self {
        Self { spec: KeySpec::of(&ThrowawayKey {}).input("compactness", &compactness.key), compactness }
    }
}

impl StageDef for ThrowawayStage {
    fn kind(&self) -> ArtifactKind {
        KIND
    }
    fn key(&self) -> Key {
        self.spec.key()
    }
    fn inputs(&self) -> Vec<&Input> {
        vec![&self.compactness]
    }
    fn published(&self) -> Vec<Published> {
        vec![Published::file(FILE, FILE)]
    }
    fn run(&self, ctx: &mut Ctx<'_>, _: &mut Shared<'_>) -> Result<Key, CromError> {
        let table = ctx
            .store
            .dir(ArtifactKind::COMPACTNESS, &self.compactness.key)
            .join(crom_schemas::artifact::compactness::FILE);
        ctx.single(KIND, "throwaway", &self.spec, |staging| {
            let rows = read_parquet(&table)?.rows() as u64;
            Table::default().with("rows", Column::U64(vec![rows])).write_parquet(&staging.path(FILE))?;
            Ok([("rows".to_string(), json!(rows))].into_iter().collect())
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dag::plan::Plan;
    use crate::dag::{publish, run_scene};
    use crate::status::{render_plan, View};
    use crate::store::{catalog, published, Store};
    use crom_schemas::SceneConfig;

    /// The throw-away stage on the rope's study: planned by one line, it is listed by the
    /// dry run ("would run") and by `crom status` ("stored" after the run), run by the
    /// executor under the plan's key, catalogued, published as `throwaway.parquet`, and read
    /// back by `crom_data` (in a Python process) with the row count of the compactness table
    /// read here directly.
    #[test]
    fn a_stage_in_one_file_and_one_line_is_seen_everywhere() {
        let dir = crate::scratch::tempdir().expect("tempdir");
        let repo = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let scene = SceneConfig::load(&repo.join("data/scenes/rope.toml")).expect("rope.toml");
        let mut plan = Plan::of(&scene);
        let compactness = plan.node("compactness").expect("compactness node");
        let compactness = Input::new("compactness", &compactness.key);

        plan.add("throwaway", false, ThrowawayStage::plan(compactness.clone()));

        let node = plan.node("throwaway").expect("planned");
        assert_eq!((node.kind, node.inputs.clone()), (KIND, vec!["compactness".to_string()]));
        let dry = render_plan(dir.path(), &scene, &plan, View::DryRun { online: true }).expect("dry run");
        assert!(dry.lines().any(|l| l.contains("throwaway") && l.ends_with("would run")), "{dry}");

        let store = Store::open(dir.path()).expect("store");
        let mut ctx = Ctx::new(&store, &scene.scene.name, "test".into(), true);
        let out = super::super::run::execute(&mut ctx, &scene, &plan, true).expect("run");
        assert_eq!(out.key("throwaway"), Some(&node.key));
        // the plain study is the same study: the extra node changed no other key
        let plain = run_scene(&mut ctx, &scene, true).expect("plain run");
        assert_eq!(plain.nodes.len() + 1, out.nodes.len());
        assert!(plain.nodes.iter().all(|n| out.key(&n.node) == Some(&n.key)));

        let study = publish::study(&scene, &out, true);
        let entry = study.entries.get(FILE).expect("published name");
        assert_eq!((entry.stage.as_str(), entry.schema_version), ("throwaway", 1));
        published::publish(dir.path(), &study).expect("publish");
        catalog::refresh(dir.path()).expect("catalog");
        let rows = catalog::rows(dir.path());
        let row = rows.iter().find(|r| r.stage == "throwaway").expect("catalogued");
        assert!(row.published.contains("rope/throwaway.parquet"), "{:?}", row.published);
        let status = render_plan(dir.path(), &scene, &plan, View::Status).expect("status");
        assert!(status.lines().any(|l| l.contains("throwaway") && l.ends_with("stored")), "{status}");

        let table =
            store.dir(ArtifactKind::COMPACTNESS, &compactness.key).join(crom_schemas::artifact::compactness::FILE);
        let expected = read_parquet(&table).expect("compactness").rows();
        assert!(expected > 0);
        let python = std::env::var("PYTHON").unwrap_or_else(|_| "python3".into());
        let script = "import sys, crom_data\n\
                      sc = crom_data.open_store(sys.argv[1]).scene('rope')\n\
                      print(int(sc.table('throwaway.parquet')['rows'][0]), sc.entries['throwaway.parquet']['stage'])";
        let run = std::process::Command::new(&python)
            .args(["-c", script])
            .arg(dir.path())
            .env("PYTHONPATH", repo.join("python"))
            .output()
            .expect("python runs");
        let stdout = String::from_utf8_lossy(&run.stdout);
        assert!(run.status.success(), "{python}: {}", String::from_utf8_lossy(&run.stderr));
        assert_eq!(stdout.trim(), format!("{expected} throwaway"));
    }
}
