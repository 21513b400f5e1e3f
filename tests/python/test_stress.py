"""The fast subset of the stress matrix (`scripts/stress.py --fast`, the whole matrix
is `just stress`): first touch and grazing contact, hertz against Hertz theory, a deep press
near the sole's corners, a stiffness contrast of 1e6 and 1e-3, a 5 x 1 slab mesh run to the
end, a mesh beyond the machine refused by the memory estimate, and the reduced solve on nearly
parallel dual vectors with primal ranks 1-3. Each case's
expectation is stated in the script (a formula or the KKT conditions on the stored fields);
every case must pass or be refused with a reason, and no artifact may hold NaN."""
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
    assert all(r.rstrip(" |").endswith("pass") or "refused" in r for r in rows), p.stdout
