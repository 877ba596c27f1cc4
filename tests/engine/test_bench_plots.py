"""engine.bench.plots.save_figure: the one way the benches write a figure."""

from __future__ import annotations

from pathlib import Path


def test_save_figure_writes_the_png_and_closes_the_figure(tmp_path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from engine.bench.plots import save_figure

    fig, ax = plt.subplots()
    ax.plot([0, 1], [1, 0])
    path = save_figure(fig, tmp_path / "new", "line.png", dpi=50)
    assert path == str(tmp_path / "new" / "line.png")
    assert Path(path).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not plt.fignum_exists(fig.number)
