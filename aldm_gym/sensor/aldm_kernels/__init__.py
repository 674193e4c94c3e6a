"""Numba kernels of the Advanced Lane Detection Model (ALDM), one module per stage.

Data flow of one frame (:func:`output._detect`, the single entry point called from
:func:`aldm_gym.sensor.aldm.detect_lanes`):

* :mod:`.sort` — drop invalid points, sort the rest by ``(x, y)`` (the one bucket
  sort, also used for the start region's y order);
* :mod:`.paper` — paper mode, the §ALDM algorithm as published; or
* :mod:`.robust` — robust mode: seeds from the start region, gated traces, using
  :mod:`.grid` (the search grid) and :mod:`.fit` (ridge quadratics and their running
  sums, shared with the output's smoothing);
* :mod:`.output` — the returned lines and the one-line lane width; the trajectory is
  the one path fit of every detector, :func:`aldm_gym.sensor.trajectory.fit_path`.
* :mod:`.track` — the tracking ALDM's kernels (:class:`aldm_gym.sensor.tracking.LaneTracker`):
  the last lines moved by odometry, the prior points and clutter filter fed to the
  pipeline above, and the matching that keeps line identities.
* :mod:`.model` — the lane-model filter's kernels
  (:class:`aldm_gym.sensor.lane_filter.LaneModelFilter`): the reference curve's table
  and the points' foot points on it, the predict step, the association with the
  robust measurement update, the lines' existence, drawing, and the start's fit.

:mod:`.layout` names the parameter vectors' slots and the four line slots.

Written the umap way: every kernel is a plain Python function ``_name_py`` (the
readable reference, runnable under ``NUMBA_DISABLE_JIT=1``) and its compiled twin
``_name = numba.njit(cache=True)(_name_py)``. Kernels call each other through the
compiled names, so with JIT disabled the whole pipeline is plain Python. Signatures
are inferred lazily on the first call and cached on disk, so importing compiles
nothing. No ``fastmath``: NaN/inf keep IEEE semantics and results are bit-identical
with the plain-Python reference. The algorithm and every decision where the paper is
silent are described in ``docs/aldm.md``; paper references are to its section
"Advanced Lane Detection Model" (§ALDM).

:func:`output._detect` dispatches to one compiled pipeline per mode, so a first run
compiles only the mode it uses.

numba's on-disk cache tracks each kernel's own source file only; the package keys
every kernel by a digest of all kernel sources instead (``aldm_gym/_numba.py``), so an
edit to any kernel module recompiles them all, once, and nothing stale is loaded.
"""
