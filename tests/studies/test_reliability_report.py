"""The reliability harness (tests/tools) writes no path of one machine: the temporary folder
of a case becomes ``$TMP`` and the checkout ``$REPO`` in what it records, and the report it
writes passes the repository's machine-path check (tests/test_repo_hygiene.py)."""
import tempfile
from pathlib import Path

from tests.test_repo_hygiene import MACHINE_PATH
from tests.tools import reliability
from tests.tools.fault_harness import ROOT, scrub


def test_scrub_replaces_the_temporary_folder_and_the_checkout():
    with tempfile.TemporaryDirectory(prefix="fabric-faults-") as tmp:
        row = {"message": f"output folder '{tmp}/out' is in use; see {ROOT}/demos/scenes/y90.toml",
               "seconds": 1.5, "rows": [f"{Path(tmp).resolve()}/a"]}
        clean = scrub(row, tmp)
    assert clean == {"message": "output folder '$TMP/out' is in use; see $REPO/demos/scenes/y90.toml",
                     "seconds": 1.5, "rows": ["$TMP/a"]}


def test_the_report_names_no_machine_path(tmp_path, monkeypatch):
    with tempfile.TemporaryDirectory(prefix="fabric-faults-") as tmp:
        rows = scrub([{"check": "x", "message (first line)": f"in use: {tmp}/study-held"}], tmp)
    table = reliability.markdown_table(rows)
    monkeypatch.setattr(reliability, "faults_sections", lambda: (table, table, table))
    res = {"date": "2000-01-01", "machine": "m, 2 cores", "code": {"git_head": "abc", "model_version": "v"},
           "out": str(ROOT / "out" / "reliability"), "versions": ["v"],
           "impact": [{"velocity": 57.3, "completed": False, "returncode": 1,
                       "log_tail": f"fabric-fenicsx impact: output in {ROOT}/out/x\n"}]}
    doc = tmp_path / "reliability.md"
    reliability.write_report(res, doc)
    text = doc.read_text()
    assert not MACHINE_PATH.search(text), MACHINE_PATH.search(text)
    assert "`$REPO/out/reliability/reliability.json`" in text and "$TMP/study-held" in text
    assert "## What this checks and how to re-run it" in text
    assert "## Shared folders, runaway sizes and full disks" in text
