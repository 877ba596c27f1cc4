"""The pan-tilt calibration chain in the loop (Gaspar 2009 sec. 3): head from DLTs, the
calibration document, the project's set-up documents, the tracker using only the
calibration (no simulator truth), and the loop closed through the loopback VISCA camera."""

from __future__ import annotations

import json

import numpy as np
import pytest

from engine.errors import CalibrationError, TrackerError
from engine.ptz.calibration import PtzCalibration, head_from_dlts
from engine.ptz.dlt import calibrate_dlt, project_P
from engine.ptz.kinematics import PtzHead


def _head() -> PtzHead:
    K = np.array([[800.0, 0, 321.0], [0, 798.0, 238.0], [0, 0, 1]])
    return PtzHead(K=K, rotation_centre_world_m=np.array([0.3, -0.2, 1.6]),
                   optical_offset_cam_m=np.array([0.01, -0.02, 0.06]), pan0_deg=4.0,
                   tilt0_deg=-2.0, roll_deg=0.7)


def test_head_from_dlts_recovers_rotation_centre_and_offset():
    head = _head()
    rng = np.random.default_rng(4)
    decs, poses = [], []
    for pan, tilt in ((-25.0, -5.0), (0.0, -5.0), (25.0, 0.0), (5.0, -15.0)):
        R = head.R_world_cam(pan, tilt)
        rays = np.vstack([rng.uniform(-0.35, 0.35, 40), rng.uniform(-0.25, 0.25, 40),
                          np.ones(40)])
        X = (head.optical_centre_world(pan, tilt)[:, None]
             + rng.uniform(3, 9, 40) * (R @ rays)).T
        uv = project_P(head.P(pan, tilt), X) + rng.normal(0, 0.2, (40, 2))
        decs.append(calibrate_dlt(X, uv).decomposition)
        poses.append((pan, tilt))
    est = head_from_dlts(decs, poses)
    # the rotation centre and the offset separate through the rotations between the poses;
    # what the tracker uses - the optical centre at any pose - is what must be right
    for pan, tilt in ((-40.0, 10.0), (12.0, -20.0), (30.0, 5.0)):
        assert est.optical_centre_world(pan, tilt) == pytest.approx(
            head.optical_centre_world(pan, tilt), abs=0.02)
    assert est.optical_offset_cam_m == pytest.approx(head.optical_offset_cam_m, abs=0.04)
    assert (est.pan0_deg, est.tilt0_deg, est.roll_deg) == pytest.approx((4.0, -2.0, 0.7),
                                                                        abs=0.15)
    with pytest.raises(CalibrationError, match="one motor pose per DLT"):
        head_from_dlts(decs, poses[:2])


def test_calibration_document_round_trip_and_one_line_errors():
    from engine.ptz.distortion import RadialModel

    cal = PtzCalibration(head=_head(), radial=RadialModel((0.1, 0.01), (320.0, 240.0), 400.0),
                         reference_points_world_m=np.array([[0.0, 9, 1], [1, 9, 2.0]]),
                         marker_bgr=(1, 2, 3))
    back = PtzCalibration.from_json(json.loads(json.dumps(cal.to_json())))
    assert back.head is not None
    assert back.head.P(3, 4) == pytest.approx(cal.head.P(3, 4))
    assert back.radial == cal.radial
    assert back.marker_bgr == (1, 2, 3)
    d = cal.to_json()
    d["head"]["K"][0][0] = float("nan")
    with pytest.raises(CalibrationError, match=r"ptz.json: head.K: contains a non-finite"):
        PtzCalibration.from_json(d, "ptz.json")
    d = cal.to_json()
    d["distortion"]["model"] = "fisheye"
    with pytest.raises(CalibrationError, match=r"distortion\.model must be 'inverse_radial'"):
        PtzCalibration.from_json(d, "ptz.json")


