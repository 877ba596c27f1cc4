"""Array type aliases and checked narrowing of loosely typed array results to one dtype.

OpenCV's stubs type every image result as ``MatLike`` (any numeric array) and numpy's
indexing returns ``Any``; the engine's arrays have one dtype each (uint8 BGR and grey images,
float32 depth in metres and gradients, float64 poses). ``u8(cv2.cvtColor(bgr, ...))`` says
which, the type checker then knows it, and a wrong dtype fails right there (a bug: a
``TypeError`` naming both dtypes) instead of deep inside a kernel. The check is an
``isinstance`` and a dtype comparison, no copy. :func:`xywh` does the same for a box read
as a sequence of numbers (JSON, OpenCV) into the 4-tuple the records hold.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import SupportsFloat, TypeVar, cast

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]
F32 = NDArray[np.float32]
U8 = NDArray[np.uint8]
I32 = NDArray[np.int32]
I64 = NDArray[np.int64]
Bool = NDArray[np.bool_]
#: a box: left, top, width, height (pixels)
XYWH = tuple[float, float, float, float]

S = TypeVar("S", bound=np.generic)


def of_dtype(a: object, dtype: type[S]) -> NDArray[S]:
    """``a`` as an array of ``dtype``; ``TypeError`` if it is not one (no conversion)."""
    if isinstance(a, np.ndarray) and a.dtype == dtype:
        return cast("NDArray[S]", a)
    got = f"a {a.dtype} array" if isinstance(a, np.ndarray) else type(a).__name__
    raise TypeError(f"expected a {np.dtype(dtype).name} array, got {got}")


def u8(a: object) -> U8:
    """``a`` as a uint8 array (an 8-bit image), checked."""
    return of_dtype(a, np.uint8)


def f32(a: object) -> F32:
    """``a`` as a float32 array, checked."""
    return of_dtype(a, np.float32)


def f64(a: object) -> F64:
    """``a`` as a float64 array, checked."""
    return of_dtype(a, np.float64)


def i32(a: object) -> I32:
    """``a`` as an int32 array (e.g. an OpenCV integral image), checked."""
    return of_dtype(a, np.int32)


def xywh(values: Iterable[SupportsFloat]) -> XYWH:
    """A box (x, y, w, h) as four floats; ``ValueError`` if there are not four values."""
    v = tuple(float(x) for x in values)
    if len(v) != 4:
        raise ValueError(f"a box needs 4 values (x, y, w, h), got {len(v)}")
    return v[0], v[1], v[2], v[3]
