"""Check the documentation's links: every relative link in README.md, docs/*.md and
python/README.md must name an existing file, and an anchor (`file.md#heading`) an existing
heading of that file. Also checks the `docs/<page>.md#<anchor>` pointers in source comments.

    python3 scripts/check_links.py          # prints each broken link; exit 1 if any
"""
import pathlib
import re
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent
PAGES = [ROOT / "README.md", ROOT / "python" / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
SOURCES = ["*.rs", "*.py", "*.toml", "*.md", "justfile"]
LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")
POINTER = re.compile(r"\bdocs/([A-Za-z0-9_.-]+\.md)(#[A-Za-z0-9_-]+)?")


def slug(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return text.replace(" ", "-")


def anchors(path: pathlib.Path) -> set[str]:
    seen: dict[str, int] = {}
    out = set()
    in_code = False
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith("```"):
            in_code = not in_code
        m = None if in_code else re.match(r"#{1,6}\s+(.*)", line)
        if m:
            s = slug(m.group(1))
            n = seen.get(s, 0)
            seen[s] = n + 1
            out.add(s if n == 0 else f"{s}-{n}")
    return out


def check(target: pathlib.Path, anchor: str | None, where: str) -> list[str]:
    if not target.exists():
        return [f"{where}: {target.relative_to(ROOT) if target.is_relative_to(ROOT) else target} does not exist"]
    if anchor and target.suffix == ".md" and anchor not in anchors(target):
        return [f"{where}: no heading #{anchor} in {target.relative_to(ROOT)}"]
    return []


def main() -> int:
    errors = []
    for page in PAGES:
        in_code = False
        for no, line in enumerate(page.read_text(encoding="utf-8").splitlines(), 1):
            if line.startswith("```"):
                in_code = not in_code
            if in_code:
                continue
            for url in LINK.findall(line):
                if re.match(r"[a-z]+:", url):
                    continue  # http(s), mailto: not checked
                file, _, anchor = url.partition("#")
                target = page if not file else (page.parent / file).resolve()
                errors += check(target, anchor or None, f"{page.relative_to(ROOT)}:{no}")
    for pattern in SOURCES:
        for src in ROOT.rglob(pattern):
            if "target" in src.relative_to(ROOT).parts or ".git" in src.parts:
                continue
            for no, line in enumerate(src.read_text(encoding="utf-8", errors="replace").splitlines(), 1):
                for name, anchor in POINTER.findall(line):
                    errors += check(ROOT / "docs" / name, anchor[1:] or None, f"{src.relative_to(ROOT)}:{no}")
    for e in errors:
        print(e)
    print(f"check_links: {len(errors)} broken" if errors else "check_links: ok")
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main())
