"""Studio project folder: calibration, keyframe store, annotations, presenter models, params.

A project is what the operator prepares before a show (Tykkälä 2014 sec. 6.1: sweep, fuse,
annotate, bundle-adjust). Layout::

    project.json        {"format": "studiotrack-project", "version": 1, "name": ...,
                         "revision": 3, "data": "rev-0003", "saved_utc": ...}
    project.json.bak    the previous project.json (points at the previous revision)
    project.json.damaged-<time>  a damaged project.json found by a save (kept, never reused)
    rev-0003/           the current revision, written completely before project.json
        camera.json         calibration (engine.camera format), optional
        floor.json          floor calibration of the presenter's second (overhead) view
                            (engine.floor format), optional; one made with the project's
                            lens file (``lens_from_project``) takes lens.json's samples
                            when the project opens
        keyframes/          keyframe store (engine.keyframes.store format), optional
        annotations.json    annotated points: observations per keyframe, 3D point
        presenter.json      presenter models slot (JSON objects by name)
        params.json         parameter groups (JSON objects by group name)
        lens.json           lens file over zoom/focus (engine.lens format), optional
        studio.json         studio frame and nodal offset ({"format": "studiotrack-studio",
                            "version": 1, "T_world_studio": 4x4 | null,
                            "nodal_offset": {x_m, y_m, z_m, pan_deg, tilt_deg, roll_deg}})
        ptz.json            pan-tilt calibration chain (engine.ptz.calibration format), optional
    rev-0002/           the previous revision = the backup of the previous version

Saving writes a new ``rev-NNNN`` folder through a temporary name, renames it, then replaces
``project.json`` atomically (the commit point): a crash at any moment leaves the previous
version loadable. Only after the commit are revisions older than the previous one removed.
Opening never writes anything.

Set-up documents (lens file, studio frame and nodal offset, pan-tilt calibration) are one
versioned JSON file each, read with :func:`read_document` (missing = not set, anything
malformed = one line naming the file and field); a newer version than this StudioTrack
knows is refused, never guessed.
"""

from __future__ import annotations

import contextlib
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from engine.camera import Intrinsics
from engine.errors import CalibrationError, StudioTrackError
from engine.persist import read_json_file
from engine.validate import shown

F64 = NDArray[np.float64]

PROJECT_FORMAT = "studiotrack-project"
PROJECT_VERSION = 1
INDEX_NAME = "project.json"
#: revisions are numbered 1..MAX_REVISION (rev-NNNN folder names stay short)
MAX_REVISION = 999_999_999
ANNOTATIONS_FORMAT = "studiotrack-annotations"
STUDIO_FORMAT = "studiotrack-studio"
STUDIO_VERSION = 1


class ProjectError(StudioTrackError):
    """A studio project cannot be opened or saved (missing, corrupt, newer version...)."""


@dataclass
class AnnotatedPoint:
    """One physical point clicked by the operator in several keyframes.

    ``observations_px`` maps keyframe id -> (u, v) pixel (distorted image coordinates);
    ``X_world`` is the current 3D estimate (None until triangulated / bundle-adjusted).
    """

    id: int
    observations_px: dict[int, tuple[float, float]] = field(default_factory=dict)
    X_world: F64 | None = None
    label: str = ""

    def to_json(self) -> dict[str, Any]:
        return {
            "id": self.id,
            "label": self.label,
            "observations_px": {
                str(k): [float(u), float(v)] for k, (u, v) in sorted(self.observations_px.items())
            },
            "X_world": None if self.X_world is None else [float(x) for x in self.X_world],
        }

    @classmethod
    def from_json(cls, d: Any, where: str) -> AnnotatedPoint:
        try:
            obs = {int(k): (float(v[0]), float(v[1])) for k, v in d["observations_px"].items()}
            X = d.get("X_world")
            X_world = None if X is None else np.asarray([float(x) for x in X], dtype=np.float64)
            if X_world is not None and X_world.shape != (3,):
                raise ValueError("X_world must have 3 numbers")
            return cls(int(d["id"]), obs, X_world, str(d.get("label", "")))
        except (KeyError, TypeError, ValueError, IndexError, AttributeError) as exc:
            raise ProjectError(f"{where}: malformed annotated point ({exc!s})") from None


