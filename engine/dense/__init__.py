"""Dense RGB-D camera tracking after Tykkälä et al. 2014 (engine only, no Qt).

Modules: ``pyramid`` (sec. 4.6 pre-processing), ``selection`` (sec. 3.4/4.5 point selection),
``robust`` (eq. 9-12 weights, NumPy reference), ``kernels`` (numba Algorithm 1),
``photometric`` (reference model + minimisation), ``keyframes`` (store and eq. 19-21),
``sweep`` (building a keyframe store). Heavy modules are imported lazily by the trackers.
"""
