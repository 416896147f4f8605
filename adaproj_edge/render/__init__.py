"""Rendering: warp mesh -> remap maps -> projector frame; the viewer simulator."""
