from __future__ import annotations

import pytest

from widgets.source_picker import SourceKind, SourcePicker


@pytest.fixture
def picker(qtbot):  # type: ignore[no-untyped-def]
    p = SourcePicker()
    qtbot.addWidget(p)
    return p


def test_studio_spec_round_trip(picker: SourcePicker) -> None:
    picker.set_spec("synthetic:frames=600,seed=3,presenter=1,path=pan,noise=1")
    assert picker.kind == SourceKind.STUDIO
    assert picker.spec() == "synthetic:frames=600,seed=3,presenter=1,path=pan,noise=1"
    picker.presenter_check.setChecked(False)
    picker.path_box.setCurrentIndex(picker.path_box.findData("handheld"))
    assert "presenter=0" in picker.spec()
    assert "path=handheld" in picker.spec()


def test_kinds(qtbot, picker: SourcePicker, tmp_path) -> None:  # type: ignore[no-untyped-def]
    with qtbot.waitSignal(picker.spec_changed) as blocker:
        picker.set_spec("camera:1")
    assert blocker.args[0] == "camera:1"
    picker.set_spec(str(tmp_path / "a.MP4"))
    assert picker.kind == SourceKind.VIDEO
    assert picker.spec() == str(tmp_path / "a.MP4")
    picker.set_spec(str(tmp_path))
    assert picker.kind == SourceKind.FOLDER
    with qtbot.waitSignal(picker.spec_changed) as blocker:
        picker.set_kind(SourceKind.CAMERA)
    assert blocker.args[0] == "camera:1"


def test_recent_files_split_by_kind(picker: SourcePicker) -> None:
    picker.set_recent(["/d/tum", "/v/clip.mp4"])
    folder_model = picker.folder_edit.line.completer().model()
    video_model = picker.video_edit.line.completer().model()
    assert folder_model.stringList() == ["/d/tum"]
    assert video_model.stringList() == ["/v/clip.mp4"]


def test_ball_option(picker: SourcePicker) -> None:
    picker.set_spec("synthetic:frames=10,ball=1")
    assert picker.ball_check.isChecked()
    assert "ball=1" in picker.spec()
    picker.ball_check.setChecked(False)
    assert "ball" not in picker.spec()


def test_missing_options_take_the_engine_defaults(picker: SourcePicker) -> None:
    from engine.sources import parse_options

    picker.set_spec("synthetic:")
    opts = parse_options(picker.spec().partition(":")[2])
    assert opts == {"frames": "300", "seed": "0", "presenter": "0", "path": "rail"}


def test_cycles_and_cycle_s_replace_frames(picker: SourcePicker) -> None:
    picker.set_spec("synthetic:cycles=10,cycle_s=4,path=rail")
    spec = picker.spec()
    assert "frames=" not in spec
    assert "cycles=10" in spec
    assert "cycle_s=4" in spec


def test_depth_cameras_listed_with_serial_and_model(qtbot) -> None:  # type: ignore[no-untyped-def]
    cams = [("realsense:serial=123", "Intel RealSense D435 · 123 (USB 3.2)"),
            ("realsense:serial=456", "Intel RealSense D455 · 456 (USB 3.2)")]
    calls = []

    def lister() -> list[tuple[str, str]]:
        calls.append(1)
        return list(cams)

    p = SourcePicker(list_depth_cameras=lister)
    qtbot.addWidget(p)
    assert calls == []  # nothing is enumerated at start-up
    with qtbot.waitSignal(p.spec_changed) as blocker:
        p.set_kind(SourceKind.DEPTH)
    assert blocker.args[0] == "realsense:serial=123"
    assert [p.depth_box.itemText(i) for i in range(p.depth_box.count())] == [c[1] for c in cams]
    p.depth_box.setCurrentIndex(1)
    assert p.spec() == "realsense:serial=456"
    cams.pop(0)  # the first camera unplugged; the chosen one stays chosen
    p.refresh_depth_cameras()
    assert p.spec() == "realsense:serial=456"
    cams.clear()
    p.refresh_depth_cameras()
    assert p.depth_box.currentText() == "no depth camera connected"
    assert p.spec() == "realsense"  # opening it gives the one-line "no camera" error


def test_depth_camera_lister_failure_keeps_the_picker(qtbot) -> None:  # type: ignore[no-untyped-def]
    def broken() -> list[tuple[str, str]]:
        raise RuntimeError("SDK exploded")

    p = SourcePicker(list_depth_cameras=broken)
    qtbot.addWidget(p)
    p.set_kind(SourceKind.DEPTH)
    assert p.spec() == "realsense"
    assert "SDK exploded" in p.depth_box.toolTip()


def test_bag_and_realsense_specs_round_trip(picker: SourcePicker, tmp_path) -> None:  # type: ignore[no-untyped-def]
    bag = str(tmp_path / "take1.bag")
    picker.set_spec(bag)
    assert picker.kind == SourceKind.BAG
    assert picker.spec() == bag
    picker.set_spec(f"realsense:file={bag},realtime=1")
    assert picker.kind == SourceKind.BAG
    assert picker.spec() == f"realsense:file={bag},realtime=1"
    picker.set_spec("realsense:serial=789,width=848,height=480")
    assert picker.kind == SourceKind.DEPTH
    assert picker.spec() == "realsense:serial=789,width=848,height=480"
    picker.set_recent(["/d/tum", "/v/clip.mp4", bag])
    assert picker.bag_edit._model.stringList() == [bag]
    assert picker.folder_edit._model.stringList() == ["/d/tum"]
