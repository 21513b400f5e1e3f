"""A shipped scene with edits, written as a new scene file: shared by the benchmark and stress
scripts (`from scene_variant import variant`)."""
import pathlib
import re

REPO = pathlib.Path(__file__).resolve().parents[1]


def drop_section(text, section):
    """`text` without the TOML table `[section]` (its header line to the next top-level table
    header or the end)."""
    out, skipping = [], False
    for line in text.splitlines(keepends=True):
        head = line.strip()
        if head.startswith("["):
            skipping = head == f"[{section}]" or head.startswith(f"[{section}.") or head.startswith(f"[[{section}")
        if not skipping:
            out.append(line)
    return "".join(out)


def variant(tmp, base, name, edits, drop=()):
    """`data/scenes/<base>.toml` with every `(old, new)` of `edits` applied (each `old` must be
    present; every occurrence is replaced), the tables in `drop` removed (e.g. `comparison`, for
    the paper's study alone, with the `study.model_dual` and `model_ranks` that pin a stored
    model to one of its entries) and the scene renamed `name`; its path in `tmp`."""
    text = (REPO / "data" / "scenes" / f"{base}.toml").read_text()
    for section in drop:
        assert f"[{section}]" in text, f"{base}.toml has no [{section}]: update the script's drops"
        text = drop_section(text, section)
    if "comparison" in drop:
        # a stored model pinned to a comparison entry goes with the comparison
        text = re.sub(r"(?m)^model_(dual|ranks) = .*\n", "", text)
    for a, b in edits:
        assert a in text, f"{base}.toml has no `{a}`: update the script's edits"
        text = text.replace(a, b)
    text = re.sub(r'name = "[^"]+"', f'name = "{name}"', text, count=1)
    path = pathlib.Path(tmp) / f"{name}.toml"
    path.write_text(text)
    return path
