//! End-to-end: hostile scene files. A scene name that tries to leave the
//! store is refused before anything is written, even with a setting that makes every solve fail
//! (which would otherwise write `runs/<name>/solver_failures.parquet`); HTML in the scene's
//! strings reaches the report escaped.

mod common;

use std::path::Path;

use common::{crom, text, variant};

/// Every file and directory under `dir`, relative to it.
fn tree(dir: &Path) -> Vec<String> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).expect("read_dir").flatten() {
            let p = e.path();
            out.push(p.strip_prefix(dir).expect("inside").display().to_string());
            if p.is_dir() && !p.is_symlink() {
                stack.push(p);
            }
        }
    }
    out.sort();
    out
}

#[test]
fn a_scene_name_cannot_lead_outside_the_store() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    let deep = tmp.path().join("a/b/c");
    std::fs::create_dir_all(&deep).expect("mkdir");
    let store = deep.join("store");
    for name in ["../../../escaped", "../x", "runs/../../y", ".hidden"] {
        let scene = variant(
            &deep,
            "rope",
            "hostile.toml",
            &[("name = \"rope\"", &format!("name = {name:?}")), ("max_iter = 100", "max_iter = 1")],
        );
        let out = crom(&store, &["--quiet", "run", scene.to_str().expect("utf-8")]);
        assert_eq!(out.status.code(), Some(2), "{name}: {}", text(&out));
        assert!(text(&out).contains("scene.name"), "{name}: the error names the field: {}", text(&out));
        assert_eq!(tree(tmp.path()), ["a", "a/b", "a/b/c", "a/b/c/hostile.toml"], "{name}: something was written");
    }
}

#[test]
fn html_in_scene_strings_is_escaped_in_the_report() {
    let tmp = crom_pipeline::scratch::tempdir().expect("tempdir");
    let store = tmp.path().join("store");
    let scene = variant(
        tmp.path(),
        "rope",
        "rope.toml",
        &[
            (
                "description = \"1-D elastic rope pressed by a distributed load onto a parametrised rigid obstacle\"",
                "description = \"<script>alert(1)</script> & co\"",
            ),
            ("description = \"slope of the obstacle\"", "description = \"<img src=x onerror=alert(2)>\""),
        ],
    );
    let out = crom(&store, &["--quiet", "run", scene.to_str().expect("utf-8")]);
    assert!(out.status.success(), "{}", text(&out));
    let html = std::fs::read_to_string(store.join("scenes/rope/report/index.html")).expect("report");
    assert!(html.contains("&lt;script&gt;alert(1)&lt;/script&gt; &amp; co"), "description escaped");
    assert!(html.contains("&lt;img src=x onerror=alert(2)&gt;"), "parameter description escaped");
    assert!(!html.contains("<script>alert") && !html.contains("<img src=x"), "raw HTML from the scene file");
}
