"""The labelled sequences of ``studiotrack bench presenter``: built-in studio variants and the
real OTB/MIL sequences of ``../shared/data``.

Every tracker starts from the first scored frame's ground-truth box. The studio variants
differ in what a tuned default could over-fit to: the set's textures and noise (``seed``),
who presents (``presenter_look``: clothes, skin, height, build), the light (``lighting``),
the camera's motion (``path``), the image size, and a second person walking in front of or
behind the presenter. A studio sequence starts at its first frame with the presenter wholly in
view (the operator frames the presenter before taking the reference).

Frames are loaded once per process (``load``) and kept, so that every tracker and every
parameter candidate runs on the same decoded frames; decoding and rendering are not timed.
"""

from __future__ import annotations

from dataclasses import dataclass

from engine.frames import Frame
from engine.progress import log
from engine.shared_data import shared_data_dir


@dataclass(frozen=True, slots=True)
class Sequence:
    """One labelled sequence: where its frames come from and what kind it is."""

    name: str
    spec: str  # a source spec (``synthetic:...``) or a folder name under ../shared/data
    colour: bool = True  # colour content (mil_david is grey)
    studio: bool = False
    #: studio: offer only the first box (the tracker splits it), not the per-part truth
    box_only: bool = False
    description: str = ""


_S = "synthetic:frames={n},presenter=1,"

#: the built-in studio variants (``studio`` is the bench's original sequence, kept as is)
STUDIO_SEQUENCES: tuple[Sequence, ...] = (
    Sequence("studio", _S + "seed=3,path=rail", studio=True,
             description="rail camera, blue-shirt presenter walking (the original sequence)"),
    Sequence("studio_warm", _S + "seed=5,path=static,presenter_look=1,lighting=warm",
             studio=True, box_only=True,
             description="static camera, red top, tungsten cast; the model from the first "
                         "box only"),
    Sequence("studio_dim", _S + "seed=7,path=handheld,presenter_look=2,lighting=dim,"
             "width=480,height=360,presenter_y=3.0,presenter_xmin=-1.2,presenter_xmax=1.4",
             studio=True, description="hand-held 480x360, green jumper, dim light"),
    Sequence("studio_ramp", _S + "seed=11,path=pan,presenter_look=3,lighting=ramp,"
             "width=320,height=240,presenter_xmin=-1.5,presenter_xmax=1.5", studio=True,
             description="panning 320x240, yellow top, light coming up from dark"),
    Sequence("studio_cross", _S + "seed=13,path=rail,presenter_look=4,lighting=side,"
             "person2=cross,person2_look=0", studio=True,
             description="rail, grey jacket under a side key, a blue-shirt person crossing "
                         "in front"),
    Sequence("studio_diagonal", _S + "seed=19,path=static,presenter_look=6,presenter_y=1.6,"
             "presenter_dy=2.4,presenter_xmin=-0.6,presenter_xmax=1.6,width=480,height=360",
             studio=True, box_only=True,
             description="static 480x360, purple top walking diagonally towards and away "
                         "from the camera (its size changes 2.5x); the model from the first "
                         "box only"),
    Sequence("studio_far", _S + "seed=17,path=static,presenter_look=5,lighting=cool,"
             "presenter_y=2.8,person2=behind,person2_look=6,width=320,height=240",
             studio=True, description="static 320x240, white shirt far from the camera, "
                                      "cool cast, a second person walking behind"),
)
REAL_SEQUENCES: tuple[Sequence, ...] = (
    Sequence("otb_girl", "otb_girl", description="OTB Girl: a face 128x96, turns, occlusion"),
    Sequence("otb_kitesurf", "otb_kitesurf", description="OTB KiteSurf: a small head, fast"),
    Sequence("mil_david", "mil_david", colour=False,
             description="MIL david: grey face/upper body, dark to light"),
)
SEQUENCES: dict[str, Sequence] = {s.name: s for s in (*STUDIO_SEQUENCES, *REAL_SEQUENCES)}

_CACHE: dict[tuple[str, int], list[Frame]] = {}


def _fully_in_view(f: Frame, margin_px: float = 2.0) -> bool:
    b = f.gt_box_xywh
    if b is None or f.color_bgr is None:
        return False
    H, W = f.color_bgr.shape[:2]
    x, y, w, h = b
    return x >= margin_px and y >= margin_px and x + w <= W - margin_px \
        and y + h <= H - margin_px


def _box_only(f: Frame) -> Frame:
    """The frame as a real sequence gives it: the truth box, no label map or part boxes."""
    from dataclasses import replace

    from engine.studio.sim import StudioLabels, StudioTruth

    kept = []
    for p in f.payloads:
        if isinstance(p, StudioLabels):
            continue
        if isinstance(p, StudioTruth):
            p = replace(p, presenter_part_boxes=None)
        kept.append(p)
    return replace(f, payloads=tuple(kept))


def load(name: str, n_frames: int = 0) -> list[Frame]:
    """Frames of sequence ``name`` (at most ``n_frames``; 0 = all, studio 300), cached.

    Studio sequences are renumbered from their first frame with the presenter wholly in
    view (index and timestamps kept, so the motion is unchanged).
    """
    seq = SEQUENCES[name]
    key = (name, n_frames)
    if key in _CACHE:
        return _CACHE[key]
    if seq.studio:
        from engine.sources.base import parse_options
        from engine.sources.synthetic import SyntheticSource

        n = n_frames or 300
        # render a few more so that n frames remain after the presenter comes into view
        src = SyntheticSource.from_options(parse_options(
            seq.spec.format(n=n + 60).partition(":")[2]))
        frames: list[Frame] = []
        for i in range(len(src)):
            f = src.frame(i)
            if seq.box_only:
                f = _box_only(f)
            if frames or _fully_in_view(f):
                frames.append(f)
            if len(frames) >= n:
                break
    else:
        from engine.sources.otb import OtbSource

        src_otb = OtbSource(shared_data_dir() / seq.spec)
        frames = [f for _, f in zip(range(n_frames or len(src_otb)), src_otb.frames(),
                                    strict=False)]
    if not frames:
        raise RuntimeError(f"{name}: no frame with the target in view")
    img = frames[0].color_bgr
    h, w = (0, 0) if img is None else img.shape[:2]
    log(f"{name}: {len(frames)} frames {w}x{h}")
    _CACHE[key] = frames
    return frames
