"""ParamForm: editors from field metadata, replace() on edit, invalid edits keep the last valid."""

from __future__ import annotations

import enum
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import ClassVar

import pytest

from engine.errors import ParamsError
from engine.params import Params as EngineParams
from engine.params import Preset, param
from widgets.param_form import ParamForm, field_label


class Mode(enum.Enum):
    FAST = "fast"
    ACCURATE = "accurate"


@dataclass(frozen=True, slots=True)
class Params:
    """Test parameters."""

    n_points: int = field(
        default=100, metadata={"help": "points used", "min": 10, "max": 1000, "step": 10}
    )
    min_depth_m: float = field(
        default=0.5, metadata={"help": "near limit", "min": 0.0, "step": 0.1}
    )
    max_depth_m: float = field(default=4.0, metadata={"help": "far limit", "min": 0.0})
    tiny_gain: float = field(default=0.000123, metadata={"help": "rounds in a spin box"})
    robust: bool = field(default=True, metadata={"help": "use weights"})
    mode: Mode = Mode.FAST
    algorithm: str = field(default="a", metadata={"choices": ("a", "b")})
    iter_counts: tuple[int, ...] = field(default=(7, 7, 10), metadata={"help": "per level"})
    name: str = "cam"

    def __post_init__(self) -> None:
        if self.min_depth_m >= self.max_depth_m:
            raise ParamsError(
                f"min_depth_m ({self.min_depth_m}) must be below max_depth_m ({self.max_depth_m})"
            )
        if any(i <= 0 for i in self.iter_counts):
            raise ParamsError(f"iter_counts must be positive, got {self.iter_counts}")


@pytest.fixture
def form(qtbot):  # type: ignore[no-untyped-def]
    f = ParamForm(Params())
    qtbot.addWidget(f)
    f.show()
    return f


def test_editors_follow_metadata(form: ParamForm) -> None:
    spin = form.editor("n_points")
    assert (spin.minimum(), spin.maximum(), spin.singleStep()) == (10, 1000, 10)
    assert spin.toolTip() == "points used"
    assert form.editor("min_depth_m").singleStep() == pytest.approx(0.1)
    assert form.editor("algorithm").count() == 2
    assert form.editor("mode").count() == 2
    assert form.editor("iter_counts").text() == "7, 7, 10"
    assert field_label("max_depth_m", {}) == "max depth (m)"
    assert field_label("rate_hz", {"label": "Rate"}) == "Rate"


def test_valid_edit_emits_replaced_params(qtbot, form: ParamForm) -> None:
    before = form.params
    with qtbot.waitSignal(form.params_changed) as blocker:
        form.editor("n_points").setValue(250)
    new = blocker.args[0]
    assert new == Params(n_points=250)
    assert new is not before
    assert before.n_points == 100
    assert form.params is new
    # untouched fields are not disturbed by the spin box's rounding of 0.000123
    assert new.tiny_gain == pytest.approx(0.000123)
    with qtbot.waitSignal(form.params_changed) as blocker:
        form.editor("mode").setCurrentIndex(1)
    assert blocker.args[0].mode is Mode.ACCURATE
    with qtbot.waitSignal(form.params_changed) as blocker:
        form.editor("robust").setChecked(False)
    assert blocker.args[0].robust is False
    line = form.editor("iter_counts")
    line.setText("3, 4")
    with qtbot.waitSignal(form.params_changed) as blocker:
        line.editingFinished.emit()
    assert blocker.args[0].iter_counts == (3, 4)