@dataclass
class Project:
    """In-memory studio project; ``save``/``open_project`` move it to and from a folder."""

    name: str = "studio"
    intrinsics: Intrinsics | None = None
    floor_calibration: Any | None = None  # engine.floor.FloorCalibration
    keyframes: Any | None = None  # engine.keyframes.store.KeyframeStore
    annotations: list[AnnotatedPoint] = field(default_factory=list)
    presenter_models: dict[str, Any] = field(default_factory=dict)
    params: dict[str, Any] = field(default_factory=dict)
    #: engine.lens.LensFile (may be incomplete while being calibrated) or None
    lens: Any | None = None
    #: engine.outputs.studio_frame.StudioFrame or None (identity)
    studio_frame: Any | None = None
    #: engine.outputs.studio_frame.CameraOffset or None (none)
    nodal_offset: Any | None = None
    #: engine.ptz.calibration.PtzCalibration or None
    ptz: Any | None = None
    folder: Path | None = None
    revision: int = 0
    dirty: bool = False

    def mark_dirty(self) -> None:
        self.dirty = True

    def next_point_id(self) -> int:
        return 1 + max((p.id for p in self.annotations), default=-1)

    # -- saving --------------------------------------------------------------------------
    def save(self, folder: str | Path | None = None) -> Path:
        """Write the project to ``folder`` (default: where it was opened/saved)."""
        target = Path(folder) if folder is not None else self.folder
        if target is None:
            raise ProjectError("project has no folder yet: use Save As")
        if target.exists() and not target.is_dir():
            raise ProjectError(f"{target}: exists and is not a folder")
        index_path = target / INDEX_NAME
        prev_rev = 0
        prev_data: str | None = None
        damaged = False
        if index_path.exists():
            try:
                prev = _read_index(target)
                prev_rev, prev_data = int(prev["revision"]), str(prev["data"])
            except ProjectError:
                # a damaged index is kept aside (project.json.damaged-<time>) and the good
                # backup project.json.bak is left alone: neither is overwritten silently
                damaged = True
                prev_rev = _max_revision(target)
        elif target.is_dir() and any(target.iterdir()):
            raise ProjectError(f"{target}: folder is not empty and holds no {INDEX_NAME}")
        target.mkdir(parents=True, exist_ok=True)
        _remove_stale_temps(target)
        rev = max(prev_rev, _max_revision(target)) + 1
        if rev > MAX_REVISION:
            raise ProjectError(f"{target}: revision {rev} is beyond {MAX_REVISION}; save the "
                               "project to a new folder")
        data_name = f"rev-{rev:04d}"
        tmp = target / f".{data_name}.tmp"
        if tmp.exists():
            shutil.rmtree(tmp)
        try:
            self._write_data(tmp)
            tmp.rename(target / data_name)
        except BaseException:
            with contextlib.suppress(OSError):
                shutil.rmtree(tmp)
            raise
        from engine.persist import atomic_write_json, backup_existing

        if damaged:
            stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
            shutil.copy2(index_path, _free_name(index_path.with_name(
                f"{INDEX_NAME}.damaged-{stamp}")))
        elif index_path.exists():
            backup_existing(index_path)  # project.json.bak -> previous revision
        index = {
            "format": PROJECT_FORMAT,
            "version": PROJECT_VERSION,
            "name": self.name,
            "revision": rev,
            "data": data_name,
            "saved_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        }
        atomic_write_json(index_path, index)  # the commit point
        # keep the current and the previous revision (the backup), drop older ones
        if prev_data is not None:  # after a damaged index, remove nothing
            keep = {data_name, prev_data}
            for old in target.glob("rev-*"):
                if old.is_dir() and old.name not in keep:
                    shutil.rmtree(old, ignore_errors=True)
        self.folder, self.revision, self.dirty = target, rev, False
        return index_path

    def _write_data(self, data: Path) -> None:
        from engine.camera import save_camera_json
        from engine.persist import atomic_write_json

        data.mkdir(parents=True)
        if self.intrinsics is not None:
            save_camera_json(self.intrinsics, data / "camera.json")
        if self.floor_calibration is not None:
            atomic_write_json(data / "floor.json", self.floor_calibration.to_json())
        if self.keyframes is not None:
            self.keyframes.save(data / "keyframes")
        atomic_write_json(
            data / "annotations.json",
            {
                "format": ANNOTATIONS_FORMAT,
                "version": 1,
                "points": [p.to_json() for p in self.annotations],
            },
        )
        atomic_write_json(data / "presenter.json", {"version": 1, "models": self.presenter_models})
        atomic_write_json(data / "params.json", {"version": 1, "groups": self.params})
        if self.lens is not None:
            atomic_write_json(data / "lens.json", self.lens.to_json())
        if self.studio_frame is not None or self.nodal_offset is not None:
            atomic_write_json(data / "studio.json", {
                "format": STUDIO_FORMAT, "version": STUDIO_VERSION,
                "T_world_studio": None if self.studio_frame is None
                else self.studio_frame.to_json_dict()["T_world_studio"],
                "nodal_offset": None if self.nodal_offset is None
                else self.nodal_offset.to_json_dict(),
            })
        if self.ptz is not None:
            atomic_write_json(data / "ptz.json", self.ptz.to_json())

    def output_config(self, config: Any) -> Any:
        """``config`` (an :class:`engine.outputs.sender.OutputConfig`) with this project's
        studio frame and nodal offset."""
        from dataclasses import replace

        from engine.outputs.studio_frame import CameraOffset, StudioFrame

        return replace(config, studio=self.studio_frame or StudioFrame(),
                       offset=self.nodal_offset or CameraOffset())


def new_project(name: str = "studio", intrinsics: Intrinsics | None = None) -> Project:
    """An empty, unsaved project (not dirty until something is added: closing an empty
    project asks nothing)."""
    return Project(name=name, intrinsics=intrinsics, dirty=False)


def open_project(folder: str | Path) -> Project:
    """Read a project; corrupt, missing or newer-version projects raise ProjectError.

    Nothing on disk is written or removed.
    """
    folder = Path(folder)
    if folder.name == INDEX_NAME and folder.is_file():
        folder = folder.parent
    index = _read_index(folder)
    data = folder / str(index["data"])
    if not data.is_dir():
        raise ProjectError(f"{data}: revision folder named in {folder / INDEX_NAME} is missing")
    intr = None
    if (data / "camera.json").exists():
        from engine.camera import load_camera_json

        try:
            intr = load_camera_json(data / "camera.json")
        except CalibrationError as exc:
            raise ProjectError(str(exc)) from None
    floor = None
    if (data / "floor.json").exists():
        from engine.floor import floor_calibration_from_json

        try:
            floor = floor_calibration_from_json(_read_json(data / "floor.json"),
                                                str(data / "floor.json"))
        except CalibrationError as exc:
            raise ProjectError(str(exc)) from None
    store = None
    if (data / "keyframes").exists():
        from engine.keyframes.store import KeyframeStore, KeyframeStoreError

        try:
            store = KeyframeStore.load(data / "keyframes")
        except KeyframeStoreError as exc:
            raise ProjectError(str(exc)) from None
    ann = _read_json(data / "annotations.json")
    if not isinstance(ann, dict) or ann.get("format") != ANNOTATIONS_FORMAT:
        raise ProjectError(f"{data / 'annotations.json'}: not a {ANNOTATIONS_FORMAT} file")
    if not isinstance(ann.get("version"), int) or ann["version"] > 1:
        raise ProjectError(
            f"{data / 'annotations.json'}: version {ann.get('version')!r} is newer than "
            "this StudioTrack supports (1)"
        )
    pts_raw = ann.get("points")
    if not isinstance(pts_raw, list):
        raise ProjectError(f"{data / 'annotations.json'}: 'points' must be a list")
    points = [
        AnnotatedPoint.from_json(p, f"{data / 'annotations.json'} point #{i}")
        for i, p in enumerate(pts_raw)
    ]
    pres = _read_json(data / "presenter.json")
    params = _read_json(data / "params.json")
    if not isinstance(pres, dict) or not isinstance(pres.get("models"), dict):
        raise ProjectError(f"{data / 'presenter.json'}: expected {{'models': {{...}}}}")
    if not isinstance(params, dict) or not isinstance(params.get("groups"), dict):
        raise ProjectError(f"{data / 'params.json'}: expected {{'groups': {{...}}}}")
    lens, studio_frame, nodal, ptz = _read_setup(data)
    if floor is not None and floor.lens_from_project and lens is not None and lens.complete:
        # a floor camera model on the project's lens file follows the file's current samples
        try:
            floor = floor.with_lens(lens)
        except CalibrationError as exc:
            raise ProjectError(f"{data / 'floor.json'}: {exc}") from None
    return Project(
        name=str(index.get("name", folder.name)),
        intrinsics=intr if intr is not None else (store.intrinsics if store is not None else None),
        floor_calibration=floor,
        keyframes=store,
        annotations=points,
        presenter_models=dict(pres["models"]),
        params=dict(params["groups"]),
        lens=lens,
        studio_frame=studio_frame,
        nodal_offset=nodal,
        ptz=ptz,
        folder=folder,
        revision=int(index["revision"]),
        dirty=False,
    )


def read_document(path: Path, fmt: str, version: int) -> dict[str, Any] | None:
    """A set-up document: None when the file is absent; its JSON object once the format is
    ``fmt`` and the version a known one (else one-line :class:`ProjectError`)."""
    if not path.exists():
        return None
    raw = _read_json(path)
    if not isinstance(raw, dict) or raw.get("format") != fmt:
        raise ProjectError(f"{path}: not a {fmt} file")
    ver = raw.get("version")
    if isinstance(ver, bool) or not isinstance(ver, int) or ver < 1:
        raise ProjectError(f"{path}: 'version' must be a positive integer, got {ver!r}")
    if ver > version:
        raise ProjectError(f"{path}: version {ver} is newer than this StudioTrack supports "
                           f"({version})")
    return raw


def _read_setup(data: Path) -> tuple[Any, Any, Any, Any]:
    """Lens file, studio frame, nodal offset and pan-tilt calibration of a revision."""
    from engine.lens import LENS_FORMAT, LENS_VERSION, LensError, LensFile
    from engine.outputs import OutputError
    from engine.outputs.studio_frame import CameraOffset, StudioFrame

    lens = None
    raw = read_document(data / "lens.json", LENS_FORMAT, LENS_VERSION)
    if raw is not None:
        try:  # a table being calibrated one sample at a time may be incomplete
            lens = LensFile.from_json(raw, str(data / "lens.json"), require_complete=False)
        except LensError as exc:
            raise ProjectError(str(exc)) from None
    studio_frame = nodal = None
    raw = read_document(data / "studio.json", STUDIO_FORMAT, STUDIO_VERSION)
    if raw is not None:
        where = str(data / "studio.json")
        try:
            if raw.get("T_world_studio") is not None:
                studio_frame = StudioFrame.from_json_dict(
                    {"T_world_studio": raw["T_world_studio"]})
            if raw.get("nodal_offset") is not None:
                nodal = CameraOffset.from_json_dict(raw["nodal_offset"], f"{where}: nodal_offset")
        except OutputError as exc:
            msg = str(exc)
            raise ProjectError(msg if msg.startswith(where) else f"{where}: {msg}") from None
    ptz = None
    from engine.ptz.calibration import PTZ_FORMAT, PTZ_VERSION, PtzCalibration

    raw = read_document(data / "ptz.json", PTZ_FORMAT, PTZ_VERSION)
    if raw is not None:
        try:
            ptz = PtzCalibration.from_json(raw, str(data / "ptz.json"))
        except CalibrationError as exc:
            raise ProjectError(str(exc)) from None
    return lens, studio_frame, nodal, ptz


def _read_json(path: Path) -> Any:
    return read_json_file(path, ProjectError, corrupt="corrupt JSON")


def _read_index(folder: Path) -> dict[str, Any]:
    if not folder.is_dir():
        raise ProjectError(f"{folder}: project folder not found")
    path = folder / INDEX_NAME
    raw = _read_json(path)
    if not isinstance(raw, dict) or raw.get("format") != PROJECT_FORMAT:
        raise ProjectError(f"{path}: not a StudioTrack project ({PROJECT_FORMAT})")
    version = raw.get("version")
    if not isinstance(version, int) or isinstance(version, bool):
        raise ProjectError(f"{path}: 'version' must be an integer, got {version!r}")
    if version > PROJECT_VERSION:
        raise ProjectError(
            f"{path}: project version {version} is newer than this StudioTrack supports "
            f"({PROJECT_VERSION}); update StudioTrack"
        )
    if version < 1:
        raise ProjectError(f"{path}: unknown project version {version}")
    data = raw.get("data")
    rev = raw.get("revision")
    if not isinstance(data, str) or not data.startswith("rev-") or "/" in data or "\\" in data:
        raise ProjectError(f"{path}: 'data' must name a rev-NNNN folder, got {data!r}")
    if not isinstance(rev, int) or isinstance(rev, bool):
        raise ProjectError(f"{path}: 'revision' must be an integer, got {rev!r}")
    if not 0 <= rev <= MAX_REVISION:
        raise ProjectError(f"{path}: 'revision' {shown(rev)} is outside 0..{MAX_REVISION}")
    return raw


def _max_revision(folder: Path) -> int:
    """The highest rev-NNNN folder number (names beyond MAX_REVISION are not revisions)."""
    best = 0
    for p in folder.glob("rev-*"):
        digits = p.name[4:]
        if digits.isdigit() and len(digits) <= len(str(MAX_REVISION)):
            best = max(best, min(int(digits), MAX_REVISION))
    return best


def _free_name(path: Path) -> Path:
    """``path``, or ``path.1``, ``path.2``... the first that does not exist."""
    candidate, n = path, 0
    while candidate.exists():
        n += 1
        candidate = path.with_name(f"{path.name}.{n}")
    return candidate


def _remove_stale_temps(folder: Path) -> None:
    """Temporary revision folders of an interrupted save (never referenced by project.json)."""
    for p in folder.glob(".rev-*.tmp"):
        shutil.rmtree(p, ignore_errors=True)
