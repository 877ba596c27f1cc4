"""Lens files: interpolation, validation (one line naming file and field), persistence,
the lensed source, the built-in studio's zoom lens and lens samples from chessboard views."""

from __future__ import annotations

import copy
import json

import numpy as np
import pytest

from engine.camera import Intrinsics
from engine.lens import LensEncoders, LensError, LensFile, LensSample, LensState


def _grid() -> LensFile:
    lf = LensFile(640, 480, sensor_width_mm=9.6, zoom_range_raw=(0, 4000),
                  focus_range_raw=(0, 1000), name="test")
    for z in (0, 1000, 4000):
        for f in (0, 1000):
            lf = lf.with_sample(LensSample(z, f, 500.0 + z / 10 + f / 100, 501.0 + z / 10,
                                           319.5 + z / 1000, 239.5, k1=-0.1 + z * 1e-5,
                                           entrance_pupil_m=0.01 * z / 1000))
    return lf


def test_exact_at_samples_bilinear_between_and_edges_hold():
    lf = _grid()
    for s in lf.samples:
        v = lf.values_at(s.zoom_raw, s.focus_raw)
        assert v["fx_px"] == pytest.approx(s.fx_px)
        assert v["k1"] == pytest.approx(s.k1)
    # half way in zoom and focus: the mean of the four corners
    v = lf.values_at(500, 500)
    corners = [lf.values_at(z, f)["fx_px"] for z in (0, 1000) for f in (0, 1000)]
    assert v["fx_px"] == pytest.approx(np.mean(corners))
    # a quarter of the way along zoom at focus 0
    assert lf.values_at(1750, 0)["fx_px"] == pytest.approx(500 + 175)
    # outside the table the edge holds
    assert lf.values_at(-50, -10)["fx_px"] == pytest.approx(500.0)
    assert lf.values_at(9999, 5000)["fx_px"] == pytest.approx(500 + 400 + 10)


def test_state_mm_fov_and_normalised_encoders():
    lf = _grid()
    st = lf.evaluate(2000, 500)
    assert isinstance(st, LensState)
    assert st.focal_length_mm == pytest.approx(st.intrinsics.fx * 9.6 / 640)
    assert st.fov_h_deg == pytest.approx(np.degrees(2 * np.arctan(320 / st.intrinsics.fx)))
    assert st.zoom_norm == pytest.approx(0.5)
    assert st.focus_norm == pytest.approx(0.5)
    assert st.entrance_pupil_m == pytest.approx(0.02)


def test_json_round_trip_and_fixed_lens(tmp_path):
    lf = _grid()
    path = tmp_path / "lens.json"
    lf.save(path)
    assert LensFile.load(path) == lf
    cam = Intrinsics(600, 601, 320, 240, 640, 480, (-0.1, 0.02, 0.001, -0.002, 0.0))
    fixed = LensFile.fixed(cam)
    assert fixed.intrinsics_at(12345, 77).dist_k1k2p1p2k3 == pytest.approx(cam.dist_k1k2p1p2k3)
    assert fixed.intrinsics_at(0).fx == 600


@pytest.mark.parametrize(("mutate", "match"), [
    (lambda d: d["samples"][2].__setitem__("k1", float("nan")), r"samples\[2\]\.k1: nan is not"),
    (lambda d: d["samples"][0].__setitem__("fx_px", 0.0), r"samples\[0\]\.fx_px: focal length"),
    (lambda d: d["samples"][1].__setitem__("fy_px", -3), r"samples\[1\]\.fy_px"),
    (lambda d: d.__setitem__("zoom_raw", [0, 4000, 1000]), r"'zoom_raw' axis is not strictly"),
    (lambda d: d.__setitem__("focus_raw", [0, 0]), r"'focus_raw' axis is not strictly"),
    (lambda d: d["samples"].pop(3), r"missing corner zoom 1000, focus 1000"),
    (lambda d: d.__setitem__("version", 9), r"version 9 is newer"),
    (lambda d: d["samples"][0].__setitem__("zoom", 1), r"unknown field 'zoom'"),
    (lambda d: d["samples"][0].pop("cx_px"), r"missing field 'cx_px'"),
    (lambda d: d.__setitem__("format", "x"), r"'format' is 'x'"),
    (lambda d: d["samples"][4].__setitem__("zoom_raw", -1), r"samples\[4\]\.zoom_raw"),
])
def test_malformed_lens_files_give_one_line_naming_file_and_field(tmp_path, mutate, match):
    d = _grid().to_json()
    if "missing corner" in match:
        d = copy.deepcopy(d)
        mutate(d)
    else:
        mutate(d)
    path = tmp_path / "bad_lens.json"
    path.write_text(json.dumps(d))
    with pytest.raises(LensError, match=match) as exc:
        LensFile.load(path)
    msg = str(exc.value)
    assert "\n" not in msg
    assert msg.startswith(str(path))


