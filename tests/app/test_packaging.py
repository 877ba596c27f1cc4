"""The wheel built from the repo carries the icons as package data, found through
importlib.resources (even from a zip), and the CLI reports its version."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SKIP_DIRS = {".venv", "build", "dist", ".git", "__pycache__", ".ruff_cache", ".hypothesis",
             ".grimp_cache", ".import_linter_cache", ".pytest_cache", ".mypy_cache", "tests"}


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    uv = shutil.which("uv")
    if uv is None:
        pytest.skip("uv is not installed (bash .ci/setup installs it)")
    src = tmp_path_factory.mktemp("src")
    shutil.copytree(ROOT, src, dirs_exist_ok=True,
                    ignore=lambda _d, names: [n for n in names if n in SKIP_DIRS
                                              or n.endswith(".egg-info")])
    out = tmp_path_factory.mktemp("wheel")
    proc = subprocess.run([uv, "build", "--wheel", "-q", "-o", str(out), str(src)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    (whl,) = out.glob("studiotrack-*.whl")
    return whl


def test_wheel_ships_every_asset(wheel: Path) -> None:
    names = set(zipfile.ZipFile(wheel).namelist())
    assets = [p.relative_to(ROOT).as_posix() for p in (ROOT / "app" / "assets").rglob("*")
              if p.is_file()]
    assert "app/assets/icons/live.svg" in assets
    assert [a for a in assets if a not in names] == []


def test_icons_load_through_importlib_resources_from_the_zipped_wheel(wheel: Path) -> None:
    code = (
        "import app, app.icons as i; assert '.whl' in app.__file__, app.__file__; "
        "assert i.asset('icons/live.svg').read_bytes().startswith(b'<svg'); "
        "assert i.asset_path('icons/page.svg').read_bytes().startswith(b'<svg'); "
        "assert not i.has_asset('icons/nope.svg')"
    )
    env = {**os.environ, "PYTHONPATH": str(wheel), "QT_QPA_PLATFORM": "offscreen"}
    proc = subprocess.run([sys.executable, "-c", code], cwd=wheel.parent, env=env,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_version_option(capsys: pytest.CaptureFixture[str]) -> None:
    from app import __version__
    from app.cli import main

    assert main(["--version"]) == 0  # main returns the exit code (the script sys.exit()s it)
    assert capsys.readouterr().out.strip() == f"studiotrack {__version__}"
    assert __version__[0].isdigit()
