"""Report HTML at 1280 px in headless Chromium: no table makes the page wider than the window
(a wide table scrolls inside its box, long cells wrap)."""

from __future__ import annotations

import re

import pytest

from html_render import CHROMIUM, SKIP_REASON, _chromium
from rlgsim.lab.report import Report, Table

_WIDTH_PROBE = ("<script>window.addEventListener('load', function () {"
                "var d = document.createElement('div'); d.id = 'rlgsim-width';"
                "d.textContent = 'page ' + document.documentElement.scrollWidth + ' window ' +"
                " window.innerWidth; document.body.appendChild(d); });</script>")


@pytest.mark.skipif(not CHROMIUM.exists(), reason=SKIP_REASON)
def test_wide_tables_stay_inside_a_1280_px_window(tmp_path):
    rep = Report("layout")
    rep.table(Table("many columns", [f"column number {i}" for i in range(40)],
                    [[1.234567e-5 * i for i in range(40)]]))
    rep.table(Table("long text", ["compensator", "note"],
                    [["IR-LSSVM (Hampel) T, dT/dt, U", "a very long note " * 40]]))
    html = rep.html()
    assert html.count("class='table-wrap'") == 2
    page = tmp_path / "report.html"
    page.write_text(html.replace("</body>", _WIDTH_PROBE + "</body>"), encoding="utf-8")
    r = _chromium(tmp_path, "--window-size=1280,900", "--virtual-time-budget=5000",
                  "--dump-dom", page.as_uri())
    assert r.returncode == 0, r.stderr[-2000:]
    m = re.search(r"page (\d+) window (\d+)", r.stdout)
    assert m, r.stdout[-500:]
    assert int(m.group(1)) <= int(m.group(2)) <= 1280
