"""The checkout itself: no file names a path of one machine, no code cites an issue number.

A path such as ``/work/main/...``, ``/home/alice/...``, ``/root/...``, ``/Users/alice/...``,
``C:\\Users\\alice\\...`` or a temporary folder ``/tmp/xyz...`` is where one person ran something;
on any other machine it names nothing. Docs and scripts name files relative to the repository
root instead (``docs/...``, ``out/...``) and stand-ins for the rest (``$TMP``, ``$REPO``,
``~/.cache/...``). System paths that are the same on every Debian 12 machine (``/usr/bin/python3``,
``/etc/...``, ``/dev/...``) are fine and not looked for.

Issue numbers (``issue 13``, ``issue #4``) mean nothing to a reader of the code or the docs without
the tracker; say what is meant instead (e.g. "the mesh-independence study").
"""
from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
THIS = Path(__file__).resolve()

# An absolute path starts a token: at the start of a line or after a space, a quote, a backtick,
# a bracket, '=', ':' or ','. Relative paths (docs/work/..., out/tmp/...) are not matched.
_START = r"(?:^|(?<=[\s'\"`(\[{<=:,]))"
MACHINE_PATH = re.compile(
    _START + r"(?:"
    r"/work/"                              # a work tree of one machine (/work/main, /work/ens, ...)
    r"|/root/"                             # root's home
    r"|/home/[A-Za-z0-9_.-]+/"             # a user's home
    r"|/Users/[A-Za-z0-9_. -]+/"           # a user's home on macOS
    r"|/tmp/[A-Za-z0-9_.-]+"               # one run's temporary folder
    r"|/mnt/[A-Za-z0-9_.-]+/"              # a mounted disk of one machine
    r")"
    r"|[A-Za-z]:\\{1,2}Users\\{1,2}",       # a user's home on Windows, C:\Users\ (also escaped)
    re.MULTILINE)

ISSUE_NUMBER = re.compile(r"issue\s*#?\d+", re.IGNORECASE)


def _tracked_files() -> list[Path]:
    """The checkout's tracked files that exist in the work tree (a file deleted but not yet
    committed is skipped); skips the test when git or the checkout is missing."""
    git = shutil.which("git")
    if git is None:
        pytest.skip("git is not installed")
    try:
        out = subprocess.run([git, "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True).stdout
    except subprocess.CalledProcessError:
        pytest.skip(f"{ROOT} is not a git checkout")
    files = []
    for name in out.decode("utf-8", "surrogateescape").split("\0"):
        if not name or name.startswith(".venv/") or "/.venv/" in name:
            continue
        path = ROOT / name
        if path.is_file() and path.resolve() != THIS:
            files.append(path)
    if not files:
        pytest.skip("git lists no files")
    return files


def _text(path: Path) -> str | None:
    """The file's text, or None for a binary file (a NUL byte, or not UTF-8)."""
    data = path.read_bytes()
    if b"\0" in data[:8192]:
        return None
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return None


def _hits(paths, pattern: re.Pattern) -> list[str]:
    """'file:line: text' of every match of pattern in the text files among paths."""
    hits = []
    for path in paths:
        text = _text(path)
        if text is None:
            continue
        for m in pattern.finditer(text):
            line_no = text.count("\n", 0, m.start()) + 1
            line = text.splitlines()[line_no - 1].strip()
            hits.append(f"{path.relative_to(ROOT)}:{line_no}: {line[:160]}")
    return hits


def test_no_tracked_file_names_a_path_of_one_machine():
    hits = _hits(_tracked_files(), MACHINE_PATH)
    assert not hits, ("paths of one machine in tracked files (name them relative to the repository "
                      "root, or as $TMP / $REPO / ~):\n" + "\n".join(hits))


def test_no_issue_numbers_in_the_package():
    paths = sorted(p for p in (ROOT / "fabric_fenicsx").rglob("*.py") if "__pycache__" not in p.parts)
    assert paths, "no package sources found"
    hits = _hits(paths, ISSUE_NUMBER)
    assert not hits, "issue numbers in the package (say what is meant instead):\n" + "\n".join(hits)


def test_no_issue_numbers_in_the_readme_and_docs():
    paths = [ROOT / "README.md"] + sorted((ROOT / "docs").rglob("*.md"))
    hits = _hits([p for p in paths if p.is_file()], ISSUE_NUMBER)
    assert not hits, "issue numbers in the README or docs (say what is meant instead):\n" + "\n".join(hits)


@pytest.mark.parametrize("text, flagged", [
    ("cd /work/main && make", True),
    ("sys.path.insert(0, '/work/ens')", True),
    ("no such file (/home/alice/x.toml)", True),
    ("`/root/.cache/fabric_fenicsx`", True),
    ("written to /tmp/fabric-faults-nlh5e2sf/out", True),
    ("open('/Users/bob/run')", True),
    ("C:\\Users\\bob\\run", True),
    ("PY := /usr/bin/python3", False),
    ("docs/convergence/runs/ and out/tmp/x", False),
    ("~/.cache/fabric_fenicsx", False),
    ("$TMP/ro-out is not writable", False),
    ("a network/work/ folder", False),
])
def test_the_machine_path_pattern(text, flagged):
    assert bool(MACHINE_PATH.search(text)) is flagged
