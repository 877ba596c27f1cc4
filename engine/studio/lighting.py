"""Lighting variants of the built-in studio (``synthetic:lighting=NAME``).

The set's lighting is baked into its textures (``engine.studio.scene``); a variant changes
what the camera records on top of it, the way a different studio plot or camera set-up
would:

- ``exposure``: overall gain (a dimmer plot, or a camera opened up); with ``exposure_end``
  the gain ramps linearly from ``exposure`` to ``exposure_end`` over the sequence (lights
  coming up, like the MIL "david" sequence going from dark to light);
- ``white_balance_bgr``: per-channel gains (tungsten light on a daylight-balanced camera
  gives a warm cast, and the reverse a cool one);
- the key light of the people and props shaded at render time (direction, ambient and
  diffuse share, ``engine.studio.render``): a side key leaves half of the body in shadow.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True, slots=True)
class Lighting:
    name: str
    exposure: float = 1.0
    exposure_end: float | None = None
    white_balance_bgr: tuple[float, float, float] = (1.0, 1.0, 1.0)
    key_dir_world: tuple[float, float, float] = (-0.35, -1.0, 0.9)  # towards the light
    ambient: float = 0.42
    diffuse: float = 0.7

    def gain_bgr(self, t_frac: float) -> NDArray[np.float32]:
        """Per-channel gain at ``t_frac`` (0 = first frame, 1 = last) of the sequence."""
        e = self.exposure
        if self.exposure_end is not None:
            e = e + (self.exposure_end - e) * min(max(t_frac, 0.0), 1.0)
        return (e * np.asarray(self.white_balance_bgr)).astype(np.float32)

    @property
    def is_identity(self) -> bool:
        return (self.exposure == 1.0 and self.exposure_end is None
                and self.white_balance_bgr == (1.0, 1.0, 1.0))

    def dynamic_light(self) -> NDArray[np.float64]:
        """(direction x, y, z, ambient, diffuse) of the render-time key light."""
        d = np.asarray(self.key_dir_world, dtype=np.float64)
        return np.array([*(d / np.linalg.norm(d)), self.ambient, self.diffuse])


LIGHTINGS: dict[str, Lighting] = {
    lt.name: lt
    for lt in (
        Lighting("default"),
        Lighting("warm", white_balance_bgr=(0.78, 0.97, 1.18)),
        Lighting("cool", white_balance_bgr=(1.2, 1.02, 0.82)),
        Lighting("dim", exposure=0.55, ambient=0.3),
        Lighting("bright", exposure=1.25),
        Lighting("ramp", exposure=0.4, exposure_end=1.1),
        Lighting("side", key_dir_world=(1.0, -0.25, 0.35), ambient=0.22, diffuse=0.95),
    )
}


def apply_gain(bgr: NDArray[np.uint8], gain_bgr: NDArray[np.float32]) -> NDArray[np.uint8]:
    """Saturating per-channel gain of a uint8 BGR image."""
    out = bgr.astype(np.float32) * gain_bgr[None, None, :] + 0.5
    return np.asarray(np.clip(out, 0, 255), dtype=np.uint8)
