"""Depth frame + calibration -> the Surface the warp engine needs.

Modules: ``settings`` (the tuning), ``estimate`` (``SurfaceEstimator``: the whole
pipeline; it owns its scratch memory), ``images`` (steps 1-2), ``rays`` (step 3),
``lattice`` (the lattice, spikes, holes, confidence), ``fits`` (the side-window
smoothing of step 4), ``sensor`` (the depth sensor's noise model: steps, sigma(z)),
``cuts`` (the lattice cut at silhouettes), ``temporal`` (``SurfaceFilter``),
``workspace`` (scratch).

Steps (``estimate.SurfaceEstimator``):

1. depth outside the working range, pixels far from their 5x5 median (speckle), and
   pixels beside a depth jump beyond the sensor's noise (flying pixels) are dropped;
2. the depth image is smoothed by normalised convolution (a Gaussian over valid
   pixels only), which also gives each pixel its *support* (how much valid data is
   around it);
3. each lattice node's projector ray is intersected with that smoothed depth surface:
   the point ``s d`` on the ray is moved into frame D, projected into the depth image,
   and ``s`` updated until the depth it predicts matches the depth measured there (the
   P-D baseline is a few centimetres, so this converges in a few steps). This
   back-projects, transforms to frame P and resamples in projector space at once,
   and keeps creases sharp;
4. this is done on a lattice fine enough to use the data between coarse nodes
   (``lattice.supersampling``); isolated spikes are rejected, the surface is smoothed
   by local quadratic fits of inverse depth in side windows, which keep creases, at
   ``smooth_m`` and wider scales, each node taking the widest scale that agrees with
   the narrower ones (``fits.smooth_lattice``), and the requested lattice is taken
   from it (the fits are evaluated at its nodes only; the finer lattice is their
   data); the lattice is cut where neighbouring nodes jump by more than the sensor's
   noise and the surface's slope explain, and only the piece under the projector's
   aim is kept (``cuts``); small holes (not touching the frame border nor a cut) are
   filled from their neighbours;
5. every node gets a confidence in [0, 1] from support, the stereo noise expected at
   its depth (grows with z^2), the viewing angle, and whether it was filled.

``temporal.SurfaceFilter`` averages estimates over time while the device is still
(:func:`~adaproj_edge.motion.tracker.is_still` decides that from IMU samples); given
the estimator, it averages the raw depth of step 4 and has the estimator smooth, cut
and fill that again (``SurfaceEstimator.re_estimate``), so that the smoothing judges a
curved surface against the averaged noise, not one frame's.
Grazing angles, holes and surfaces out of range lower coverage and confidence; they
never raise. Pure: arrays in, arrays out.
"""
