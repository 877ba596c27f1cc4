"""A form built from a frozen parameters dataclass.

One editor per field, chosen from the field's current value: ``bool`` -> check box, ``int`` ->
spin box, ``float`` -> double spin box, ``Enum`` or ``metadata["choices"]`` -> combo box,
``str`` -> line edit, tuples/lists of numbers -> comma-separated line edit. Field metadata gives
``help`` (tooltip), ``min``, ``max``, ``step`` and optionally ``decimals``/``label``/``unit``
(what :func:`engine.params.param` writes). A params class with presets
(:class:`engine.params.Params` ``PRESETS``) gets a *preset* box on top: choosing one applies
its overrides to the current values; it shows the first preset the values match, else
"custom".

Every edit builds a candidate with :func:`dataclasses.replace` from the last valid params and
*all* editor values (so fixing one side of a cross-field rule also applies the other side). If
the dataclass rejects it (``__post_init__`` raises), the form keeps the last valid params,
marks the edited field and shows why; otherwise it emits ``params_changed(new_params)``.
"""

from __future__ import annotations

import dataclasses
import enum
import math
from collections.abc import Callable
from typing import Any

from PySide6.QtCore import Qt, Signal, Slot
from PySide6.QtWidgets import (
    QAbstractSpinBox,
    QCheckBox,
    QComboBox,
    QDoubleSpinBox,
    QFormLayout,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QPushButton,
    QSizePolicy,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)

from engine.params import Params

INT_LIMIT = 2**31 - 1
UNIT_SUFFIXES = {
    "px": "px",
    "m": "m",
    "mm": "mm",
    "cm": "cm",
    "s": "s",
    "ms": "ms",
    "hz": "Hz",
    "deg": "°",
    "rad": "rad",
    "pct": "%",
    "fps": "fps",
}
INVALID_STYLE = "border: 1px solid #ff4d4f; background: #3a1f22;"


def field_label(name: str, metadata: Any) -> str:
    """``max_depth_m`` -> ``max depth (m)`` unless ``metadata["label"]`` says otherwise; a
    ``metadata["unit"]`` is shown when the name carries no unit suffix."""
    if "label" in metadata:
        return str(metadata["label"])
    words = name.split("_")
    unit = None
    if len(words) > 1 and words[-1].lower() in UNIT_SUFFIXES:
        unit = UNIT_SUFFIXES[words.pop().lower()]
    elif metadata.get("unit"):
        unit = str(metadata["unit"])
    text = " ".join(words)
    return f"{text} ({unit})" if unit else text


def _decimals_for(step: float | None, value: float) -> int:
    if step is not None and step > 0:
        return int(min(8, max(1, math.ceil(-math.log10(step)) + 1)))
    if value != 0 and math.isfinite(value):
        return int(min(8, max(2, math.ceil(-math.log10(abs(value))) + 3)))
    return 3


class _Editor:
    """Wraps one field's widget: read/write its value, connect its change signal."""

    def __init__(
        self,
        widget: QWidget,
        get: Callable[[], Any],
        put: Callable[[Any], None],
        changed: Any,
    ) -> None:
        self.widget = widget
        self.get = get
        self.put = put
        self.changed = changed


def _parse_sequence(text: str, like: tuple[Any, ...] | list[Any]) -> tuple[Any, ...] | list[Any]:
    parts = [p.strip() for p in text.replace(";", ",").split(",") if p.strip()]
    kinds = [type(v) for v in like] or [float]
    out: list[Any] = []
    for i, part in enumerate(parts):
        kind = kinds[i] if i < len(kinds) else kinds[-1]
        if kind is int:
            out.append(int(part))
        elif kind is bool:
            out.append(part.lower() in ("1", "true", "yes", "on"))
        elif kind is str:
            out.append(part)
        else:
            out.append(float(part))
    return tuple(out) if isinstance(like, tuple) else out


