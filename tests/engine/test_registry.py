"""One registry pattern (engine.registry.Registry) for trackers, sources, benches, commands."""

from __future__ import annotations

import sys
import textwrap
from dataclasses import dataclass
from pathlib import Path

import pytest

from engine.errors import SourceError, TrackerError
from engine.registry import Registry, RegistryError


@dataclass(frozen=True)
class ThingSpec:
    name: str


@pytest.fixture
def plugin_package(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):  # type: ignore[no-untyped-def]
    """A throw-away package ``fakeplugins`` whose modules the test writes."""
    pkg = tmp_path / "fakeplugins"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    monkeypatch.syspath_prepend(str(tmp_path))

    def write(name: str, body: str) -> None:
        (pkg / f"{name}.py").write_text(textwrap.dedent(body))

    yield write
    for mod in [m for m in sys.modules if m == "fakeplugins" or m.startswith("fakeplugins.")]:
        del sys.modules[mod]


HEADER = "from tests.engine.test_registry import ThingSpec\n"


def test_discovers_specs_in_module_order_and_skips_private_modules(plugin_package) -> None:  # type: ignore[no-untyped-def]
    plugin_package("b_second", HEADER + "THINGS = (ThingSpec('b1'), ThingSpec('b2'))\n")
    plugin_package("a_first", HEADER + "THINGS = (ThingSpec('a'),)\n")
    plugin_package("_private", HEADER + "THINGS = (ThingSpec('hidden'),)\n")
    plugin_package("nothing", "X = 1\n")
    reg = Registry("thing", "THINGS", ThingSpec, places=("fakeplugins",))
    assert reg.names() == ["a", "b1", "b2"]
    assert reg.get("b2") == ThingSpec("b2")
    assert reg.specs() is reg.specs()  # cached


def test_a_module_can_be_named_directly(plugin_package) -> None:  # type: ignore[no-untyped-def]
    plugin_package("one", HEADER + "THINGS = (ThingSpec('one'),)\n")
    plugin_package("two", HEADER + "THINGS = (ThingSpec('two'),)\n")
    reg = Registry("thing", "THINGS", ThingSpec, places=("fakeplugins.two",))
    assert reg.names() == ["two"]


def test_unknown_name_is_a_one_line_error_listing_all(plugin_package) -> None:  # type: ignore[no-untyped-def]
    plugin_package("m", HEADER + "THINGS = (ThingSpec('zeta'), ThingSpec('alpha'))\n")
    reg = Registry("thing", "THINGS", ThingSpec, places=("fakeplugins",), error=TrackerError)
    with pytest.raises(TrackerError, match=r"^unknown thing 'x'; available: alpha, zeta$"):
        reg.get("x")


def test_duplicate_names_and_wrong_records_are_refused(plugin_package) -> None:  # type: ignore[no-untyped-def]
    plugin_package("m1", HEADER + "THINGS = (ThingSpec('same'),)\n")
    plugin_package("m2", HEADER + "THINGS = (ThingSpec('same'),)\n")
    reg = Registry("thing", "THINGS", ThingSpec, places=("fakeplugins",))
    twice = r"'same' registered twice \(fakeplugins.m1, fakeplugins.m2\)"
    with pytest.raises(RegistryError, match=twice):
        reg.names()
    plugin_package("m2", "THINGS = ({'name': 'dict'},)\n")
    del sys.modules["fakeplugins.m2"]
    reg.clear()
    with pytest.raises(RegistryError, match=r"m2.THINGS holds a dict, not a ThingSpec"):
        reg.names()
    plugin_package("m2", HEADER + "THINGS = ThingSpec('bare')\n")
    del sys.modules["fakeplugins.m2"]
    with pytest.raises(RegistryError, match=r"THINGS must be a tuple of ThingSpec"):
        Registry("thing", "THINGS", ThingSpec, places=("fakeplugins",)).names()


def test_every_built_in_tracker_source_bench_and_command_is_registered() -> None:
    from app.commands import available_commands
    from engine.bench import available_benches
    from engine.sources import available_sources
    from engine.trackers import available_trackers

    assert {"dense", "opencv-odometry", "presenter", "ptz", "beacon-slam", "kcf"} <= set(
        available_trackers()
    )
    assert {"synthetic", "ptz-sim", "camera", "beacons", "beacons-csv", "beacons-udp",
            "tum", "otb", "video"} <= set(available_sources())
    assert set(available_benches()) >= {
        "render", "dense", "keyframes", "presenter", "ptz", "beacon", "soak"}
    assert set(available_commands()) >= {
        "track", "eval", "bench", "calibrate", "sweep", "record", "replay", "listen",
        "demo-data", "gui"}


def test_source_errors_name_what_is_available(tmp_path: Path) -> None:
    from engine.sources import open_source

    with pytest.raises(SourceError, match=r"'synthetc' is not a source scheme; .*synthetic:"):
        open_source("synthetc:frames=3")
    (tmp_path / "notes.txt").write_text("x")
    with pytest.raises(SourceError, match=r"notes.txt: unsupported source; expected .*TUM"):
        open_source(str(tmp_path / "notes.txt"))


def test_a_folder_matching_two_kinds_is_refused_not_guessed(tmp_path: Path) -> None:
    from engine.sources import open_source

    (tmp_path / "rgb.txt").write_text("")
    (tmp_path / "img").mkdir()
    with pytest.raises(SourceError, match=r"looks like several kinds of source \(otb, tum\)"):
        open_source(str(tmp_path))
