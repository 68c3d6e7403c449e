"""docs/python.md is a script: its ```python blocks run in order, in a fresh folder, so the page cannot rot.
A block fenced ```python no-run (one that needs a server, like the Console example) is shown, not run;
it must still compile."""
import os
import re

DOC = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "docs", "python.md")


def blocks(text):
    """[(info string after ```python, code)] of every python block, in order."""
    return re.findall(r"^```python([^\n]*)\n(.*?)^```", text, flags=re.S | re.M)


def test_the_worked_analysis_runs(fpss, source_dir, tmp_path, monkeypatch):
    found = blocks(open(DOC, encoding="utf-8").read())
    code = [c for info, c in found if "no-run" not in info.split()]
    shown = [c for info, c in found if "no-run" in info.split()]
    assert len(code) >= 5
    for k, block in enumerate(shown, 1):
        compile(block, f"docs/python.md no-run block {k}", "exec")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("FPSS_STAND_BIN", fpss.binary)
    monkeypatch.setenv("FPSS_SOURCE_DIR", source_dir)
    namespace = {"__name__": "__docs__"}
    for k, block in enumerate(code, 1):
        exec(compile(block, f"docs/python.md block {k}", "exec"), namespace)
    assert namespace["refit"].json["method"] == "differences"