def test_incomplete_grid_loads_for_editing_but_not_for_use(tmp_path):
    lf = _grid().without_sample(4000, 1000)
    assert not lf.complete
    assert lf.missing_corners() == [(4000, 1000)]
    path = tmp_path / "lens.json"
    lf.save(path)
    again = LensFile.load(path, require_complete=False)
    assert again.missing_corners() == [(4000, 1000)]
    with pytest.raises(LensError, match="missing corner zoom 4000, focus 1000"):
        again.values_at(10, 10)


def test_lensed_source_uses_frame_encoders_then_typed_values():
    from engine.frames import Frame
    from engine.sources.base import Source
    from engine.sources.lensed import LensedSource

    class Two(Source):
        nominal_fps = 25.0

        @property
        def intrinsics(self):
            return None

        def __len__(self):
            return 2

        def frames(self):
            yield Frame(0, 0.0, np.zeros((480, 640, 3), np.uint8),
                        payloads=(LensEncoders(1000, 0),))
            yield Frame(1, 0.04, np.zeros((480, 640, 3), np.uint8))

    lf = _grid()
    src = LensedSource(Two(), lf, typed=(4000, 1000))
    a, b = list(src.frames())
    assert a.intrinsics.fx == pytest.approx(600.0)
    assert a.payload(LensState).zoom_raw == 1000
    assert b.intrinsics.fx == pytest.approx(500 + 400 + 10)
    src.set_encoders(None)
    assert list(src.frames())[1].intrinsics.fx == pytest.approx(500.0)
    with pytest.raises(LensError, match="missing corner"):
        LensedSource(Two(), lf.without_sample(0, 0))

    class Small(Two):
        def frames(self):
            from engine.camera import Intrinsics

            yield Frame(0, 0.0, np.zeros((240, 320, 3), np.uint8),
                        intrinsics=Intrinsics(300.0, 300.0, 160.0, 120.0, width=320, height=240))

    with pytest.raises(LensError, match=r"is for 640x480 px images, .* gives 320x240"):
        list(LensedSource(Small(), lf).frames())


def test_studio_zoom_sweep_renders_through_the_known_lens():
    from engine.sources import open_source
    from engine.studio.zoom import studio_zoom_lens

    src = open_source("synthetic:zoom=sweep,frames=4,width=160,height=120")
    truth = studio_zoom_lens(160, 120)
    frames = list(src.frames())
    zooms = [f.payload(LensEncoders).zoom_raw for f in frames]
    assert zooms[0] == 0
    assert zooms[2] == 65535  # the sweep reaches tele half way
    for f, z in zip(frames, zooms, strict=True):
        assert f.intrinsics == truth.intrinsics_at(z, f.payload(LensEncoders).focus_raw)
    # tele sees less of the set than wide: the images differ
    assert np.abs(frames[0].color_bgr.astype(int) - frames[2].color_bgr.astype(int)).mean() > 5
    with pytest.raises(Exception, match="zoom"):
        open_source("synthetic:zoom=tele")


def test_lens_sample_from_rendered_chessboard_views_recovers_the_lens():
    from engine.ptz.chessboard import lens_sample_from_chessboard
    from engine.studio.chessboard_view import calibration_views, render_chessboard
    from engine.studio.zoom import studio_zoom_lens

    cam = studio_zoom_lens(640, 480).intrinsics_at(16384)
    # fill/views chosen on seeds 0, 32768, 65535 (see engine/bench/lens.py); this one differs
    poses = calibration_views(cam, 12, (9, 6), 0.05, fill=0.7, seed=123)
    views = [render_chessboard(cam, T, (9, 6), 0.05) for T in poses]
    sample, res = lens_sample_from_chessboard(views, 16384, 0, (9, 6), 0.05)
    assert res.rms_px < 0.3
    assert sample.fx_px == pytest.approx(cam.fx, rel=0.005)
    assert sample.k1 == pytest.approx(cam.dist[0], abs=0.01)
    assert sample.zoom_raw == 16384


def test_ptz_head_intrinsics_follow_the_lens_file_at_read_encoders():
    from engine.frames import Frame
    from engine.ptz.head import PtzHeadReading
    from engine.ptz.kinematics import PtzHead
    from engine.trackers.ptz import PtzParams, PtzTracker

    lf = _grid()
    head = PtzHead(K=np.array([[700.0, 0, 320], [0, 700, 240], [0, 0, 1]]))
    tr = PtzTracker(PtzParams())
    img = np.zeros((480, 640, 3), np.uint8)
    state = lf.evaluate(4000, 0)
    read = Frame(0, 0.0, img, payloads=(PtzHeadReading(head, 0.0, 0.0), LensEncoders(4000, 0),
                                        state))
    np.testing.assert_allclose(tr._head(read).K, state.intrinsics.K)
    assert tr._head(read).K[0, 0] == pytest.approx(900.0)
    # a lens state without read encoders (typed / the file's first sample): calibrated K
    typed = Frame(1, 0.04, img, payloads=(PtzHeadReading(head, 0.0, 0.0), state))
    np.testing.assert_allclose(tr._head(typed).K, head.K)
