"""Intel RealSense depth cameras, live and from their ``.bag`` recordings, through the SDK.

Specs (``pyrealsense2``, the vendor SDK, is imported only when one is opened):

- ``realsense[:serial=…,width=640,height=480,fps=30,align=color,emitter=1,laser_power=150]``
  a connected camera (the first one without ``serial``);
- ``path/to/file.bag`` a recording, played as fast as possible, every frame;
- ``realsense:file=path/to/file.bag[,realtime=1]`` the same, ``realtime=1`` at the recorded
  rate like a live camera (frames the tracker is too slow for are skipped).

Colour and depth: depth is aligned to colour by the SDK (``rs.align``) unless both streams
already share one geometry (same intrinsics, identity extrinsics), when the depth is passed
through untouched (the SDK's align re-samples even then and opens ~3 % holes at
edges); ``align=sdk`` forces the SDK's alignment. Depth is Z16 times the depth sensor's
Depth Units, in metres. The intrinsics are the colour stream's (``rs2_intrinsics``),
converted by :mod:`engine.sources.rs_intrinsics` (fisheye models are refused). Timestamps are
the frames' own (the SDK's hardware clock, ms), kept increasing across reconnects.

Live streams follow the newest-frame policy (:mod:`engine.sources.grabber`): a thread reads
the camera, the engine takes the newest frame; ``Frame.skipped_before`` counts the frames
it skipped (from the SDK's frame numbers, so drops in the SDK or on USB count too). When no
frame arrives for ``timeout_s`` (cable pulled, camera reset), the source yields frames
without a picture and ``link_lost_reason = "camera disconnected"`` (the loop reports LOST)
and tries to reopen the camera every ``reconnect_s`` until it is back.

Closing a recording first brings the SDK's reader thread to rest (the recording is run to
its end, the pipeline stopped, the thread waited for): librealsense 2.59 crashes when a
playback device is freed under a running reader thread (see :func:`_release_sdk`).
"""

from __future__ import annotations

import contextlib
import functools
import math
import threading
import time
import weakref
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from engine.camera import Intrinsics
from engine.errors import SourceError
from engine.frames import Frame
from engine.sources.base import Source, SourceSpec

DISCONNECTED = "camera disconnected"
DEFAULT_SIZE = (640, 480)
DEFAULT_FPS = 30
ALIGN_MODES = ("color", "sdk")
#: largest gap between a frame's stamp and a ground-truth stamp that still pairs them
GT_MATCH_S = 5e-4
#: times a recording is restarted when the SDK dropped its first frame
MAX_START_RETRIES = 5


@dataclass(frozen=True, slots=True)
class RealSenseOptions:
    """What ``realsense:…`` (or a ``.bag`` path) asks for."""

    serial: str | None = None
    file: Path | None = None
    width: int | None = None
    height: int | None = None
    fps: int | None = None
    align: str = "color"
    realtime: bool = False
    emitter: bool | None = None
    laser_power: float | None = None
    timeout_s: float = 1.0
    reconnect_s: float = 1.0

    @property
    def live(self) -> bool:
        """True for a camera and for a bag played at its recorded rate."""
        return self.file is None or self.realtime

    @property
    def label(self) -> str:
        if self.file is not None:
            return str(self.file)
        return f"realsense {self.serial}" if self.serial else "realsense"


def _positive_int(key: str, value: str) -> int:
    try:
        v = int(value)
    except ValueError:
        raise SourceError(f"realsense option {key}={value!r}: expected an integer") from None
    if v <= 0:
        raise SourceError(f"realsense option {key}={value!r}: must be positive")
    return v


def _positive_float(key: str, value: str) -> float:
    try:
        v = float(value)
    except ValueError:
        raise SourceError(f"realsense option {key}={value!r}: expected a number") from None
    if not math.isfinite(v) or v <= 0:
        raise SourceError(f"realsense option {key}={value!r}: must be a positive number")
    return v


def _flag(key: str, value: str) -> bool:
    if value in ("0", "1"):
        return value == "1"
    raise SourceError(f"realsense option {key}={value!r}: expected 0 or 1")


