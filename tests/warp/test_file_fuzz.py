"""Surface and warp files come from outside: any bytes give a named error, never a crash."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from adaproj_edge.errors import InputError
from adaproj_edge.geometry.analytic import simulate_surface
from adaproj_edge.geometry.surface import Surface
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.planner import compute_warp
from adaproj_edge.warp.warpmap import Grid, Warp


def _valid_files() -> dict[str, bytes]:
    s = simulate_surface("bowl", step=40)
    buf = io.BytesIO()
    np.savez(buf, points=s.points, K=s.projector.K, meta=np.array('{"name": "bowl"}'))
    w = compute_warp(s, (64, 40), settings=WarpSettings(mode="conformal", grid=Grid(6, 4)))
    wbuf = io.BytesIO()
    np.savez(
        wbuf,
        grid_uv=w.grid_uv,
        image_xy=w.image_xy,
        K=w.projector.K,
        meta=np.array('{"width": 1280, "height": 800, "content_width": 64, "content_height": 40}'),
    )
    return {"surface": buf.getvalue(), "warp": wbuf.getvalue()}


VALID = _valid_files()
LOADERS = {"surface": Surface.load, "warp": Warp.load}


@pytest.mark.parametrize("kind", ["surface", "warp"])
@settings(
    max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(data=st.data())
def test_any_bytes_load_or_fail_with_a_named_error(
    tmp_path: Path, kind: str, data: st.DataObject
) -> None:
    good = VALID[kind]
    how = data.draw(st.sampled_from(["random", "truncated", "flipped"]))
    if how == "random":
        blob = data.draw(st.binary(max_size=2048))
    elif how == "truncated":
        blob = good[: data.draw(st.integers(0, len(good) - 1))]
    else:
        pos = data.draw(st.integers(0, len(good) - 1))
        blob = good[:pos] + bytes([good[pos] ^ data.draw(st.integers(1, 255))]) + good[pos + 1 :]
    path = tmp_path / f"{kind}.npz"
    path.write_bytes(blob)
    try:
        LOADERS[kind](path)
    except InputError:
        pass
