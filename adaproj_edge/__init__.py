"""adaproj-edge: content- and surface-aware projection for a handheld pico-projector."""

__version__ = "0.1.0"
