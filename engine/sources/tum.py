"""TUM RGB-D benchmark folders (Sturm et al. 2012, "A Benchmark for the Evaluation of
RGB-D SLAM Systems"; file formats: https://cvg.cit.tum.de/data/datasets/rgbd-dataset/file_formats).

A folder holds ``rgb.txt`` and ``depth.txt`` (``timestamp filename`` per line, ``#`` comments),
the PNGs they list, optionally ``groundtruth.txt`` (``timestamp tx ty tz qx qy qz qw``) and
``camera.json``. Colour and depth are recorded unsynchronised; each colour image is paired
with a depth image within ``max_dt_s`` (20 ms), one-to-one and in time order, keeping as many
pairs as possible (see :func:`associate_one_to_one`). Colour images without a
partner are dropped (counted in :attr:`TumSource.dropped_rgb`). A folder without
``depth.txt`` is read as colour only (``Frame.depth_m`` None).

Depth latency. The Kinect of the TUM benchmark recordings stamps its depth images later than
the scene they show: on freiburg1_xyz, trajectories from depth alone (OpenCV's ICP odometry)
match the ground truth best with their poses stamped 35-40 ms before the colour stamps,
trajectories from colour (photometric) at 0 ms, while the depth stamps are only ~15 ms before
the colour ones: the depth shows the scene ~20 ms before its stamp. A recording of the
benchmark (``depth.txt`` names its ``rgbd_dataset_freiburg...`` bag in the header) therefore
has ``depth_latency_s`` = :data:`TUM_KINECT_DEPTH_LATENCY_S` (other folders, e.g. ours: 0):
colour and depth are paired by the instant the depth shows (stamp - latency; then the depth
image after the nearest-stamped one: 2 ms instead of 35 ms apart), and
``Frame.depth_timestamp_s`` is that instant.

Everything that can be checked without decoding images is checked at construction.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from engine.camera import Intrinsics, load_camera_json, tum_default_for
from engine.errors import SourceError
from engine.frames import Frame, SourceFiles
from engine.geometry import R_from_quat_xyzw, make_T, so3_exp, so3_log
from engine.sources.base import Source, SourceSpec
from engine.sources.images import read_color_bgr, read_depth_m

F64 = NDArray[np.float64]

#: association window of the TUM tools (associate.py --max_difference 0.02)
MAX_ASSOCIATION_DT_S = 0.02
#: how long before its stamp a TUM benchmark (Kinect) depth image shows the scene (see the
#: module doc; measured on freiburg1_xyz, not by the trackers' ATE)
TUM_KINECT_DEPTH_LATENCY_S = 0.02
#: ground truth is interpolated only between samples at most this far from the query time
MAX_GT_GAP_S = 0.05


@dataclass(frozen=True, slots=True)
class TumListEntry:
    """One line of ``rgb.txt``/``depth.txt``."""

    line_no: int
    timestamp_s: float
    rel_path: str


def read_tum_list(path: Path) -> list[TumListEntry]:
    """Parse a TUM ``timestamp filename`` list; timestamps must increase strictly."""
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise SourceError(f"{path}: file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise SourceError(f"{path}: cannot read ({exc})") from None
    entries: list[TumListEntry] = []
    for line_no, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        parts = line.split()
        try:
            if len(parts) != 2:
                raise ValueError
            t = float(parts[0])
            if not np.isfinite(t):
                raise ValueError
        except ValueError:
            raise SourceError(
                f"{path}:{line_no}: expected 'timestamp filename', got {line[:60]!r}"
            ) from None
        if entries and t <= entries[-1].timestamp_s:
            raise SourceError(
                f"{path}:{line_no}: timestamp {parts[0]} is not after the previous one "
                f"({entries[-1].timestamp_s:.6f}); timestamps must increase"
            )
        entries.append(TumListEntry(line_no, t, parts[1]))
    return entries


class _Link(NamedTuple):
    """One pair (i, j) of an association chain and the chain before it."""

    i: int
    j: int
    parent: _Link | None


def associate_one_to_one(
    t_a: F64, t_b: F64, max_dt_s: float = MAX_ASSOCIATION_DT_S
) -> list[tuple[int, int]]:
    """Index pairs (i, j) with |t_a[i] - t_b[j]| < max_dt_s, one-to-one, sorted by i.

    The pairing preserves time order (i < i' implies j < j') and, among such pairings, keeps
    as many pairs as possible, then the smallest total gap. TUM's ``associate.py`` pairs
    greedily by smallest gap first, which can strand a colour image whose nearest depth was
    taken by its neighbour even when the next depth is also within the window (on
    freiburg1_xyz it drops 5 of the first 37 frames that pair one by one within 17 ms).
    Both inputs must be sorted. Dynamic programme over the candidate edges, O(N k).
    """
    t_a = np.asarray(t_a, dtype=np.float64)
    t_b = np.asarray(t_b, dtype=np.float64)
    lo = np.searchsorted(t_b, t_a - max_dt_s, side="left")
    hi = np.searchsorted(t_b, t_a + max_dt_s, side="right")
    # state: last used j -> (pairs, -total gap, back-pointer chain of (i, j, parent))
    states: dict[int, tuple[int, float, _Link | None]] = {-1: (0, 0.0, None)}
    for i in range(len(t_a)):
        cands = [
            (j, abs(float(t_a[i]) - float(t_b[j])))
            for j in range(int(lo[i]), int(hi[i]))
            if abs(float(t_a[i]) - float(t_b[j])) < max_dt_s
        ]
        if not cands:
            continue
        new = dict(states)
        for last_j, (count, neg_gap, chain) in states.items():
            for j, gap in cands:
                if j <= last_j:
                    continue
                cand = (count + 1, neg_gap - gap, _Link(i, j, chain))
                old = new.get(j)
                if old is None or cand[:2] > old[:2]:
                    new[j] = cand
        # Keep only states not dominated by one with a smaller last j and a score as good.
        states = {}
        best: tuple[int, float] | None = None
        for j in sorted(new):
            score = new[j][:2]
            if best is None or score > best:
                states[j] = new[j]
                best = score
    count, _, chain = max(states.values(), key=lambda s: s[:2])
    pairs: list[tuple[int, int]] = []
    while chain is not None:
        i, j, parent = chain
        pairs.append((i, j))
        chain = parent
    pairs.reverse()
    assert len(pairs) == count
    return pairs


@dataclass(frozen=True, slots=True)
class GroundTruth:
    """A TUM ground-truth trajectory: times (N,), positions (N, 3), rotations (N, 3, 3)."""

    timestamps_s: F64
    t_world_cam: F64
    R_world_cam: F64

    def pose_at(self, t_s: float, max_gap_s: float = MAX_GT_GAP_S) -> F64 | None:
        """T_world_cam at ``t_s``: linear translation + slerp between the bracketing samples.

        None when ``t_s`` is outside the trajectory or a bracketing sample is more than
        ``max_gap_s`` away (a motion-capture dropout).
        """
        ts = self.timestamps_s
        if len(ts) == 0 or t_s < ts[0] or t_s > ts[-1]:
            return None
        j = int(np.searchsorted(ts, t_s, side="left"))
        if ts[j] == t_s:
            return make_T(self.R_world_cam[j], self.t_world_cam[j])
        i = j - 1
        if t_s - ts[i] > max_gap_s or ts[j] - t_s > max_gap_s:
            return None
        alpha = (t_s - ts[i]) / (ts[j] - ts[i])
        t = (1.0 - alpha) * self.t_world_cam[i] + alpha * self.t_world_cam[j]
        # slerp(R_i, R_j; a) = R_i exp(a log(R_i^T R_j)): constant angular velocity
        R_i, R_j = self.R_world_cam[i], self.R_world_cam[j]
        R = R_i @ so3_exp(alpha * so3_log(R_i.T @ R_j))
        return make_T(R, t)


def read_tum_groundtruth(path: Path) -> GroundTruth:
    """Parse ``groundtruth.txt`` (``timestamp tx ty tz qx qy qz qw``, strictly increasing)."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise SourceError(f"{path}: cannot read ({exc})") from None
    times: list[float] = []
    trans: list[F64] = []
    rots: list[F64] = []
    for line_no, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        parts = line.replace(",", " ").split()
        try:
            if len(parts) != 8:
                raise ValueError
            row = np.array([float(p) for p in parts], dtype=np.float64)
            if not np.all(np.isfinite(row)):
                raise ValueError
            R = R_from_quat_xyzw(row[4:8])
        except ValueError:
            raise SourceError(
                f"{path}:{line_no}: expected 'timestamp tx ty tz qx qy qz qw' with finite "
                f"numbers and a non-zero quaternion, got {line[:80]!r}"
            ) from None
        if times and row[0] <= times[-1]:
            raise SourceError(
                f"{path}:{line_no}: timestamp {parts[0]} is not after the previous one "
                f"({times[-1]:.6f}); timestamps must increase"
            )
        times.append(float(row[0]))
        trans.append(row[1:4])
        rots.append(R)
    if not times:
        raise SourceError(f"{path}: contains no poses")
    return GroundTruth(np.array(times), np.array(trans), np.array(rots))


