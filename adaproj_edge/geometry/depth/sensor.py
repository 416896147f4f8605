"""What a depth sensor's frames look like: its noise model, in one place.

Stereo (an OAK-D) and structured light (a Kinect-class sensor) both measure a
disparity ``d = f B / z`` (focal ``f`` in pixels, baseline ``B``) and report it in
steps of ``1 / 2^bits`` pixel. A surface at depth ``z`` therefore comes out in depth
steps of

    dz = z^2 / (f B 2^bits)

(an OAK-D with 3 subpixel bits: about 6 mm at 1.25 m, 24 mm at 2.5 m), the same in
every frame, and with a random error of ``sigma(z) = z^2 / (f B) * sigma_d`` on top,
where ``sigma_d`` combines the matcher's disparity noise and the step's own
(``1 / (2^bits sqrt(12))``). In inverse depth the step is a constant,
``1 / (f B 2^bits)``: a quadratic fit of inverse depth sees the same staircase at every
distance.

Real sensors also warp a flat wall slowly: a disparity error that varies over a few
hundred pixels (bands, bowls), the same in every frame, of ``bias_px`` RMS: a few cm
at 3 m, up to a step. Averaging does not remove it either; :meth:`SensorModel.bias_m`
is its size in depth, ``z^2 / (f B) * bias_px``. Its shape matters as much as its
size: it is smooth (a bowl or a curl toward the image's corners), so over a piece of a
wall it adds a nearly affine disparity, which tilts the piece's plane (a plane's
disparity is affine in the normalised image coordinates ``x = X / Z``, ``y = Y / Z``), and
two pieces of one flat wall come out as two planes a few degrees apart. ``curve_px``
bounds that: the slow error's curvature, the largest ``|eig|`` of the quadratic
``qxx x^2 + qxy x y + qyy y^2`` it adds over a wall (px of disparity per unit of
normalised coordinate squared). Two pieces of one plane whose centroids are ``s``
apart in normalised coordinates are tilted apart by at most ``2 curve_px s`` px of
disparity per unit, a dihedral of about ``2 curve_px s D / (f B)`` radians on a plane at
distance ``D`` (:meth:`SensorModel.max_dihedral_rad`): what a crease must exceed for
the sensor to resolve it.

The smoothing (:mod:`~adaproj_edge.geometry.depth.fits`) lets a wider fit replace a
narrower one that only follows a step, plane snapping
(:mod:`~adaproj_edge.geometry.planes`) accepts a wall's nodes within its steps and its
slow error, and
the lattice is cut where neighbouring nodes differ by more than the noise and the
surface's slope explain (:mod:`~adaproj_edge.geometry.depth.cuts`). The session
simulator draws frames from the same model (:mod:`adaproj_edge.session.stereo`).

A sensor's focal length and baseline come from the calibration's depth camera
model (an OAK-D's own, read from the device); :data:`SENSORS` holds what is not in
it: the subpixel bits and the disparity noise of each kind of sensor.

Pure: numbers in, numbers out.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from adaproj_edge.arrays import FloatArray
from adaproj_edge.errors import InputError
from adaproj_edge.geometry.calibration import DepthCameraModel


@dataclass(frozen=True)
class SensorKind:
    """What a kind of depth sensor adds to its camera model.

    Attributes
    ----------
    name : str
        ``"oak-d"`` or ``"kinect"`` (keys of :data:`SENSORS`).
    subpixel_bits : int
        Fractional bits of the reported disparity (steps of ``1 / 2^bits`` px).
    disparity_sigma_px : float
        Random disparity error of the matcher (px), before the steps.
    bias_px : float
        RMS over a plane of the disparity's slowly varying error (px): what a wall keeps
        of its error when its depth is averaged over patches of many pixels.
    footprint_px : float
        Radius (px) of the patch of the image one pixel's depth is made from (the
        matcher's window, the device's median filter): a pixel this close to a crease
        or an edge mixes the two sides' depths, so its depth is off both.
    curve_px : float
        The largest curvature of the slow error over a plane (px of disparity per unit
        of normalised image coordinate squared; see the module's docstring): how far
        it can tilt two pieces of one flat wall apart.
    """

    name: str
    subpixel_bits: int
    disparity_sigma_px: float
    bias_px: float = 0.0
    footprint_px: float = 3.0
    curve_px: float = 0.0


# The slowly varying disparity error (``bias_px``) of a Kinect-class sensor, measured on
# the real frames of ``tests/fixtures/real`` (a TUM and an NYU Kinect v1, a SUN3D Xtion):
# the residual of a robust plane fitted to the raw points of a floor or a wall, in
# disparity, averaged over 16 x 16 pixel blocks (the steps and the random error average
# out there), has an RMS of 0.021-0.045 px (peaks 0.06-0.10 px) on the six floor and wall
# boxes: 0.04 px. Its size is a few cm at 3 m, up to a step: a flat floor seen by such a
# sensor is a gently warped sheet. No OAK-D recording is in the repository; until one
# measures it, an OAK-D is given the same (a stereo camera's calibration leaves a
# slowly varying disparity error of the same order).
#
# Its curvature (``curve_px``), measured on the same frames by
# ``tools/measure_sensor_bend.py``: each floor and wall box's inlier disparities split
# in halves (left / right, top / bottom), an affine disparity fitted to each, the
# difference of their gradients over twice the distance of their centroids (the
# curvature of a quadratic that tilts them so): 1.3-4.3 px on the six boxes that are
# one plane (at 2.2-2.9 m, image radius 0.20-0.57), their halves 0.2-3.2 deg and
# 1-12 mm apart at the seam. The boxes are too few to resolve a trend with depth or
# radius in that range (the literature on Kinect-class calibration finds the error
# growing with depth and toward the corners); the model takes the largest, rounded
# up: 4.5 px. The same is given to an OAK-D until a recording of one measures it.
SENSORS: dict[str, SensorKind] = {
    # OAK-D stereo: subpixel mode, 3 fractional bits by default (DepthAI), its depth
    # median-filtered over 7 x 7 pixels by default (a footprint of 3 px)
    "oak-d": SensorKind("oak-d", 3, 0.1, 0.04, 3.0, 4.5),
    # Kinect-class structured light: disparity in 1/8 px (11-bit raw values), matched
    # over windows of about 9 x 9 pixels (a footprint of 4 px)
    "kinect": SensorKind("kinect", 3, 0.07, 0.04, 4.0, 4.5),
}


@dataclass(frozen=True)
class SensorModel:
    """The noise model of one depth sensor.

    Parameters
    ----------
    name : str
        The kind of sensor (:data:`SENSORS`).
    focal_px : float
        Focal length of the depth image in pixels.
    baseline_m : float
        Stereo (or projector-camera) baseline in metres.
    subpixel_bits : int
        Fractional bits of the disparity.
    disparity_sigma_px : float
        Random disparity error of the matcher (px).
    bias_px : float
        RMS of the disparity's slowly varying error over a plane (px; see
        :class:`SensorKind`).
    footprint_px : float
        Radius (px) of the patch one pixel's depth is made from (see :class:`SensorKind`).
    curve_px : float
        The largest curvature of the slow error over a plane (see :class:`SensorKind`).
    """

    name: str
    focal_px: float
    baseline_m: float
    subpixel_bits: int = 3
    disparity_sigma_px: float = 0.1
    bias_px: float = 0.0
    footprint_px: float = 3.0
    curve_px: float = 0.0

    def __post_init__(self) -> None:
        if self.focal_px <= 0 or self.baseline_m <= 0:
            raise InputError("a depth sensor needs a positive focal length and baseline")
        if not 0 <= self.subpixel_bits <= 8 or self.disparity_sigma_px < 0 or self.bias_px < 0:
            raise InputError("subpixel bits must be 0..8 and the disparity noise and bias >= 0")
        if self.footprint_px < 0 or self.curve_px < 0:
            raise InputError("a depth sensor's footprint and curvature must be >= 0")

    @classmethod
    def of(cls, camera: DepthCameraModel, kind: str = "oak-d") -> SensorModel:
        """The model of a ``kind`` sensor (:data:`SENSORS`) with ``camera``'s focal
        length and baseline (a unit's own, from its calibration)."""
        k = SENSORS.get(kind)
        if k is None:
            raise InputError(f"unknown depth sensor {kind!r}: one of {', '.join(SENSORS)}")
        return cls(
            k.name,
            camera.focal,
            camera.baseline_m,
            k.subpixel_bits,
            k.disparity_sigma_px,
            k.bias_px,
            k.footprint_px,
            k.curve_px,
        )

    @property
    def fb(self) -> float:
        """Focal length times baseline (px m): disparity = fb / z."""
        return self.focal_px * self.baseline_m

    @property
    def disparity_step_px(self) -> float:
        """The disparity's step (px): ``1 / 2^bits``."""
        return float(2.0**-self.subpixel_bits)

    @property
    def inverse_step(self) -> float:
        """The step of inverse depth (1/m), the same at every depth: ``1 / (f B 2^bits)``."""
        return self.disparity_step_px / self.fb

    def step_m(self, z: FloatArray | float) -> FloatArray:
        """Depth step (m) at depth ``z``: ``z^2 / (f B 2^bits)``."""
        zz = np.asarray(z, dtype=np.float64)
        return zz * zz * self.inverse_step

    @property
    def disparity_total_px(self) -> float:
        """The disparity's whole random error (px): the matcher's and the step's."""
        return float(np.hypot(self.disparity_sigma_px, self.disparity_step_px / np.sqrt(12.0)))

    def sigma_m(self, z: FloatArray | float) -> FloatArray:
        """Depth error (m, one sigma) of one pixel at depth ``z``:
        ``z^2 / (f B) * sigma_d``."""
        zz = np.asarray(z, dtype=np.float64)
        return zz * zz / self.fb * self.disparity_total_px

    def bias_m(self, z: FloatArray | float) -> FloatArray:
        """RMS (m) over a plane at depth ``z`` of the depth's slowly varying error:
        ``z^2 / (f B) * bias_px``."""
        zz = np.asarray(z, dtype=np.float64)
        return zz * zz / self.fb * self.bias_px

    def max_dihedral_rad(self, distance_m: float, separation: float) -> float:
        """The largest dihedral (rad) the slow error can put between two pieces of one
        flat plane at ``distance_m`` from the camera whose centroids lie ``separation``
        apart in normalised image coordinates: their disparities' gradients differ by up
        to ``2 curve_px separation`` px per unit, and a plane's disparity gradient is
        ``f B n_xy / D``. A crease of a larger dihedral is one the sensor resolves."""
        return 2.0 * self.curve_px * abs(separation * distance_m) / self.fb
