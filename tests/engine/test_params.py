"""engine.params: typed fields, validation derived from their metadata, presets; every params
class of the engine is declared that one way."""

from __future__ import annotations

import dataclasses
import enum
import importlib
import math
import pkgutil
from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pytest

import engine
from engine.errors import ParamsError
from engine.params import Params, Preset, is_params_class, param
from engine.tracking_run import apply_param_overrides


class Mode(enum.Enum):
    FAST = "fast"
    EXACT = "exact"


class LocalError(Exception):
    pass


@dataclass(frozen=True, slots=True)
class Demo(Params):
    """A test group."""

    n: int = param(100, help="count", lo=10, hi=5000, step=10)
    sigma_m: float = param(0.3, help="noise", lo=0.001, hi=10.0)
    robust: bool = param(True, help="robust weights")
    kind: str = param("fast", help="rule", choices=("fast", "exact"))
    mode: Mode = param(Mode.FAST, help="mode")
    gains: tuple[float, float] = param((1.0, 2.0), help="two gains", lo=0.0)
    name: str = param("cam", help="a name")
    limit: float | None = param(None, help="optional limit")
    lo_m: float = param(0.0, help="near", lo=0.0)
    hi_m: float = param(4.0, help="far", lo=0.0)
    rate: float = param(30.0, help="frame rate", unit="Hz")

    PRESETS: ClassVar[Mapping[str, Preset]] = {
        "exact": Preset("the exact rule, fewer particles", kind="exact", n=50),
        "broken": Preset("names no field", nonsense=1),
    }

    def validate(self) -> None:
        if self.lo_m >= self.hi_m:
            raise ParamsError(f"Demo: lo_m ({self.lo_m}) must be below hi_m ({self.hi_m})")


@dataclass(frozen=True, slots=True)
class Strict(Params):
    """Raises its module's own error type."""

    ERROR = LocalError

    k: int = param(1, help="k", lo=0, hi=3)


def test_param_returns_the_default_and_writes_the_metadata() -> None:
    f = {f.name: f for f in dataclasses.fields(Demo)}
    assert Demo().n == 100
    assert dict(f["n"].metadata) == {"help": "count", "min": 10, "max": 5000, "step": 10}
    assert f["kind"].metadata["choices"] == ("fast", "exact")
    assert "unit" not in f["sigma_m"].metadata
    assert f["rate"].metadata["unit"] == "Hz"
    with pytest.raises(ParamsError, match="help must not be empty"):
        param(1, help=" ")
    with pytest.raises(ParamsError, match="lo 2 > hi 1"):
        param(1, help="x", lo=2, hi=1)


@pytest.mark.parametrize(
    ("kw", "message"),
    [
        ({"n": 5}, r"Demo\.n must be in \[10, 5000\], got 5"),
        ({"n": 2.5}, r"Demo\.n must be an integer, got 2\.5"),
        ({"n": True}, r"Demo\.n must be an integer"),
        ({"sigma_m": math.nan}, r"Demo\.sigma_m must be finite, got nan"),
        ({"sigma_m": math.inf}, r"Demo\.sigma_m must be finite"),
        ({"sigma_m": "0.3"}, r"Demo\.sigma_m must be a number"),
        ({"sigma_m": 11.0}, r"Demo\.sigma_m must be in \[0\.001, 10\.0\], got 11\.0"),
        ({"robust": 1}, r"Demo\.robust must be true or false, got 1"),
        ({"kind": "slow"}, r"Demo\.kind 'slow' is not one of fast, exact"),
        ({"mode": "FAST"}, r"Demo\.mode must be one of FAST, EXACT"),
        ({"gains": (1.0, -1.0)}, r"Demo\.gains must be >= 0\.0"),
        ({"gains": [1.0, 2.0]}, r"Demo\.gains must be a tuple"),
        ({"name": 3}, r"Demo\.name must be text"),
        ({"lo_m": 5.0}, r"lo_m \(5\.0\) must be below hi_m"),
    ],
)
def test_validation_derived_from_metadata_then_cross_field_rules(
        kw: dict[str, object], message: str) -> None:
    with pytest.raises(ParamsError, match=message):
        Demo(**kw)  # type: ignore[arg-type]


def test_valid_values_pass_and_numpy_scalars_count() -> None:
    d = Demo(n=np.int64(10), sigma_m=np.float64(10.0), robust=np.bool_(False))  # type: ignore[arg-type]
    assert d.n == 10
    assert Demo(sigma_m=1).sigma_m == 1  # an int is a valid float
    assert Demo(limit=3.0).limit == 3.0  # an optional field: no metadata type check
    assert dataclasses.replace(Demo(), kind="exact").kind == "exact"