def test_project_keeps_lens_studio_frame_offset_and_ptz(tmp_path):
    from engine.lens import LensFile
    from engine.outputs.studio_frame import CameraOffset, StudioFrame
    from engine.project import ProjectError, new_project, open_project
    from engine.studio.zoom import studio_zoom_lens

    proj = new_project("set")
    proj.lens = studio_zoom_lens(320, 240, n=5)
    proj.studio_frame = StudioFrame().with_origin_at([1.0, 2.0, 0.0])
    proj.nodal_offset = CameraOffset(z_m=0.12, pan_deg=1.5)
    proj.ptz = PtzCalibration(head=_head())
    proj.save(tmp_path / "p")
    back = open_project(tmp_path / "p")
    assert back.lens == proj.lens
    assert back.studio_frame.matrix == pytest.approx(proj.studio_frame.matrix)
    assert back.nodal_offset == proj.nodal_offset
    assert back.ptz.head.P(0, 0) == pytest.approx(_head().P(0, 0))
    from engine.outputs.sender import OutputConfig

    cfg = back.output_config(OutputConfig())
    assert cfg.offset == proj.nodal_offset
    # a malformed document in the saved revision: one line naming the file and the field
    rev = tmp_path / "p" / f"rev-{back.revision:04d}"
    doc = json.loads((rev / "studio.json").read_text())
    doc["nodal_offset"]["z_m"] = "far"
    (rev / "studio.json").write_text(json.dumps(doc))
    with pytest.raises(ProjectError, match=r"studio.json: nodal_offset.z_m: 'far' is not") as e:
        open_project(tmp_path / "p")
    assert "\n" not in str(e.value)
    lens_doc = json.loads((rev / "lens.json").read_text())
    lens_doc["samples"][1]["fx_px"] = -1
    (rev / "studio.json").write_text(json.dumps({**doc, "nodal_offset": None}))
    (rev / "lens.json").write_text(json.dumps(lens_doc))
    with pytest.raises(ProjectError, match=r"lens.json: samples\[1\].fx_px: focal length"):
        open_project(tmp_path / "p")
    assert isinstance(proj.lens, LensFile)


def test_tracker_without_calibration_in_the_project_says_so(tmp_path):
    from engine.project import new_project
    from engine.trackers.ptz import PtzParams, PtzTracker

    new_project("empty").save(tmp_path / "e")
    with pytest.raises(TrackerError, match="has no pan-tilt calibration"):
        PtzTracker(PtzParams(project_dir=str(tmp_path / "e")))


@pytest.mark.slow
def test_calibrated_chain_tracks_without_simulator_truth(tmp_path):
    """Lines -> distortion, marker DLTs -> head, pan/tilt from markers: saved to a project,
    loaded by the tracker; the ball is followed to a few centimetres."""
    from engine.loop import run_tracking
    from engine.project import new_project
    from engine.ptz.sim import CircleScenario, PtzSimSource, PtzTargetTruth
    from engine.ptz.sim_calibration import calibrate_sim
    from engine.trackers.ptz import PtzDetails, PtzParams, PtzTracker

    sc = CircleScenario(duration_s=4.0, markers=True, distortion_k3=0.12, encoder=False)
    src = PtzSimSource(sc)
    cal, report = calibrate_sim(src)
    assert report["straightness_after_px"] < 0.5 * report["straightness_before_px"]
    proj = new_project("ptz")
    proj.ptz = cal
    proj.save(tmp_path / "proj")
    params = PtzParams(project_dir=str(tmp_path / "proj")).with_preset("ptz-sim")
    tr = PtzTracker(params)
    errs, sources = [], set()
    for rec in run_tracking(src, tr):
        d = rec.result.details_as(PtzDetails)
        truth = rec.frame.payload(PtzTargetTruth)
        assert rec.frame.payload(__import__("engine.ptz.head", fromlist=["x"]).PtzHeadReading) \
            is None  # no encoder: nothing of the simulator's head reaches the tracker
        sources.add(d.pan_tilt_source)
        if d.target_xyz is not None and rec.frame.timestamp_s > 2.0:
            errs.append(np.linalg.norm(d.target_xyz - np.asarray(truth.xyz_world)))
    assert sources == {"markers"}
    assert np.median(errs) < 0.1


@pytest.mark.slow
def test_visca_loop_follows_the_ball():
    """The tracker's commands go out as VISCA bytes, the loopback camera moves at finite
    speed, its FreeD output is the head reading: the ball stays in view."""
    from engine.loop import run_tracking
    from engine.ptz.sim import CircleScenario, PtzSimSource, PtzTargetTruth
    from engine.trackers.ptz import PtzDetails, PtzParams, PtzTracker

    sc = CircleScenario(duration_s=8.0, period_s=12.0, width=320, height=240, f_px=400.0)
    src = PtzSimSource(sc, head="visca")
    try:
        tr = PtzTracker(PtzParams(deadband_px=20.0).with_preset("ptz-sim"))
        errs, pans = [], []
        for rec in run_tracking(src, tr):
            d = rec.result.details_as(PtzDetails)
            truth = rec.frame.payload(PtzTargetTruth)
            pans.append(truth.pan_tilt_deg[0])
            if d.target_xyz is not None and rec.frame.timestamp_s > 3.0:
                errs.append(np.linalg.norm(d.target_xyz - np.asarray(truth.xyz_world)))
        cam, _driver, listener = src._ensure_visca()
        assert cam.commands > 3  # real VISCA commands moved the camera
        assert listener.count == len(src)  # one FreeD reading per frame
        assert max(pans) - min(pans) > 20.0  # it turned to follow the ball
        assert np.median(errs) < 0.15
    finally:
        src.close()
