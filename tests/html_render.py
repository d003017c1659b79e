"""Render a report.html in headless Chromium for the study tests: count the figures that
loaded (a script appended to a copy of the page) and take a screenshot."""

from __future__ import annotations

import pathlib
import subprocess

import numpy as np

CHROMIUM = pathlib.Path("/usr/bin/chromium")
SKIP_REASON = ("headless Chromium is not installed (/usr/bin/chromium missing; "
               "apt-get install chromium)")

_IMAGE_CHECK = (
    "<script>window.addEventListener('load', function () {"
    "var im = document.images, ok = 0;"
    "for (var i = 0; i < im.length; i++) {"
    " if (im[i].complete && im[i].naturalWidth > 0 &&"
    "     im[i].getAttribute('src').indexOf('data:image/png;base64,') === 0) ok++; }"
    "var d = document.createElement('div'); d.id = 'rlgsim-image-check';"
    "d.textContent = 'images ' + im.length + ' loaded ' + ok;"
    "document.body.appendChild(d); });</script>")


def _chromium(tmp_path: pathlib.Path, *args: str) -> subprocess.CompletedProcess:
    profile = tmp_path / f"profile{len(list(tmp_path.glob('profile*')))}"
    return subprocess.run(
        [str(CHROMIUM), "--headless", "--no-sandbox", "--disable-gpu",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--no-first-run", f"--user-data-dir={profile}", *args],
        capture_output=True, text=True, timeout=90)


def check_report_renders(report_html: pathlib.Path, tmp_path: pathlib.Path,
                         min_figures: int) -> None:
    """Every embedded figure of ``report_html`` loads in Chromium (at least ``min_figures``),
    and a 1200×3000 screenshot of the page shows text, tables and plots, not a blank page."""
    html = report_html.read_text()
    n_figures = html.count("<img ")
    assert n_figures >= min_figures
    probe = tmp_path / "probe.html"
    probe.write_text(html.replace("</body>", _IMAGE_CHECK + "</body>"))
    r = _chromium(tmp_path, "--virtual-time-budget=10000", "--dump-dom", probe.as_uri())
    assert r.returncode == 0, r.stderr[-2000:]
    assert f"images {n_figures} loaded {n_figures}" in r.stdout
    shot = tmp_path / "shot.png"
    r = _chromium(tmp_path, f"--screenshot={shot}", "--window-size=1200,3000",
                  report_html.as_uri())
    assert r.returncode == 0 and shot.is_file(), r.stderr[-2000:]
    from PIL import Image
    img = np.asarray(Image.open(shot).convert("L"), dtype=float)
    assert img.shape == (3000, 1200)
    assert img.std() > 10
    assert (img < 128).mean() > 0.01