def test_a_class_can_raise_its_modules_error_type() -> None:
    with pytest.raises(LocalError, match=r"Strict\.k must be in \[0, 3\], got 4"):
        Strict(k=4)


def test_presets_apply_on_top_of_the_current_values() -> None:
    d = Demo(sigma_m=2.0).with_preset("exact")
    assert (d.kind, d.n, d.sigma_m) == ("exact", 50, 2.0)
    assert d.matching_presets() == ("exact",)
    assert Demo().matching_presets() == ()
    assert Demo.preset_names() == ("exact", "broken")
    with pytest.raises(ParamsError, match=r"no preset 'paper' \(presets: exact, broken\)"):
        Demo().with_preset("paper")
    with pytest.raises(ParamsError, match="preset 'broken'"):
        Demo().with_preset("broken")
    with pytest.raises(ParamsError, match="Strict has no preset 'x' \\(presets: none\\)"):
        Strict().with_preset("x")


def test_cli_preset_is_applied_first_then_the_other_keys() -> None:
    d = apply_param_overrides(Demo(), ["n=70", "preset=exact"])
    assert (d.kind, d.n) == ("exact", 70)
    with pytest.raises(ParamsError, match="no preset 'nope'"):
        apply_param_overrides(Demo(), ["preset=nope"])
    with pytest.raises(ParamsError, match="Strict has no presets"):
        apply_param_overrides(Strict(), ["preset=x"])
    with pytest.raises(ParamsError, match=r"n must be in \[10, 5000\]"):
        apply_param_overrides(Demo(), ["preset=exact", "n=1"])


def test_params_instances_are_frozen_and_slotted() -> None:
    d = Demo()
    with pytest.raises(dataclasses.FrozenInstanceError):
        d.n = 3  # type: ignore[misc]
    assert not hasattr(d, "__dict__")


# ---------------------------------------------------------------- one way, engine-wide
#: dataclasses with help metadata that are not Params yet: moved by another engineer now
#: (the coordinator converts them after), or a calibration record with its own error type
PENDING = {
    "engine.camera.Intrinsics",
}


def _engine_dataclasses() -> list[type]:
    out = []
    for mod in pkgutil.walk_packages(engine.__path__, "engine."):
        try:
            m = importlib.import_module(mod.name)
        except ImportError:  # optional heavy dependency (open3d) missing: skip that module
            continue
        for obj in vars(m).values():
            if (isinstance(obj, type) and dataclasses.is_dataclass(obj)
                    and obj.__module__ == m.__name__):
                out.append(obj)
    return out


def test_every_engine_params_class_is_declared_one_way() -> None:
    from engine.trackers import available_trackers

    classes = [c for c in _engine_dataclasses()
               if is_params_class(c) or any("help" in f.metadata for f in dataclasses.fields(c))]
    classes += [s.params_cls for s in available_trackers().values()]
    seen = set()
    for cls in classes:
        qual = f"{cls.__module__}.{cls.__qualname__}"
        if qual in PENDING or qual in seen:
            continue
        seen.add(qual)
        assert is_params_class(cls), f"{qual} is not an engine.params.Params dataclass"
        dp = cls.__dataclass_params__  # type: ignore[attr-defined]
        assert dp.frozen, f"{qual} is not frozen"
        assert "__slots__" in vars(cls), f"{qual} is not slotted"
        assert cls.__post_init__ is Params.__post_init__, (
            f"{qual} defines __post_init__: put cross-field rules in validate()")
        for f in dataclasses.fields(cls):
            assert str(f.metadata.get("help", "")).strip(), f"{qual}.{f.name} has no help"
            assert f.name != "preset", f"{qual}: 'preset' is reserved for --param preset=NAME"
        cls()  # the defaults are valid
        for name in cls.PRESETS:
            cls().with_preset(name)  # every preset is valid
    for qual in ("engine.presenter.params.PresenterParams", "engine.beacons.params."
                 "BeaconFilterParams", "engine.beacons.simulator.SimConfig",
                 "engine.trackers.ptz.PtzParams", "engine.ptz.sim.CircleScenario",
                 "engine.outputs.timing.DelayParams", "engine.outputs.sender.FreeDSettings",
                 "engine.keyframes.fusion.FusionParams", "engine.keyframes.sba.SBAParams",
                 "engine.keyframes.sweep.SweepParams"):
        assert qual in seen, f"{qual} not found among the engine's params classes"
