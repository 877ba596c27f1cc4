"""CLI: the project's lens file (lens add-sample/show/delete/import/export/fixed), track with
--project (lens on the wire, timecode), pan-tilt calibration into a project, bad input."""

from __future__ import annotations

import json
import socket
import threading

import cv2
import jsonschema
import pytest

from app.cli import main
from tests.conftest import shared_path


def _last_json(out: str) -> dict:  # type: ignore[type-arg]
    return json.loads(out.strip().splitlines()[-1])


def _board_images(tmp_path, zoom: int, n: int = 8, seed: int = 0) -> list[str]:
    from engine.studio.chessboard_view import calibration_views, render_chessboard
    from engine.studio.zoom import studio_zoom_lens

    cam = studio_zoom_lens(320, 240).intrinsics_at(zoom)
    paths = []
    for i, T in enumerate(calibration_views(cam, n, (9, 6), 0.05, fill=0.7, seed=seed)):
        p = tmp_path / f"z{zoom}_{i}.png"
        cv2.imwrite(str(p), render_chessboard(cam, T, (9, 6), 0.05))
        paths.append(str(p))
    return paths


def test_lens_file_workflow_and_track_sends_lens_and_timecode(tmp_path, capsys):
    proj = tmp_path / "studio"
    for z in (0, 65535):
        assert main(["lens", "add-sample", *_board_images(tmp_path, z, seed=z), "--project",
                     str(proj), "--zoom", str(z), "--focus", "0", "--pattern", "9x6",
                     "--square", "0.05", "--json"]) == 0
    assert _last_json(capsys.readouterr().out)["samples"] == 2
    assert main(["lens", "show", "--project", str(proj), "--json"]) == 0
    shown = _last_json(capsys.readouterr().out)
    assert shown["complete"] is True
    assert shown["lens"]["zoom_raw"] == [0, 65535]
    assert main(["lens", "export", str(tmp_path / "lens.json"), "--project", str(proj)]) == 0

    # a sweep through the project's lens file, OpenTrackIO to a loopback listener
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(60.0)  # the first frames wait for the renderer to compile
    got: list[bytes] = []

    def listen() -> None:
        try:
            for _ in range(6):
                got.append(sock.recv(65535))
        except OSError:
            pass

    th = threading.Thread(target=listen)
    th.start()
    try:
        rc = main(["track", "synthetic:zoom=sweep,frames=6,width=320,height=240,fps=25",
                   "--tracker", "ground-truth", "--out", str(tmp_path / "t.txt"), "--project",
                   str(proj), "--opentrackio", f"127.0.0.1:{sock.getsockname()[1]}",
                   "--timecode-start", "10:00:00:00", "--timecode-rate", "25", "--json"])
        th.join(60.0)
    finally:
        sock.close()
    assert rc == 0
    from engine.outputs.opentrackio import decode_datagrams

    samples = decode_datagrams(got)
    assert len(samples) == 6
    schema = json.loads(shared_path("opentrackio", "schema.json").read_text())
    for i, s in enumerate(samples):
        jsonschema.validate(s, schema)
        assert s["timing"]["timecode"]["seconds"] == 0
        assert s["timing"]["timecode"]["hours"] == 10
        assert s["timing"]["timecode"]["frames"] == i
    zooms = [s["lens"]["rawEncoders"]["zoom"] for s in samples]
    f_mm = [s["lens"]["pinholeFocalLength"] for s in samples]
    assert zooms[0] == 0
    assert max(zooms) > 50000
    assert f_mm[zooms.index(max(zooms))] > 2.5 * f_mm[0]  # the lens file follows the zoom

    assert main(["lens", "delete-sample", "--project", str(proj), "--zoom", "0"]) == 0
    assert main(["lens", "import", str(tmp_path / "lens.json"), "--project", str(proj),
                 "--force"]) == 0


@pytest.mark.parametrize(("argv", "match"), [
    (["--timecode-start", "10:00:00:30", "--timecode-rate", "25"], "--timecode-start"),
    (["--timecode-rate", "31"], "--timecode-rate"),
    (["--head", "visca:127.0.0.1,speed=2"], "unknown option 'speed'"),
    (["--head-position", "serial:3"], "--head-position"),
])
def test_bad_setup_options_are_one_line_exit_2(tmp_path, capsys, argv, match):
    rc = main(["track", "synthetic:frames=2,width=64,height=48", "--tracker", "ground-truth",
               "--out", str(tmp_path / "t.txt"), *argv])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2
    assert match in err[-1]
    assert err[-1].startswith("studiotrack: error:")


