//! Every shipped scene file loads, and every kind of bad input gives an error that names the file,
//! the field and a fix.

use std::path::{Path, PathBuf};

use crom_schemas::{Model, SceneConfig, SceneError};

fn scenes_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/scenes")
}

fn rope_text() -> String {
    std::fs::read_to_string(scenes_dir().join("rope.toml")).expect("rope.toml is shipped")
}

fn load_err(text: &str) -> SceneError {
    SceneConfig::from_toml_str(text, Path::new("bad.toml")).expect_err("must be rejected")
}

#[test]
fn every_shipped_scene_loads_and_matches_scenes_md() {
    let mut names = Vec::new();
    for entry in std::fs::read_dir(scenes_dir()).expect("data/scenes exists") {
        let path = entry.expect("dir entry").path();
        let cfg = SceneConfig::load(&path).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(cfg.scene.name, path.file_stem().and_then(|s| s.to_str()).unwrap_or(""));
        names.push(cfg.scene.name.clone());
        match (&cfg.model, cfg.scene.name.as_str()) {
            (Model::Rope(r), "rope") => {
                assert_eq!(r.n_elements, 200);
                assert_eq!(cfg.parameter.n_train, Some(10));
            }
            (Model::Hertz(h), "hertz") => assert_eq!(h.n_arc, 78),
            (Model::Hertz(h), "hertz-fine") => assert_eq!(h.n_arc, 312),
            (Model::Ironing(i), "ironing-coarse") => {
                assert_eq!((i.slab.nx, i.slab.ny, i.iron.nx, i.iron.ny), (100, 20, 30, 30));
                assert_eq!(cfg.parameter.n_train, Some(128));
                assert_eq!(cfg.parameter.nested_levels, 7);
            }
            (Model::Ironing(i), "ironing-fine") => {
                assert_eq!((i.slab.nx, i.slab.ny, i.iron.nx, i.iron.ny), (200, 40, 60, 60));
            }
            (Model::Ironing(i), "ironing-fine-2d") => {
                // The fine mesh, with d_y a parameter axis: 129 x 33 training points.
                assert_eq!((i.slab.nx, i.slab.ny, i.iron.nx, i.iron.ny), (200, 40, 60, 60));
                assert_eq!((i.d_y, cfg.parameter.names()), (None, vec!["d_x", "d_y"]));
                assert_eq!(cfg.parameter.train_points().len(), 129 * 33);
            }
            (Model::Hertz3d(h), "hertz-3d") => {
                // docs/scenes.md#hertz-3d: 24 elements a side graded with exponent 3, d up to 0.01,
                // 48 training points
                assert_eq!(
                    (h.n, h.grading.to_bits(), h.contact_radius.to_bits()),
                    (24, 3f64.to_bits(), 0.25f64.to_bits())
                );
                assert_eq!(cfg.parameter.train_points().len(), 48);
            }
            (Model::Ironing3d(i), "ironing-3d") => {
                // docs/scenes.md#ironing-3d: 100 x 15 x 20 and 20 x 10 x 10 elements, 129 points
                assert_eq!((i.block.nx, i.block.ny, i.block.nz), (100, 15, 20));
                assert_eq!((i.die.nx, i.die.ny, i.die.nz), (20, 10, 10));
                assert_eq!(cfg.parameter.train_points().len(), 129);
            }
            (Model::Ironing3d(i), "ironing-3d-2d") => {
                // docs/scenes.md#ironing-3d-2d: ironing-3d's mesh, d_z a parameter axis: 33 x 5
                assert_eq!((i.block.nx, i.block.ny, i.block.nz), (100, 15, 20));
                assert_eq!((i.d_z, cfg.parameter.names()), (None, vec!["d_x", "d_z"]));
                assert_eq!(cfg.parameter.train_points().len(), 33 * 5);
            }
            (m, n) => panic!("scene {n} has unexpected model {}", m.kind()),
        }
    }
    names.sort();
    assert_eq!(
        names,
        [
            "hertz",
            "hertz-3d",
            "hertz-fine",
            "ironing-3d",
            "ironing-3d-2d",
            "ironing-coarse",
            "ironing-fine",
            "ironing-fine-2d",
            "rope"
        ]
    );
}

