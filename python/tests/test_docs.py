"""docs/python.md is a script: its ```python blocks run in order, in a fresh folder, so the page cannot rot."""
import os
import re

DOC = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "docs", "python.md")


def blocks(text):
    return re.findall(r"^```python\n(.*?)^```", text, flags=re.S | re.M)


def test_the_worked_analysis_runs(fpss, source_dir, tmp_path, monkeypatch):
    code = blocks(open(DOC, encoding="utf-8").read())
    assert len(code) >= 5
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("FPSS_STAND_BIN", fpss.binary)
    monkeypatch.setenv("FPSS_SOURCE_DIR", source_dir)
    namespace = {"__name__": "__docs__"}
    for k, block in enumerate(code, 1):
        exec(compile(block, f"docs/python.md block {k}", "exec"), namespace)
    assert namespace["refit"].json["method"] == "differences"
