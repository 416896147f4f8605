"""The calibration the hold gesture starts on the device.

The device loop (:mod:`adaproj_edge.app.live`) stops reading the depth camera and the
IMU, then hands the board to :func:`calibrate_device`, which opens them again the way
``adaproj calibrate`` does (one DepthAI pipeline for depth and the structured-light
camera, the IMU on a thread), runs the procedure with its instructions shown on the
projector (the device has no other screen) and in the journal, and writes the
calibration file ``adaproj run`` reads at start (only a good or acceptable one, never
over a better one). The runtime then goes on with the new calibration
(:meth:`~adaproj_edge.app.runtime.Runtime.recalibrate`).

The tap-then-hold gesture hands it the board for :func:`measure_colour_device`: the
surface's colour measured again from five frames
(:mod:`adaproj_edge.procam.colour_capture`), written beside the calibration
(``OUT.photometric.npz``, atomically) and given to the runtime
(:meth:`~adaproj_edge.app.runtime.Runtime.remeasured`); a refused capture writes
nothing and the measurement in use stays.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Protocol

from adaproj_edge.errors import AdaprojError
from adaproj_edge.geometry.calibration import Calibration
from adaproj_edge.hal.board import Board
from adaproj_edge.hal.camera import OakRig
from adaproj_edge.hal.clock import Clock
from adaproj_edge.hal.display import Display
from adaproj_edge.hal.lsm6dsox import Lsm6dsox, open_i2c
from adaproj_edge.hal.polled_imu import PolledImu
from adaproj_edge.procam.colour_capture import measure_colour
from adaproj_edge.procam.outputs import calibrate
from adaproj_edge.procam.photometric import Measured
from adaproj_edge.procam.procedure import Devices, Listener, LiveShow
from adaproj_edge.render.sheet import text_page
from adaproj_edge.resources import DEVICE_CALIBRATION
from adaproj_edge.session.codec import Record

log = logging.getLogger(__name__)

SHOWN_LINES = 6  # the newest lines on the projector


class _Closable(Protocol):
    def close(self) -> None: ...


class ProjectedConsole:
    """The procedure's instructions, on the projector and in the log.

    Parameters
    ----------
    display : Display
    size : (int, int)
        The projector's frame, pixels.
    """

    def __init__(self, display: Display, size: tuple[int, int]) -> None:
        self.display, self.size = display, size
        self.lines: list[str] = []

    def say(self, event: str, message: str) -> None:
        """Log ``message`` and show it under the last few."""
        log.info("calibration %s: %s", event, message)
        self.lines = [*self.lines, message][-SHOWN_LINES:]
        self.display.show(text_page(self.lines, self.size))

    def record(self, rec: Record) -> None:
        """Nothing is recorded on the device (``adaproj calibrate --record`` does)."""


def calibrate_device(
    board: Board,
    display: Display,
    clock: Clock,
    nominal: Calibration,
    out: Path = DEVICE_CALIBRATION,
) -> tuple[Calibration | None, str]:
    """Run the structured-light calibration on the board's devices.

    Parameters
    ----------
    board : Board
    display : Display
        The projector (already open: the runtime's).
    clock : Clock
    nominal : Calibration
        The calibration in use (the starting guess).
    out : Path
        Where the calibration is written.

    Returns
    -------
    calibration : Calibration or None
        The one written, or None when none was (the reason is in the message).
    message : str
        The verdict, or why nothing was written.
    """
    w, h = nominal.projector.width, nominal.projector.height
    console = ProjectedConsole(display, (w, h))
    console.say("start", "calibration: aim at a wall corner (or a wall and the floor)")
    opened: list[_Closable] = []
    try:
        chip = Lsm6dsox(
            open_i2c(board.imu.bus),
            clock,
            board.imu.address,
            board.imu.config,
            f"/dev/i2c-{board.imu.bus}",
        )
        opened.append(chip)
        chip.start()
        imu = PolledImu(chip, board.imu.config.rate_hz, clock)
        opened[-1] = imu  # closes the chip too
        rig = OakRig(board.depth, board.camera, clock)
        opened.append(rig)
        devices = Devices(LiveShow(display, clock, console), rig.camera, rig.depth, imu, clock)
        start = nominal.with_depth(rig.depth.model)
        outcome = calibrate(devices, board.camera, start, out, console)
    except AdaprojError as e:
        log.error("calibration failed: %s", e)
        console.say("failed", f"calibration failed: {e}")
        return None, str(e)
    finally:
        for dev in reversed(opened):
            try:
                dev.close()
            except AdaprojError as e:
                log.warning("closing after the calibration: %s", e)
    if outcome.refused:
        console.say("refused", outcome.refused)
        return None, outcome.refused
    try:
        return Calibration.load(out), outcome.verdict.line
    except AdaprojError as e:  # written a moment ago: the storage failed
        log.error("the calibration just written cannot be read: %s", e)
        return None, str(e)


def measure_colour_on(
    show: LiveShow,
    rig: OakRig,
    clock: Clock,
    board: Board,
    calibration: Calibration,
    out: Path,
    console: Listener,
) -> tuple[Measured | None, str]:
    """Capture and measure the surface's colour with open devices and write it to
    ``out``; None and the reason when refused (nothing written)."""
    try:
        measured = measure_colour(
            show, rig.camera, rig.depth, clock, board.camera, calibration, console
        )
        measured.save(out)
    except AdaprojError as e:
        message = f"the surface's colour was not measured: {e}"
        log.warning("%s", message)
        console.say("refused", message)
        return None, message
    message = "the surface's colour and the room's light measured"
    console.say("done", message)
    return measured, message


def measure_colour_device(
    board: Board, display: Display, clock: Clock, calibration: Calibration, out: Path
) -> tuple[Measured | None, str]:
    """The tap-then-hold gesture: open the board's camera and depth, measure the
    surface's colour (:func:`measure_colour_on`), close them.

    Returns
    -------
    measured : Measured or None
        The new measurement (written to ``out``), None when refused.
    message : str
        What was done, or why not.
    """
    w, h = calibration.projector.width, calibration.projector.height
    console = ProjectedConsole(display, (w, h))
    try:
        rig = OakRig(board.depth, board.camera, clock)
    except AdaprojError as e:
        message = f"the surface's colour was not measured: {e}"
        log.error("%s", message)
        console.say("failed", message)
        return None, message
    try:
        cal = calibration.with_depth(rig.depth.model)
        show = LiveShow(display, clock, console)
        return measure_colour_on(show, rig, clock, board, cal, out, console)
    finally:
        try:
            rig.close()
        except AdaprojError as e:
            log.warning("closing after the colour captures: %s", e)
