"""Range-beacon sources: frames without images that carry range readings as payloads.

Every frame has ``color_bgr=None`` and two payloads:

- :class:`RangeReadings`: ``ranges`` ``{beacon_id: range_m}`` of this step (missing beacons
  left out; empty for the heartbeat frames of the live UDP source, which let the engine
  loop poll its stop flag), ``layout`` ``{beacon_id: (x, y)}`` the operator's layout or None
  (the tracker uses only its quadrants in SLAM mode, its coordinates in known-beacon mode),
  ``beacon_ids`` (the ids a layout-less live source expects, else None) and
  ``input_stats`` (skipped-input counters of CSV / UDP, see
  :class:`engine.beacons.io.InputStats`, else None);
- :class:`BeaconTruth`: ``gt_xy`` the true camera position or None (``gt_T_world_cam``
  holds it too) and ``gt_beacons`` the true beacons (simulator only) for evaluation.

Specs (see :func:`open_beacon_source`):

- ``beacons[:layout=paper|FILE,steps=120,speed=0.15,noise=0.1,dropout=0,outliers=0,seed=0,fps=10]``
- ``beacons:scene=studio[,sensor=uwb|ultrasonic,seed=0]``: the studio simulation
  (:mod:`engine.beacons.studio_sim`: a crane move in a 3D studio, ranges projected to the
  floor), at its ranging rate
- ``beacons-csv:FILE[,layout=FILE,window=0]``
- ``beacons-udp:[port=9871,host=127.0.0.1,layout=FILE,heartbeat=0.5,idle_timeout=0]``
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, replace
from types import MappingProxyType
from typing import Any

import numpy as np

from engine.camera import Intrinsics
from engine.errors import ParamsError, SourceError
from engine.frames import Frame, FramePayload, Heartbeat
from engine.sources.base import Source, SourceSpec
from engine.validate import number
from engine.validate import port as validate_port

DEFAULT_UDP_PORT = 9871  # 9870 is the presenter robot-control output (engine.presenter.control)


def _T_from_xy(xy: Sequence[float] | None) -> np.ndarray | None:
    if xy is None:
        return None
    T = np.eye(4)
    T[0, 3], T[1, 3] = float(xy[0]), float(xy[1])
    return T


def _frozen_layout(layout: Mapping[str, Sequence[float]] | None) -> Mapping[str, Any] | None:
    if layout is None:
        return None
    return MappingProxyType({k: (float(v[0]), float(v[1])) for k, v in layout.items()})


@dataclass(frozen=True, slots=True)
class RangeReadings(FramePayload):
    """One time step of range readings (see the module docstring)."""

    ranges: Mapping[str, float]
    layout: Mapping[str, tuple[float, float]] | None = None
    beacon_ids: tuple[str, ...] | None = None
    input_stats: Mapping[str, object] | None = None


@dataclass(frozen=True, slots=True)
class BeaconTruth(FramePayload):
    """The simulator's truth: camera position and beacon positions (m)."""

    gt_xy: tuple[float, float] | None
    gt_beacons: Mapping[str, Any] | None = None


def _frame(
    index: int,
    t_s: float,
    ranges: Mapping[str, float],
    gt_xy: Sequence[float] | None,
    layout: Mapping[str, Any] | None,
    gt_beacons: Mapping[str, Any] | None = None,
    stats: dict[str, object] | None = None,
    beacon_ids: tuple[str, ...] | None = None,
) -> Frame:
    readings = RangeReadings(
        ranges=MappingProxyType(dict(ranges)),
        layout=layout,
        beacon_ids=beacon_ids,
        input_stats=None if stats is None else MappingProxyType(dict(stats)),
    )
    truth = BeaconTruth(
        gt_xy=None if gt_xy is None else (float(gt_xy[0]), float(gt_xy[1])),
        gt_beacons=gt_beacons,
    )
    return Frame(index=index, timestamp_s=t_s, color_bgr=None, gt_T_world_cam=_T_from_xy(gt_xy),
                 payloads=(readings, truth))


