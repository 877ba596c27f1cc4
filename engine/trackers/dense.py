"""Dense RGB-D camera trackers after Tykkälä et al. 2014.

- ``dense-incremental``: Algorithm 2, tracking against a recent reference frame that is
  replaced when the camera has moved far enough from it.
- ``dense``: Algorithm 3, tracking against the nearest keyframe of a keyframe store
  (``--keyframes DIR``, built by ``studiotrack sweep``); without a store it builds its
  keyframes online (the paper's sec. 6.1 alternation of Algorithms 2 and 3).

The implementation lives in :mod:`engine.dense` and is imported when a tracker is built, so
that tracker discovery stays fast.

Beyond the paper (each a parameter): the median of eq. (9) is taken over the points the depth
test of eq. (12) keeps (a presenter does not inflate the Tukey scale); a global brightness
offset (auto exposure) is removed once per pyramid level (``brightness_offset``); reference
points are moved by the camera motion between the depth and colour timestamps when a source
gives both (``compensate_depth_delay``, TUM); points on depth discontinuities are not selected;
a level's iterations stop once an update moves the image by less than ``stop_px`` (the counts
become caps: 12 instead of 15 iterations on the rail, the same accuracy); the coarse
levels use half and a quarter of the points (``coarse_point_fraction``); a point-to-plane
depth residual is added to the photometric cost at the finest level (``geometric_weight`` 2,
as in the authors' follow-up "direct ICP", with 8192 points of its own over all valid depth:
``geometric_points``; each term in units of its own robust scale, ``min_geometric_scale_m``
only a guard against zero; each point-to-plane residual in units of its depth noise, the
Kinect model sigma(z) ~ z^2: ``geometric_noise_model``). On TUM fr1_xyz it brings ``dense``
from ATE 5.3 to 2.9 mm (RPE 7.4 -> 7.6 mm/s); on the noise-free built-in studio (rail with
presenter, hand-held, pan) it lowers every error; with Kinect-like depth noise at studio
distances its robust scale is large and it changes less; about 1.35x the CPU per frame.
Off by default (measured on TUM fr1_xyz and the studio rail without a clear gain, see
``studiotrack bench dense``): an affine brightness model (``brightness_gain``).
"""

from __future__ import annotations

import argparse
import dataclasses
from typing import Any

from engine.dense.params import DenseParams
from engine.errors import ParamsError
from engine.trackers.base import Tracker, TrackerSpec


def _make_incremental(params: DenseParams) -> Tracker:
    from engine.dense.tracking import DenseIncrementalTracker

    return DenseIncrementalTracker(params)


def _make_keyframe(params: DenseParams) -> Tracker:
    from engine.dense.tracking import DenseKeyframeTracker

    return DenseKeyframeTracker(params)


def _add_cli(parser: argparse.ArgumentParser) -> None:
    """Options of both dense trackers; idempotent, as the CLI may call it once per tracker."""
    if "--keyframes" in parser._option_string_actions:
        return
    g = parser.add_argument_group("dense trackers")
    g.add_argument("--points", type=int, default=None, help="reference points (default 8192)")
    g.add_argument(
        "--iterations", default=None, metavar="C,M,F",
        help="Gauss-Newton iterations coarse,mid,fine (default 2,3,10)",
    )
    g.add_argument("--tau", type=float, default=None, help="depth noise tau in metres")
    g.add_argument("--threads", type=int, default=None, metavar="N",
                   help="threads sharing each iteration's point passes (default 1)")
    g.add_argument(
        "--keyframes", default=None, metavar="DIR",
        help="keyframe store built by `studiotrack sweep` (tracker dense)",
    )


def _params_from_cli(args: argparse.Namespace, params: Any) -> Any:
    upd: dict[str, Any] = {}
    if getattr(args, "points", None) is not None:
        upd["n_points"] = args.points
    its = getattr(args, "iterations", None)
    if its:
        try:
            c, m, f = (int(s) for s in str(its).split(","))
        except ValueError:
            raise ParamsError(f"--iterations {its!r}: expected three integers C,M,F") from None
        upd.update(iterations_coarse=c, iterations_mid=m, iterations_fine=f)
    if getattr(args, "tau", None) is not None:
        upd["tau_m"] = args.tau
    if getattr(args, "threads", None) is not None:
        upd["threads"] = args.threads
    if getattr(args, "keyframes", None):
        upd["keyframes_dir"] = str(args.keyframes)
    return dataclasses.replace(params, **upd) if upd else params


TRACKERS = (
    TrackerSpec(
        name="dense-incremental",
        description="Dense RGB-D photometric tracking against a recent reference frame "
        "(Tykkälä 2014, Algorithm 2): fast, drifts slowly",
        params_cls=DenseParams,
        factory=_make_incremental,
        needs_depth=True,
        output="pose",
        add_cli_arguments=_add_cli,
        params_from_cli=_params_from_cli,
    ),
    TrackerSpec(
        name="dense",
        description="Dense RGB-D keyframe tracking (Tykkälä 2014, Algorithm 3): driftless "
        "against a keyframe store (--keyframes DIR), ignores moving presenters",
        params_cls=DenseParams,
        factory=_make_keyframe,
        needs_depth=True,
        output="pose",
        add_cli_arguments=_add_cli,
        params_from_cli=_params_from_cli,
    ),
)
