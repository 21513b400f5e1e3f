"""A shipped scene with edits, written as a new scene file: shared by the benchmark and stress
scripts (`from scene_variant import variant`)."""
import pathlib
import re

REPO = pathlib.Path(__file__).resolve().parents[1]


def variant(tmp, base, name, edits):
    """`data/scenes/<base>.toml` with every `(old, new)` of `edits` applied (each `old` must be
    present; every occurrence is replaced) and the scene renamed `name`; its path in `tmp`."""
    text = (REPO / "data" / "scenes" / f"{base}.toml").read_text()
    for a, b in edits:
        assert a in text, f"{base}.toml has no `{a}`: update the script's edits"
        text = text.replace(a, b)
    text = re.sub(r'name = "[^"]+"', f'name = "{name}"', text, count=1)
    path = pathlib.Path(tmp) / f"{name}.toml"
    path.write_text(text)
    return path
