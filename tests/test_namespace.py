"""One import namespace: everything installs under ``rlgsim``; nothing generic at the top."""

from __future__ import annotations

import subprocess
import sys


def test_import_rlgsim_exposes_version_and_entry_points():
    import rlgsim
    assert isinstance(rlgsim.__version__, str) and rlgsim.__version__
    for name in rlgsim.__all__:
        assert getattr(rlgsim, name) is not None, name


def test_no_generic_top_level_package_is_installed(tmp_path):
    """From a clean folder (``-I``: no current folder, no PYTHONPATH on the path), none of the
    generic names is importable, and ``rlgsim``'s subpackages are."""
    code = ("import importlib.util as u; "
            "print(sorted(n for n in ('sim', 'estimators', 'scenarios') if u.find_spec(n))); "
            "import rlgsim.sim, rlgsim.estimators, rlgsim.scenarios, rlgsim.ground")
    proc = subprocess.run([sys.executable, "-I", "-c", code], cwd=tmp_path, capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "[]"


def test_a_user_file_named_sim_does_not_break_the_api(tmp_path):
    (tmp_path / "sim.py").write_text("raise SystemExit('the user sim.py was imported')\n")
    (tmp_path / "estimators.py").write_text("raise SystemExit('the user estimators.py')\n")
    code = ("from rlgsim.sim.run.scenario import load_scenario; "
            "from rlgsim.estimators.metrics import bias_stability; "
            "print(load_scenario('quickstart').name)")
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "quickstart"


def test_python_dash_m_rlgsim_is_the_command(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "rlgsim", "list"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "quickstart" in proc.stdout