class BeaconSimSource(Source):
    """The simulated studio of the paper (or any layout), one frame per time step."""

    live = False

    def __init__(
        self,
        layout: Mapping[str, Sequence[float]] | None = None,
        config: Any | None = None,
        fps: float = 10.0,
        run: Any | None = None,
        name: str | None = None,
    ) -> None:
        from engine.beacons.simulator import PAPER_LAYOUT, SimConfig, simulate

        self.layout = dict(layout if layout is not None else PAPER_LAYOUT)
        self.config = config or SimConfig()
        self.run = run if run is not None else simulate(self.layout, self.config)
        self.nominal_fps = float(fps)
        self.name = name or (f"beacon simulator ({len(self.layout)} beacons, "
                             f"{self.config.n_steps} steps)")
        self._layout = _frozen_layout(self.layout)

    @classmethod
    def studio(cls, opts: Mapping[str, str]) -> BeaconSimSource:
        """``scene=studio``: the studio simulation (``sensor``, ``seed`` options)."""
        from engine.beacons.studio_sim import (
            StudioRangingConfig,
            simulate_studio,
            studio_layout_xy,
        )

        o = dict(opts)
        sensor = o.pop("sensor", "uwb")
        seed_text = o.pop("seed", "0")
        if o:
            raise SourceError(f"beacons source: scene=studio takes sensor and seed, not "
                              f"{', '.join(sorted(o))}")
        if sensor not in ("uwb", "ultrasonic"):
            raise SourceError(f"beacons source: sensor={sensor!r}: expected uwb or ultrasonic")
        seed = int(number(seed_text, "beacons source: option seed", integer=True,
                          error=SourceError, text=True))
        cfg = StudioRangingConfig(seed=seed)
        if sensor == "ultrasonic":
            cfg = cfg.with_preset("ultrasonic")
        run = simulate_studio(cfg).floor
        return cls(studio_layout_xy(), None, cfg.rate_hz, run=run,
                   name=f"beacon studio simulation ({sensor}, {len(run.path_xy)} steps)")

    @classmethod
    def from_options(cls, opts: Mapping[str, str]) -> BeaconSimSource:
        from engine.beacons.io import load_layout
        from engine.beacons.simulator import SimConfig

        o = dict(opts)
        scene = o.pop("scene", "paper")
        if scene == "studio":
            return cls.studio(o)
        if scene != "paper":
            raise SourceError(f"beacons source: scene={scene!r}: expected paper or studio")
        lay_opt = o.pop("layout", "paper")
        layout = None if lay_opt in ("", "paper") else load_layout(lay_opt)
        names = {"steps": ("n_steps", True), "speed": ("speed_m", False),
                 "noise": ("noise_sigma_m", False), "dropout": ("dropout_prob", False),
                 "outliers": ("outlier_prob", False), "outlier_max": ("outlier_max_m", False),
                 "seed": ("seed", True)}
        kw: dict[str, Any] = {}
        fps = 10.0
        for key, value in o.items():
            what = f"beacons source: option {key}"
            if key == "fps":
                fps = number(value, what, gt=0, hi=1e6, error=SourceError, text=True)
            elif key in names:
                field_name, integer = names[key]
                hi = 10**7 if key == "steps" else None
                kw[field_name] = number(value, what, integer=integer, hi=hi, error=SourceError,
                                        text=True)
            else:
                raise SourceError(
                    f"beacons source: unknown option {key!r} (known: scene, layout, fps, "
                    f"{', '.join(names)})"
                )
        try:
            cfg = SimConfig(**kw)
        except ParamsError as exc:
            raise SourceError(f"beacons source: {exc}") from None
        if not (math.isfinite(fps) and fps > 0):
            raise SourceError(f"beacons source: fps must be > 0, got {fps}")
        return cls(layout, cfg, fps)

    @property
    def intrinsics(self) -> Intrinsics | None:
        return None

    def __len__(self) -> int:
        return len(self.run.path_xy)

    def frames(self) -> Iterator[Frame]:
        gt_b = MappingProxyType(
            {i: (float(x), float(y)) for i, (x, y) in zip(self.run.ids, self.run.beacons_xy,
                                                          strict=True)}
        )
        for t in range(len(self.run.path_xy)):
            yield _frame(t, t / self.nominal_fps, self.run.ranges_dict(t), self.run.path_xy[t],
                         self._layout, gt_b)


