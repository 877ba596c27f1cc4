"""CLI: output options, ``studiotrack record`` (with outputs) and ``studiotrack replay``."""

from __future__ import annotations

import argparse
import json
import socket

import pytest

from app.cli import main
from app.commands._outputs_cli import add_output_arguments, config_from_args
from engine.outputs import OutputError
from engine.outputs import freed as fd
from tests.conftest import shared_path


def _args(*argv: str) -> argparse.Namespace:
    p = argparse.ArgumentParser()
    add_output_arguments(p)
    return p.parse_args(list(argv))


def test_output_options_build_a_config():
    assert config_from_args(_args()) is None
    cfg = config_from_args(
        _args(
            "--freed",
            "127.0.0.1:40000",
            "--freed-camera-id",
            "3",
            "--opentrackio",
            "multicast,cbor",
            "--opentrackio-source",
            "5",
            "--output-delay-ms",
            "pan=33,x=40",
        )
    )
    f, o = cfg.targets
    assert (f.protocol, f.host, f.port, f.effective_bind) == (
        "freed",
        "127.0.0.1",
        40000,
        "127.0.0.1",
    )
    assert (o.host, o.port, o.encoding) == ("239.135.1.5", 55555, "cbor")
    assert cfg.freed.camera_id == 3
    assert (cfg.delays.pan_ms, cfg.delays.x_ms, cfg.delays.y_ms) == (33.0, 40.0, 0.0)
    cfg = config_from_args(_args("--opentrackio", "10.0.0.5:6000", "--output-delay-ms", "20"))
    assert cfg.targets[0].effective_bind == "0.0.0.0"
    assert cfg.delays.roll_ms == 20.0


@pytest.mark.parametrize(
    "bad",
    [
        ["--freed", "127.0.0.1"],
        ["--freed", "h:x"],
        ["--freed", "h:1,cbor"],
        ["--opentrackio", "h:99999"],
        ["--freed", "h:1", "--output-delay-ms", "yaw=3"],
    ],
)
def test_bad_output_options_raise_clear_errors(bad):
    with pytest.raises(OutputError):
        config_from_args(_args(*bad))


def test_record_with_outputs_then_replay(tmp_path, capsys, udp_rx):
    tum = shared_path("tum_fr1_xyz_37")
    rx = udp_rx()
    sess = tmp_path / "sess"
    rc = main(
        [
            "record",
            str(tum),
            "--tracker",
            "ground-truth",
            "--out",
            str(sess),
            "--max-frames",
            "6",
            "--freed",
            f"127.0.0.1:{rx.getsockname()[1]}",
        ]
    )
    assert rc == 0
    got = [fd.decode_d1(rx.recv(64)) for _ in range(6)]
    assert all(p.camera_id == 1 for p in got)
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert out["frames"] == 6
    stats = json.loads((sess / "outputs.json").read_text())
    assert stats["targets"][0]["packets_sent"] == 6
    traj = tmp_path / "traj.txt"
    assert main(["replay", str(sess), "--out", str(traj), "--json"]) == 0
    res = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert res["identical"] is True
    assert res["frames"] == 6
    assert len([ln for ln in traj.read_text().splitlines() if not ln.startswith("#")]) == 6
    assert main(["replay", str(sess), "--recorded", "--out", str(tmp_path / "t.csv")]) == 0


def test_replay_of_a_missing_session_is_a_clear_error(tmp_path, capsys):
    assert main(["replay", str(tmp_path / "nope")]) == 2
    assert "index.json: not found" in capsys.readouterr().err


def test_listen_decodes_packets(capsys):
    import threading

    from engine.outputs import opentrackio as ot
    from engine.progress import redirected

    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()
    rcs = []
    t = threading.Thread(
        target=lambda: rcs.append(
            main(
                [
                    "listen",
                    "--freed",
                    str(port),
                    "--opentrackio",
                    str(port + 1),
                    "--seconds",
                    "5",
                    "--count",
                    "3",
                    "--json",
                ]
            )
        )
    )
    listening = threading.Event()
    with redirected(lambda msg: msg.startswith("listening on") and listening.set()):
        t.start()
        assert listening.wait(30), "listen never said it was listening"
        tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        golden = bytes.fromhex("d100df78aa0047ef" + "00" * 13 + "4000001501d1ff12")
        tx.sendto(golden, ("127.0.0.1", port))
        tx.sendto(golden[:-1] + b"\x00", ("127.0.0.1", port))  # bad checksum: counted
        for p in ot.build_packets(b'{"tracker":{"status":"LOST"}}', 1, "json", max_segment=10):
            tx.sendto(p, ("127.0.0.1", port + 1))
        tx.sendto(golden, ("127.0.0.1", port))
        tx.close()
        t.join(10)
    out = capsys.readouterr().out.strip().splitlines()
    res = json.loads(out[-1])
    assert rcs == [0]
    assert (res["freed"], res["opentrackio"], res["errors"]) == (2, 1, 1)
    assert any("pan -65.057" in ln for ln in out)
    assert any("LOST" in ln for ln in out)


def test_track_sends_one_freed_and_one_opentrackio_packet_per_frame(tmp_path, capsys, udp_rx):
    from engine.outputs import opentrackio as ot

    tum = shared_path("tum_fr1_xyz_37")
    rx_f, rx_o = udp_rx(), udp_rx()
    rc = main(["track", str(tum), "--tracker", "ground-truth",
               "--out", str(tmp_path / "t.txt"), "--max-frames", "5", "--json",
               "--freed", f"127.0.0.1:{rx_f.getsockname()[1]}", "--freed-camera-id", "9",
               "--opentrackio", f"127.0.0.1:{rx_o.getsockname()[1]},cbor"])
    assert rc == 0
    freed = [fd.decode_d1(rx_f.recv(64)) for _ in range(5)]
    samples = [ot.decode_datagrams([rx_o.recv(4096)])[0] for _ in range(5)]
    assert {p.camera_id for p in freed} == {9}
    assert [s["timing"]["sequenceNumber"] for s in samples] == [0, 1, 2, 3, 4]
    assert "outputs sent: freed:127.0.0.1" in capsys.readouterr().err