def test_malformed_lens_file_is_one_line(tmp_path, capsys):
    bad = tmp_path / "lens.json"
    bad.write_text(json.dumps({"format": "studiotrack-lens", "version": 1,
                               "image": {"width": 64, "height": 48},
                               "samples": [{"zoom_raw": 0, "focus_raw": 0, "fx_px": 0,
                                            "fy_px": 50, "cx_px": 32, "cy_px": 24}]}))
    rc = main(["track", "synthetic:frames=2,width=64,height=48", "--tracker", "ground-truth",
               "--out", str(tmp_path / "t.txt"), "--lens", str(bad)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2
    assert f"{bad}: samples[0].fx_px: focal length 0.0 must be > 0" in err[-1]


def test_dlt_and_lines_into_a_project(tmp_path, capsys):
    import numpy as np

    from engine.project import open_project
    from engine.ptz.dlt import project_P, save_points_csv
    from engine.ptz.sim import CircleScenario

    head = CircleScenario().head()
    rng = np.random.default_rng(2)
    X = np.column_stack([rng.uniform(-3, 3, 12), rng.uniform(4, 9, 12), rng.uniform(0, 3, 12)])
    uv = project_P(head.P(5.0, -3.0), X)
    save_points_csv(tmp_path / "pts.csv", X, uv)
    proj = tmp_path / "p"
    assert main(["calibrate", "dlt", str(tmp_path / "pts.csv"), "--project", str(proj),
                 "--pan", "5", "--tilt", "-3", "--offset-m", "0,0,0.04"]) == 0
    cal = open_project(proj).ptz
    # the saved head projects like the true one at other motor angles
    Y = np.array([[1.0, 6.0, 1.0], [-2.0, 8.0, 0.5], [0.5, 3.0, 2.0]])
    assert project_P(cal.head.P(-10.0, 2.0), Y) == pytest.approx(
        project_P(head.P(-10.0, 2.0), Y), abs=0.05)
    assert main(["calibrate", "dlt", str(tmp_path / "pts.csv"), "--project", str(proj),
                 "--offset-m", "0,0"]) == 2
    assert "--offset-m" in capsys.readouterr().err


def test_studio_frame_and_nodal_offset_into_a_project(tmp_path, capsys):
    import numpy as np

    from engine.outputs.studio_frame import CameraOffset
    from engine.project import open_project
    from engine.ptz.dlt import project_P, save_points_csv
    from engine.ptz.sim import CircleScenario

    proj = tmp_path / "p"
    assert main(["calibrate", "studio", "--project", str(proj), "--floor-points",
                 "0,0,0;2,0,0;0,3,0", "--origin", "1,2,0", "--nodal", "0.1,0,0.05,1.5,0,0",
                 "--json"]) == 0
    out = _last_json(capsys.readouterr().out)
    p = open_project(proj)
    assert p.nodal_offset == CameraOffset(x_m=0.1, z_m=0.05, pan_deg=1.5)
    np.testing.assert_allclose(p.studio_frame.matrix[:3, 3], [1.0, 2.0, 0.0])
    assert out["nodal_offset"]["x_m"] == 0.1
    # bad input: one line, exit 2, nothing saved
    rev = p.revision
    for argv, match in ((["--nodal", "0,a,0"], "--nodal '0,a,0'"),
                        (["--floor-points", "0,0,0;0,0,0;1,1,0"], "origin and X point"),
                        (["--nodal", "20,0,0"], "over 10 m"),
                        (["--floor-points", "0,0,0;1,0,0"], "three X,Y,Z points")):
        assert main(["calibrate", "studio", "--project", str(proj), *argv]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert match in err[-1]
        assert err[-1].startswith("studiotrack: error:")
    assert open_project(proj).revision == rev
    # from a DLT: the calibration points' frame, seen from the camera (identity pose)
    sc = CircleScenario()
    head = sc.head()
    rng = np.random.default_rng(2)
    X = np.column_stack([rng.uniform(-3, 3, 12), rng.uniform(4, 9, 12), rng.uniform(0, 3, 12)])
    save_points_csv(tmp_path / "pts.csv", X, project_P(head.P(0.0, 0.0), X))
    assert main(["calibrate", "studio", "--project", str(proj), "--dlt",
                 str(tmp_path / "pts.csv"), "--nodal", "0,0,0"]) == 0
    p = open_project(proj)
    assert p.nodal_offset is None
    R = p.studio_frame.matrix[:3, :3]
    # a DLT point maps into the camera as T_cam_dlt: the studio frame is that transform
    Xc = (p.studio_frame.matrix @ np.append(X[0], 1.0))[:3]
    uv = head.K @ Xc
    np.testing.assert_allclose(uv[:2] / uv[2], project_P(head.P(0.0, 0.0), X[:1])[0], atol=0.05)
    assert np.allclose(R.T @ R, np.eye(3), atol=1e-6)


def test_a_head_that_never_answers_is_a_warning_not_a_failure(tmp_path, capsys):
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))  # a port where nothing answers VISCA
    port = s.getsockname()[1]
    try:
        rc = main(["track", "synthetic:frames=3,width=64,height=48", "--tracker",
                   "ground-truth", "--out", str(tmp_path / "t.txt"), "--json", "--head",
                   f"visca:127.0.0.1:{port}"])
    finally:
        s.close()
    assert rc == 0
    res = _last_json(capsys.readouterr().out)
    assert any("never answered" in w for w in res["warnings"])
    assert main(["track", "synthetic:frames=2,width=64,height=48", "--tracker", "ground-truth",
                 "--out", str(tmp_path / "t.txt"), "--head", "visca:nonexistent.invalid"]) == 2
    assert "does not resolve" in capsys.readouterr().err.strip().splitlines()[-1]
