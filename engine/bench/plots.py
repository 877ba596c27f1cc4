"""How the benches write their figures (``--plots DIR``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any


def save_figure(fig: Any, folder: Path, name: str, dpi: int = 100) -> str:
    """Lay ``fig`` out tightly, write it to ``folder / name`` (the folder made if needed),
    close it; the path written, as a string (what the benches list under ``plots``)."""
    import matplotlib.pyplot as plt

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / name
    fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return str(path)