fn assert_names(err: &SceneError, needles: &[&str]) {
    let msg = err.to_string();
    assert!(msg.contains("bad.toml"), "no file name in: {msg}");
    assert!(msg.contains("fix:"), "no fix in: {msg}");
    for n in needles {
        assert!(msg.contains(n), "`{n}` missing from: {msg}");
    }
}

#[test]
fn unknown_key_is_named() {
    let text = rope_text().replace("n_elements = 200", "n_elements = 200\nn_elemnts = 3");
    assert_names(&load_err(&text), &["n_elemnts"]);
}

#[test]
fn missing_field_is_named() {
    let text = rope_text().replace("nu = 30.0\n", "");
    assert_names(&load_err(&text), &["nu"]);
}

#[test]
fn wrong_type_is_named() {
    let text = rope_text().replace("n_elements = 200", "n_elements = \"many\"");
    assert_names(&load_err(&text), &["n_elements"]);
}

#[test]
fn too_few_elements() {
    let text = rope_text().replace("n_elements = 200", "n_elements = 1");
    assert_names(&load_err(&text), &["model.rope.n_elements", "at least 2"]);
}

#[test]
fn negative_tolerance() {
    let text = rope_text().replace("dual_cone_tol_truncated = 0.2", "dual_cone_tol_truncated = -0.2");
    assert_names(&load_err(&text), &["study.dual_cone_tol_truncated", ">= 0"]);
}

#[test]
fn reversed_and_empty_ranges() {
    let text = rope_text().replace("max = 0.5", "max = -0.6");
    assert_names(&load_err(&text), &["parameter.max", "reversed"]);
    let text = rope_text().replace("max = 0.5", "max = -0.5");
    assert_names(&load_err(&text), &["parameter.max", "empty"]);
}

#[test]
fn non_finite_numbers() {
    let text = rope_text().replace("nu = 30.0", "nu = nan");
    assert_names(&load_err(&text), &["model.rope.nu", "finite"]);
    let text = rope_text().replace("f = 250.0", "f = inf");
    assert_names(&load_err(&text), &["model.rope.f", "finite"]);
}

#[test]
fn two_models_or_unknown_model() {
    let text = rope_text().replace("[model.rope]", "[model.rop]");
    assert_names(&load_err(&text), &["rop"]);
}

#[test]
fn unreadable_file() {
    let err = SceneConfig::load(Path::new("/nonexistent/bad.toml")).expect_err("missing file");
    assert_names(&err, &["cannot read"]);
}

#[test]
fn vector_parameters_are_checked_against_the_model() {
    let base = std::fs::read_to_string(scenes_dir().join("ironing-fine-2d.toml")).expect("scene");
    // d_y both a model value and an axis.
    let both = base.replace("[model.ironing.slab]", "[model.ironing]\nd_y = 0.04\n\n[model.ironing.slab]");
    let err = SceneConfig::from_toml_str(&both, Path::new("bad.toml")).expect_err("d_y twice");
    assert_names(&err, &["model.ironing.d_y", "axis"]);
    // An axis the ironing model does not have.
    let other = base.replace("name = \"d_y\"", "name = \"angle\"");
    let err = SceneConfig::from_toml_str(&other, Path::new("bad.toml")).expect_err("unknown axis");
    assert_names(&err, &["parameter.axes", "(d_x, d_y)"]);
    // The registered neighbours order by the travel and a second component: accepted with two
    // (in place of the shipped comparison), with the whole-node shifts they need.
    let without = base.split("\n[comparison]").next().expect("the scene before its comparison");
    let nb = format!(
        "{without}\n[comparison]\napproximations = [{{ kind = \"registered\", map = \"translate\", interpolation = \"nodes\", basis = \"neighbours\" }}]\n"
    );
    SceneConfig::from_toml_str(&nb, Path::new("ok.toml")).expect("neighbours on two components");
    // An axis with both grid settings.
    let grid = base.replace("train_level = 5", "train_level = 5\nn_train = 9");
    let err = SceneConfig::from_toml_str(&grid, Path::new("bad.toml")).expect_err("two grids");
    assert_names(&err, &["parameter.axes[0].train_level"]);
    // Too many points on a tensor grid: 4 097 x 33 = 135 201 > 2^17 + 1.
    let big = base.replace("train_level = 7", "train_level = 12");
    let err = SceneConfig::from_toml_str(&big, Path::new("bad.toml")).expect_err("too many points");
    assert_names(&err, &["parameter", "training points"]);
}