def parse_realsense_options(options: dict[str, str], file: Path | None = None) -> RealSenseOptions:
    """Validate ``realsense:key=value,...`` options; an unknown key is an error naming it."""
    kw: dict[str, Any] = {"file": file}
    for key, value in options.items():
        if key == "serial":
            kw["serial"] = value or None
        elif key == "file":
            kw["file"] = Path(value).expanduser()
        elif key in ("width", "height", "fps"):
            kw[key] = _positive_int(key, value)
        elif key == "align":
            if value not in ALIGN_MODES:
                raise SourceError(
                    f"realsense option align={value!r}: expected one of {', '.join(ALIGN_MODES)}"
                )
            kw["align"] = value
        elif key in ("realtime", "emitter"):
            kw[key] = _flag(key, value)
        elif key in ("laser_power", "timeout_s", "reconnect_s"):
            kw[key] = _positive_float(key, value)
        else:
            raise SourceError(
                f"realsense option {key!r} is unknown (serial, file, width, height, fps, align, "
                "realtime, emitter, laser_power, timeout_s, reconnect_s)"
            )
    opts = RealSenseOptions(**kw)
    if opts.file is not None:
        if opts.serial is not None:
            raise SourceError("realsense: give serial= for a camera or file= for a recording")
        if not opts.file.is_file():
            raise SourceError(f"{opts.file}: no such file")
    if (opts.width is None) != (opts.height is None):
        raise SourceError("realsense: give both width= and height=, or neither")
    return opts


# -- what a stream backend delivers ---------------------------------------------------------
@dataclass(frozen=True, slots=True)
class RawFrame:
    """One colour + aligned depth pair as the device delivered it."""

    color_bgr: NDArray[np.uint8]
    depth_m: NDArray[np.float32]
    timestamp_s: float
    frame_number: int | None


class EndOfRecording(Exception):
    """The recording has no more frames."""


class DeviceLost(Exception):
    """The device stopped delivering or went away."""


class RgbdStream(Protocol):
    """An opened colour + depth stream (the SDK pipeline, or a test's fake device)."""

    intrinsics: Intrinsics
    fps: float
    name: str

    def read(self, timeout_s: float) -> RawFrame | None:
        """The next frame; None if none came within ``timeout_s``.

        Raises :class:`EndOfRecording` at the end of a recording and :class:`DeviceLost`
        when the device failed.
        """

    def close(self) -> None: ...


Opener = Callable[[RealSenseOptions], RgbdStream]


# -- the SDK backend ------------------------------------------------------------------------
def _rs() -> Any:
    try:
        import pyrealsense2 as rs
    except ImportError as exc:
        raise SourceError(
            f"realsense: the RealSense SDK (pyrealsense2) is not installed ({exc}); "
            "install it with: pip install pyrealsense2"
        ) from None
    return rs


@dataclass(frozen=True, slots=True)
class DeviceInfo:
    """A connected camera, as the source picker lists it."""

    serial: str
    model: str
    usb: str

    @property
    def spec(self) -> str:
        return f"realsense:serial={self.serial}"


def list_devices() -> list[DeviceInfo]:
    """Connected RealSense cameras; empty when none (or when the SDK is not installed)."""
    try:
        rs = _rs()
    except SourceError:
        return []
    out = []
    try:
        for dev in rs.context().query_devices():
            out.append(DeviceInfo(
                serial=_info(rs, dev, "serial_number"),
                model=_info(rs, dev, "name"),
                usb=_info(rs, dev, "usb_type_descriptor"),
            ))
    except RuntimeError:
        return out
    return out


def _info(rs: Any, dev: Any, key: str) -> str:
    field = getattr(rs.camera_info, key)
    try:
        return str(dev.get_info(field)) if dev.supports(field) else ""
    except RuntimeError:
        return ""


def _mode_text(modes: set[tuple[int, int, int]]) -> str:
    return ", ".join(f"{w}x{h}@{f}" for w, h, f in sorted(modes)) or "none"


_COLOR_CONVERSIONS = {"bgr8": None, "rgb8": "COLOR_RGB2BGR", "rgba8": "COLOR_RGBA2BGR",
                      "bgra8": "COLOR_BGRA2BGR", "y8": "COLOR_GRAY2BGR",
                      "yuyv": "COLOR_YUV2BGR_YUYV", "uyvy": "COLOR_YUV2BGR_UYVY"}


