"""Source picker: built-in studio (with options), folder, video file, webcam, depth camera or
RealSense recording -> a spec string.

The spec strings are those of :func:`engine.sources.open_source`:
``synthetic:frames=600,seed=3,presenter=1,path=rail``, a TUM/OTB folder path, a video file path,
``camera:N``, ``realsense:serial=…``, a ``.bag`` path. The picker does not open anything; the
engine thread does (errors come back through the run owner). Connected depth cameras are listed
(serial, model) when the "Depth camera" kind is chosen and on Refresh, not at start-up.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

from PySide6.QtCore import QMargins, QPoint, QRect, QSize, QStringListModel, Qt, Signal, Slot
from PySide6.QtGui import QResizeEvent
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QCompleter,
    QFileDialog,
    QHBoxLayout,
    QLabel,
    QLayout,
    QLayoutItem,
    QLineEdit,
    QPushButton,
    QSizePolicy,
    QSpinBox,
    QStackedWidget,
    QWidget,
)

STUDIO_PATHS = ("rail", "pan", "handheld", "static")
VIDEO_FILTER = "Video files (*.mp4 *.avi *.mov *.mkv *.m4v);;All files (*)"
BAG_FILTER = "RealSense recordings (*.bag);;All files (*)"


class SourceKind:
    STUDIO = "studio"
    FOLDER = "folder"
    VIDEO = "video"
    CAMERA = "camera"
    DEPTH = "depth"
    BAG = "bag"


KIND_TITLES = {
    SourceKind.STUDIO: "Built-in studio",
    SourceKind.FOLDER: "Folder (TUM / OTB)",
    SourceKind.VIDEO: "Video file",
    SourceKind.CAMERA: "Camera",
    SourceKind.DEPTH: "Depth camera",
    SourceKind.BAG: "Recording (.bag)",
}


def _list_depth_cameras() -> list[tuple[str, str]]:
    """(spec, label) of each connected RealSense camera, through the vendor SDK."""
    from engine.sources.realsense import list_devices

    return [(d.spec, f"{d.model or 'RealSense'} · {d.serial}" + (f" (USB {d.usb})" if d.usb
                                                                 else ""))
            for d in list_devices()]


def parse_synthetic(spec: str) -> dict[str, str]:
    """Options of a ``synthetic:...`` spec (lenient: malformed items are ignored here)."""
    _, _, rest = spec.partition(":")
    out: dict[str, str] = {}
    for item in filter(None, (s.strip() for s in rest.split(","))):
        key, sep, value = item.partition("=")
        if sep and key.strip():
            out[key.strip()] = value.strip()
    return out


class FlowLayout(QLayout):
    """Lays its widgets out left to right and wraps to the next line when the row is full.

    The studio options then fit a narrow panel (Keyframes page) on two lines instead of
    clipping every field, and stay on one line on a wide page. The last item may stretch to
    fill the rest of its line (``stretch_last``).
    """

    def __init__(
        self, parent: QWidget | None = None, spacing: int = 6, stretch_last: bool = False
    ) -> None:
        super().__init__(parent)
        self._items: list[QLayoutItem] = []
        self._spacing = spacing
        self.stretch_last = stretch_last
        self.setContentsMargins(QMargins(0, 0, 0, 0))

    def addItem(self, item: QLayoutItem) -> None:
        self._items.append(item)

    def count(self) -> int:
        return len(self._items)

    def itemAt(self, index: int) -> QLayoutItem | None:  # type: ignore[override]
        return self._items[index] if 0 <= index < len(self._items) else None

    def takeAt(self, index: int) -> QLayoutItem | None:  # type: ignore[override]
        return self._items.pop(index) if 0 <= index < len(self._items) else None

    def expandingDirections(self) -> Qt.Orientation:
        return Qt.Orientation(0)

    def hasHeightForWidth(self) -> bool:
        return True

    def heightForWidth(self, width: int) -> int:
        return self._do_layout(QRect(0, 0, width, 0), apply=False)

    def setGeometry(self, rect: QRect) -> None:
        super().setGeometry(rect)
        self._do_layout(rect, apply=True)

    def sizeHint(self) -> QSize:
        w = sum(i.sizeHint().width() for i in self._items if not i.isEmpty())
        w += self._spacing * max(0, len(self._items) - 1)
        h = max((i.sizeHint().height() for i in self._items), default=0)
        return QSize(w, h)

    def minimumSize(self) -> QSize:
        size = QSize()
        for item in self._items:
            size = size.expandedTo(item.minimumSize())
        return size

    def _do_layout(self, rect: QRect, apply: bool) -> int:
        x, y, line_h = rect.x(), rect.y(), 0
        lines: list[list[tuple[QLayoutItem, int]]] = [[]]
        for item in self._items:
            if item.isEmpty():
                continue
            w = item.sizeHint().width()
            if lines[-1] and x + w > rect.right() + 1:
                lines.append([])
                x = rect.x()
            lines[-1].append((item, w))
            x += w + self._spacing
        for n, line in enumerate(lines):
            line_h = max((i.sizeHint().height() for i, _ in line), default=0)
            x = rect.x()
            for k, (item, w) in enumerate(line):
                last = n == len(lines) - 1 and k == len(line) - 1
                if last and self.stretch_last:
                    w = max(w, rect.right() + 1 - x)
                w = min(w, rect.width())
                if apply:
                    h = item.sizeHint().height()
                    item.setGeometry(QRect(QPoint(x, y + (line_h - h) // 2), QSize(w, h)))
                x += w + self._spacing
            y += line_h + (self._spacing if n < len(lines) - 1 else 0)
        return y - rect.y()


def _flow(*widgets: QWidget, stretch_last: bool = False) -> QWidget:
    w = QWidget()
    layout = FlowLayout(w, stretch_last=stretch_last)
    for child in widgets:
        layout.addWidget(child)
    policy = QSizePolicy(QSizePolicy.Policy.Preferred, QSizePolicy.Policy.Preferred)
    policy.setHeightForWidth(True)
    w.setSizePolicy(policy)
    return w


def _row(*widgets: QWidget, stretch_last: bool = False) -> QWidget:
    w = QWidget()
    layout = QHBoxLayout(w)
    layout.setContentsMargins(0, 0, 0, 0)
    layout.setSpacing(6)
    for i, child in enumerate(widgets):
        layout.addWidget(child, 1 if stretch_last and i == len(widgets) - 1 else 0)
    if not stretch_last:
        layout.addStretch(1)
    return w


class _PathEditor(QWidget):
    """Line edit with recent-path completion and a Browse button."""

    edited = Signal()

    def __init__(self, placeholder: str, pick_dir: bool, parent: QWidget | None = None,
                 file_filter: str = VIDEO_FILTER) -> None:
        super().__init__(parent)
        self.pick_dir = pick_dir
        self.file_filter = file_filter
        self.line = QLineEdit()
        self.line.setPlaceholderText(placeholder)
        self.line.setClearButtonEnabled(True)
        self._model = QStringListModel()
        completer = QCompleter(self._model, self)
        completer.setFilterMode(completer.filterMode().MatchContains)
        self.line.setCompleter(completer)
        self.browse = QPushButton("Browse…")
        layout = QHBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.setSpacing(6)
        layout.addWidget(self.line, 1)
        layout.addWidget(self.browse)
        self.browse.clicked.connect(self._browse)
        self.line.editingFinished.connect(self.edited)

    def set_recent(self, paths: Sequence[str]) -> None:
        self._model.setStringList(list(paths))

    @Slot()
    def _browse(self) -> None:
        start = self.line.text() or str(Path.home())
        if self.pick_dir:
            path = QFileDialog.getExistingDirectory(self, "Choose a TUM or OTB folder", start)
        else:
            path, _ = QFileDialog.getOpenFileName(self, "Choose a file", start, self.file_filter)
        if path:
            self.line.setText(path)
            self.edited.emit()


class SourcePicker(QWidget):
    """Choose the input; ``spec()`` gives the source spec, ``spec_changed`` fires on edits."""

    spec_changed = Signal(str)

    def __init__(
        self,
        parent: QWidget | None = None,
        *,
        list_depth_cameras: Callable[[], list[tuple[str, str]]] = _list_depth_cameras,
    ) -> None:
        super().__init__(parent)
        self._list_depth_cameras = list_depth_cameras
        self._listed = False
        self.kind_box = QComboBox()
        for kind, title in KIND_TITLES.items():
            self.kind_box.addItem(title, kind)
        self.kind_box.setToolTip("Where frames come from")
        self.stack = QStackedWidget()

        # built-in studio
        self.path_box = QComboBox()
        for p in STUDIO_PATHS:
            self.path_box.addItem(p, p)
        self.path_box.setToolTip(
            "Camera path: rail = 3.3 m dolly back and forth, pan = pan sweep, "
            "handheld = hand-held wobble"
        )
        self.presenter_check = QCheckBox("presenter")
        self.presenter_check.setChecked(True)
        self.presenter_check.setToolTip("A presenter walks through the set (occludes it)")
        self.ball_check = QCheckBox("ball")
        self.ball_check.setToolTip("The red target ball moves on a circle")
        self.seed_spin = QSpinBox()
        self.seed_spin.setRange(0, 1_000_000)
        self.seed_spin.setPrefix("seed ")
        self.seed_spin.setToolTip("Random seed of the studio (deterministic)")
        self.frames_spin = QSpinBox()
        self.frames_spin.setRange(1, 10_000_000)
        self.frames_spin.setValue(100_000)
        self.frames_spin.setSuffix(" frames")
        self.frames_spin.setToolTip("Length of the generated sequence")
        self.frames_spin.setGroupSeparatorShown(True)
        self.extra_line = QLineEdit()
        self.extra_line.setPlaceholderText("more options, e.g. noise=1")
        self.extra_line.setToolTip("Further key=value options of the studio, comma separated")
        self.extra_line.setMinimumWidth(140)
        # sized for typical values, not the range maximum: seed and length share a line
        # when the picker sits in a narrow panel
        self.seed_spin.setMaximumWidth(110)
        self.frames_spin.setMaximumWidth(150)
        path_label = QLabel("path")
        self.studio_page = _flow(
            _row(path_label, self.path_box),  # the label never wraps away from its box
            self.presenter_check,
            self.ball_check,
            self.seed_spin,
            self.frames_spin,
            self.extra_line,
            stretch_last=True,
        )
        # folder / video / camera
        self.folder_edit = _PathEditor("TUM RGB-D or OTB folder", pick_dir=True)
        self.video_edit = _PathEditor("video file (.mp4, .avi, ...)", pick_dir=False)
        self.camera_spin = QSpinBox()
        self.camera_spin.setRange(0, 63)
        self.camera_spin.setPrefix("camera ")
        self.camera_spin.setToolTip("OpenCV camera index")
        self.camera_page = _row(self.camera_spin)
        # depth camera (RealSense, listed through its SDK) / recording
        self.depth_box = QComboBox()
        self.depth_box.setMinimumWidth(220)
        self.depth_box.setToolTip("Connected RealSense depth cameras (model · serial)")
        self.depth_refresh = QPushButton("Refresh")
        self.depth_refresh.setToolTip("List the connected depth cameras again")
        self.depth_page = _row(self.depth_box, self.depth_refresh, stretch_last=False)
        self.bag_edit = _PathEditor("RealSense recording (.bag)", pick_dir=False,
                                    file_filter=BAG_FILTER)
        for page in (self.studio_page, self.folder_edit, self.video_edit, self.camera_page,
                     self.depth_page, self.bag_edit):
            self.stack.addWidget(page)

        layout = QHBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.setSpacing(6)
        layout.addWidget(self.kind_box, 0, Qt.AlignmentFlag.AlignTop)
        layout.addWidget(self.stack, 1)

        self.kind_box.currentIndexChanged.connect(self._on_kind)
        for sig in (
            self.path_box.currentIndexChanged,
            self.presenter_check.toggled,
            self.ball_check.toggled,
            self.seed_spin.valueChanged,
            self.frames_spin.valueChanged,
            self.extra_line.editingFinished,
            self.folder_edit.edited,
            self.video_edit.edited,
            self.camera_spin.valueChanged,
            self.depth_box.currentIndexChanged,
            self.bag_edit.edited,
        ):
            sig.connect(self._emit)
        self.depth_refresh.clicked.connect(self.refresh_depth_cameras)

        self.setSizePolicy(QSizePolicy.Policy.Preferred, QSizePolicy.Policy.Fixed)

    # The studio options wrap (FlowLayout). Height-for-width is kept inside the picker: a
    # page in a QScrollArea would otherwise be sized to its preferred height and scroll. The
    # picker instead takes the height its current width needs.
    def hasHeightForWidth(self) -> bool:
        return False

    def resizeEvent(self, event: QResizeEvent) -> None:
        super().resizeEvent(event)
        layout = self.layout()
        h = layout.heightForWidth(self.width()) if layout.hasHeightForWidth() else -1
        if h > 0 and h != self.minimumHeight():
            self.setMinimumHeight(h)
            self.updateGeometry()

    # ------------------------------------------------------------------- spec
    @property
    def kind(self) -> str:
        return str(self.kind_box.currentData())

    def set_kind(self, kind: str) -> None:
        self.kind_box.setCurrentIndex(self.kind_box.findData(kind))

    def spec(self) -> str:
        kind = self.kind
        if kind == SourceKind.STUDIO:
            opts = {
                "frames": str(self.frames_spin.value()),
                "seed": str(self.seed_spin.value()),
                "presenter": "1" if self.presenter_check.isChecked() else "0",
                "path": str(self.path_box.currentData()),
            }
            if self.ball_check.isChecked():
                opts["ball"] = "1"
            extra = parse_synthetic("synthetic:" + self.extra_line.text())
            if "cycles" in extra and "cycle_s" in extra:
                del opts["frames"]  # the studio accepts at most two of frames/cycles/cycle_s
            opts.update(extra)
            return "synthetic:" + ",".join(f"{k}={v}" for k, v in opts.items())
        if kind == SourceKind.FOLDER:
            return self.folder_edit.line.text().strip()
        if kind == SourceKind.VIDEO:
            return self.video_edit.line.text().strip()
        if kind == SourceKind.DEPTH:
            return str(self.depth_box.currentData() or "realsense")
        if kind == SourceKind.BAG:
            return self.bag_edit.line.text().strip()
        return f"camera:{self.camera_spin.value()}"

    @Slot()
    def refresh_depth_cameras(self) -> None:
        """List the connected depth cameras again (keeps the chosen one if still there)."""
        current = self.depth_box.currentData()
        self.depth_box.blockSignals(True)
        try:
            self.depth_box.clear()
            try:
                cams = self._list_depth_cameras()
            except Exception as exc:  # the SDK failing must not take the window down
                cams = []
                self.depth_box.setToolTip(f"cannot list depth cameras: {exc}")
            for spec, label in cams:
                self.depth_box.addItem(label, spec)
            if not cams:
                self.depth_box.addItem("no depth camera connected", "realsense")
            idx = self.depth_box.findData(current) if current else -1
            self.depth_box.setCurrentIndex(max(idx, 0))
        finally:
            self.depth_box.blockSignals(False)
        self._listed = True
        self._emit()

    def set_spec(self, spec: str) -> None:
        """Show ``spec`` (any string :func:`engine.sources.open_source` accepts)."""
        spec = spec.strip()
        self.blockSignals(True)
        try:
            kind, _, rest = spec.partition(":")
            if kind == "synthetic":
                opts = parse_synthetic(spec)
                path = opts.pop("path", "rail")
                if self.path_box.findData(path) < 0:
                    self.path_box.addItem(path, path)
                self.path_box.setCurrentIndex(self.path_box.findData(path))
                self.presenter_check.setChecked(opts.pop("presenter", "0") not in ("0", "false"))
                self.ball_check.setChecked(opts.pop("ball", "0") not in ("0", "false"))
                self.seed_spin.setValue(_int_or(opts.pop("seed", "0"), 0))
                self.frames_spin.setValue(_int_or(opts.pop("frames", "300"), 300))
                self.extra_line.setText(",".join(f"{k}={v}" for k, v in opts.items()))
                self.set_kind(SourceKind.STUDIO)
            elif kind == "camera":
                self.camera_spin.setValue(_int_or(rest or "0", 0))
                self.set_kind(SourceKind.CAMERA)
            elif kind == "realsense" and "file=" not in rest:
                if self.depth_box.findData(spec) < 0:
                    self.depth_box.addItem(spec, spec)
                self.depth_box.setCurrentIndex(self.depth_box.findData(spec))
                self._listed = True  # keep what was asked for; Refresh lists the cameras
                self.set_kind(SourceKind.DEPTH)
            elif Path(spec).suffix.lower() == ".bag" or kind == "realsense":
                self.bag_edit.line.setText(spec)
                self.set_kind(SourceKind.BAG)
            elif Path(spec).suffix.lower() in (".mp4", ".avi", ".mov", ".mkv", ".m4v"):
                self.video_edit.line.setText(spec)
                self.set_kind(SourceKind.VIDEO)
            else:
                self.folder_edit.line.setText(spec)
                self.set_kind(SourceKind.FOLDER)
        finally:
            self.blockSignals(False)
        self._emit()

    def set_recent(self, paths: Sequence[str]) -> None:
        """Offer recently used folders/files for completion."""
        video_suffixes = (".mp4", ".avi", ".mov", ".mkv", ".m4v")
        self.video_edit.set_recent([p for p in paths if p.lower().endswith(video_suffixes)])
        self.bag_edit.set_recent([p for p in paths if p.lower().endswith(".bag")])
        self.folder_edit.set_recent(
            [p for p in paths if not p.lower().endswith((*video_suffixes, ".bag"))])

    @Slot()
    def _on_kind(self) -> None:
        self.stack.setCurrentIndex(self.kind_box.currentIndex())
        if self.kind == SourceKind.DEPTH and not self._listed:
            self.refresh_depth_cameras()  # emits
            return
        self._emit()

    @Slot()
    def _emit(self) -> None:
        self.spec_changed.emit(self.spec())


def _int_or(text: str, default: int) -> int:
    try:
        return int(float(text))
    except ValueError:
        return default