class BeaconCsvSource(Source):
    """A recorded range log (``timestamp, beacon_id, range_m``)."""

    live = False

    def __init__(
        self,
        path: str,
        layout: Mapping[str, Sequence[float]] | None = None,
        window_s: float = 0.0,
    ) -> None:
        from engine.beacons.io import read_range_csv

        self.path = path
        self.layout = dict(layout) if layout is not None else None
        self.steps, stats = read_range_csv(path, self.layout.keys() if self.layout else None,
                                           window_s)
        self.stats = stats.as_dict()
        if not self.steps:
            raise SourceError(f"{path}: no valid range readings ({self.stats['malformed']} "
                              f"malformed, {self.stats['unknown_ids']} unknown ids)")
        # a log's steps all carry their timestamp (only live readings may lack one)
        ts = [s.timestamp_s for s in self.steps if s.timestamp_s is not None]
        if len(ts) != len(self.steps):
            raise SourceError(f"{path}: a range reading has no timestamp")
        self._times = ts
        span = ts[-1] - ts[0]
        self.nominal_fps = (len(ts) - 1) / span if len(ts) > 1 and span > 0 else 10.0
        self.name = f"beacon log {path} ({len(self.steps)} steps)"
        self._layout = _frozen_layout(self.layout)
        self.beacon_ids = tuple(sorted({b for s in self.steps for b in s.ranges_m}))

    @classmethod
    def from_rest(cls, rest: str) -> BeaconCsvSource:
        from engine.beacons.io import load_layout

        path, opts = _split_path_options(rest, "beacons-csv")
        if not path:
            raise SourceError("beacons-csv: expected beacons-csv:FILE[,layout=FILE,window=S]")
        layout = load_layout(opts.pop("layout")) if "layout" in opts else None
        window = number(opts.pop("window", "0"), "beacons-csv: window (seconds)", lo=0,
                        hi=1e7, error=SourceError, text=True)
        if opts:
            raise SourceError(f"beacons-csv: unknown option(s) {sorted(opts)}")
        return cls(path, layout, window)

    @property
    def intrinsics(self) -> Intrinsics | None:
        return None

    def __len__(self) -> int:
        return len(self.steps)

    def frames(self) -> Iterator[Frame]:
        for i, (s, t) in enumerate(zip(self.steps, self._times, strict=True)):
            yield _frame(i, t, s.ranges_m, s.gt_xy, self._layout, None, self.stats,
                         self.beacon_ids)


