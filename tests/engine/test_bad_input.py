"""Issue 18 at the engine level: validated numbers, output checks and atomic writes, the
OpenTrackIO byte limit, truncated media, calibration photo sets, projects, replay integrity."""

from __future__ import annotations

import json
import os
import struct
from pathlib import Path

import cv2
import numpy as np
import pytest

from engine.errors import CalibrationError, ParamsError, SourceError, StudioTrackError
from engine.validate import number, port, shown

BIG = 10**400


# ------------------------------------------------------------------------------ validate
@pytest.mark.parametrize(
    ("value", "rule", "message"),
    [
        (BIG, {}, "must be in [-1e+15, 1e+15], got 100000000000... (401 digits)"),
        (float("inf"), {}, "must be finite, got inf"),
        (float("nan"), {"lo": 0}, "must be finite, got nan"),
        (True, {}, "must be a number, got True"),
        ("12", {}, "must be a number, got '12'"),  # JSON strings are not numbers
        (160.5, {"integer": True}, "must be an integer, got 160.5"),
        (1e308, {"gt": 0, "hi": 1e7}, "must be > 0 and <= 1e+07, got 1e+308"),
        (-1, {"gt": 0}, "must be > 0, got -1"),
        (None, {}, "must be a number, got None"),
    ],
)
def test_number_refuses_with_one_line(value: object, rule: dict, message: str) -> None:
    with pytest.raises(ParamsError) as exc:
        number(value, "x", **rule)
    assert str(exc.value) == f"x {message}"


def test_number_accepts_and_converts() -> None:
    assert number(3, "x") == 3.0
    assert isinstance(number(3, "x"), float)
    assert number(160.0, "w", integer=True) == 160
    assert isinstance(number(np.int64(5), "n", integer=True), int)
    assert number(" 1e-3 ", "t", text=True) == pytest.approx(1e-3)
    assert number("42", "n", integer=True, text=True) == 42
    with pytest.raises(ParamsError, match="must be an integer, got '1e400'"):
        number("1e400", "n", integer=True, text=True)
    with pytest.raises(SourceError, match=r"port must be in \[0, 65535\], got '99999'"):
        port("99999", "port", error=SourceError)
    assert len(shown(BIG)) < 40


# ------------------------------------------------------------------------------ persist
def test_atomic_writes_use_the_umask_and_keep_a_replaced_files_mode(tmp_path: Path) -> None:
    from engine.persist import atomic_write_text

    old = os.umask(0o022)
    try:
        atomic_write_text(tmp_path / "a.txt", "x")
        assert (tmp_path / "a.txt").stat().st_mode & 0o777 == 0o644
        os.umask(0o077)
        atomic_write_text(tmp_path / "b.txt", "x")
        assert (tmp_path / "b.txt").stat().st_mode & 0o777 == 0o600
        (tmp_path / "a.txt").chmod(0o640)
        atomic_write_text(tmp_path / "a.txt", "y")  # a replaced file keeps its own mode
        assert (tmp_path / "a.txt").stat().st_mode & 0o777 == 0o640
    finally:
        os.umask(old)


def test_check_output_file(tmp_path: Path) -> None:
    from engine.persist import check_output_file

    def check(p: Path, **kw: object) -> str:
        with pytest.raises(StudioTrackError) as exc:
            check_output_file(p, error=StudioTrackError, label="--out", **kw)  # type: ignore[arg-type]
        return str(exc.value)

    assert check_output_file(tmp_path / "new.txt", error=StudioTrackError) == tmp_path / "new.txt"
    assert "is a folder" in check(tmp_path)
    assert "does not exist" in check(tmp_path / "no" / "x.txt")
    assert check_output_file(tmp_path / "no" / "x.txt", error=StudioTrackError, make_parents=True)
    assert "cannot write in /proc" in check(Path("/proc/studiotrack.txt"))
    assert "File name too long" in check(tmp_path / ("x" * 300))
    data = tmp_path / "seq"
    (data / "rgb").mkdir(parents=True)
    (data / "groundtruth.txt").write_text("gt")
    msg = check(data / "groundtruth.txt", inputs=[data / "groundtruth.txt"])
    assert msg.endswith("is an input of this run; choose another file")
    assert "is inside" in check(data / "rgb" / "x.png", inputs=[data / "rgb"])
    ro = tmp_path / "ro.txt"
    ro.write_text("precious")
    ro.chmod(0o444)
    assert "is read-only; refusing to replace it (--force replaces it)" in check(ro)
    assert check_output_file(ro, error=StudioTrackError, force=True) == ro


