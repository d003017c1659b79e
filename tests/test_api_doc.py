"""docs/api.md runs as written: every ```python block in order, in one namespace, in an empty
folder; the printed output of each block must equal the ```text block that follows it."""

from __future__ import annotations

import contextlib
import io
import pathlib
import re

DOC = pathlib.Path(__file__).resolve().parent.parent / "docs" / "api.md"
_BLOCK = re.compile(r"^```(\w*)\n(.*?)^```\s*$", re.S | re.M)


def blocks() -> list[tuple[str, str | None]]:
    """(code, expected output or None) of every python block of the tutorial."""
    found = [(m.group(1), m.group(2)) for m in _BLOCK.finditer(DOC.read_text(encoding="utf-8"))]
    out = []
    for i, (lang, body) in enumerate(found):
        if lang != "python":
            continue
        nxt = found[i + 1] if i + 1 < len(found) else None
        out.append((body, nxt[1] if nxt is not None and nxt[0] == "text" else None))
    return out


def test_tutorial_runs_and_prints_what_it_shows(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code = blocks()
    assert len(code) >= 6
    namespace: dict = {"__name__": "__tutorial__"}
    for i, (body, expected) in enumerate(code):
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            exec(compile(body, f"{DOC.name} block {i + 1}", "exec"), namespace)
        if expected is not None:
            assert buf.getvalue() == expected, f"block {i + 1} of {DOC.name} printed:\n" \
                                               f"{buf.getvalue()}"