def test_invalid_edit_keeps_last_valid_and_shows_why(qtbot, form: ParamForm) -> None:
    valid = form.params
    with qtbot.assertNotEmitted(form.params_changed), qtbot.waitSignal(form.edit_rejected) as b:
        form.editor("min_depth_m").setValue(5.0)
    assert "min_depth_m (5.0) must be below max_depth_m (4.0)" in b.args[0]
    assert form.params is valid
    assert form.error_label.isVisible()
    assert "must be below" in form.error_label.text()
    assert "min_depth_m" in form.errors
    assert "#ff4d4f" in form.editor("min_depth_m").styleSheet()
    # fixing the other side of the rule applies both edits at once
    with qtbot.waitSignal(form.params_changed) as blocker:
        form.editor("max_depth_m").setValue(8.0)
    assert (blocker.args[0].min_depth_m, blocker.args[0].max_depth_m) == (5.0, 8.0)
    assert not form.errors
    assert not form.error_label.isVisible()


def test_unparsable_text_is_rejected(qtbot, form: ParamForm) -> None:
    valid = form.params
    line = form.editor("iter_counts")
    line.setText("7, seven")
    with qtbot.waitSignal(form.edit_rejected):
        line.editingFinished.emit()
    assert form.params is valid
    line.setText("7, -1")
    with qtbot.waitSignal(form.edit_rejected) as blocker:
        line.editingFinished.emit()
    assert "iter_counts must be positive" in blocker.args[0]


def test_defaults_and_programmatic_set(qtbot, form: ParamForm) -> None:
    form.set_params(Params(n_points=500, name="x"))
    assert form.editor("n_points").value() == 500
    assert form.editor("name").text() == "x"
    with qtbot.waitSignal(form.params_changed) as blocker:
        form.defaults_button.click()
    assert blocker.args[0] == Params()
    form.set_params(None)
    assert form.params is None


def test_rejects_non_dataclass(qtbot) -> None:  # type: ignore[no-untyped-def]
    form = ParamForm()
    qtbot.addWidget(form)
    with pytest.raises(TypeError, match="dataclass"):
        form.set_params(object())


def test_real_tracker_params_build_a_form(qtbot) -> None:  # type: ignore[no-untyped-def]
    from engine.trackers import available_trackers

    for spec in available_trackers().values():
        form = ParamForm(spec.params_cls())
        qtbot.addWidget(form)
        assert form.params == spec.params_cls()


@dataclass(frozen=True, slots=True)
class WithPresets(EngineParams):
    """Parameters with presets."""

    n: int = param(10, help="count", lo=1, hi=100)
    rate: float = param(30.0, help="update rate", unit="Hz")
    exact: bool = param(False, help="exact rule")

    PRESETS: ClassVar[Mapping[str, Preset]] = {
        "paper": Preset("as published", n=50, exact=True),
        "bad": Preset("out of range", n=1000),
    }


def test_preset_box_applies_presets_and_follows_edits(qtbot) -> None:  # type: ignore[no-untyped-def]
    f = ParamForm(WithPresets())
    qtbot.addWidget(f)
    box = f.preset_box
    assert box is not None
    assert [box.itemText(i) for i in range(box.count())] == ["custom", "paper", "bad"]
    assert box.currentText() == "custom"
    with qtbot.waitSignal(f.params_changed) as blocker:
        box.setCurrentIndex(box.findData("paper"))
    assert blocker.args[0] == WithPresets(n=50, exact=True)
    assert f.editor("n").value() == 50
    with qtbot.waitSignal(f.params_changed):
        f.editor("n").setValue(49)
    assert box.currentText() == "custom"  # the values no longer match the preset
    with qtbot.waitSignal(f.edit_rejected):
        box.setCurrentIndex(box.findData("bad"))
    assert f.params == WithPresets(n=49, exact=True)  # kept the last valid params
    assert "preset" in f.errors
    assert box.currentText() == "custom"
    assert ParamForm(Params()).preset_box is None  # a plain dataclass: no preset box


def test_unit_metadata_labels_a_field_without_a_unit_suffix() -> None:
    assert field_label("rate", {"unit": "Hz"}) == "rate (Hz)"
    assert field_label("rate_hz", {"unit": "1/s"}) == "rate (Hz)"  # the name's suffix wins
