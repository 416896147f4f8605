"""Projector-camera calibration from structured light (``adaproj calibrate``).

Pure modules: :mod:`~adaproj_edge.procam.graycode` (patterns, decoding),
:mod:`~adaproj_edge.procam.pairs` (decoded camera pixels + depth -> 3D point /
projector pixel pairs), :mod:`~adaproj_edge.procam.solve` (the projector model and
``T_P_D``), :mod:`~adaproj_edge.procam.imu` (``R_P_I``), :mod:`~adaproj_edge.procam.plan`
(what the user still has to do) and :mod:`~adaproj_edge.procam.report` (verdict, JSON,
picture). :mod:`~adaproj_edge.procam.procedure` drives the capture through the ``hal``
protocols and an injected clock.
"""