#[test]
fn max_rank_is_optional_and_positive() {
    let cfg = SceneConfig::from_toml_str(&rope_text(), Path::new("rope.toml")).expect("shipped scene");
    assert_eq!(cfg.study.max_rank, None);
    // Default: every m up to 256 snapshots, 256 beyond.
    assert_eq!((cfg.study.max_rank_for(128), cfg.study.max_rank_for(256)), (128, 256));
    assert_eq!(cfg.study.max_rank_for(512), 256);
    let text = rope_text().replace("seed = ", "max_rank = 40\nseed = ");
    let cfg = SceneConfig::from_toml_str(&text, Path::new("rope.toml")).expect("max_rank = 40 is valid");
    assert_eq!((cfg.study.max_rank, cfg.study.max_rank_for(512)), (Some(40), 40));
    let text = rope_text().replace("seed = ", "max_rank = 0\nseed = ");
    assert_names(&load_err(&text), &["study.max_rank", "is 0"]);
    let text = rope_text().replace("seed = ", "max_rank = -3\nseed = ");
    assert_names(&load_err(&text), &["max_rank"]);
}

#[test]
fn loo_folds_are_all_up_to_256_snapshots_then_an_even_sample() {
    let cfg = SceneConfig::from_toml_str(&rope_text(), Path::new("rope.toml")).expect("shipped scene");
    assert_eq!(cfg.study.loo_folds_for(10), (0..10).collect::<Vec<_>>());
    assert_eq!(cfg.study.loo_folds_for(256).len(), 256);
    let big = cfg.study.loo_folds_for(1105);
    // floor(k 1105 / 256), k = 0..256: first, spacing 4 or 5, last 1100.
    assert_eq!((big.len(), big[0], big[1], big[255]), (256, 0, 4, 1100));
    assert!(big.windows(2).all(|w| (4..=5).contains(&(w[1] - w[0]))), "evenly spaced: {big:?}");
    let text = rope_text().replace("seed = ", "loo_folds = 4\nseed = ");
    let cfg = SceneConfig::from_toml_str(&text, Path::new("rope.toml")).expect("loo_folds = 4 is valid");
    assert_eq!(cfg.study.loo_folds_for(10), vec![0, 2, 5, 7]);
    let text = rope_text().replace("seed = ", "loo_folds = 0\nseed = ");
    assert_names(&load_err(&text), &["study.loo_folds", "is 0"]);
}

/// Every size in a scene file is bounded: an absurd `nx = 1000000000` and its kin are
/// refused with the field, the bound and a fix, before anything is allocated.
#[test]
fn every_size_is_bounded() {
    let ironing = std::fs::read_to_string(scenes_dir().join("ironing-coarse.toml")).expect("scene");
    let hertz = std::fs::read_to_string(scenes_dir().join("hertz.toml")).expect("scene");
    let cases = [
        (ironing.replace("nx = 100", "nx = 1000000000"), "model.ironing.slab.nx"),
        (ironing.replace("ny = 20", "ny = 1000000000"), "model.ironing.slab.ny"),
        (ironing.replace("nx = 30", "nx = 1000000000"), "model.ironing.iron.nx"),
        (hertz.replace("n_arc = 78", "n_arc = 1000000000"), "model.hertz.n_arc"),
        (rope_text().replace("n_elements = 200", "n_elements = 1000000000"), "model.rope.n_elements"),
        (rope_text().replace("n_train = 10", "n_train = 1000000000"), "parameter.n_train"),
        (rope_text().replace("max_iter = ", "max_iter = 1000000000000 # "), "solver.max_iter"),
    ];
    for (text, field) in cases {
        assert!(text.contains("1000000000"), "{field}: the replacement must apply");
        assert_names(&load_err(&text), &[field, "largest accepted"]);
    }
}

#[test]
fn scene_names_that_are_not_plain_directory_names_are_refused() {
    // The name becomes `runs/<name>` and `scenes/<name>` in the store: a separator, a leading dot
    // or a parent reference would escape or hide the directory.
    for bad in ["../escape", "a/b", ".hidden", "with space", "x".repeat(101).as_str()] {
        let text = rope_text().replace("name = \"rope\"", &format!("name = {bad:?}"));
        assert_names(&load_err(&text), &["scene.name", "letters, digits"]);
    }
    let ok = rope_text().replace("name = \"rope\"", "name = \"rope_v2.1-b\"");
    assert!(SceneConfig::from_toml_str(&ok, Path::new("ok.toml")).is_ok());
}

