"""The keyframe tracker's precomputed references (points, c* and J of eq. (6)), by keyframe id.

A reference costs about 1.2 MB (8192 photometric and 8192 geometric points) and 20 ms to
build from a stored keyframe's images. Without a bound a tracker keeps one per keyframe it
has ever used, so memory grows with the studio model (200 keyframes: 483 MB peak, ``bench
dense`` ``rss_mb_by_keyframes``). Two kinds are held:

- rebuildable: built from a keyframe's stored images (:meth:`DenseKeyframeTracker._reference`),
  so a dropped one is rebuilt bit for bit the same when the camera comes back; at most
  ``capacity`` of them, the least recently used dropped first;
- kept: built online from a live frame (its depth timing and the camera's motion at that
  frame), which the store's images alone would not reproduce; never dropped.
"""

from __future__ import annotations

from collections import OrderedDict

from engine.dense.photometric import Reference


class ReferenceCache:
    """References by keyframe id, rebuildable ones bounded by ``capacity`` (LRU)."""

    def __init__(self, capacity: int) -> None:
        self._kept: dict[int, Reference] = {}
        self._lru: OrderedDict[int, Reference] = OrderedDict()
        self.capacity = capacity

    @property
    def capacity(self) -> int:
        return self._capacity

    @capacity.setter
    def capacity(self, n: int) -> None:
        self._capacity = max(1, int(n))
        self._trim()

    def get(self, kf_id: int) -> Reference | None:
        """The reference of keyframe ``kf_id`` (now the most recently used), or None."""
        ref = self._kept.get(kf_id)
        if ref is not None:
            return ref
        ref = self._lru.get(kf_id)
        if ref is not None:
            self._lru.move_to_end(kf_id)
        return ref

    def keep(self, kf_id: int, ref: Reference) -> None:
        """A reference built online from a live frame: held until :meth:`clear`."""
        self._lru.pop(kf_id, None)
        self._kept[kf_id] = ref

    def keep_rebuildable(self, kf_id: int, ref: Reference) -> None:
        """A reference built from the store's images: may be dropped later."""
        self._kept.pop(kf_id, None)
        self._lru[kf_id] = ref
        self._lru.move_to_end(kf_id)
        self._trim()

    def clear(self) -> None:
        self._kept.clear()
        self._lru.clear()

    def __len__(self) -> int:
        return len(self._kept) + len(self._lru)

    @property
    def nbytes(self) -> int:
        """Memory held by the resident references' arrays (bytes)."""
        return sum(r.nbytes for r in (*self._kept.values(), *self._lru.values()))

    def _trim(self) -> None:
        while len(self._lru) > self._capacity:
            self._lru.popitem(last=False)