@dataclass(frozen=True, slots=True)
class _Pair:
    timestamp_s: float
    rgb_path: Path
    depth_path: Path | None
    depth_timestamp_s: float | None


class TumSource(Source):
    """Frames of a TUM RGB-D folder: colour, depth (metres), ground-truth pose, intrinsics.

    Intrinsics come from ``camera.json`` if present, else from the TUM defaults of the
    camera named in the folder name (fr1/fr2/fr3, freiburg1/2/3); otherwise construction
    fails. Depth PNGs are divided by ``intrinsics.depth_scale`` (5000 for TUM).
    """

    def __init__(
        self,
        path: str | Path,
        *,
        max_dt_s: float = MAX_ASSOCIATION_DT_S,
        depth_latency_s: float | None = None,
    ) -> None:
        folder = Path(path).expanduser()
        if not folder.exists():
            raise SourceError(f"{folder}: no such folder")
        if not folder.is_dir():
            raise SourceError(f"{folder}: not a folder (a TUM source is a folder with rgb.txt)")
        if not any(folder.iterdir()):
            raise SourceError(f"{folder}: folder is empty (expected rgb.txt, depth.txt, rgb/)")
        rgb_txt = folder / "rgb.txt"
        if not rgb_txt.is_file():
            raise SourceError(f"{folder}: no rgb.txt (not a TUM RGB-D folder)")
        self.folder = folder
        self.name = f"TUM folder {folder.name}"
        self._intrinsics = self._load_intrinsics(folder)

        rgb = read_tum_list(rgb_txt)
        if not rgb:
            raise SourceError(f"{rgb_txt}: lists no images")
        self._check_files_exist(rgb_txt, rgb)
        depth_txt = folder / "depth.txt"
        self.has_depth = depth_txt.is_file()
        #: how long before its stamp a depth image shows the scene (see the module doc)
        self.depth_latency_s = 0.0
        pairs: list[_Pair] = []
        if self.has_depth:
            depth = read_tum_list(depth_txt)
            self._check_files_exist(depth_txt, depth)
            if depth_latency_s is None:
                depth_latency_s = (
                    TUM_KINECT_DEPTH_LATENCY_S if _is_benchmark_recording(depth_txt) else 0.0
                )
            self.depth_latency_s = float(depth_latency_s)
            shown = [e.timestamp_s - self.depth_latency_s for e in depth]
            matches = associate_one_to_one(
                np.array([e.timestamp_s for e in rgb]), np.array(shown), max_dt_s
            )
            for i, j in matches:
                pairs.append(
                    _Pair(
                        rgb[i].timestamp_s,
                        folder / rgb[i].rel_path,
                        folder / depth[j].rel_path,
                        shown[j],
                    )
                )
            if not pairs:
                raise SourceError(
                    f"{folder}: no colour image has a depth image within "
                    f"{max_dt_s * 1000:.0f} ms (check rgb.txt and depth.txt timestamps)"
                )
        else:
            pairs = [_Pair(e.timestamp_s, folder / e.rel_path, None, None) for e in rgb]
        self._pairs = pairs
        #: colour images listed in rgb.txt that found no depth partner (and are skipped)
        self.dropped_rgb = len(rgb) - len(pairs)

        gt_txt = folder / "groundtruth.txt"
        self.groundtruth_path: Path | None = gt_txt if gt_txt.is_file() else None
        self.groundtruth = read_tum_groundtruth(gt_txt) if self.groundtruth_path else None
        self._gt_poses = [
            self.groundtruth.pose_at(p.timestamp_s) if self.groundtruth else None for p in pairs
        ]
        times = np.array([p.timestamp_s for p in pairs])
        if len(times) > 1:
            self.nominal_fps = float(1.0 / np.median(np.diff(times)))

    def input_paths(self) -> tuple[Path, ...]:
        lists = [self.folder / n for n in ("rgb.txt", "depth.txt", "camera.json")]
        folders = {p.rgb_path.parent for p in self._pairs}
        folders |= {p.depth_path.parent for p in self._pairs if p.depth_path is not None}
        return (*super().input_paths(), *lists, *sorted(folders))

    @staticmethod
    def _load_intrinsics(folder: Path) -> Intrinsics:
        cam_json = folder / "camera.json"
        default = tum_default_for(folder.name)
        if cam_json.exists():
            cam = load_camera_json(cam_json)  # CalibrationError naming the file
            if cam.rolling_shutter_s == 0.0 and default is not None:
                # a TUM camera.json says nothing of the shutter: the sensor's readout
                cam = dataclasses.replace(cam, rolling_shutter_s=default.rolling_shutter_s)
            return cam
        if default is None:
            raise SourceError(
                f"{folder}: no camera.json and the folder name does not say fr1/fr2/fr3; "
                "add camera.json (fx, fy, cx, cy, width, height, distortion[5], depth_scale)"
            )
        return default

    @staticmethod
    def _check_files_exist(list_path: Path, entries: list[TumListEntry]) -> None:
        folder = list_path.parent
        for e in entries:
            try:
                exists = (folder / e.rel_path).is_file()
            except (OSError, ValueError) as exc:  # name too long, NUL byte...
                why = getattr(exc, "strerror", None) or exc
                raise SourceError(
                    f"{list_path}:{e.line_no}: image name {e.rel_path[:60]!r}... cannot be "
                    f"used ({why})"
                ) from None
            if not exists:
                raise SourceError(
                    f"{list_path}:{e.line_no}: image {e.rel_path} does not exist in {folder}"
                )

    @property
    def intrinsics(self) -> Intrinsics:
        return self._intrinsics

    @property
    def timestamps_s(self) -> F64:
        """Colour timestamps of the frames this source yields."""
        return np.array([p.timestamp_s for p in self._pairs])

    def __len__(self) -> int:
        return len(self._pairs)

    def frames(self) -> Iterator[Frame]:
        cam = self._intrinsics
        for index, (pair, gt) in enumerate(zip(self._pairs, self._gt_poses, strict=True)):
            color = read_color_bgr(pair.rgb_path)
            h, w = color.shape[:2]
            if (w, h) != cam.size_wh:
                raise SourceError(
                    f"{pair.rgb_path}: image is {w}x{h} but the intrinsics say "
                    f"{cam.width}x{cam.height}"
                )
            depth = None
            depth_t: float | None = None
            if pair.depth_path is not None:
                depth = read_depth_m(pair.depth_path, cam.depth_scale)
                if depth.shape != (h, w):
                    raise SourceError(
                        f"{pair.depth_path}: depth image is {depth.shape[1]}x{depth.shape[0]} "
                        f"but colour image {pair.rgb_path.name} is {w}x{h}"
                    )
                depth_t = pair.depth_timestamp_s
            files = SourceFiles(
                color_path=str(pair.rgb_path),
                depth_path=None if pair.depth_path is None else str(pair.depth_path),
            )
            yield Frame(
                index=index,
                timestamp_s=pair.timestamp_s,
                color_bgr=color,
                intrinsics=cam,
                depth_m=depth,
                gt_T_world_cam=None if gt is None else gt.copy(),
                payloads=(files,),
                depth_timestamp_s=depth_t,
            )


def _is_benchmark_recording(list_path: Path) -> bool:
    """``depth.txt`` of the TUM benchmark: its header names the recording's bag."""
    try:
        with list_path.open(encoding="utf-8") as fh:
            head = [fh.readline() for _ in range(3)]
    except (OSError, UnicodeDecodeError):
        return False
    return any(
        line.startswith("#") and "rgbd_dataset_freiburg" in line for line in head
    )


def _is_tum_folder(path: Path) -> bool:
    return path.is_dir() and (path / "rgb.txt").exists()


SOURCES = (
    SourceSpec(
        name="tum",
        description="a TUM RGB-D folder (rgb.txt)",
        opener=TumSource,
        detect=_is_tum_folder,
        example="tum_fr1_xyz_37",
    ),
)
