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


_FIT_PROBE = ("<script>window.addEventListener('load', function () {"
              "var w = document.querySelectorAll('.table-wrap'), s = [];"
              "for (var i = 0; i < w.length; i++) s.push(w[i].scrollWidth - w[i].clientWidth);"
              "var im = document.images, iw = [];"
              "for (var j = 0; j < im.length; j++) iw.push(im[j].naturalWidth - im[j].width);"
              "var d = document.createElement('div'); d.id = 'rlgsim-fit';"
              "d.textContent = 'overflow ' + s.join(',') + ' images ' + iw.join(',');"
              "document.body.appendChild(d); });</script>")


def _fit(tmp_path, html: str, width: int) -> tuple[list[int], list[int]]:
    page = tmp_path / f"report{width}.html"
    page.write_text(html.replace("</body>", _FIT_PROBE + "</body>"), encoding="utf-8")
    r = _chromium(tmp_path, f"--window-size={width},900", "--virtual-time-budget=5000",
                  "--dump-dom", page.as_uri())
    assert r.returncode == 0, r.stderr[-2000:]
    m = re.search(r"overflow ([-\d,]*) images ([\d,]*)", r.stdout)
    assert m, r.stdout[-500:]
    ints = lambda t: [int(x) for x in t.split(",") if x]          # noqa: E731
    return ints(m.group(1)), ints(m.group(2))


@pytest.mark.skipif(not CHROMIUM.exists(), reason=SKIP_REASON)
def test_monte_carlo_tables_unclipped_at_1280_and_figures_full_size_at_1920(tmp_path):
    """The Monte Carlo summary (its real columns) fits a 1280 px window without scrolling,
    and a 1600 px six-panel figure is shown at its own size in a 1920 px window."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    rep = Report("layout")
    cols = ["compensator", "metric", "unit", "units", "median", "p5", "p95", "beats baseline"]
    rows = [["IR-LSSVM (Hampel) T, dT/dt, U", "resid_std_true@test2", "°/h", 200,
             1.234567e-3, 9.87654e-4, 2.345678e-3, 0.975]] * 6
    rep.table(Table("Distributions", cols, rows))
    scores = ["compensator", "stability_before", "stability_after", "improvement_pct",
              "improvement_factor", "rmse_true", "mae_true", "resid_std_true",
              "law_resid_std", "r2_true", "fit_s"]
    rep.table(Table("Truth-based scores", scores,
                    [["IR-LSSVM (Myriad) T, dT/dt, U", *[1.234567e-3 * k for k in range(10)]]]
                    * 8))
    params = [f"gyro.bias.gradients[{k}].coeff_deg_per_h_per_k" for k in range(5)] + [
        "thermal.rlg_block.internal_conductance", "uhfo.c1_v_per_k", "noise.gyro_arw"]
    rep.table(Table("Worst units: LSSVM T, dT/dt, U", ["unit", "resid_std_true", *params],
                    [[u, 1.234567e-3, *[1.234567e-5 * k for k in range(len(params))]]
                     for u in range(5)]))
    fig, _ = plt.subplots(2, 3, figsize=(14.5, 8))        # ~1600 px at the report's dpi
    rep.figure(fig, "six", "six panels")
    html = rep.html()
    overflow, _ = _fit(tmp_path, html, 1280)
    assert overflow and max(overflow) <= 0, overflow
    _, shrunk = _fit(tmp_path, html, 1920)
    assert shrunk == [0], shrunk                  # shown at its natural width
