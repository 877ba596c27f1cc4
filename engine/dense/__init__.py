"""Dense RGB-D camera tracking after Tykkälä et al. 2014 (engine only, no Qt).

Modules: ``params`` (DenseParams), ``pyramid`` (sec. 4.6 pre-processing), ``selection``
(sec. 3.4/4.5 point selection), ``robust`` (eq. 9-12 weights, NumPy reference), ``kernels``
(numba Algorithm 1), ``photometric`` (reference model + minimisation), ``tracking``
(Algorithms 2 and 3, loss and relocalisation). The keyframe store and the sweep that builds
it are :mod:`engine.keyframes`; the tracker adapters are :mod:`engine.trackers.dense`.
Heavy modules are imported lazily by the trackers.
"""
