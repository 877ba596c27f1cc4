"""Text results are written atomically, and a failure is one line naming the file."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from engine.errors import EvaluationError
from engine.evaluation.trajectory import Trajectory, write_tum
from engine.persist import write_text_file
from engine.session import SessionError
from engine.session.export import export_trajectory


def test_write_text_file_replaces_atomically(tmp_path: Path) -> None:
    path = tmp_path / "sub" / "result.txt"
    write_text_file(path, "one\n", EvaluationError)
    write_text_file(path, "two\n", EvaluationError)
    assert path.read_text() == "two\n"
    assert [p.name for p in path.parent.iterdir()] == ["result.txt"]  # no temp file left


def test_unwritable_result_is_a_one_line_error_of_the_callers_type(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(EvaluationError, match=r"^.*file/out.txt: cannot write \(.+\)$"):
        write_tum(blocker / "out.txt", Trajectory(np.zeros(1), np.eye(4)[None]))
    with pytest.raises(SessionError, match=r"file/out.csv: cannot write"):
        export_trajectory([], blocker / "out.csv")
