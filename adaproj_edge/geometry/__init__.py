"""Pure geometry: projector model, surfaces, triangles, inscribed rectangles."""
