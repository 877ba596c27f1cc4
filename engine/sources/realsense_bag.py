"""The RealSense SDK's recording layout (``.bag``, ROS 1 bag format 2.0) and a writer for it.

The layout is the one librealsense's ``ros_writer``/``ros_reader`` use (file version 3,
``src/media/ros/ros_file_format.h``); the SDK reads a bag written here through its ordinary
playback device (``rs.config.enable_device_from_file``):

======================================================  =============================  =========
topic                                                   type                           when
======================================================  =============================  =========
``/file_version``                                       std_msgs/UInt32 (3)            static
``/device_0/info``                                      diagnostic_msgs/KeyValue       static
``/device_0/sensor_S/info``                             diagnostic_msgs/KeyValue       static
``/device_0/sensor_S/<Stream>_0/info``                  realsense_msgs/StreamInfo      static
``/device_0/sensor_S/<Stream>_0/info/camera_info``      sensor_msgs/CameraInfo         static
``/device_0/sensor_S/<Stream>_0/tf/0``                  geometry_msgs/Transform        static
``/device_0/sensor_0/option/Depth_Units/value``         std_msgs/Float32 (m per unit)  static
``/device_0/sensor_0/option/Depth_Units/description``   std_msgs/String                static
``/device_0/sensor_S/<Stream>_0/image/data``            sensor_msgs/Image              per frame
``/device_0/sensor_S/<Stream>_0/image/metadata``        diagnostic_msgs/KeyValue       per frame
======================================================  =============================  =========

Sensor 0 is the depth sensor ("Stereo Module", stream ``Depth_0``, ``mono16`` = Z16 in
units of Depth Units metres), sensor 1 the colour sensor ("RGB Camera", ``Color_0``,
``rgb8``). Static messages carry ROS time ``TIME_MIN`` (1 ns), as the SDK writes them; frame
messages the frame's time since the first frame plus :data:`FIRST_FRAME_NS`. The image
header stamp is the capture timestamp (the SDK's "hardware clock" in ms).
``camera_info.distortion_model`` holds the SDK's distortion-model name
(``rs2_distortion_to_string``: "Brown Conrady" for our Caltech/OpenCV model).

Ground truth, where the source has it (the built-in studio), goes on one extra topic
:data:`GROUNDTRUTH_TOPIC` (geometry_msgs/PoseStamped, ``T_world_cam``; stamp = the frame's
timestamp). The SDK's reader only plays the topics of the streams it enables, so it ignores
this topic; :func:`read_groundtruth` reads it back with ``rosbags``.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from engine.camera import Intrinsics
from engine.errors import SourceError
from engine.frames import Frame

F64 = NDArray[np.float64]

FILE_VERSION = 3
#: ROS TIME_MIN: the time the SDK gives its static (device/stream description) messages
STATIC_NS = 1
#: bag time of the first frame; later frames follow at their timestamp offsets
FIRST_FRAME_NS = 1_000_000
#: metres per depth unit written (the D4xx default: 1 mm)
DEFAULT_DEPTH_UNITS_M = 0.001
GROUNDTRUTH_TOPIC = "/studiotrack/groundtruth"
DEPTH_PREFIX = "/device_0/sensor_0/Depth_0"
COLOR_PREFIX = "/device_0/sensor_1/Color_0"

# realsense_msgs/StreamInfo as the SDK defines it (md5 311d7e24eac31bb87271d041bf70ff7d)
_STREAM_INFO_MSG = """\
uint32 fps
string encoding
bool is_recommended
"""
STREAM_INFO_MD5 = "311d7e24eac31bb87271d041bf70ff7d"


def _typestore() -> Any:
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    store.register(get_types_from_msg(_STREAM_INFO_MSG, "realsense_msgs/msg/StreamInfo"))
    return store


@dataclass(frozen=True, slots=True)
class BagDevice:
    """What the bag says about the recorded device (``/device_0/info``)."""

    name: str = "StudioTrack virtual studio"
    serial: str = "studio-0"
    firmware: str = "0.0.0.0"
    product_line: str = "D400"


class _BagWriter:
    """Thin layer over ``rosbags.rosbag1.Writer``: one connection per topic, typed messages."""

    def __init__(self, path: Path) -> None:
        from rosbags.rosbag1 import Writer

        self.store = _typestore()
        self.t = self.store.types
        self._writer = Writer(path)
        self._writer.open()
        self._conns: dict[str, Any] = {}

    def write(self, topic: str, msgtype: str, msg: object, t_ns: int) -> None:
        conn = self._conns.get(topic)
        if conn is None:
            conn = self._writer.add_connection(topic, msgtype, typestore=self.store)
            self._conns[topic] = conn
        self._writer.write(conn, t_ns, self.store.serialize_ros1(msg, msgtype))

    def close(self) -> None:
        self._writer.close()

    # message builders -------------------------------------------------------------------
    def time(self, t_ns: int) -> Any:
        return self.t["builtin_interfaces/msg/Time"](sec=t_ns // 1_000_000_000,
                                                     nanosec=t_ns % 1_000_000_000)

    def header(self, seq: int, t_ns: int) -> Any:
        return self.t["std_msgs/msg/Header"](seq=seq, stamp=self.time(t_ns), frame_id="0")

    def key_value(self, topic: str, key: str, value: str, t_ns: int = STATIC_NS) -> None:
        msg = self.t["diagnostic_msgs/msg/KeyValue"](key=key, value=value)
        self.write(topic, "diagnostic_msgs/msg/KeyValue", msg, t_ns)


def _camera_info(w: _BagWriter, cam: Intrinsics, model: str | None) -> Any:
    t = w.t
    K = np.array([cam.fx, 0.0, cam.cx, 0.0, cam.fy, cam.cy, 0.0, 0.0, 1.0])
    P = np.array([cam.fx, 0.0, cam.cx, 0.0, 0.0, cam.fy, cam.cy, 0.0, 0.0, 0.0, 1.0, 0.0])
    return t["sensor_msgs/msg/CameraInfo"](
        header=w.header(0, 0),
        height=cam.height,
        width=cam.width,
        # the SDK's rs2_distortion_to_string; coefficients k1 k2 p1 p2 k3 (OpenCV order)
        distortion_model=model or ("Brown Conrady" if cam.has_distortion else "None"),
        D=np.asarray(cam.dist_k1k2p1p2k3, dtype=np.float64),
        K=K,
        R=np.eye(3).ravel(),
        P=P,
        binning_x=0,
        binning_y=0,
        roi=t["sensor_msgs/msg/RegionOfInterest"](
            x_offset=0, y_offset=0, height=0, width=0, do_rectify=False
        ),
    )


def _write_static(
    w: _BagWriter, cam: Intrinsics, fps: float, depth_units_m: float, device: BagDevice,
    streams: tuple[str, ...], model: str | None,
) -> None:
    t = w.t
    w.write("/file_version", "std_msgs/msg/UInt32", t["std_msgs/msg/UInt32"](data=FILE_VERSION),
            STATIC_NS)
    for key, value in (
        ("Name", device.name),
        ("Serial Number", device.serial),
        ("Firmware Version", device.firmware),
        ("Product Line", device.product_line),
        ("Physical Port", "studiotrack"),
    ):
        w.key_value("/device_0/info", key, value)
    identity = t["geometry_msgs/msg/Transform"](
        translation=t["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
        rotation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
    )
    sensors = {"depth": (0, "Stereo Module", DEPTH_PREFIX, "mono16"),
               "color": (1, "RGB Camera", COLOR_PREFIX, "rgb8")}
    # Both sensors are described whatever streamed, as the SDK's recorder does (its reader
    # indexes sensors from 0: a bag without sensor 0 fails there with "map::at").
    for index, sensor_name, _prefix, _enc in sensors.values():
        w.key_value(f"/device_0/sensor_{index}/info", "Name", sensor_name)
    for stream in streams:
        _index, _name, prefix, encoding = sensors[stream]
        info = t["realsense_msgs/msg/StreamInfo"](
            fps=round(fps), encoding=encoding, is_recommended=True
        )
        w.write(f"{prefix}/info", "realsense_msgs/msg/StreamInfo", info, STATIC_NS)
        w.write(f"{prefix}/info/camera_info", "sensor_msgs/msg/CameraInfo",
                _camera_info(w, cam, model), STATIC_NS)
        # depth and colour share one viewpoint (the studio renders depth in the colour camera)
        w.write(f"{prefix}/tf/0", "geometry_msgs/msg/Transform", identity, STATIC_NS)
    # the depth sensor's Depth Units option (metres per Z16 unit), streaming or not
    opt = "/device_0/sensor_0/option/Depth_Units"
    w.write(f"{opt}/value", "std_msgs/msg/Float32",
            t["std_msgs/msg/Float32"](data=float(depth_units_m)), STATIC_NS)
    w.write(f"{opt}/description", "std_msgs/msg/String",
            t["std_msgs/msg/String"](data="Number of meters represented by a single depth unit"),
            STATIC_NS)


def _image(w: _BagWriter, seq: int, stamp_ns: int, encoding: str, pixels: np.ndarray) -> Any:
    h, wd = pixels.shape[:2]
    data = np.ascontiguousarray(pixels).view(np.uint8).reshape(-1)
    return w.t["sensor_msgs/msg/Image"](
        header=w.header(seq, stamp_ns), height=h, width=wd, encoding=encoding,
        is_bigendian=0, step=data.size // h, data=data,
    )


def check_bag_path(path: Path) -> Path:
    """A new ``.bag`` path in an existing folder, or SourceError saying what is wrong."""
    path = Path(path)
    if path.suffix.lower() != ".bag":
        raise SourceError(f"{path}: a RealSense recording must end in .bag")
    if path.exists():
        raise SourceError(f"{path}: exists (will not overwrite a recording)")
    if not path.parent.is_dir():
        raise SourceError(f"{path}: folder {path.parent} does not exist")
    return path


def write_realsense_bag(
    frames: Iterable[Frame],
    path: Path,
    intrinsics: Intrinsics,
    *,
    fps: float = 30.0,
    depth_units_m: float = DEFAULT_DEPTH_UNITS_M,
    device: BagDevice | None = None,
    with_depth: bool = True,
    distortion_model: str | None = None,
    progress: Callable[[int], None] | None = None,
) -> dict[str, object]:
    """Write ``frames`` (colour + depth in metres, same viewpoint) as a RealSense bag.

    ``with_depth=False`` writes a colour-only recording and ``distortion_model`` names another
    SDK model for the same coefficients (what bad-input tests need).
    Returns a small summary. The file is written next to ``path`` and renamed at the end,
    so a failure never leaves a half-written bag under the final name.
    """
    import os

    from engine.geometry import tum_from_T

    path = check_bag_path(path)
    if not depth_units_m > 0:
        raise SourceError(f"depth units must be positive, got {depth_units_m}")
    tmp = path.with_name(f".{path.name}.part")
    if tmp.exists():
        tmp.unlink()
    streams = ("depth", "color") if with_depth else ("color",)
    w = _BagWriter(tmp)
    n = 0
    has_gt = False
    try:
        _write_static(w, intrinsics, fps, depth_units_m, device or BagDevice(), streams,
                      distortion_model)
        t0: float | None = None
        for frame in frames:
            if frame.color_bgr is None or (with_depth and frame.depth_m is None):
                raise SourceError(f"frame {frame.index}: a RealSense bag needs colour and depth")
            if (frame.color_bgr.shape[1], frame.color_bgr.shape[0]) != intrinsics.size_wh:
                raise SourceError(
                    f"frame {frame.index}: image is {frame.color_bgr.shape[1]}x"
                    f"{frame.color_bgr.shape[0]}, intrinsics say {intrinsics.width}x"
                    f"{intrinsics.height}"
                )
            if t0 is None:
                t0 = frame.timestamp_s
            stamp_ns = round(frame.timestamp_s * 1e9)
            bag_ns = FIRST_FRAME_NS + round((frame.timestamp_s - t0) * 1e9)
            if with_depth:
                assert frame.depth_m is not None
                units = np.round(frame.depth_m.astype(np.float64) / depth_units_m)
                z16 = np.clip(np.nan_to_num(units, nan=0.0), 0, 65535).astype("<u2")
                w.write(f"{DEPTH_PREFIX}/image/data", "sensor_msgs/msg/Image",
                        _image(w, n, stamp_ns, "mono16", z16), bag_ns)
                w.key_value(f"{DEPTH_PREFIX}/image/metadata", "timestamp_domain",
                            "Hardware Clock", bag_ns)
            rgb = np.ascontiguousarray(frame.color_bgr[:, :, ::-1])
            w.write(f"{COLOR_PREFIX}/image/data", "sensor_msgs/msg/Image",
                    _image(w, n, stamp_ns, "rgb8", rgb), bag_ns)
            w.key_value(f"{COLOR_PREFIX}/image/metadata", "timestamp_domain",
                        "Hardware Clock", bag_ns)
            if frame.gt_T_world_cam is not None:
                has_gt = True
                tx, ty, tz, qx, qy, qz, qw = (float(v) for v in tum_from_T(frame.gt_T_world_cam))
                t = w.t
                pose = t["geometry_msgs/msg/PoseStamped"](
                    header=w.header(n, stamp_ns),
                    pose=t["geometry_msgs/msg/Pose"](
                        position=t["geometry_msgs/msg/Point"](x=tx, y=ty, z=tz),
                        orientation=t["geometry_msgs/msg/Quaternion"](x=qx, y=qy, z=qz, w=qw),
                    ),
                )
                w.write(GROUNDTRUTH_TOPIC, "geometry_msgs/msg/PoseStamped", pose, bag_ns)
            n += 1
            if progress is not None:
                progress(n)
        if n == 0:
            raise SourceError(f"{path}: the source yielded no frames")
        w.close()
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(Exception):
            w.close()
        if tmp.exists():
            tmp.unlink()
        raise
    return {"out": str(path), "frames": n, "groundtruth": has_gt, "format": "realsense",
            "depth_units_m": depth_units_m}


def _color_topic(topics: Iterable[str]) -> str | None:
    import re

    pattern = re.compile(r"^/device_\d+/sensor_\d+/Color_\d+/image/data$")
    return next((t for t in sorted(topics) if pattern.match(t)), None)


def count_color_frames(path: Path) -> int:
    """Colour frames in a RealSense bag (message count of its colour stream; 0 if none)."""
    from rosbags.rosbag1 import Reader

    try:
        with Reader(path) as reader:
            topic = _color_topic(c.topic for c in reader.connections)
            return sum(c.msgcount for c in reader.connections if c.topic == topic)
    except Exception as exc:  # rosbags raises its own types for a corrupt bag
        raise SourceError(f"{path}: cannot read the bag ({type(exc).__name__}: {exc})") from None


def first_color_seq(path: Path) -> int | None:
    """Header ``seq`` of the recording's first colour frame (the SDK's frame number)."""
    from rosbags.rosbag1 import Reader

    store = _typestore()
    try:
        with Reader(path) as reader:
            topic = _color_topic(c.topic for c in reader.connections)
            conns = [c for c in reader.connections if c.topic == topic]
            for conn, _t, raw in reader.messages(connections=conns):
                return int(store.deserialize_ros1(raw, conn.msgtype).header.seq)
    except Exception as exc:  # rosbags raises its own types for a corrupt bag
        raise SourceError(f"{path}: cannot read the bag ({type(exc).__name__}: {exc})") from None
    return None


def read_groundtruth(path: Path) -> tuple[F64, F64] | None:
    """Ground truth stored by :func:`write_realsense_bag`: (stamps_s (N,), T_world_cam (N,4,4)).

    None when the bag has no ground-truth topic (any recording made by the SDK itself).
    """
    from rosbags.rosbag1 import Reader

    from engine.geometry import R_from_quat_xyzw, make_T

    store = _typestore()
    stamps: list[float] = []
    poses: list[F64] = []
    try:
        with Reader(path) as reader:
            conns = [c for c in reader.connections if c.topic == GROUNDTRUTH_TOPIC]
            if not conns:
                return None
            for conn, _t, raw in reader.messages(connections=conns):
                msg = store.deserialize_ros1(raw, conn.msgtype)
                st = msg.header.stamp
                stamps.append(st.sec + st.nanosec * 1e-9)
                p, q = msg.pose.position, msg.pose.orientation
                R = R_from_quat_xyzw(np.array([q.x, q.y, q.z, q.w]))
                poses.append(make_T(R, np.array([p.x, p.y, p.z])))
    except Exception as exc:  # rosbags raises its own types for a corrupt bag
        raise SourceError(f"{path}: cannot read the bag ({type(exc).__name__}: {exc})") from None
    return np.array(stamps), np.array(poses)
