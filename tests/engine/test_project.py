"""Studio project folder: round trip, backups, corrupt/newer projects, crash during save."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from engine.camera import Intrinsics
from engine.keyframes.store import KeyframeStore
from engine.project import AnnotatedPoint, Project, ProjectError, open_project


def _store(n: int = 2) -> KeyframeStore:
    intr = Intrinsics(fx=100.0, fy=100.0, cx=31.5, cy=23.5, width=64, height=48)
    store = KeyframeStore(intr)
    rng = np.random.default_rng(0)
    for i in range(n):
        T = np.eye(4)
        T[0, 3] = 0.1 * i
        store.add(
            T,
            rng.integers(0, 255, (48, 64), dtype=np.uint8),
            np.full((48, 64), 2.0 + i, np.float32),
        )
    return store


def _project() -> Project:
    store = _store()
    return Project(
        name="studio A",
        intrinsics=store.intrinsics,
        keyframes=store,
        annotations=[
            AnnotatedPoint(
                0, {0: (10.5, 20.25), 1: (12.0, 20.0)}, np.array([0.1, 0.2, 2.0]), "desk corner"
            )
        ],
        presenter_models={"anna": {"height_m": 1.7}},
        params={"fusion": {"delta_inv_m": 0.005}},
    )


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(folder)): p.read_bytes()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def test_round_trip(tmp_path: Path) -> None:
    prj = _project()
    prj.save(tmp_path / "p")
    assert not prj.dirty
    assert prj.revision == 1
    back = open_project(tmp_path / "p")
    assert back.name == "studio A"
    assert back.revision == 1
    assert back.intrinsics == prj.intrinsics
    assert len(back.keyframes) == 2
    np.testing.assert_allclose(back.keyframes.keyframes[1].T_world_cam[:3, 3], [0.1, 0, 0])
    np.testing.assert_allclose(back.keyframes.keyframes[1].depth_m, 3.0)
    a = back.annotations[0]
    assert a.label == "desk corner"
    assert a.observations_px == {0: (10.5, 20.25), 1: (12.0, 20.0)}
    np.testing.assert_allclose(a.X_world, [0.1, 0.2, 2.0])
    assert back.presenter_models == {"anna": {"height_m": 1.7}}
    assert back.params == {"fusion": {"delta_inv_m": 0.005}}


def test_save_keeps_previous_version_as_backup(tmp_path: Path) -> None:
    prj = _project()
    prj.save(tmp_path / "p")
    prj.annotations.clear()
    prj.name = "second"
    prj.save()
    assert prj.revision == 2
    assert (tmp_path / "p" / "project.json.bak").exists()
    bak = json.loads((tmp_path / "p" / "project.json.bak").read_text())
    assert bak["data"] == "rev-0001"
    assert (tmp_path / "p" / "rev-0001").is_dir()
    # the backup is a complete, openable previous version
    bak_dir = tmp_path / "bak"
    bak_dir.mkdir()
    (bak_dir / "project.json").write_text(json.dumps(bak))
    import shutil

    shutil.copytree(tmp_path / "p" / "rev-0001", bak_dir / "rev-0001")
    assert len(open_project(bak_dir).annotations) == 1
    prj.save()  # third save: only the current and previous revision stay
    assert sorted(p.name for p in (tmp_path / "p").glob("rev-*")) == ["rev-0002", "rev-0003"]


def test_crash_during_save_loses_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    prj = _project()
    prj.save(tmp_path / "p")
    before = _snapshot(tmp_path / "p")
    prj.annotations.clear()
    calls = {"n": 0}
    import engine.persist as persist

    real = persist.atomic_write_bytes

    def flaky(path: Path, data: bytes) -> None:
        calls["n"] += 1
        if calls["n"] == 3:  # mid-way through the new revision
            raise OSError("disk full (simulated)")
        real(path, data)

    monkeypatch.setattr(persist, "atomic_write_bytes", flaky)
    with pytest.raises(OSError, match="simulated"):
        prj.save()
    monkeypatch.setattr(persist, "atomic_write_bytes", real)
    assert _snapshot(tmp_path / "p") == before
    assert not list((tmp_path / "p").glob(".rev-*"))
    assert len(open_project(tmp_path / "p").annotations) == 1


def test_crash_at_commit_point_keeps_previous(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    prj = _project()
    prj.save(tmp_path / "p")
    prj.annotations.clear()
    import engine.persist as persist

    def boom(path: Path, obj: object) -> None:
        raise KeyboardInterrupt  # killed just before project.json is replaced

    monkeypatch.setattr(
        persist,
        "atomic_write_json",
        lambda p, o: boom(p, o) if Path(p).name == "project.json" else _real_json(p, o),
    )
    with pytest.raises(KeyboardInterrupt):
        prj.save()
    monkeypatch.undo()
    back = open_project(tmp_path / "p")
    assert back.revision == 1
    assert len(back.annotations) == 1
    prj.save()  # the next save succeeds and uses a fresh revision
    assert open_project(tmp_path / "p").annotations == []


def _real_json(p: Path, o: object) -> None:
    from engine.persist import atomic_write_text

    atomic_write_text(Path(p), json.dumps(o, indent=2) + "\n")


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (lambda d: d.update(version=2), "newer than this StudioTrack supports"),
        (lambda d: d.update(format="other"), "not a StudioTrack project"),
        (lambda d: d.update(data="rev-0099"), "missing"),
        (lambda d: d.update(data="../x"), "must name a rev-NNNN folder"),
    ],
)
def test_bad_index_fails_clearly_and_changes_nothing(tmp_path: Path, mutate, message) -> None:  # type: ignore[no-untyped-def]
    _project().save(tmp_path / "p")
    idx = tmp_path / "p" / "project.json"
    d = json.loads(idx.read_text())
    mutate(d)
    idx.write_text(json.dumps(d))
    before = _snapshot(tmp_path / "p")
    with pytest.raises(ProjectError, match=message) as err:
        open_project(tmp_path / "p")
    assert ("\n" not in str(err.value) and "project.json" in str(err.value)) or "rev-" in str(
        err.value
    )
    assert _snapshot(tmp_path / "p") == before


def test_corrupt_files_fail_clearly(tmp_path: Path) -> None:
    _project().save(tmp_path / "p")
    (tmp_path / "p" / "project.json").write_text("{ not json")
    with pytest.raises(ProjectError, match=r"project.json: corrupt JSON at line 1"):
        open_project(tmp_path / "p")
    _project().save(tmp_path / "q")
    (tmp_path / "q" / "rev-0001" / "annotations.json").write_text('{"format": 1}')
    with pytest.raises(ProjectError, match=r"annotations\.json: not a studiotrack-annotations"):
        open_project(tmp_path / "q")
    (tmp_path / "q" / "rev-0001" / "keyframes" / "kf_0000_depth.png").write_bytes(b"junk")
    with pytest.raises(ProjectError, match=r"kf_0000_depth\.png"):
        open_project(tmp_path / "q")
    with pytest.raises(ProjectError, match="not found"):
        open_project(tmp_path / "nothing")


def test_save_refuses_foreign_folder(tmp_path: Path) -> None:
    (tmp_path / "f").mkdir()
    (tmp_path / "f" / "mine.txt").write_text("x")
    with pytest.raises(ProjectError, match="not empty"):
        _project().save(tmp_path / "f")
    with pytest.raises(ProjectError, match="Save As"):
        Project().save()
