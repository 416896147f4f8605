"""``adaproj doctor`` on a fake /sys + /dev tree (a root prefix, as tests/hal does), with
the OAK-D's DepthAI calls replaced and the IMU served by its register model: every
device there passes; each missing or wrong one fails with what to do."""

from __future__ import annotations

import errno
from pathlib import Path

import numpy as np
import pytest

from adaproj_edge.cli import main
from adaproj_edge.errors import DeviceNotFoundError
from adaproj_edge.geometry.calibration import Calibration, DepthCameraModel
from adaproj_edge.hal import depth, lsm6dsox
from adaproj_edge.hal.depth import StereoSettings
from adaproj_edge.hal.probes import Probes
from tests.hal.lsm6dsox_model import FakeSMBus, Lsm6dsoxModel

OAK_ID = "1844301011B546F500"
BUTTON = "dev/input/by-path/platform-button@11-event"


class Rig:
    """The fake device: its tree, its IMU on bus 1 and its OAK-D."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self.imu = Lsm6dsoxModel()
        self.imu_address = 0x6A
        self.oak: list[str] = [OAK_ID]
        self.framebuffer(1280, 800)
        for dev in ("dev/i2c-1", "dev/ttyGS0", BUTTON):
            (root / dev).parent.mkdir(parents=True, exist_ok=True)
            (root / dev).write_bytes(b"")

    def framebuffer(self, w: int, h: int, bpp: int = 16) -> None:
        sysdir = self.root / "sys/class/graphics/fb0"
        sysdir.mkdir(parents=True, exist_ok=True)
        (sysdir / "virtual_size").write_text(f"{w},{h}\n")
        (sysdir / "bits_per_pixel").write_text(f"{bpp}\n")
        (sysdir / "stride").write_text(f"{w * bpp // 8}\n")
        (self.root / "dev").mkdir(exist_ok=True)
        (self.root / "dev/fb0").write_bytes(bytes(w * bpp // 8 * h))

    def oak_model(self, settings: StereoSettings) -> DepthCameraModel:
        K = np.array([[441.0, 0.0, 319.5], [0.0, 441.0, 199.5], [0.0, 0.0, 1.0]])
        return DepthCameraModel(K, settings.width, settings.height, 0.075)


@pytest.fixture
def rig(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Rig:
    r = Rig(tmp_path / "root")
    monkeypatch.setattr(depth, "find_oak_devices", lambda: list(r.oak))
    monkeypatch.setattr(depth, "read_oak_calibration", r.oak_model)
    monkeypatch.setattr(lsm6dsox, "open_i2c", lambda bus: FakeSMBus({r.imu_address: r.imu}))
    return r


@pytest.fixture
def measured(tmp_path: Path) -> Path:
    cal = Calibration.default()
    cal = Calibration(
        cal.projector, cal.depth, cal.T_P_D, cal.R_P_I, quality={"verdict": "good", "rms_px": 0.21}
    )
    path = tmp_path / "calibration.toml"
    path.write_text(cal.to_toml())
    return path


def doctor(
    rig: Rig, calibration: Path | None, capsys: pytest.CaptureFixture[str]
) -> tuple[int, list[str]]:
    argv = ["doctor", "--root", str(rig.root), "--store", str(rig.root / "var/content")]
    if calibration is not None:
        argv += ["--calibration", str(calibration)]
    rc = main(argv)
    return rc, capsys.readouterr().out.splitlines()


def line_of(lines: list[str], what: str) -> tuple[str, str]:
    """The check's line and the line after it (its fix, when it has one)."""
    i = next(i for i, line in enumerate(lines) if line[6:].startswith(what))
    return lines[i], lines[i + 1]