class ParamForm(QWidget):
    """Edits a frozen params dataclass; ``params_changed`` carries each valid new object."""

    params_changed = Signal(object)
    edit_rejected = Signal(str)  # "field: reason"

    def __init__(self, params: Any | None = None, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self._params: Any | None = None
        self._editors: dict[str, _Editor] = {}
        self.preset_box: QComboBox | None = None  # only for params classes with presets
        self._errors: dict[str, str] = {}
        #: editor values as loaded from the last valid params (spin boxes may round)
        self._shown: dict[str, Any] = {}
        self._form = QFormLayout()
        self._form.setLabelAlignment(Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter)
        self._form.setFieldGrowthPolicy(QFormLayout.FieldGrowthPolicy.AllNonFixedFieldsGrow)
        self._form.setContentsMargins(0, 0, 0, 0)
        self._form.setVerticalSpacing(4)
        self.title = QLabel()
        self.title.setObjectName("readout_caption")
        self.title.setWordWrap(True)
        # a long docstring must not widen the form beyond its scroll area
        self.title.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Preferred)
        self.title.setMinimumWidth(0)
        self.error_label = QLabel()
        self.error_label.setObjectName("param_error")
        self.error_label.setWordWrap(True)
        self.error_label.setVisible(False)
        self.defaults_button = QPushButton("Defaults")
        self.defaults_button.setToolTip("Restore the default value of every parameter")
        self.defaults_button.clicked.connect(self.restore_defaults)
        self.empty_label = QLabel("No adjustable parameters")
        self.empty_label.setObjectName("readout_caption")
        buttons = QHBoxLayout()
        buttons.addStretch(1)
        buttons.addWidget(self.defaults_button)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addWidget(self.title)
        layout.addLayout(self._form)
        layout.addWidget(self.empty_label)
        layout.addWidget(self.error_label)
        layout.addLayout(buttons)
        layout.addStretch(1)
        self.set_params(params, rebuild=True)

    # ------------------------------------------------------------------ state
    @property
    def params(self) -> Any | None:
        """The last valid params object."""
        return self._params

    @property
    def errors(self) -> dict[str, str]:
        """Rejected edits by field name (empty when the form shows valid params)."""
        return dict(self._errors)

    def editor(self, name: str) -> QWidget:
        return self._editors[name].widget

    def set_params(self, params: Any | None, rebuild: bool | None = None) -> None:
        """Show ``params`` (rebuilding the editors when the class changes); emits nothing."""
        if params is not None and not dataclasses.is_dataclass(params):
            raise TypeError(f"ParamForm needs a dataclass instance, got {type(params).__name__}")
        if rebuild is None:
            rebuild = type(params) is not type(self._params)
        self._params = params
        self._errors.clear()
        if rebuild:
            self._rebuild()
        else:
            self._load_values()
        self._show_errors()

    def _rebuild(self) -> None:
        while self._form.rowCount():
            self._form.removeRow(0)
        self._editors.clear()
        self.preset_box = None
        params = self._params
        self.title.setText(
            "" if params is None else (type(params).__doc__ or "").strip().split("\n")[0]
        )
        self.title.setVisible(bool(self.title.text()))
        if isinstance(params, Params) and params.PRESETS:
            self._add_preset_box(params)
        fields = [] if params is None else [f for f in dataclasses.fields(params) if f.init]
        for f in fields:
            value = getattr(params, f.name)
            editor = self._make_editor(f, value)
            if editor is None:
                continue
            tip = str(f.metadata.get("help", "")) or f.name
            label = QLabel(field_label(f.name, f.metadata))
            label.setToolTip(tip)
            editor.widget.setToolTip(tip)
            editor.widget.setObjectName(f"param_{f.name}")
            # spin boxes size themselves for their largest value: let the panel decide
            editor.widget.setMinimumWidth(72)
            self._form.addRow(label, editor.widget)
            self._editors[f.name] = editor
            editor.changed.connect(lambda *_a, n=f.name: self._on_edit(n))
        self._shown = {name: editor.get() for name, editor in self._editors.items()}
        self.empty_label.setVisible(params is not None and not self._editors)
        self.defaults_button.setVisible(bool(self._editors))

    def _add_preset_box(self, params: Params) -> None:
        box = QComboBox()
        box.setObjectName("param_preset")
        box.addItem("custom", None)
        box.setItemData(0, "values of no preset", Qt.ItemDataRole.ToolTipRole)
        for name, preset in params.PRESETS.items():
            box.addItem(name, name)
            box.setItemData(box.count() - 1, preset.help, Qt.ItemDataRole.ToolTipRole)
        box.setToolTip("apply a named set of values (the other fields keep theirs)")
        box.setMinimumWidth(72)
        label = QLabel("preset")
        label.setToolTip(box.toolTip())
        self._form.addRow(label, box)
        self.preset_box = box
        self._show_preset()
        box.currentIndexChanged.connect(self._on_preset)

    def _show_preset(self) -> None:
        box = self.preset_box
        if box is None or not isinstance(self._params, Params):
            return
        matching = self._params.matching_presets()
        box.blockSignals(True)
        try:
            box.setCurrentIndex(max(0, box.findData(matching[0])) if matching else 0)
        finally:
            box.blockSignals(False)

    @Slot()
    def _on_preset(self) -> None:
        box = self.preset_box
        name = None if box is None else box.currentData()
        if name is None or not isinstance(self._params, Params):
            return  # "custom": nothing to apply
        try:
            candidate = self._params.with_preset(str(name))
        except Exception as exc:  # a preset the class rejects
            reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            self._errors = {"preset": reason}
            self._show_errors()
            self.edit_rejected.emit(f"preset: {reason}")
            self._show_preset()
            return
        changed = candidate != self._params
        self.set_params(candidate, rebuild=False)
        if changed:
            self.params_changed.emit(candidate)

    def _make_editor(self, f: dataclasses.Field[Any], value: Any) -> _Editor | None:
        md = f.metadata
        choices = md.get("choices")
        if choices is not None:
            box = QComboBox()
            for c in choices:
                box.addItem(str(c), c)
            box.setCurrentIndex(max(0, box.findData(value)))
            return _Editor(
                box,
                box.currentData,
                lambda v, b=box: b.setCurrentIndex(max(0, b.findData(v))),
                box.currentIndexChanged,
            )
        if isinstance(value, bool):
            check = QCheckBox()
            check.setChecked(value)
            return _Editor(check, check.isChecked, check.setChecked, check.toggled)
        if isinstance(value, enum.Enum):
            box = QComboBox()
            for member in type(value):
                box.addItem(member.name.replace("_", " ").lower(), member)
            box.setCurrentIndex(box.findData(value))
            return _Editor(
                box,
                box.currentData,
                lambda v, b=box: b.setCurrentIndex(b.findData(v)),
                box.currentIndexChanged,
            )
        if isinstance(value, int):
            spin = QSpinBox()
            spin.setRange(int(md.get("min", -INT_LIMIT)), int(md.get("max", INT_LIMIT)))
            spin.setSingleStep(int(md.get("step", 1)))
            spin.setKeyboardTracking(False)
            spin.setValue(value)
            spin.setAlignment(Qt.AlignmentFlag.AlignRight)
            return _Editor(spin, spin.value, spin.setValue, spin.valueChanged)
        if isinstance(value, float):
            dspin = QDoubleSpinBox()
            step = md.get("step")
            dspin.setDecimals(int(md.get("decimals", _decimals_for(step, value))))
            dspin.setRange(float(md.get("min", -1e9)), float(md.get("max", 1e9)))
            if step is not None:
                dspin.setSingleStep(float(step))
            else:
                dspin.setStepType(QAbstractSpinBox.StepType.AdaptiveDecimalStepType)
            dspin.setKeyboardTracking(False)
            dspin.setValue(value)
            dspin.setAlignment(Qt.AlignmentFlag.AlignRight)
            return _Editor(dspin, dspin.value, dspin.setValue, dspin.valueChanged)
        if isinstance(value, str):
            line = QLineEdit(value)
            return _Editor(line, line.text, line.setText, line.editingFinished)
        if isinstance(value, tuple | list) and all(
            isinstance(v, int | float | str) for v in value
        ):
            line = QLineEdit(", ".join(str(v) for v in value))
            like = value
            return _Editor(
                line,
                lambda ln=line, lk=like: _parse_sequence(ln.text(), lk),
                lambda v, ln=line: ln.setText(", ".join(str(x) for x in v)),
                line.editingFinished,
            )
        return None  # not editable here (arrays, nested objects): keeps its value

    def _load_values(self) -> None:
        if self._params is None:
            return
        for name, editor in self._editors.items():
            editor.widget.blockSignals(True)
            try:
                editor.put(getattr(self._params, name))
            finally:
                editor.widget.blockSignals(False)
        self._shown = {name: editor.get() for name, editor in self._editors.items()}
        self._show_preset()

    # ------------------------------------------------------------------ edits
    def _candidate(self) -> Any:
        values = {name: editor.get() for name, editor in self._editors.items()}
        # only what the operator changed: a spin box's rounding of an untouched value is not
        # an edit
        changed = {k: v for k, v in values.items() if v != self._shown.get(k)}
        return dataclasses.replace(self._params, **changed) if changed else self._params

    @Slot()
    def _on_edit(self, name: str) -> None:
        if self._params is None:
            return
        try:
            candidate = self._candidate()
        except Exception as exc:  # the dataclass (or parsing) rejected the edit
            reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            self._errors = {name: reason}
            self._show_errors()
            self.edit_rejected.emit(f"{name}: {reason}")
            return
        self._errors.clear()
        self._show_errors()
        self._shown = {n: editor.get() for n, editor in self._editors.items()}
        if candidate is not self._params and candidate != self._params:
            self._params = candidate
            self._show_preset()
            self.params_changed.emit(candidate)

    def _show_errors(self) -> None:
        for name, editor in self._editors.items():
            editor.widget.setStyleSheet(INVALID_STYLE if name in self._errors else "")
        if self._errors:
            text = "\n".join(
                f"{field_label(n, {})}: {msg} (keeping the last valid value)"
                for n, msg in self._errors.items()
            )
            self.error_label.setText(text)
        self.error_label.setVisible(bool(self._errors))

    @Slot()
    def restore_defaults(self) -> None:
        if self._params is None:
            return
        try:
            defaults = type(self._params)()
        except Exception as exc:  # a params class without full defaults
            self._errors = {"defaults": str(exc)}
            self._show_errors()
            return
        changed = defaults != self._params
        self.set_params(defaults, rebuild=False)
        if changed:
            self.params_changed.emit(defaults)
