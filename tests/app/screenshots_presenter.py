"""Screenshots of the Presenter page as an operator sets it up and watches it (offscreen),
at 1280x800 and 1920x1080:

- ``two_views_tracking``: the built-in studio with its overhead camera (``views=2``), the
  floor calibration from the source's marks, both views tracking, d on the plot;
- ``desk_lost``: the desk scenario (reference taken with the presenter standing, the
  presenter walks out past the news desk): LOST with the empty set in view;
- ``desk_reacquired``: the presenter is back and tracked again;
- ``stopped``: after Stop.

    QT_QPA_PLATFORM=offscreen .venv/bin/python tests/app/screenshots_presenter.py OUT_DIR
"""

from __future__ import annotations

import sys
from pathlib import Path

OUT = Path(sys.argv[1] if len(sys.argv) > 1 else "/tmp/studiotrack_presenter_shots")
TWO_VIEWS = "synthetic:frames=100000,presenter=1,path=static,views=2,seed=3"
# the bench's desk scenario (engine.bench.presenter_scenarios.DESK['report']), the walk out
# later (the start-up of a run in a fresh process is over by then)
DESK = ("synthetic:frames=100000,presenter=1,path=static,seed=3,presenter_mode=leave,"
        "presenter_x=0.4,presenter_out=-2.4,presenter_leave=240,presenter_return=360")


def main() -> None:
    from screenshot_kit import open_window, shoot, wait

    from engine.presenter.model import auto_patches
    from engine.sources import open_source
    from engine.trackers.base import TrackState

    ctx, win = open_window()
    win.show_page("Presenter")
    page = win.page("Presenter")
    OUT.mkdir(parents=True, exist_ok=True)

    def shot(name: str) -> None:
        shoot(win, OUT, f"presenter_{name}")

    def start(spec: str) -> None:
        if ctx.run.is_running:
            ctx.run.stop()
            wait(lambda: not ctx.run.is_running)
        page.source_edit.setText(spec)
        page.take_reference()  # the first frame (and the overhead view with its marks)
        with open_source(spec) as src:
            first = next(iter(src.frames()))
        box = first.gt_box_xywh
        page.canvas.set_model(box, [(p.name, p.xywh) for p in auto_patches(box, 3)])
        if page.over_reference is not None:
            page.save_floor_calibration()
        page.realtime_check.setChecked(True)
        if not page.start_tracking():
            raise SystemExit(f"the Presenter page did not start: {page.message.text()}")

    def frame_index() -> int:
        rec = ctx.run.latest()
        return -1 if rec is None else int(rec.frame.index)

    def state() -> object:
        rec = ctx.run.latest()
        return None if rec is None else rec.result.state

    start(TWO_VIEWS)
    wait(lambda: frame_index() > 90, step=0.05)
    shot("two_views_tracking")

    start(DESK)
    # the presenter has left (from frame ~310) and the tracker said LOST
    wait(lambda: frame_index() > 320 and state() == TrackState.LOST, timeout=120, step=0.05)
    shot("desk_lost")
    wait(lambda: frame_index() > 420 and state() == TrackState.TRACKING, timeout=120,
         step=0.05)
    shot("desk_reacquired")
    ctx.run.stop()
    wait(lambda: not ctx.run.is_running)
    shot("stopped")
    win.close()
    print(f"screenshots in {OUT}")


if __name__ == "__main__":
    main()
