"""Screenshots of every page with the status header in TRACKING, LOST, output failure,
ERROR and STOPPED, at 1280x800 and 1920x1080 (offscreen).

    QT_QPA_PLATFORM=offscreen .venv/bin/python tests/app/screenshots_onair.py OUT_DIR
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

OUT = Path(sys.argv[1] if len(sys.argv) > 1 else "/tmp/studiotrack_onair_shots")
STUDIO = "synthetic:frames=100000,width=320,height=240,presenter=0,path=rail"
COVERED = STUDIO + ",cover_start=40,cover_frames=100000"


class _FailsAt:
    """A tracker that raises at frame ``n`` (an engine exception mid-show)."""

    def __init__(self, inner, n: int) -> None:  # type: ignore[no-untyped-def]
        self._inner, self._n, self._k = inner, n, 0

    def __getattr__(self, name: str):  # type: ignore[no-untyped-def]
        return getattr(self._inner, name)

    def track(self, frame):  # type: ignore[no-untyped-def]
        self._k += 1
        if self._k >= self._n:
            raise RuntimeError(f"injected engine failure at frame {self._k - 1}")
        return self._inner.track(frame)


def main() -> None:
    from screenshot_kit import open_window, pump, shoot, wait

    import app.run_owner as run_owner
    from app.run_owner import RunRequest
    from engine.outputs.sender import OutputConfig, TargetSpec
    from engine.pipeline import RunPhase
    from engine.presenter.model import auto_patches
    from engine.sources import open_source
    from engine.trackers import create_tracker

    ctx, win = open_window()
    OUT.mkdir(parents=True, exist_ok=True)

    def shot(page: str, state: str) -> None:
        shoot(win, OUT, f"{page.lower()}_{state}", page)

    live = win.page("Live")
    ptz = win.page("PTZ")
    beacons = win.page("Beacons")
    presenter = win.page("Presenter")

    def start_for(page: str, covered: bool = False) -> None:
        run = ctx.run
        if run.is_running:
            run.stop()
        if page == "PTZ":
            ptz.live.start("ptz-sim:duration=600", realtime=True)
        elif page == "Beacons":
            beacons.fps_spin.setValue(20.0)
            beacons.steps_spin.setValue(100000)
            beacons.start()
        elif page == "Presenter":
            spec = ("synthetic:frames=100000,width=320,height=240,seed=3,presenter=1,"
                    "path=static" + (",cover_start=30,cover_frames=100000" if covered else ""))
            with open_source(spec) as src:
                first = next(iter(src.frames()))
            presenter.source_edit.setText(spec)
            presenter.set_reference(np.array(first.color_bgr))
            main_box = first.gt_box_xywh
            presenter.canvas.set_model(main_box, [(p.name, p.xywh)
                                                  for p in auto_patches(main_box, 3)])
            presenter.start_tracking()
        else:
            live.configure(source=COVERED if covered else STUDIO, tracker="dense",
                           realtime=True)
            live.start()
        wait(lambda: run.frames_received > (60 if covered else 20))

    pages = list(win.pages)
    # TRACKING (each page with its own tracker where it has one)
    for page in pages:
        start_for(page)
        shot(page, "tracking")
    # LOST (lens covered: dense on the Live run, the presenter on its page)
    for page in pages:
        start_for(page if page in ("Presenter",) else "Live", covered=True)
        wait(lambda: win.header.state.state == "LOST" or
             (win.display_tick(force_header=True) or False), timeout=30)
        shot(page, "lost")
    # output failure: the route to a target goes away (a loopback-bound socket cannot send
    # to a network address; the check at Apply is bypassed as if the route vanished after)
    real_check = run_owner.check_targets
    run_owner.check_targets = lambda cfg: None  # type: ignore[assignment]
    ctx.run.apply_outputs(OutputConfig(targets=(
        TargetSpec("freed", "192.0.2.1", 40000, bind_host="127.0.0.1"),
        TargetSpec("opentrackio", "127.0.0.1", 55555, bind_host="127.0.0.1"))))
    ctx.run.set_outputs_enabled(True)
    for page in pages:
        start_for(page)
        pump(1.5)
        shot(page, "output_failure")
    # ERROR: the engine raises mid-show (outputs on: they hold the last pose flagged LOST)
    ctx.run.stop()
    ctx.run.apply_outputs(OutputConfig(targets=(
        TargetSpec("freed", "127.0.0.1", 40000, bind_host="127.0.0.1"),
        TargetSpec("opentrackio", "127.0.0.1", 55555, bind_host="127.0.0.1"))))
    ctx.run.start(RunRequest(STUDIO, "dense", page="Live",
                             tracker_factory=lambda: _FailsAt(create_tracker("dense"), 30)))
    wait(lambda: ctx.run.pipeline is not None and ctx.run.pipeline.phase is RunPhase.FAULT)
    for page in pages:
        shot(page, "error")
    ctx.run.set_outputs_enabled(False)
    run_owner.check_targets = real_check  # type: ignore[assignment]
    # STOPPED
    ctx.run.stop()
    for page in pages:
        shot(page, "stopped")
    win.close()
    print(f"screenshots in {OUT}")


if __name__ == "__main__":
    main()