fn hertz_text() -> String {
    let text = std::fs::read_to_string(scenes_dir().join("hertz.toml")).expect("hertz.toml is shipped");
    let cut = text.find("[comparison]").unwrap_or(text.len());
    text[..cut].to_string()
}

/// Every bad `[comparison]` setting is refused with the field and a fix.
#[test]
fn bad_comparison_settings_are_named() {
    let cases: [(&str, &[&str]); 16] = [
        (
            "[comparison]\napproximations = [{ kind = \"local\", cells = [12] }]\n",
            &["comparison.approximations[0].cells[0]", "12 points", "at most 11 cells"],
        ),
        ("[comparison]\napproximations = []\n", &["comparison.approximations", "nothing to compare"]),
        ("[comparison]\nmax_m = 0\napproximations = [{ kind = \"pod\" }]\n", &["comparison.max_m"]),
        (
            "[comparison]\napproximations = [{ kind = \"pod\" }, { kind = \"pod\" }]\n",
            &["comparison.approximations[1]", "once"],
        ),
        (
            "[comparison]\napproximations = [{ kind = \"local\", cells = [] }]\n",
            &["comparison.approximations[0].cells"],
        ),
        (
            "[comparison]\napproximations = [{ kind = \"local\", cells = [4], overlap = -1.0 }]\n",
            &["comparison.approximations[0].overlap"],
        ),
        (
            "[comparison]\napproximations = [{ kind = \"registered\", map = \"moments\", interpolation = \"nodes\", basis = \"pod\" }]\n",
            &["comparison.approximations[0].interpolation", "linear"],
        ),
        (
            "[comparison]\napproximations = [{ kind = \"registered\", map = \"moments\", basis = \"neighbours\" }]\n",
            &["comparison.approximations[0].basis", "interpolation = \"nodes\""],
        ),
        (
            "[comparison]\napproximations = [{ kind = \"registered\", map = \"moments\", basis = \"level-pod\" }]\n",
            &["comparison.approximations[0].basis", "level-pod", "1 parameter component", "basis = \"pod\""],
        ),
        (
            "[comparison]\napproximations = [{ kind = \"registered\", map = \"translate\", basis = \"pod\", primal_translates = 8 }]\n",
            &["comparison.approximations[0].primal_translates", "no online solve", "basis = \"cpg\""],
        ),
        (
            "[comparison]\napproximations = [{ kind = \"registered\", map = \"moments\", basis = \"cpg\", primal_translates = 8 }]\n",
            &["comparison.approximations[0].primal_translates", "map = \"translate\""],
        ),
        (
            "[comparison]\napproximations = [{ kind = \"registered\", map = \"translate\", basis = \"cpg\", primal_translates = 4 }]\n",
            &["comparison.approximations[0].primal_translates", "arc", "remove primal_translates"],
        ),
        (
            "[comparison]\napproximations = [{ kind = \"registered\", map = \"translate\", basis = \"cpg\", primal_translates = 0 }]\n",
            &["comparison.approximations[0].primal_translates", "at least 1"],
        ),
        ("[comparison]\napproximations = [{ kind = \"svd\" }]\n", &["svd"]),
        (
            "[comparison]\napproximations = [{ kind = \"nnmf\", iterations = 10 }, { kind = \"nnmf\" }]\n",
            &["comparison.approximations[1]", "`nnmf`", "entry [0]", "keep one"],
        ),
        (
            "[comparison]\napproximations = [{ kind = \"local\", cells = [2, 2] }]\n",
            &["comparison.approximations[0].cells", "twice"],
        ),
    ];
    for (section, needles) in cases {
        let err = load_err(&format!("{}\n{section}", hertz_text()));
        assert_names(&err, needles);
    }
    let rope = format!(
        "{}\n[comparison]\napproximations = [{{ kind = \"registered\", map = \"translate\", basis = \"pod\" }}]\n",
        rope_text()
    );
    assert_names(&load_err(&rope), &["comparison.approximations[0].map", "no natural map"]);
}