def test_check_output_dir_and_replace_dir(tmp_path: Path) -> None:
    from engine.persist import check_output_dir, replace_dir

    def check(p: Path, **kw: object) -> str:
        with pytest.raises(StudioTrackError) as exc:
            check_output_dir(p, error=StudioTrackError, label="--out", kind="keyframe store",
                             marker="keyframes.json", **kw)  # type: ignore[arg-type]
        return str(exc.value)

    assert check_output_dir(tmp_path / "new", error=StudioTrackError) is False
    assert not (tmp_path / "new").exists()  # checking creates nothing
    other = tmp_path / "other"
    other.mkdir()
    (other / "rgb.txt").write_text("x")
    assert "not empty and is not a keyframe store" in check(other)
    assert "not empty and is not a keyframe store" in check(other, force=True)
    store = tmp_path / "kf"
    store.mkdir()
    (store / "keyframes.json").write_text("{}")
    (store / "kf_0016_gray.png").write_bytes(b"old")
    assert "is a keyframe store already; refusing to replace it (--force" in check(store)
    assert check_output_dir(store, error=StudioTrackError, marker="keyframes.json", force=True)
    assert "is a file" in check(other / "rgb.txt")
    new = tmp_path / "new_store"
    new.mkdir()
    (new / "keyframes.json").write_text('{"new": 1}')
    replace_dir(new, store)
    assert sorted(p.name for p in store.iterdir()) == ["keyframes.json"]  # no stale PNGs
    assert json.loads((store / "keyframes.json").read_text()) == {"new": 1}
    assert not new.exists()
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


# ------------------------------------------------------------------------------ OpenTrackIO
def _segment(seq: int, off: int, payload: bytes, last: bool = False) -> bytes:
    from engine.outputs import opentrackio as ot

    head = ot.IDENTIFIER + bytes([0, 1]) + struct.pack(">HIH", seq, off,
                                                      (0x8000 if last else 0) | len(payload))
    return head + ot.fletcher16_mod256(head + payload).to_bytes(2, "big") + payload


def test_reassembler_holds_at_most_its_byte_limit() -> None:
    from engine.outputs import opentrackio as ot

    r = ot.Reassembler()
    errors: list[str] = []
    for i in range(2000):  # overlapping segments of one sample that never completes
        try:
            r.feed(_segment(1, i * 500, b"x" * 1400))
        except ot.OpenTrackIOError as exc:
            errors.append(str(exc))
        assert r.held_bytes <= r.max_bytes
    assert all("exceed the 1048576-byte limit" in e for e in errors)
    assert errors
    assert r.dropped >= 1
    # a normal segmented sample still reassembles afterwards
    payload = ot.encode_payload({"protocol": {"name": "OpenTrackIO"}, "x": "y" * 3000}, "json")
    out = [r.feed(p) for p in ot.build_packets(payload, 9, "json")]
    assert out[-1] is not None
    assert out[-1]["x"] == "y" * 3000


@pytest.mark.parametrize(
    ("sample", "problem"),
    [
        ({"transforms": {"translation": {"x": 1}}}, "'transforms' must be a list of objects"),
        ({"transforms": [{"translation": {"x": BIG}}]}, "translation.x must be in"),
        ({"transforms": [{"rotation": {"pan": "left"}}]}, "rotation.pan must be a number"),
        ({"transforms": [{"translation": [1, 2, 3]}]}, "must be objects"),
        ({"timing": {"sequenceNumber": -3}}, "timing.sequenceNumber must be in"),
    ],
)
def test_sample_pose_validates_what_listen_prints(sample: dict, problem: str) -> None:
    from engine.outputs import opentrackio as ot

    with pytest.raises(ot.OpenTrackIOError, match=None) as exc:
        ot.sample_pose(sample)
    assert problem in str(exc.value)


