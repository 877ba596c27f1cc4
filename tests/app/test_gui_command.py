"""``studiotrack gui`` end to end in a subprocess (offscreen): quit-after, screenshot, errors."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from tests.app.conftest import REAL_TRACKER


def _studiotrack(tmp_path: Path, *args: str) -> subprocess.CompletedProcess[str]:
    env = {
        **os.environ,
        "QT_QPA_PLATFORM": "offscreen",
        "STUDIOTRACK_SETTINGS": str(tmp_path / "settings.ini"),
    }
    return subprocess.run(
        [sys.executable, "-m", "app", *args],
        capture_output=True,
        text=True,
        timeout=240,
        env=env,
        check=False,
    )


def test_gui_quits_after_n_frames_and_saves_a_screenshot(tmp_path: Path) -> None:
    import cv2

    png = tmp_path / "shots" / "live.png"
    proc = _studiotrack(
        tmp_path,
        "gui",
        "--source",
        "synthetic:frames=1000,width=160,height=120,presenter=1,path=rail",
        "--tracker",
        REAL_TRACKER,
        "--quit-after",
        "6",
        "--flat-out",
        "--screenshot",
        str(png),
    )
    assert proc.returncode == 0, proc.stderr
    image = cv2.imread(str(png))
    assert image is not None
    assert image.shape[:2] == (960, 1600)
    assert float(image.astype(np.float32).var()) > 100.0


def test_gui_bad_source_exits_1_with_one_line_message(tmp_path: Path) -> None:
    missing = tmp_path / "missing"
    proc = _studiotrack(
        tmp_path, "gui", "--source", str(missing), "--tracker", REAL_TRACKER, "--quit-after", "5"
    )
    assert proc.returncode == 1
    assert f"studiotrack: engine failed: SourceError: {missing}: no such file or folder" in (
        proc.stderr
    )


def test_gui_unknown_tracker_is_a_cli_error(tmp_path: Path) -> None:
    proc = _studiotrack(tmp_path, "gui", "--tracker", "nope", "--quit-after", "1")
    assert proc.returncode == 2
    assert "studiotrack: error: unknown tracker 'nope'" in proc.stderr