/// `study.contact_sampling`: accepted on a node-to-segment scene, and every bad setting refused
/// with the field and a fix; the rope, whose constraint rows are fixed, refuses it.
#[test]
fn contact_sampling_is_checked() {
    let with =
        |text: &str, setting: &str| text.replace("[study]\n", &format!("[study]\ncontact_sampling = {setting}\n"));
    let good = with(&hertz_text(), "{ tol = 3e-2, ranks = [[8, 8], [12, 7]] }");
    let cfg = SceneConfig::from_toml_str(&good, Path::new("ok.toml")).expect("a valid setting");
    let cs = cfg.study.contact_sampling.expect("parsed");
    assert_eq!((cs.tol, cs.ranks), (3e-2, vec![[8, 8], [12, 7]]));
    let cases = [
        (with(&rope_text(), "{ tol = 3e-2, ranks = [[4, 4]] }"), "study.contact_sampling"),
        (with(&hertz_text(), "{ tol = 1.0, ranks = [[4, 4]] }"), "study.contact_sampling.tol"),
        (with(&hertz_text(), "{ tol = -0.1, ranks = [[4, 4]] }"), "study.contact_sampling.tol"),
        (with(&hertz_text(), "{ tol = nan, ranks = [[4, 4]] }"), "study.contact_sampling.tol"),
        (with(&hertz_text(), "{ tol = 3e-2, ranks = [] }"), "study.contact_sampling.ranks"),
        (with(&hertz_text(), "{ tol = 3e-2, ranks = [[4, 0]] }"), "study.contact_sampling.ranks[0] (r_dual)"),
        (with(&hertz_text(), "{ tol = 3e-2 }"), "ranks"),
    ];
    for (text, field) in cases {
        assert!(text.contains("contact_sampling"), "{field}: the setting must be inserted");
        assert_names(&load_err(&text), &[field]);
    }
}

/// An external scene: `[scene]`, `[model.external]` and `[study]` (the rope's).
fn external_text(model: &str) -> String {
    let rope = rope_text();
    let study = &rope[rope.find("[study]").expect("rope has [study]")..];
    format!("[scene]\nname = \"ext\"\ndescription = \"d\"\n\n[model.external]\n{model}\n{study}")
}

const EXTERNAL: &str = "dual = { file = \"d.h5\", dataset = \"/dual\" }\n\
                        parameters = { file = \"mu.csv\", names = [\"mu\"] }\n\
                        train = [0, 1, 2]\ntest = [3]\n";

#[test]
fn an_external_scene_has_no_parameter_or_solver_and_a_native_one_needs_both() {
    let ext = SceneConfig::from_toml_str(&external_text(EXTERNAL), Path::new("ext.toml")).expect("external scene");
    assert!(ext.parameter.is_unset() && ext.solver.is_unset());
    let e = ext.model.external().expect("external");
    assert_eq!((e.train.as_deref(), e.test.as_deref()), (Some(&[0, 1, 2][..]), Some(&[3][..])));
    // A native scene without [solver] or [parameter] is refused by name, not by a stand-in value.
    let rope = rope_text();
    let solver = rope.find("[solver]").expect("[solver]");
    let study = rope.find("[study]").expect("[study]");
    let no_solver = format!("{}{}", &rope[..solver], &rope[study..]);
    assert_names(&load_err(&no_solver), &["`solver`", "is missing"]);
    let param = rope.find("[parameter]").expect("[parameter]");
    let no_param = format!("{}{}", &rope[..param], &rope[solver..]);
    assert_names(&load_err(&no_param), &["`parameter`", "is missing"]);
}

#[test]
fn external_scene_mistakes_are_named() {
    let with = |extra: &str| load_err(&format!("{}{extra}", external_text(EXTERNAL)));
    assert_names(
        &with("\n[parameter]\nname = \"mu\"\ndescription = \"\"\nmin = 0.0\nmax = 1.0\nn_train = 2\n"),
        &["`parameter`", "is given"],
    );
    assert_names(&with("\n[solver]\nrel_tol = 1e-10\nmax_iter = 10\n"), &["`solver`", "is given"]);
    let both = EXTERNAL.to_string() + "[model.external.test_files]\ndual = { file = \"t.npy\" }\nparameters = { file = \"t.csv\", names = [\"mu\"] }\n";
    assert_names(&load_err(&external_text(&both)), &["model.external.test", "exactly one"]);
    let overlap = EXTERNAL.replace("test = [3]", "test = [2, 3]");
    assert_names(&load_err(&external_text(&overlap)), &["model.external.test", "column 2"]);
    let twice = EXTERNAL.replace("train = [0, 1, 2]", "train = [0, 1, 1]");
    assert_names(&load_err(&external_text(&twice)), &["model.external.train", "twice"]);
    let names = EXTERNAL.replace("names = [\"mu\"]", "names = [\"mu\", \"mu\"]");
    assert_names(&load_err(&external_text(&names)), &["model.external.parameters.names[1]", "repeats"]);
    let tol = EXTERNAL.to_string() + "negative_tolerance = -1.0\n";
    assert_names(&load_err(&external_text(&tol)), &["model.external.negative_tolerance"]);
}

