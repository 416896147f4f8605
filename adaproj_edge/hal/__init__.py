"""Hardware-abstraction layer: one typing.Protocol per device, real and replay side by side."""