class BeaconUdpSource(Source):
    """Live range readings over UDP (JSON datagrams, see :mod:`engine.beacons.io`)."""

    live = True

    def __init__(
        self,
        host: str = "127.0.0.1",
        port: int = DEFAULT_UDP_PORT,
        layout: Mapping[str, Sequence[float]] | None = None,
        heartbeat_s: float = 0.5,
        idle_timeout_s: float = 0.0,
    ) -> None:
        from engine.beacons.io import UdpRangeListener

        self.layout = dict(layout) if layout is not None else None
        self.listener = UdpRangeListener(host, port, self.layout.keys() if self.layout else None)
        self.heartbeat_s = float(heartbeat_s)
        self.idle_timeout_s = float(idle_timeout_s)
        self.nominal_fps = 10.0
        self.name = f"beacon UDP {self.listener.host}:{self.listener.port}"
        self._layout = _frozen_layout(self.layout)

    @classmethod
    def from_options(cls, opts: Mapping[str, str]) -> BeaconUdpSource:
        from engine.beacons.io import load_layout

        o = dict(opts)
        layout = load_layout(o.pop("layout")) if "layout" in o else None
        port = validate_port(o.pop("port", str(DEFAULT_UDP_PORT)), "beacons-udp: port",
                             error=SourceError)
        heartbeat = number(o.pop("heartbeat", "0.5"), "beacons-udp: heartbeat", lo=0, hi=3600,
                           error=SourceError, text=True)
        idle = number(o.pop("idle_timeout", "0"), "beacons-udp: idle_timeout", lo=0, hi=1e7,
                      error=SourceError, text=True)
        host = o.pop("host", "127.0.0.1")
        if o:
            raise SourceError(f"beacons-udp: unknown option(s) {sorted(o)}")
        return cls(host, port, layout, heartbeat, idle)

    @property
    def intrinsics(self) -> Intrinsics | None:
        return None

    def __len__(self) -> int:
        return 0

    def frames(self) -> Iterator[Frame]:
        """Readings as they arrive, on one clock per source: the sender's ``timestamp_s``
        when the first reading carries one, else the receive time (seconds since the source
        started) - never both. A reading not after the previous one (out of order, late) is
        counted in ``input_stats.out_of_order`` and skipped; a sender-clocked stream's
        reading without a timestamp is counted as malformed. While nothing arrives,
        heartbeat frames (no readings, a :class:`engine.frames.Heartbeat` payload, the last
        reading's time) let the engine loop poll its stop flag; they are not readings."""
        stats = self.listener.stats
        index = 0
        t0 = last_data = time.monotonic()
        last_t = -math.inf
        while True:
            step = self.listener.receive(self.heartbeat_s if self.heartbeat_s > 0 else 0.5)
            now = time.monotonic()
            if step is None:
                if self.idle_timeout_s > 0 and now - last_data > self.idle_timeout_s:
                    return
                if self.heartbeat_s > 0:  # empty frame: lets the loop poll its stop flag
                    stats.heartbeats += 1
                    frame = _frame(index, last_t if math.isfinite(last_t) else 0.0, {}, None,
                                   self._layout, None, stats.as_dict())
                    yield replace(
                        frame, payloads=(*frame.payloads, Heartbeat(now - last_data)))
                    index += 1
                continue
            last_data = now
            if not stats.clock:
                stats.clock = "sender" if step.timestamp_s is not None else "receive"
            if stats.clock == "sender":
                if step.timestamp_s is None:
                    stats.note("malformed", "udp: reading without timestamp_s in a stream "
                               "stamped by its sender: skipped")
                    continue
                t = step.timestamp_s
            else:
                if step.timestamp_s is not None:
                    stats.ignored_timestamps += 1
                t = now - t0
            if t <= last_t:
                stats.note("out_of_order", f"udp: reading at {t:.6f} s is not after the "
                           f"previous one ({last_t:.6f} s): skipped")
                continue
            last_t = t
            yield _frame(index, t, step.ranges_m, step.gt_xy, self._layout, None,
                         stats.as_dict())
            index += 1

    def close(self) -> None:
        self.listener.close()


def _split_path_options(rest: str, kind: str) -> tuple[str, dict[str, str]]:
    """``"FILE,a=1,b=2"`` -> (``"FILE"``, {a: 1, b: 2}); ``file=FILE`` works too."""
    path = ""
    opts: dict[str, str] = {}
    for item in filter(None, (s.strip() for s in rest.split(","))):
        key, sep, value = item.partition("=")
        if not sep:
            if path:
                raise SourceError(f"{kind}: two file names given ({path!r}, {item!r})")
            path = item
        elif key.strip() == "file":
            path = value.strip()
        else:
            opts[key.strip()] = value.strip()
    return path, opts


def open_beacon_source(kind: str, rest: str) -> Source:
    """Open ``beacons`` / ``beacons-csv`` / ``beacons-udp`` specs (called by ``open_source``)."""
    from engine.sources.base import parse_options

    if kind == "beacons":
        return BeaconSimSource.from_options(parse_options(rest))
    if kind == "beacons-csv":
        return BeaconCsvSource.from_rest(rest)
    if kind == "beacons-udp":
        return BeaconUdpSource.from_options(parse_options(rest))
    raise SourceError(f"unknown beacon source kind {kind!r}")


SOURCES = (
    SourceSpec(
        name="beacons",
        description="simulated range beacons (Yang 2007's set-up)",
        opener=lambda rest: open_beacon_source("beacons", rest),
        example="beacons:steps=120,seed=0",
    ),
    SourceSpec(
        name="beacons-csv",
        description="range readings from a CSV log",
        opener=lambda rest: open_beacon_source("beacons-csv", rest),
        example="beacons-csv:ranges.csv,layout=layout.json",
    ),
    SourceSpec(
        name="beacons-udp",
        description="live range readings over UDP",
        opener=lambda rest: open_beacon_source("beacons-udp", rest),
        example="beacons-udp:port=9870",
    ),
)
