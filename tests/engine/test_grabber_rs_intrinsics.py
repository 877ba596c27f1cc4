"""The newest-frame grabber, and RealSense distortion models checked against the SDK's own
projection (``rs2_project_point_to_pixel`` / ``rs2_deproject_pixel_to_point``)."""

from __future__ import annotations

import queue
import threading
import time

import numpy as np
import pytest

from engine.camera import backproject, project
from engine.errors import SourceError
from engine.sources.grabber import RATE_WINDOW_S, NewestGrabber
from engine.sources.rs_intrinsics import intrinsics_from_sdk, model_key


class Feed:
    """A device for the grabber that delivers exactly the items the test puts in.

    ``grab()`` blocks briefly for the next item (returning None, "nothing this time", when
    there is none); :meth:`wait_stored` returns once the grabber has stored the ``n``-th
    item, i.e. called ``grab()`` again after it returned that item.
    """

    def __init__(self) -> None:
        self.items: queue.Queue[int] = queue.Queue()
        self._cond = threading.Condition()
        self._returned = 0
        self._asked_after = 0  # items returned before the latest call of grab()

    def grab(self) -> int | None:
        with self._cond:
            self._asked_after = self._returned
            self._cond.notify_all()
        try:
            item = self.items.get(timeout=0.01)
        except queue.Empty:
            return None
        with self._cond:
            self._returned += 1
        return item

    def put(self, *items: int) -> None:
        for item in items:
            self.items.put(item)

    def wait_stored(self, n: int) -> None:
        with self._cond:
            assert self._cond.wait_for(lambda: self._asked_after >= n, timeout=10.0)


def test_grabber_hands_out_the_newest_and_counts_the_rest() -> None:
    feed = Feed()
    g: NewestGrabber[int] = NewestGrabber(feed.grab)
    g.start()
    feed.put(100)
    feed.wait_stored(1)
    first = g.take(1.0)
    assert first is not None
    assert (first.item, first.seq, first.skipped) == (100, 1, 0)
    feed.put(*range(101, 108))  # seven arrive while the consumer is busy
    feed.wait_stored(8)
    second = g.take(1.0)
    assert second is not None
    assert (second.item, second.seq, second.skipped) == (107, 8, 6)  # the newest; 6 dropped
    assert g.take(0.05) is None  # nothing newer: no frame is handed out twice
    assert g.total_skipped == 6
    # "skipping N frames/s" over the last RATE_WINDOW_S seconds, at the consumer's clock
    assert g.skipped_per_s(second.arrival_s) == pytest.approx(6 / RATE_WINDOW_S)
    assert g.skipped_per_s(second.arrival_s + RATE_WINDOW_S + 0.01) == 0.0
    assert first.arrival_s <= second.arrival_s <= time.monotonic()
    g.stop()
    assert not g.running


def test_grabber_times_out_and_reraises_the_grab_error() -> None:
    calls = [0]

    def grab() -> int | None:
        calls[0] += 1
        if calls[0] == 1:
            return 7
        if calls[0] < 4:
            return None  # the device's own timeout: not a frame
        raise RuntimeError("USB gone")

    g: NewestGrabber[int] = NewestGrabber(grab)
    g.start()
    got = g.take(1.0)
    assert got is not None
    assert got.item == 7
    assert got.skipped == 0
    with pytest.raises(RuntimeError, match="USB gone"):
        g.take(1.0)
    assert g.take(0.01) is None
    g.stop()


def _sdk_intrinsics(rs, model, coeffs):  # type: ignore[no-untyped-def]
    i = rs.intrinsics()
    i.width, i.height, i.fx, i.fy, i.ppx, i.ppy = 640, 480, 615.0, 616.0, 321.5, 242.5
    i.model, i.coeffs = model, list(coeffs)
    return i


@pytest.mark.parametrize("name", ["brown_conrady", "modified_brown_conrady",
                                  "inverse_brown_conrady", "none"])
def test_models_match_the_sdk_projection(name: str) -> None:
    rs = pytest.importorskip("pyrealsense2", reason="the RealSense SDK has no wheel here")
    coeffs = [-0.0553, 0.0654, 0.0003, 0.0007, -0.0210]  # a D455 colour stream
    model = getattr(rs.distortion, name)
    sdk = _sdk_intrinsics(rs, model, coeffs)
    cam, fit_px = intrinsics_from_sdk(width=640, height=480, fx=615.0, fy=616.0, ppx=321.5,
                                      ppy=242.5, model=str(model), coeffs=coeffs,
                                      depth_scale=1000.0, where="test")
    rng = np.random.default_rng(0)
    P = np.column_stack([rng.uniform(-0.9, 0.9, 50), rng.uniform(-0.6, 0.6, 50),
                         np.ones(50)]) * rng.uniform(0.5, 6.0, (50, 1))
    ours = project(cam, P)
    keep = (ours[:, 0] > 0) & (ours[:, 0] < 640) & (ours[:, 1] > 0) & (ours[:, 1] < 480)
    theirs = np.array([rs.rs2_project_point_to_pixel(sdk, list(p)) for p in P])
    assert np.max(np.abs(ours[keep] - theirs[keep])) < 0.02
    if name != "modified_brown_conrady":  # the SDK cannot deproject a forward model
        uv = ours[keep]
        z = P[keep, 2]
        back = np.array([rs.rs2_deproject_pixel_to_point(sdk, list(p), float(d))
                         for p, d in zip(uv, z, strict=True)])
        np.testing.assert_allclose(backproject(cam, uv, z), back, atol=1e-4 * 6)
    assert fit_px < 0.05


def test_fisheye_and_bad_coefficients_are_refused() -> None:
    kw = {"width": 640, "height": 480, "fx": 300.0, "fy": 300.0, "ppx": 320.0, "ppy": 240.0,
          "depth_scale": 1000.0, "where": "cam"}
    for model in ("distortion.kannala_brandt4", "Ftheta"):
        with pytest.raises(SourceError, match="is not supported"):
            intrinsics_from_sdk(model=model, coeffs=[0.1, 0.01, 0, 0, 0], **kw)  # type: ignore[arg-type]
    with pytest.raises(SourceError, match="cannot be expressed"):
        intrinsics_from_sdk(model="Inverse Brown Conrady", coeffs=[0.9, -2.0, 0.05, 0.05, 3.0],
                            **kw)  # type: ignore[arg-type]
    with pytest.raises(SourceError, match="not finite"):
        intrinsics_from_sdk(model="Brown Conrady", coeffs=[float("nan"), 0, 0, 0, 0], **kw)  # type: ignore[arg-type]
    # zero Brown Conrady coefficients are the pinhole (D4xx depth streams); zero fisheye is not
    cam, _ = intrinsics_from_sdk(model="Inverse Brown Conrady", coeffs=[0] * 5, **kw)  # type: ignore[arg-type]
    assert not cam.has_distortion
    with pytest.raises(SourceError, match="is not supported"):
        intrinsics_from_sdk(model="Kannala Brandt4", coeffs=[0] * 5, **kw)  # type: ignore[arg-type]
    assert model_key("distortion.inverse_brown_conrady") == "inverse_brown_conrady"
