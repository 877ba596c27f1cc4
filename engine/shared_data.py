"""Where the real data for tests and benchmarks lives (see ``../shared/README.md``):
``$STUDIOTRACK_SHARED_DATA`` if set, else ``shared/data`` beside the repository checkout."""

from __future__ import annotations

import os
from pathlib import Path

ENV_VAR = "STUDIOTRACK_SHARED_DATA"


def shared_data_dir() -> Path:
    """The shared data folder (it may be absent: callers skip or report what is missing)."""
    env = os.environ.get(ENV_VAR)
    if env:
        return Path(env)
    return Path(__file__).resolve().parents[2] / "shared" / "data"
