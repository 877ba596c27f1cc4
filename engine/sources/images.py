"""Image file reading shared by the folder sources (TUM, OTB/MIL).

``cv2.imread`` returns ``None`` for some damaged files but silently decodes a *truncated*
JPEG into a half-grey image (it only prints "Premature end of JPEG file"). These helpers
check the format's end marker first so that a cut-off file fails loudly, naming the file.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.errors import SourceError

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
# The last chunk of every PNG: length 0, type IEND, CRC ae426082.
_PNG_IEND = b"IEND\xaeB`\x82"
_JPEG_SOI = b"\xff\xd8"
_JPEG_EOI = b"\xff\xd9"


def _read_bytes(path: Path) -> bytes:
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise SourceError(f"{path}: image file not found") from None
    except OSError as exc:
        raise SourceError(f"{path}: cannot read image ({exc.strerror or exc})") from None
    if not data:
        raise SourceError(f"{path}: image file is empty (0 bytes)")
    return data


def _check_complete(path: Path, data: bytes) -> None:
    """Raise if a PNG/JPEG lacks its end marker (a truncated copy or download)."""
    if data.startswith(_PNG_SIGNATURE):
        if _PNG_IEND not in data[-64:]:
            raise SourceError(f"{path}: truncated PNG (no IEND chunk at the end)")
    elif data.startswith(_JPEG_SOI) and _JPEG_EOI not in data[-64:]:
        # Some cameras pad after EOI, hence the search in the last bytes, not an exact tail.
        raise SourceError(f"{path}: truncated JPEG (no end-of-image marker)")


def _decode(path: Path, flags: int) -> NDArray[np.generic]:
    data = _read_bytes(path)
    _check_complete(path, data)
    image = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), flags)
    if image is None:
        raise SourceError(f"{path}: cannot decode image (corrupt or unsupported format)")
    return image


def read_image(path: str | Path, flags: int) -> NDArray[np.uint8]:
    """An 8-bit image decoded with ``cv2.imdecode`` ``flags`` after the completeness check;
    SourceError naming the file (missing, empty, truncated, undecodable)."""
    return np.asarray(_decode(Path(path), flags), dtype=np.uint8)


def read_color_bgr(path: str | Path) -> NDArray[np.uint8]:
    """An 8-bit 3-channel BGR image (grey files are expanded); SourceError naming the file."""
    path = Path(path)
    # IMREAD_COLOR always yields 8-bit BGR (16-bit and grey files are converted)
    return np.asarray(_decode(path, cv2.IMREAD_COLOR), dtype=np.uint8)


def read_depth_m(path: str | Path, depth_scale: float) -> NDArray[np.float32]:
    """A 16-bit single-channel depth PNG divided by ``depth_scale`` (metres; 0 = invalid)."""
    path = Path(path)
    raw = _decode(path, cv2.IMREAD_UNCHANGED)
    if raw.dtype != np.uint16 or raw.ndim != 2:
        chans = 1 if raw.ndim == 2 else raw.shape[2]
        raise SourceError(
            f"{path}: expected a 16-bit single-channel depth image, "
            f"got {raw.dtype} with {chans} channel(s)"
        )
    return raw.astype(np.float32) / np.float32(depth_scale)
