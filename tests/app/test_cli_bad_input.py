"""Issue 18 through the command line: interruptions keep what was done, outputs report
their failures, truncated media and partial runs say so, listen survives bad packets."""

from __future__ import annotations

import json
import signal
import socket
import threading
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

from tests.app.test_cli_fuzz import run_cli

TINY = "width=32,height=24"


def _json(out: str) -> dict:  # type: ignore[type-arg]
    return json.loads(out.strip().splitlines()[-1])


def _signal_on(text: str, sig: int = signal.SIGINT):  # type: ignore[no-untyped-def]
    """A progress sink that sends ``sig`` to this process when a line contains ``text``."""
    sent = []

    def sink(msg: str) -> None:
        if text in msg and not sent:
            sent.append(msg)
            signal.raise_signal(sig)

    return sink


@pytest.mark.parametrize(("sig", "code"), [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_track_interrupted_writes_what_was_tracked(tmp_path: Path, sig: int, code: int) -> None:
    out = tmp_path / "t.txt"
    before = signal.getsignal(signal.SIGINT)  # SIG_IGN where pytest runs as a background job
    o = run_cli(["track", f"synthetic:frames=40,{TINY}", "--tracker", "opencv-odometry",
                 "--out", str(out), "--json"], budget_s=60,
                on_progress=_signal_on("frame 8/", sig))
    assert o.rc == code, o.stderr
    res = _json(o.stdout)
    assert res["partial"] is True
    assert res["stop_reason"] == f"interrupted by {signal.Signals(sig).name}"
    assert 8 <= res["frames"] < 40
    assert len(out.read_text().splitlines()) == 1 + res["frames"]  # header + one per frame
    assert signal.getsignal(signal.SIGINT) is before  # handlers restored


def test_record_interrupted_is_labelled_interrupted(tmp_path: Path) -> None:
    from engine.session.reader import read_index

    out = tmp_path / "sess"
    o = run_cli(["record", f"synthetic:frames=1000,{TINY}", "--tracker", "opencv-odometry",
                 "--out", str(out)], budget_s=120, on_progress=_signal_on("recorded 100 frames"))
    assert o.rc == 130, o.stderr
    res = _json(o.stdout)
    assert (res["status"], res["partial"]) == ("interrupted", True)
    idx = read_index(out)
    assert idx.status == "interrupted"
    assert idx.stop_reason == "interrupted by SIGINT"
    assert 100 <= idx.frames_recorded < 1000
    again = run_cli(["record", f"synthetic:frames=2,{TINY}", "--tracker", "opencv-odometry",
                     "--out", str(out)])
    assert again.rc == 2
    assert "is a session already; refusing to replace it (--force replaces it)" in \
        again.stderr[0]
    forced = run_cli(["record", f"synthetic:frames=2,{TINY}", "--tracker", "opencv-odometry",
                      "--out", str(out), "--force"])
    assert forced.rc == 0
    assert read_index(out).frames_recorded == 2


def test_a_source_error_mid_run_keeps_the_frames_before_it(tmp_path: Path) -> None:
    from engine.sources.synthetic import SyntheticSource
    from engine.studio.export import write_tum_folder

    src = SyntheticSource.from_options({"frames": "10", "width": "32", "height": "24"})
    folder = tmp_path / "seq"
    write_tum_folder(src.frames(), folder, src.intrinsics)
    sixth = sorted((folder / "rgb").iterdir())[6]
    sixth.write_bytes(sixth.read_bytes()[:40])  # truncated PNG at frame 6
    out = tmp_path / "t.txt"
    o = run_cli(["track", str(folder), "--tracker", "opencv-odometry", "--out", str(out),
                 "--json"])
    assert o.rc == 2
    assert len(o.stderr) == 1
    assert "truncated PNG" in o.stderr[0]
    assert "the 6 frames before it were written" in o.stderr[0]
    res = _json(o.stdout)
    assert (res["frames"], res["partial"], res["skipped_frames"]) == (6, True, 0)
    assert len(out.read_text().splitlines()) == 1 + 6


def test_outputs_that_send_nothing_fail_the_run_and_say_so(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from engine.outputs import sender

    def unreachable(self: object) -> socket.socket:
        raise OSError(101, "Network is unreachable")

    monkeypatch.setattr(sender._Target, "open", unreachable)  # the interface went down
    out = tmp_path / "t.txt"
    o = run_cli(["track", f"synthetic:frames=5,{TINY}", "--tracker", "opencv-odometry",
                 "--out", str(out), "--freed", "127.0.0.1:40000", "--json"])
    assert o.rc == 2
    assert len(o.stderr) == 1
    assert o.stderr[0].startswith("studiotrack: error: outputs: nothing could be sent (5 error")
    assert "Network is unreachable" in o.stderr[0]
    res = _json(o.stdout)
    assert res["outputs"]["nothing_sent"] is True
    assert (res["outputs"]["send_errors"], res["outputs"]["packets_sent"]) == (5, 0)
    assert out.exists()  # the trajectory is still written
    assert any("0 packets, 5 send errors" in p for p in o.progress)


def test_a_pose_freed_cannot_carry_is_an_error_not_silence(tmp_path: Path) -> None:
    sf = tmp_path / "far.json"
    far = np.eye(4)
    far[0, 3] = -200_000.0  # 200 km: beyond FreeD's signed 24-bit 1/64 mm
    sf.write_text(json.dumps({"T_world_studio": far.tolist()}))
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as rx:
        rx.bind(("127.0.0.1", 0))
        port = rx.getsockname()[1]
        o = run_cli(["track", f"synthetic:frames=4,{TINY}", "--tracker", "opencv-odometry",
                     "--out", str(tmp_path / "t.txt"), "--freed", f"127.0.0.1:{port}",
                     "--studio-frame", str(sf), "--json"])
    res = _json(o.stdout)["outputs"]
    assert res["encode_errors"] == 4
    assert "does not fit a signed 24-bit field" in res["last_encode_error"]
    assert res["nothing_sent"] is True
    assert o.rc == 2
    assert any("encode errors 4" in p for p in o.progress)


def test_track_of_a_truncated_video_warns_with_the_last_good_frame(tmp_path: Path) -> None:
    path = tmp_path / "clip.avi"
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, (64, 48))
    rng = np.random.default_rng(0)
    for _ in range(40):
        w.write(rng.integers(0, 255, (48, 64, 3), dtype=np.uint8))
    w.release()
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    o = run_cli(["track", str(path), "--tracker", "kcf", "--param",
                 "init_box_xywh=10,10,20,20", "--out", str(tmp_path / "b.txt"), "--json"])
    assert o.rc == 0
    res = _json(o.stdout)
    (warning,) = res["warnings"]
    assert f"video ended after {res['frames']} of the 40 frames" in warning
    assert any(p.startswith("warning: ") and "last good frame" in p for p in o.progress)


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_listen_counts_malformed_opentrackio_samples(tmp_path: Path) -> None:
    from engine.outputs import opentrackio as ot

    port = _free_port()
    big = "1" + "0" * 400
    payloads = [
        b'{"transforms": {"translation": {"x": 1}}}',
        b'{"transforms": [{"translation": {"x": ' + big.encode() + b"}}]}",
        b'{"transforms": [{"translation": {"x": 1.5}}]}',
    ]

    listening = threading.Event()

    def send() -> None:
        assert listening.wait(30), "listen never said it was listening"
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            for i, p in enumerate(payloads):
                for pkt in ot.build_packets(p, i, "json"):
                    s.sendto(pkt, ("127.0.0.1", port))
                time.sleep(0.05)

    t = threading.Thread(target=send)
    t.start()
    o = run_cli(["listen", "--opentrackio", str(port), "--seconds", "20", "--count", "1",
                 "--json"], budget_s=30,
                on_progress=lambda msg: msg.startswith("listening on") and listening.set())
    t.join()
    assert o.rc == 0, o.stderr
    res = _json(o.stdout)
    assert (res["opentrackio"], res["errors"]) == (1, 2)
    assert "x 1.500" in o.stdout


def test_calibrate_chessboard_warns_for_each_skipped_photo(tmp_path: Path) -> None:
    from tests.engine.test_bad_input import _board

    rng = np.random.default_rng(2)
    paths = []
    for i in range(4):
        img = _board((640, 480))
        M = cv2.getRotationMatrix2D((320, 240), float(rng.uniform(-15, 15)), 1.0)
        img = cv2.warpAffine(img, M, (640, 480), borderValue=255)
        if i == 2:
            img = cv2.rotate(img, cv2.ROTATE_90_COUNTERCLOCKWISE)
        paths.append(tmp_path / f"c{i}.png")
        cv2.imwrite(str(paths[-1]), img)
    o = run_cli(["calibrate", "chessboard", *map(str, paths), "--json"], budget_s=60)
    assert o.rc == 0, o.stderr
    res = _json(o.stdout)
    assert res["n_used"] == 3
    assert res["skipped"] == [str(paths[2])]
    assert [p for p in o.progress if p.startswith("warning:")] == [
        f"warning: {paths[2]}: skipped ({res['skipped_reasons'][0]})"]


# ------------------------------------------------------------------------------ live beacons
def _dg(t: float | None, a: float = 5.0) -> bytes:
    msg: dict[str, object] = {"ranges_m": {"A": a, "B": 6.0, "C": 7.0, "D": 8.0}}
    if t is not None:
        msg["timestamp_s"] = t
    return json.dumps(msg).encode()


def _track_udp(tmp_path: Path, plan: list[bytes | float], *, sigint_after: bool = False,
               extra: str = "") -> tuple[object, Path]:
    """``track beacons-udp`` in-process while a thread sends ``plan`` (bytes = a datagram,
    float = a pause in seconds) once the source is listening."""
    port = _free_port()
    out = tmp_path / "traj.txt"
    started = threading.Event()

    def send() -> None:
        started.wait(30)
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            for item in plan:
                if isinstance(item, float):
                    time.sleep(item)
                else:
                    s.sendto(item, ("127.0.0.1", port))
                    time.sleep(0.03)
        if sigint_after:
            time.sleep(1.0)
            signal.raise_signal(signal.SIGINT)  # as Ctrl-C in the terminal would

    def on_progress(msg: str) -> None:
        if msg.startswith("tracking beacon UDP"):
            started.set()

    t = threading.Thread(target=send)
    t.start()
    idle = "" if sigint_after else ",idle_timeout=1.5"
    o = run_cli(["track", f"beacons-udp:port={port}{idle}{extra}", "--tracker", "beacon-slam",
                 "--out", str(out), "--json"], budget_s=60, on_progress=on_progress)
    t.join()
    return o, out


def test_live_beacons_survive_pauses_late_and_bad_readings(tmp_path: Path) -> None:
    big = ('{"timestamp_s": 1.05, "ranges_m": {"A": ' + "1" + "0" * 400 + "}}").encode()
    plan: list[bytes | float] = [_dg(0.1 * i) for i in range(1, 11)]  # 0.1 .. 1.0 s
    plan += [1.2]  # a pause longer than the heartbeat
    plan += [_dg(0.5), big, _dg(None), b"garbage"]  # late, absurd number, no clock, junk
    plan += [_dg(1.0 + 0.1 * i) for i in range(1, 11)]  # 1.1 .. 2.0 s
    o, out = _track_udp(tmp_path, plan)
    assert o.rc == 0, (o.stderr, o.progress[-5:])
    res = _json(o.stdout)
    inp = res["input"]
    assert inp["clock"] == "sender"
    assert inp["out_of_order"] == 1
    assert inp["malformed"] == 3  # the 400-digit range... then the clockless and junk datagrams
    assert inp["heartbeats"] >= 2
    stamps = [float(ln.split()[0]) for ln in out.read_text().splitlines()[1:]]
    assert stamps == sorted(stamps)
    assert len(stamps) == res["frames"] == 21  # 10 + the 400-digit one's B,C,D step + 10
    assert stamps[0] == pytest.approx(0.1)
    assert stamps[-1] == pytest.approx(2.0)


def test_live_beacons_without_sender_time_use_the_receive_clock(tmp_path: Path) -> None:
    plan: list[bytes | float] = [_dg(None) for _ in range(5)] + [0.7] + [_dg(None),
                                                                         _dg(99.0)]
    o, out = _track_udp(tmp_path, plan)
    assert o.rc == 0, o.stderr
    inp = _json(o.stdout)["input"]
    assert (inp["clock"], inp["ignored_timestamps"], inp["out_of_order"]) == ("receive", 1, 0)
    stamps = [float(ln.split()[0]) for ln in out.read_text().splitlines()[1:]]
    assert len(stamps) == 7
    assert stamps == sorted(stamps)
    assert stamps[-1] < 30  # seconds since the source started, not the sender's 99 s


def test_ctrl_c_on_a_live_source_writes_the_trajectory(tmp_path: Path) -> None:
    o, out = _track_udp(tmp_path, [_dg(0.1 * i) for i in range(1, 9)], sigint_after=True)
    assert o.rc == 0, o.stderr  # Ctrl-C is how a live run ends
    res = _json(o.stdout)
    assert (res["partial"], res["stop_reason"]) == (True, "interrupted by SIGINT")
    assert 1 <= res["frames"] <= 8  # readings still queued when the signal came are not used
    assert len(out.read_text().splitlines()) == 1 + res["frames"]