class SdkStream:
    """Colour + depth through ``rs.pipeline`` from a camera or a bag (playback device)."""

    def __init__(self, opts: RealSenseOptions) -> None:
        from engine.sources.rs_intrinsics import intrinsics_from_sdk

        rs = _rs()
        self._rs = rs
        where = opts.label
        ctx = rs.context()
        cfg = rs.config()
        if opts.file is not None:
            try:
                device = ctx.load_device(str(opts.file))
            except RuntimeError as exc:
                raise SourceError(f"{opts.file}: not a RealSense recording ({exc})") from None
            cfg.enable_device_from_file(str(opts.file), repeat_playback=False)
        else:
            device = self._find_device(rs, ctx, opts)
            cfg.enable_device(_info(rs, device, "serial_number"))
            where = f"realsense {_info(rs, device, 'serial_number')}"
        self.name = (f"RealSense recording {opts.file.name}" if opts.file is not None
                     else f"{_info(rs, device, 'name')} {_info(rs, device, 'serial_number')}")
        try:
            depth_modes, color_modes = self._modes(rs, device)
        except RuntimeError as exc:
            raise SourceError(f"{where}: the SDK cannot list its streams ({exc})") from None
        if not depth_modes:
            raise SourceError(
                f"{where}: no depth stream (streams: colour {_mode_text(color_modes)}); "
                "the camera tracker needs depth"
            )
        if not color_modes:
            raise SourceError(f"{where}: no colour stream (depth {_mode_text(depth_modes)})")
        w, h, fps = self._choose(where, opts, depth_modes, color_modes)
        dmode = (w, h, fps) if (w, h, fps) in depth_modes else max(
            (m for m in depth_modes if m[2] == fps), key=lambda m: m[0] * m[1])
        cfg.enable_stream(rs.stream.depth, dmode[0], dmode[1], rs.format.z16, fps)
        if opts.file is None:
            cfg.enable_stream(rs.stream.color, w, h, rs.format.bgr8, fps)
        else:
            cfg.enable_stream(rs.stream.color, w, h, rs.format.any, fps)
        self._pipe = rs.pipeline(ctx)
        self._playback: Any = None
        try:
            if opts.file is not None:
                # Resolved before start(), the pipeline starts this very device (the config
                # keeps it), so a recording plays at the asked rate from its first frame on;
                # set after start(), the first frames play in real time and the SDK drops
                # those the consumer has not taken yet (12 of 100 starts under load).
                resolved = cfg.resolve(rs.pipeline_wrapper(self._pipe))
                self._playback = resolved.get_device().as_playback()
                self._playback.set_real_time(bool(opts.realtime))
            profile = self._pipe.start(cfg)
        except RuntimeError as exc:
            raise SourceError(f"{where}: the SDK cannot start {w}x{h}@{fps} ({exc})") from None
        self._closed = False
        self._finalizer = weakref.finalize(self, _release_sdk, rs, self._pipe, self._playback)
        try:
            if self._playback is not None:
                # the sensors' start has run on the reader thread: from here on a stopped
                # status means the recording ended, not that it has not begun
                _reader_barrier(self._playback)
            dev = profile.get_device()
            depth_sensor = dev.first_depth_sensor()
            # the SDK keeps Depth Units as float32 (0.001 -> 0.0010000000475): round it back
            self._depth_units_m = float(f"{float(depth_sensor.get_depth_scale()):.7g}")
            if opts.file is None:
                self._set_options(rs, depth_sensor, opts, where)
            cprof = profile.get_stream(rs.stream.color).as_video_stream_profile()
            dprof = profile.get_stream(rs.stream.depth).as_video_stream_profile()
            self._color_format = str(cprof.format()).rsplit(".", 1)[-1]
            if self._color_format not in _COLOR_CONVERSIONS:
                raise SourceError(
                    f"{where}: colour format {self._color_format} is not supported "
                    f"({', '.join(_COLOR_CONVERSIONS)})"
                )
            ci = cprof.get_intrinsics()
            self.intrinsics, self.distortion_fit_px = intrinsics_from_sdk(
                width=ci.width, height=ci.height, fx=ci.fx, fy=ci.fy, ppx=ci.ppx, ppy=ci.ppy,
                model=str(ci.model), coeffs=list(ci.coeffs),
                depth_scale=1.0 / self._depth_units_m, where=f"{where} colour stream",
            )
            self.fps = float(cprof.fps())
            self._align = None
            if opts.align == "sdk" or not self._same_geometry(dprof, cprof):
                self._align = rs.align(rs.stream.color)
            self.aligned_by_sdk = self._align is not None
        except BaseException:
            self.close()
            raise

    @staticmethod
    def _find_device(rs: Any, ctx: Any, opts: RealSenseOptions) -> Any:
        devices = list(ctx.query_devices())
        if not devices:
            raise SourceError(
                "realsense: no RealSense camera connected (plug it into a USB 3 port; "
                "the SDK lists none)"
            )
        if opts.serial is None:
            return devices[0]
        for dev in devices:
            if _info(rs, dev, "serial_number") == opts.serial:
                return dev
        found = ", ".join(_info(rs, d, "serial_number") for d in devices)
        raise SourceError(f"realsense: no camera with serial {opts.serial} (connected: {found})")

    @staticmethod
    def _modes(rs: Any, device: Any) -> tuple[set[Any], set[Any]]:
        depth: set[tuple[int, int, int]] = set()
        color: set[tuple[int, int, int]] = set()
        for sensor in device.query_sensors():
            for p in sensor.get_stream_profiles():
                if not p.is_video_stream_profile():
                    continue
                v = p.as_video_stream_profile()
                mode = (v.width(), v.height(), v.fps())
                if p.stream_type() == rs.stream.depth and p.format() == rs.format.z16:
                    depth.add(mode)
                elif p.stream_type() == rs.stream.color:
                    color.add(mode)
        return depth, color

    @staticmethod
    def _choose(
        where: str, opts: RealSenseOptions, depth_modes: set[Any], color_modes: set[Any]
    ) -> tuple[int, int, int]:
        usable = {m for m in color_modes if any(d[2] == m[2] for d in depth_modes)}
        if opts.file is not None and opts.width is None and opts.fps is None:
            m = max(usable or color_modes, key=lambda m: m[0] * m[1])
            return int(m[0]), int(m[1]), int(m[2])
        w, h = ((opts.width, opts.height) if opts.width is not None and opts.height is not None
                else DEFAULT_SIZE)
        fps = opts.fps or DEFAULT_FPS
        if opts.file is not None and opts.fps is None:
            fps = max(m[2] for m in usable or color_modes)
        if (w, h, fps) not in usable:
            kind = "recording has" if opts.file is not None else "camera offers"
            raise SourceError(
                f"{where}: {w}x{h}@{fps} is not supported (colour with depth: the {kind} "
                f"{_mode_text(usable)})"
            )
        return int(w), int(h), int(fps)

    @staticmethod
    def _same_geometry(dprof: Any, cprof: Any) -> bool:
        di, ci = dprof.get_intrinsics(), cprof.get_intrinsics()
        same_k = (di.width, di.height) == (ci.width, ci.height) and all(
            abs(a - b) < 1e-6 for a, b in ((di.fx, ci.fx), (di.fy, ci.fy),
                                           (di.ppx, ci.ppx), (di.ppy, ci.ppy))
        ) and str(di.model) == str(ci.model) and list(di.coeffs) == list(ci.coeffs)
        try:
            ext = dprof.get_extrinsics_to(cprof)
        except RuntimeError:
            return False
        identity = np.allclose(np.asarray(ext.rotation), np.eye(3).ravel(), atol=1e-9) and \
            np.allclose(np.asarray(ext.translation), 0.0, atol=1e-9)
        return bool(same_k and identity)

    @staticmethod
    def _set_options(rs: Any, sensor: Any, opts: RealSenseOptions, where: str) -> None:
        for key, value in (("emitter_enabled", opts.emitter), ("laser_power", opts.laser_power)):
            if value is None:
                continue
            option = getattr(rs.option, key)
            if not sensor.supports(option):
                raise SourceError(f"{where}: this camera has no {key} option")
            rng = sensor.get_option_range(option)
            v = float(value)
            if not rng.min <= v <= rng.max:
                raise SourceError(f"{where}: {key}={v:g} outside [{rng.min:g}, {rng.max:g}]")
            sensor.set_option(option, v)

    def read(self, timeout_s: float) -> RawFrame | None:
        import cv2

        if self._closed:
            raise EndOfRecording  # a grabber thread still reading after close()
        try:
            ok, fs = self._pipe.try_wait_for_frames(max(1, round(timeout_s * 1000)))
        except RuntimeError as exc:
            raise DeviceLost(str(exc)) from None
        if not ok:
            if self._playback is not None and (
                self._playback.current_status() == self._rs.playback_status.stopped
            ):
                raise EndOfRecording
            return None
        if self._align is not None:
            fs = self._align.process(fs)
        c, d = fs.get_color_frame(), fs.get_depth_frame()
        if not c or not d:
            return None
        color = np.asanyarray(c.get_data())
        conv = _COLOR_CONVERSIONS[self._color_format]
        color = np.array(color) if conv is None else cv2.cvtColor(color, getattr(cv2, conv))
        depth = np.asanyarray(d.get_data()).astype(np.float32) * np.float32(self._depth_units_m)
        return RawFrame(color_bgr=color, depth_m=depth, timestamp_s=c.get_timestamp() / 1000.0,
                        frame_number=int(c.get_frame_number()))

    def close(self) -> None:
        """Stop streaming and let the SDK objects go (safely: see :func:`_release_sdk`)."""
        self._closed = True
        self._finalizer()