/// `study.model_ranks`: accepted as `[r_primal, r_dual]`, each at least 1; a zero or a wrong
/// shape is refused naming the field.
#[test]
fn model_ranks_are_checked() {
    let with = |setting: &str| rope_text().replace("[study]\n", &format!("[study]\nmodel_ranks = {setting}\n"));
    let cfg = SceneConfig::from_toml_str(&with("[4, 7]"), Path::new("ok.toml")).expect("a valid setting");
    assert_eq!(cfg.study.model_ranks, Some([4, 7]));
    assert_names(&load_err(&with("[0, 7]")), &["study.model_ranks (r_primal)"]);
    assert_names(&load_err(&with("[4, 0]")), &["study.model_ranks (r_dual)"]);
    assert_names(&load_err(&with("[4]")), &["model_ranks"]);
}

/// `study.online_u_tol`: accepted strictly between 0 and 1 (the exact solve's relative stopping
/// distance); 0, 1, a negative value, infinity and NaN are refused naming the field, and an
/// external scene (no online solve) refuses the key.
#[test]
fn the_online_tolerance_is_checked() {
    let with = |setting: &str| rope_text().replace("[study]\n", &format!("[study]\nonline_u_tol = {setting}\n"));
    let cfg = SceneConfig::from_toml_str(&with("1e-6"), Path::new("ok.toml")).expect("a valid setting");
    assert_eq!(cfg.study.online_u_tol.map(f64::to_bits), Some(1e-6f64.to_bits()));
    let plain = SceneConfig::from_toml_str(&rope_text(), Path::new("ok.toml")).expect("rope");
    assert_eq!(plain.study.online_u_tol, None, "absent unless given");
    for bad in ["0.0", "1.0", "-1e-6", "inf", "nan", "2.0"] {
        assert_names(&load_err(&with(bad)), &["study.online_u_tol"]);
    }
    let ext = external_text(EXTERNAL).replace("[study]\n", "[study]\nonline_u_tol = 1e-6\n");
    assert_names(&load_err(&ext), &["study.online_u_tol", "no online solve"]);
}

/// A stored model carries a registered CPG on the moments map over one parameter component and
/// over several (its table keeps each training point's components): `study.model_dual` naming
/// it is accepted on ironing-fine-2d and on hertz; naming the registered POD of the same map is
/// refused with the storable names.
#[test]
fn model_dual_takes_a_moments_map_over_a_vector_parameter() {
    let text = std::fs::read_to_string(scenes_dir().join("ironing-fine-2d.toml")).expect("shipped");
    assert!(text.contains("map = \"moments\", refine = 16, basis = \"cpg\""), "the shipped entry moved");
    let pin = |text: &str, name: &str| {
        let seed = text.lines().find(|l| l.starts_with("seed = ")).expect("a seed line").to_string();
        let pinned = text.replace(&seed, &format!("{seed}\nmodel_dual = \"{name}\""));
        assert_ne!(pinned, text);
        pinned
    };
    let cfg = SceneConfig::from_toml_str(&pin(&text, "registered-moments-cpg"), Path::new("ok.toml"))
        .expect("a moments map over two components is storable");
    assert_eq!(cfg.study.model_dual.as_deref(), Some("registered-moments-cpg"));
    let err = load_err(&pin(&text, "registered-moments-pod"));
    assert_names(&err, &["study.model_dual", "registered-moments-cpg"]);
    let one = std::fs::read_to_string(scenes_dir().join("hertz.toml")).expect("shipped");
    assert!(one.contains("map = \"moments\"") && one.contains("basis = \"cpg\""), "hertz's moments CPG entry moved");
    SceneConfig::from_toml_str(&pin(&one, "registered-moments-cpg"), Path::new("ok.toml"))
        .expect("a moments map over one component is storable");
}
