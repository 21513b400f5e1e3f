"""The fast subset of the stress matrix (`scripts/stress.py --fast`, the whole matrix
is `just stress`): first touch and grazing contact, hertz against Hertz theory, a deep press
near the sole's corners, a stiffness contrast of 1e6 and 1e-3, a 5 x 1 slab mesh run to the
end, a mesh beyond the machine refused by the memory estimate, and the reduced solve on nearly
parallel dual vectors with primal ranks 1-3. Each case's
expectation is stated in the script (a formula or the KKT conditions on the stored fields);
every case must pass or be refused with a reason, and no artifact may hold NaN."""
import importlib.util
import os
import pathlib
import subprocess
import sys

REPO = pathlib.Path(__file__).resolve().parents[2]


def test_fast_stress_matrix_passes():
    env = dict(os.environ)
    env["CROM_BIN"] = str(pathlib.Path(os.environ.get("CROM_BIN", REPO / "target" / "release" / "crom")).resolve())
    p = subprocess.run([sys.executable, str(REPO / "scripts" / "stress.py"), "--fast"], cwd=REPO, env=env,
                       capture_output=True, text=True, timeout=1200)
    assert p.returncode == 0, p.stdout + p.stderr
    rows = [l for l in p.stdout.splitlines() if l.startswith("| ") and not l.startswith("| case")]
    assert len(rows) >= 6, p.stdout
    # each row's verdict is what its expectation says: an answer, or a refusal it asks for
    for r in rows:
        cells = [c.strip() for c in r.strip().strip("|").split(" | ")]
        expect, got = cells[1].split("]")[0].lstrip("["), cells[-1]
        assert expect in ("pass", "refused", "either"), r
        ok = {"pass": got == "pass", "refused": got.startswith("refused (exit"),
              "either": got == "pass" or got.startswith("refused (exit")}[expect]
        assert ok, r


def _stress():
    spec = importlib.util.spec_from_file_location("stress", REPO / "scripts" / "stress.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_a_refusal_is_a_fail_where_an_answer_is_expected():
    """The harness's verdicts, case by case: a refusal with a reason passes only where the case
    asks for it (or allows either); an answer where a refusal is asked for, a refusal without the
    field or after writing the store, and an exit without a reason are FAILs."""
    v = _stress().verdict
    refusal = "error: bad.toml: field `parameter.n_train` is 1\n  fix: give at least 2"
    assert v("pass", 0, "", []) == "pass"
    assert v("pass", 0, "", ["KKT 1e-3"]).startswith("FAIL")
    assert v("pass", 2, refusal, []).startswith("FAIL: refused, though the case should be answered")
    assert v("refused", 2, refusal, [], "parameter.n_train") == "refused (exit 2)"
    assert v("refused", 2, refusal, [], "parameter.n_train", store_exists=True).startswith("FAIL")
    assert v("refused", 2, refusal, [], "parameter.max").startswith("FAIL")
    assert v("refused", 0, "", []).startswith("FAIL: answered")
    assert v("either", 2, refusal, []) == "refused (exit 2)" and v("either", 0, "", []) == "pass"
    assert v("pass", 101, "thread 'main' panicked", []).startswith("FAIL: no answer and no reason")