def test_a_device_with_everything_passes(
    rig: Rig, measured: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rc, lines = doctor(rig, measured, capsys)
    assert rc == 0, lines
    assert lines[-1] == "all 7 checks passed"
    assert all(line.startswith("ok  ") for line in lines[:-1]), lines
    assert (
        f"OAK-D {OAK_ID}: calibration read (640x400, focal 441 px, baseline 7.5 cm)"
        in (line_of(lines, "depth camera")[0])
    )
    assert "LSM6DSOX at 0x6A on /dev/i2c-1 (WHO_AM_I 0x6C)" in line_of(lines, "IMU")[0]
    assert "/dev/fb0: 1280x800, 16 bits per pixel" in line_of(lines, "display")[0]
    assert "good, reprojection RMS 0.21 px" in line_of(lines, "calibration")[0]


def test_the_nominal_calibration_is_a_warning_that_says_to_calibrate(
    rig: Rig, capsys: pytest.CaptureFixture[str]
) -> None:
    nominal = Path(__file__).resolve().parents[2] / "hw/calibration/rpi5-oakd.toml"
    rc, lines = doctor(rig, nominal, capsys)
    assert rc == 0 and lines[-1] == "all 7 checks passed (1 warned)"
    check, fix = line_of(lines, "calibration")
    assert check.startswith("warn") and "nominal values" in check
    assert "run `adaproj calibrate`" in fix


def test_no_oak_d_says_to_plug_it_and_install_the_udev_rule(
    rig: Rig, measured: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rig.oak.clear()
    rc, lines = doctor(rig, measured, capsys)
    assert rc == 1 and lines[-1] == "1 of 7 checks failed"
    check, fix = line_of(lines, "depth camera")
    assert check.startswith("FAIL") and "no OAK-D found on USB" in check
    assert "80-adaproj-oakd.rules" in fix


def test_an_oak_d_whose_calibration_does_not_read(
    rig: Rig, measured: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    def broken(settings: StereoSettings) -> DepthCameraModel:
        raise DeviceNotFoundError("cannot open the OAK-D (X_LINK_DEVICE_NOT_FOUND)")

    monkeypatch.setattr(depth, "read_oak_calibration", broken)
    rc, lines = doctor(rig, measured, capsys)
    check, fix = line_of(lines, "depth camera")
    assert rc == 1 and "found, but its calibration does not read" in check
    assert "plug it in again" in fix


def test_i2c_off(rig: Rig, measured: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (rig.root / "dev/i2c-1").unlink()
    rc, lines = doctor(rig, measured, capsys)
    check, fix = line_of(lines, "IMU")
    assert rc == 1 and "/dev/i2c-1 is not there: I2C is off" in check
    assert "dtparam=i2c_arm=on" in fix


def test_another_chip_at_the_imu_address(
    rig: Rig, measured: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rig.imu.regs[lsm6dsox.WHO_AM_I] = 0x69  # an LSM6DS33
    rc, lines = doctor(rig, measured, capsys)
    check, fix = line_of(lines, "IMU")
    assert rc == 1 and "WHO_AM_I = 0x69, expected 0x6C" in check
    assert "SDA to GPIO2" in fix and "i2cdetect -y 1" in fix


def test_no_chip_answers(rig: Rig, measured: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rig.imu_address = 0x6B  # wired with SA0 high, the board file says 0x6A
    rc, lines = doctor(rig, measured, capsys)
    check, _ = line_of(lines, "IMU")
    assert rc == 1 and "no device answers as LSM6DSOX at 0x6A" in check


def test_the_framebuffer_in_another_mode(
    rig: Rig, measured: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rig.framebuffer(1920, 1080)
    rc, lines = doctor(rig, measured, capsys)
    check, fix = line_of(lines, "display")
    assert rc == 1 and "1920x1080" in check and "the calibration is for 1280x800" in check
    assert "video=HDMI-A-1:1280x800@60" in fix


def test_no_framebuffer(rig: Rig, measured: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (rig.root / "dev/fb0").unlink()
    rc, lines = doctor(rig, measured, capsys)
    check, fix = line_of(lines, "display")
    assert rc == 1 and check.startswith("FAIL") and "HDMI" in fix


def test_no_usb_gadget(rig: Rig, measured: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (rig.root / "dev/ttyGS0").unlink()
    rc, lines = doctor(rig, measured, capsys)
    check, fix = line_of(lines, "USB serial link")
    assert rc == 1 and "the USB gadget is not up" in check
    assert "adaproj-gadget.service" in fix and "dwc2" in fix


def test_no_button(rig: Rig, measured: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (rig.root / BUTTON).unlink()
    rc, lines = doctor(rig, measured, capsys)
    check, fix = line_of(lines, "button")
    assert rc == 1 and "no gpio-keys device" in check and "dtoverlay=gpio-key" in fix


def test_a_full_disk(
    rig: Rig, measured: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(Probes, "free_bytes", lambda self, path: 100 * 2**20)
    rc, lines = doctor(rig, measured, capsys)
    check, fix = line_of(lines, "disk")
    assert rc == 1 and "0.1 GiB free" in check and "--store" in fix


def test_a_bad_calibration_file(
    rig: Rig, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("format = 'nope'\n")
    rc, lines = doctor(rig, bad, capsys)
    check, fix = line_of(lines, "calibration")
    assert rc == 1 and check.startswith("FAIL") and "adaproj calibrate" in fix


def test_no_permission_on_the_bus_says_which_group(
    rig: Rig, measured: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    def denied(bus: int) -> FakeSMBus:
        raise lsm6dsox.device_error(
            OSError(errno.EACCES, "Permission denied"), "I2C bus /dev/i2c-1", "the bus"
        )

    monkeypatch.setattr(lsm6dsox, "open_i2c", denied)
    rc, lines = doctor(rig, measured, capsys)
    _, fix = line_of(lines, "IMU")
    assert rc == 1 and "add the user to group i2c" in fix


def test_run_check_exits_non_zero_when_a_device_is_missing(
    capsys: pytest.CaptureFixture[str],
) -> None:
    # this machine has no projector hardware
    assert main(["run", "--board", "rpi5-oakd", "--check"]) == 1
    out = capsys.readouterr().out.splitlines()
    assert out[-1].endswith("missing: `adaproj doctor` says what to do")