def test_sample_pose_of_a_good_sample() -> None:
    from engine.outputs import opentrackio as ot

    p = ot.sample_pose({"timing": {"sequenceNumber": 4}, "tracker": {"status": "TRACKING"},
                        "transforms": [{"translation": {"x": 1.5}, "rotation": {"pan": 2}}]})
    assert (p.sequence_number, p.status, p.x_m, p.pan_deg, p.z_m) == (4, "TRACKING", 1.5, 2.0,
                                                                      0.0)


# ------------------------------------------------------------------------------ media
def test_truncated_video_ends_with_a_note_naming_the_last_good_frame(tmp_path: Path) -> None:
    from engine.sources.video import VideoSource

    path = tmp_path / "clip.avi"
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, (64, 48))
    rng = np.random.default_rng(0)
    for _ in range(60):
        w.write(rng.integers(0, 255, (48, 64, 3), dtype=np.uint8))
    w.release()
    whole = VideoSource(path)
    assert sum(1 for _ in whole.frames()) == 60
    assert whole.end_notes() == ()
    data = path.read_bytes()
    cut = tmp_path / "cut.avi"
    cut.write_bytes(data[: len(data) // 2])
    src = VideoSource(cut)
    n = sum(1 for _ in src.frames())
    assert 0 < n < 60
    (note,) = src.end_notes()
    assert f"video ended after {n} of the 60 frames" in note
    assert f"last good frame: frame {n - 1} at" in note


def _board(size_wh: tuple[int, int], cols: int = 9, rows: int = 6) -> np.ndarray:
    """A synthetic chessboard photo (cols x rows inner corners), slightly tilted."""
    w, h = size_wh
    sq = min(w, h) // (max(cols, rows) + 3)
    img = np.full((h, w), 255, np.uint8)
    x0, y0 = (w - sq * (cols + 1)) // 2, (h - sq * (rows + 1)) // 2
    for r in range(rows + 1):
        for c in range(cols + 1):
            if (r + c) % 2 == 0:
                img[y0 + r * sq:y0 + (r + 1) * sq, x0 + c * sq:x0 + (c + 1) * sq] = 0
    return img


def test_chessboard_set_skips_portrait_photos_naming_each(tmp_path: Path) -> None:
    from engine.ptz.chessboard import calibrate_chessboard

    rng = np.random.default_rng(1)
    paths = []
    for i in range(5):
        img = _board((640, 480))
        M = cv2.getRotationMatrix2D((320, 240), float(rng.uniform(-15, 15)), 1.0)
        img = cv2.warpAffine(img, M, (640, 480), borderValue=255)
        if i in (1, 3):
            img = cv2.rotate(img, cv2.ROTATE_90_CLOCKWISE)  # portrait, no EXIF
        p = tmp_path / f"p{i}.png"
        cv2.imwrite(str(p), img)
        paths.append(p)
    res = calibrate_chessboard(paths, (9, 6), 0.025)
    assert (res.intrinsics.width, res.intrinsics.height) == (640, 480)
    assert len(res.used_images) == 3
    assert [Path(p).name for p in res.skipped_images] == ["p1.png", "p3.png"]
    assert all("portrait 480x640" in r for r in res.skipped_reasons)


@pytest.mark.parametrize("square", [float("nan"), float("inf"), 0.0, -1.0])
def test_chessboard_square_must_be_a_positive_number(tmp_path: Path, square: float) -> None:
    from engine.ptz.chessboard import calibrate_chessboard

    with pytest.raises(CalibrationError, match="square size must be a positive number"):
        calibrate_chessboard([tmp_path / "x.png"], (9, 6), square)


def test_calibration_images_tiny_or_truncated(tmp_path: Path) -> None:
    from engine.ptz.chessboard import calibrate_chessboard, read_calibration_image
    from engine.ptz.distortion import propose_lines_chessboard

    one = tmp_path / "one.png"
    cv2.imwrite(str(one), np.zeros((1, 1), np.uint8))
    assert propose_lines_chessboard(read_calibration_image(one), (9, 6)) == []
    with pytest.raises(CalibrationError, match="too small for a 9x6 chessboard"):
        calibrate_chessboard([one], (9, 6), 0.025)
    ok, jpg = cv2.imencode(".jpg", _board((320, 240)))
    assert ok
    cut = tmp_path / "cut.jpg"
    cut.write_bytes(jpg.tobytes()[: len(jpg) // 2])
    with pytest.raises(CalibrationError, match="truncated JPEG"):
        read_calibration_image(cut)


def test_opencv_box_tracker_refuses_a_box_outside_the_image() -> None:
    from engine.errors import TrackerError
    from engine.frames import Frame
    from engine.trackers.opencv_box import OpenCVBoxParams, OpenCVBoxTracker

    img = np.random.default_rng(0).integers(0, 255, (48, 64, 3), dtype=np.uint8)
    for kind in ("kcf", "mil", "csrt"):
        t = OpenCVBoxTracker(kind, OpenCVBoxParams(init_box_xywh=(1000, 1000, 40, 40)))
        with pytest.raises(TrackerError, match="does not overlap the 64x48 image of frame 0"):
            t.track(Frame(index=0, timestamp_s=0.0, color_bgr=img))
    t = OpenCVBoxTracker("kcf", OpenCVBoxParams(init_box_xywh=(50, 30, 40, 40)))  # clipped
    assert t.track(Frame(index=0, timestamp_s=0.0, color_bgr=img)).box_xywh == (50, 30, 40, 40)


# ------------------------------------------------------------------------------ beacons
def test_beacon_inputs_with_absurd_numbers(tmp_path: Path) -> None:
    from engine.beacons.io import InputStats, load_layout, parse_datagram

    lay = tmp_path / "l.json"
    lay.write_text('{"version": 1, "beacons": [{"id": "A", "x_m": ' + str(BIG) + ', "y_m": 1}]}')
    with pytest.raises(SourceError, match="beacon 'A' x_m must be in"):
        load_layout(lay)
    lay.write_text('{"version": 1e400, "beacons": [{"id": "A", "x_m": 1, "y_m": 1}]}')
    with pytest.raises(SourceError, match="'version' must be an integer"):
        load_layout(lay)
    stats = InputStats()
    bad_t = ('{"timestamp_s": ' + str(BIG) + ', "ranges_m": {"A": 1}}').encode()
    assert parse_datagram(bad_t, None, stats) is None
    step = parse_datagram(('{"timestamp_s": 1, "ranges_m": {"A": ' + str(BIG)
                           + ', "B": 2}}').encode(), None, stats)
    assert step is not None
    assert dict(step.ranges_m) == {"B": 2.0}
    assert stats.malformed == 2
    assert parse_datagram(b"[1, 2]", None, stats) is None
    assert stats.malformed == 3


def test_beacon_udp_port_is_validated_and_not_the_robot_port() -> None:
    from engine.presenter.control import DEFAULT_PORT as ROBOT_PORT
    from engine.sources import open_source
    from engine.sources.beacons import DEFAULT_UDP_PORT

    assert ROBOT_PORT != DEFAULT_UDP_PORT
    with pytest.raises(SourceError, match=r"beacons-udp: port must be in \[0, 65535\]"):
        open_source("beacons-udp:port=99999")
    with pytest.raises(SourceError, match="heartbeat must be finite"):
        open_source("beacons-udp:port=0,heartbeat=nan")


# ------------------------------------------------------------------------------ project
def test_project_save_over_a_damaged_index_keeps_the_good_backup(tmp_path: Path) -> None:
    from engine.project import new_project, open_project

    d = tmp_path / "proj"
    p = new_project("s")
    p.save(d)
    p.save(d)
    good_bak = (d / "project.json.bak").read_text()
    (d / "project.json").write_text("{ damaged")
    p.save(d)
    assert (d / "project.json.bak").read_text() == good_bak
    damaged = list(d.glob("project.json.damaged-*"))
    assert len(damaged) == 1
    assert damaged[0].read_text() == "{ damaged"
    assert open_project(d).revision == 3


def test_project_with_an_absurd_revision(tmp_path: Path) -> None:
    from engine.project import ProjectError, new_project, open_project

    d = tmp_path / "proj"
    new_project("s").save(d)
    idx = json.loads((d / "project.json").read_text())
    idx["revision"] = BIG
    (d / "project.json").write_text(json.dumps(idx))
    with pytest.raises(ProjectError, match=r"'revision' 100000000000\.\.\. \(401 digits\)"):
        open_project(d)
    new_project("s").save(d)  # a save repairs it (the damaged index is kept aside)
    assert open_project(d).revision == 2
    (d / f"rev-{'9' * 30}").mkdir()  # a folder name that is no revision
    new_project("s").save(d)
    assert open_project(d).revision == 3


# ------------------------------------------------------------------------------ sessions
def _session(tmp_path: Path, frames: int = 4) -> Path:
    from engine.session.recorder import SessionRecorder, record_session
    from engine.sources import open_source
    from engine.trackers import create_tracker

    out = tmp_path / "sess"
    src = open_source(f"synthetic:frames={frames},width=32,height=24")
    tracker = create_tracker("opencv-odometry")
    rec = SessionRecorder(out, source=src, source_spec="synthetic", tracker_name="opencv-odometry",
                          tracker_params=tracker.params)
    for _ in record_session(src, tracker, rec):
        pass
    return out


def test_replay_checks_records_before_claiming_identity(tmp_path: Path) -> None:
    from engine.session import SessionError
    from engine.session.replay import replay_session

    sess = _session(tmp_path)
    assert replay_session(sess).identical
    lines = (sess / "records.jsonl").read_text().splitlines()
    (sess / "records.jsonl").write_text("\n".join(lines[:2]) + "\n")  # truncated
    res = replay_session(sess)
    assert not res.identical
    assert res.mismatches == 0
    assert "index.json says 4 frame(s) were recorded, records.jsonl holds 2" in res.integrity[0]
    (sess / "records.jsonl").write_text("\n".join([lines[0], lines[2], lines[3]]) + "\n")
    (sess / "index.json").write_text((sess / "index.json").read_text().replace(
        '"frames_recorded": 4', '"frames_recorded": 3'))
    res = replay_session(sess)
    assert not res.identical
    assert any("frame 1 is missing" in p for p in res.integrity)
    (sess / "records.jsonl").write_text("")
    with pytest.raises(SessionError, match="holds no frame records"):
        replay_session(sess)
    (sess / "records.jsonl").unlink()
    with pytest.raises(SessionError, match=r"records\.jsonl: missing"):
        replay_session(sess)


def test_exports_leave_out_non_finite_poses(tmp_path: Path) -> None:
    from engine.session.export import export_trajectory, nonfinite_poses
    from engine.session.reader import read_records

    sess = _session(tmp_path)
    lines = (sess / "records.jsonl").read_text().splitlines()
    r = json.loads(lines[1])
    r["T_world_cam"][3] = None
    lines[1] = json.dumps(r)
    (sess / "records.jsonl").write_text("\n".join(lines) + "\n")
    records = read_records(sess)
    assert nonfinite_poses(records) == [1]
    for name in ("t.txt", "t.csv", "t.json"):
        export_trajectory(records, tmp_path / name)
        assert "nan" not in (tmp_path / name).read_text().lower()
    assert len((tmp_path / "t.txt").read_text().splitlines()) == 1 + 3


def test_recording_stopped_by_the_flag_is_interrupted_with_the_reason(tmp_path: Path) -> None:
    from engine.session.reader import read_index
    from engine.session.recorder import SessionRecorder, record_session
    from engine.sources import open_source
    from engine.trackers import create_tracker

    class Stop:
        reason = "interrupted by SIGINT"

        def __init__(self) -> None:
            self.n = 0

        def __call__(self) -> bool:
            self.n += 1
            return self.n > 3

    out = tmp_path / "sess"
    src = open_source("synthetic:frames=50,width=32,height=24")
    tracker = create_tracker("opencv-odometry")
    rec = SessionRecorder(out, source=src, source_spec="synthetic", tracker_name="opencv-odometry",
                          tracker_params=tracker.params)
    n = sum(1 for _ in record_session(src, tracker, rec, should_stop=Stop()))
    idx = read_index(out)
    assert 0 < n < 50
    assert idx.status == "interrupted"
    assert idx.stop_reason == "interrupted by SIGINT"
    assert json.loads((out / "index.json").read_text())["partial"] is True
    assert idx.frames_recorded == n
