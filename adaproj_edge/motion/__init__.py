"""The device's own motion from its IMU: still or moving, its orientation.

Pure: samples in, state out (no clock, no hardware)."""