#: longest a close waits for a recording's reader thread to come to rest
CLOSE_TIMEOUT_S = 10.0
#: SDK objects whose reader thread did not come to rest in time: kept, never freed
_NEVER_FREED: list[tuple[Any, Any]] = []


def _reader_barrier(playback: Any) -> None:
    """Return once the playback's reader thread has run every step queued before this call.

    ``resume()`` of a playback that is not paused queues a step that does nothing on the
    reader thread and waits for it (librealsense ``playback_device::resume``: invoke, flush).
    StudioTrack never pauses a playback, so this is a pure barrier.
    """
    playback.resume()


def _seek_to_end(playback: Any) -> None:
    with contextlib.suppress(RuntimeError):
        playback.seek(playback.get_duration())


def _end_playback(rs: Any, pipe: Any, playback: Any) -> bool:
    """Bring a recording to its end so the SDK stops it itself; False if it did not in time.

    At the end of the file the reader thread flushes the frames it handed out and stops the
    sensors itself: the one stop in which no SDK thread has a frame in flight. Seeking there
    waits for the reader thread, which may be blocked handing a frame to the pipeline's full
    queue (a recording played every frame waits for its consumer), so the seek runs on a
    helper thread while this one drains the queue.
    """
    stopped = rs.playback_status.stopped
    if playback.current_status() == stopped:
        return True
    seeker = threading.Thread(target=_seek_to_end, args=(playback,), name="realsense-close",
                              daemon=True)
    seeker.start()
    deadline = time.monotonic() + CLOSE_TIMEOUT_S
    while seeker.is_alive() or playback.current_status() != stopped:
        if time.monotonic() > deadline:
            return False
        with contextlib.suppress(RuntimeError):
            pipe.poll_for_frames()
        time.sleep(0.001)
    return True


def _release_sdk(rs: Any, pipe: Any, playback: Any) -> None:
    """Stop a pipeline so that no SDK thread still runs when its objects are freed.

    librealsense 2.59 frees a playback device while its reader thread may still run a queued
    step: ``dispatcher::stop`` waits for the step being run but not for one the thread has
    just taken off the queue, and the destructor then frees the sensors that step uses
    (heap corruption, SIGSEGV or SIGABRT; a few closes in a thousand on a loaded machine). The
    reader thread has steps queued while a recording plays and right after the pipeline
    stops (the sensors' stop and close queue theirs), so a recording is stopped at its end
    (:func:`_end_playback`), the pipeline stopped, and the reader thread waited for
    (:func:`_reader_barrier`) before anything is freed. If the recording cannot be brought
    to rest, its objects are kept for the life of the process rather than freed under a
    running thread. A live camera has no reader thread: its pipeline is just stopped.
    """
    if playback is not None and not _end_playback(rs, pipe, playback):
        _NEVER_FREED.append((pipe, playback))
        return
    with contextlib.suppress(RuntimeError):
        pipe.stop()
    if playback is not None:
        _reader_barrier(playback)


# -- the source -----------------------------------------------------------------------------
class RealSenseSource(Source):
    """A RealSense camera or recording as a frame source (see the module docstring).

    ``opener`` builds the stream (the SDK by default; tests pass a fake device). The stream is
    opened at construction, so a missing camera or a bad recording fails before tracking.
    """

    def __init__(self, opts: RealSenseOptions, *, opener: Opener | None = None) -> None:
        self.opts = opts
        self._opener: Opener = opener or SdkStream
        self._stream: RgbdStream | None = self._opener(opts)
        self.live = opts.live
        self.name = self._stream.name
        self.nominal_fps = self._stream.fps or float(DEFAULT_FPS)
        self._intrinsics = self._stream.intrinsics
        self._gt: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None
        if opts.file is not None:
            from engine.sources.realsense_bag import read_groundtruth

            self._gt = read_groundtruth(opts.file)
        self._len = 0 if self.live else self._count_frames()
        #: frames skipped so far: by the newest-frame policy (live), or dropped by the SDK
        #: (gaps in a recording's frame numbers)
        self.total_skipped = 0
        #: times the camera was reopened after a disconnect
        self.reconnects = 0
        #: times a recording was restarted because the SDK dropped its first frame
        self.playback_restarts = 0

    @property
    def intrinsics(self) -> Intrinsics:
        return self._intrinsics

    def __len__(self) -> int:
        return self._len

    def _count_frames(self) -> int:
        # Frames of a recording: the colour stream's message count (cheap, no decoding).
        assert self.opts.file is not None
        from engine.sources.realsense_bag import count_color_frames

        return count_color_frames(self.opts.file)

    def _gt_at(self, t_s: float) -> NDArray[np.float64] | None:
        if self._gt is None or len(self._gt[0]) == 0:
            return None
        stamps, poses = self._gt
        j = int(np.argmin(np.abs(stamps - t_s)))
        return poses[j].copy() if abs(stamps[j] - t_s) <= GT_MATCH_S else None

    def _frame(self, index: int, raw: RawFrame, t_s: float, skipped: int,
               capture_mono_s: float | None = None) -> Frame:
        if raw.color_bgr.shape[:2] != (self._intrinsics.height, self._intrinsics.width):
            raise SourceError(
                f"{self.opts.label}: frame {index} is {raw.color_bgr.shape[1]}x"
                f"{raw.color_bgr.shape[0]}, the stream said {self._intrinsics.width}x"
                f"{self._intrinsics.height}"
            )
        return Frame(index=index, timestamp_s=t_s, color_bgr=raw.color_bgr,
                     intrinsics=self._intrinsics, depth_m=raw.depth_m,
                     gt_T_world_cam=self._gt_at(raw.timestamp_s), skipped_before=skipped,
                     capture_mono_s=time.monotonic() if capture_mono_s is None
                     else capture_mono_s)

    def frames(self) -> Iterator[Frame]:
        if self._stream is None:
            raise SourceError(f"{self.opts.label}: already closed")
        if not self.live:
            yield from self._frames_recorded()
        else:
            yield from self._frames_live()

    def _frames_recorded(self) -> Iterator[Frame]:
        # Every frame, in order, as fast as the consumer takes them: reopen to rewind.
        from engine.sources.realsense_bag import first_color_seq

        assert self.opts.file is not None
        if getattr(self, "_played", False):
            self._reopen_or_raise()
        self._played = True
        first_seq = first_color_seq(self.opts.file)
        index = 0
        waited = 0.0
        restarts = 0
        last_fn: int | None = None
        while True:
            assert self._stream is not None
            try:
                raw = self._stream.read(self.opts.timeout_s)
            except EndOfRecording:
                return
            except DeviceLost as exc:
                raise SourceError(f"{self.opts.label}: playback failed ({exc})") from None
            if raw is None:
                waited += self.opts.timeout_s
                if waited > 10 * self.opts.timeout_s:
                    raise SourceError(f"{self.opts.label}: playback delivers no frames")
                continue
            waited = 0.0
            if index == 0 and first_seq is not None and raw.frame_number != first_seq \
                    and restarts < MAX_START_RETRIES:
                # The SDK's pipeline now and then drops the first frame(s) of a playback
                # while it starts (4 in 100 starts on a loaded machine, with the playback
                # set to every-frame before the start; 12 in 100 when set after it) and
                # never a later one; start again (all 5 tries failing: ~1e-7).
                restarts += 1
                self.playback_restarts += 1
                self._reopen_or_raise()
                continue
            # frames missing from the recording's own numbering were dropped by the SDK
            gap = 0
            if raw.frame_number is not None and last_fn is not None:
                gap = max(0, raw.frame_number - last_fn - 1)
            last_fn = raw.frame_number
            self.total_skipped += gap
            yield self._frame(index, raw, raw.timestamp_s, gap)
            index += 1

    def _reopen_or_raise(self) -> None:
        if self._stream is not None:
            self._stream.close()
        self._stream = self._opener(self.opts)

    def _frames_live(self) -> Iterator[Frame]:
        from engine.sources.grabber import NewestGrabber

        index = 0
        last_t: float | None = None
        t_offset = 0.0
        last_fn: int | None = None
        if self.opts.file is not None:
            # a recording played in real time plays from its first frame: the frames it
            # played before the first one was taken count as skipped too
            from engine.sources.realsense_bag import first_color_seq

            first_seq = first_color_seq(self.opts.file)
            last_fn = None if first_seq is None else first_seq - 1
        period = 1.0 / self.nominal_fps
        while True:
            stream = self._stream
            assert stream is not None
            grabber: NewestGrabber[RawFrame] = NewestGrabber(
                functools.partial(stream.read, self.opts.timeout_s), name="realsense-grabber"
            )
            grabber.start()
            lost_since: float | None = None
            try:
                while True:
                    try:
                        got = grabber.take(self.opts.timeout_s)
                    except EndOfRecording:
                        return
                    except DeviceLost:
                        got = None
                        lost_since = time.monotonic() - self.opts.timeout_s
                    if got is None:
                        break  # no frame within timeout_s: the camera is gone
                    raw = got.item
                    skipped = got.skipped
                    if raw.frame_number is not None and last_fn is not None:
                        gap = raw.frame_number - last_fn - 1
                        if 0 <= gap < 100_000:
                            skipped = max(skipped, gap)
                    last_fn = raw.frame_number
                    t = raw.timestamp_s + t_offset
                    if last_t is not None and t <= last_t:  # clock restarted (reconnect)
                        t_offset += last_t + period - t
                        t = last_t + period
                    last_t = t
                    self.total_skipped += skipped
                    yield self._frame(index, raw, t, skipped, got.arrival_s)  # grab time
                    index += 1
            finally:
                grabber.stop()
            # Disconnected: report, then try to reopen every reconnect_s until it works.
            if lost_since is None:
                lost_since = time.monotonic()
            last_fn = None
            while True:
                t = (last_t + period) if last_t is not None else 0.0
                last_t = t
                yield Frame(index=index, timestamp_s=t, color_bgr=None,
                            intrinsics=self._intrinsics, link_lost_reason=DISCONNECTED)
                index += 1
                time.sleep(self.opts.reconnect_s)
                with contextlib.suppress(RuntimeError):
                    stream.close()
                try:
                    self._stream = self._opener(self.opts)
                except SourceError:
                    continue
                self.reconnects += 1
                break

    def close(self) -> None:
        if self._stream is not None:
            self._stream.close()
            self._stream = None


def open_realsense(rest: str) -> RealSenseSource:
    """``realsense:…`` (``rest`` = the options)."""
    from engine.sources.base import parse_options

    return RealSenseSource(parse_realsense_options(parse_options(rest)))


def open_bag(path: str) -> RealSenseSource:
    """A ``.bag`` recording, every frame as fast as the consumer takes them."""
    return RealSenseSource(parse_realsense_options({}, Path(path)))


SOURCES = (
    SourceSpec(name="realsense", description="a RealSense depth camera (SDK)",
               opener=open_realsense, example="realsense:width=640,height=480,fps=30"),
    SourceSpec(name="realsense-bag", description="a RealSense recording (.bag)",
               opener=open_bag, detect=lambda p: p.is_file() and p.suffix.lower() == ".bag",
               example="studio.bag"),
)
