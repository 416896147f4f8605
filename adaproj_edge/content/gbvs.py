"""Graph-based visual saliency (Harel, Koch & Perona, NIPS 2006): parameters and reference.

This is the readable numpy version of the default saliency model. The ONNX graph in
``models/gbvs_saliency.onnx`` is built by ``tools/build_saliency_model.py`` from the same
:class:`GBVSParams` and the same constant arrays (:func:`constants`), and performs the
same fixed sequence of float32 operations, so the two agree up to float32 rounding.

The computation, for an RGB image ``(3, H, W)`` in [0, 1]:

1. **Pyramid.** Level 0 is the input; level ``k + 1`` is level ``k`` blurred with the
   5-tap binomial kernel (reflect padding) and subsampled by 2.
2. **Feature maps.** At each level in ``params.levels``: intensity ``(r + g + b) / 3``;
   four rectified colour-opponency maps R−G, G−R, B−Y, Y−B (``Y = min(r, g)``), each
   divided by ``max(max(r, g, b), colour_floor)``; four orientation-energy maps
   ``sqrt(even² + odd²)`` of a quadrature Gabor pair at 0°, 45°, 90°, 135°. Every map is
   average-pooled down to the graph size ``params.map_size``.
3. **Activation.** Over each map ``M`` (``n`` nodes) the fully connected graph with
   weights ``w(i, j) = (|log(M_i + e) − log(M_j + e)| + ε) F_act(i, j)``, where ``F`` is
   a Gaussian of the grid distance (σ = ``sigma_frac_act`` × mean map side) with
   reflecting borders, so no place is favoured. The activation ``A`` is the
   equilibrium distribution of the Markov chain that walks this graph (rows normalised).
4. **Normalisation.** A second chain with weights ``w(i, j) = A_j F_norm(i, j)``; its
   equilibrium concentrates mass where activation is high and isolated. Applied
   ``norm_iters`` times.
5. **Combination.** Maps are averaged within their channel (intensity, colour,
   orientation), channels are summed, blurred once with the binomial kernel (as the
   authors blur the master map) and divided by the maximum.

Both chains are *reversible*: the first has symmetric weights, so its equilibrium is
proportional to the weighted degree ``Σ_j w(i, j)``; the second satisfies detailed
balance with ``π_i ∝ A_i (F_norm A)_i``. The equilibria are therefore computed exactly
in closed form (one fixed computation, no iteration count to tune); the test suite
checks them against power iteration on the explicit transition matrices
(:func:`transition_matrix`, :func:`power_iteration`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import NDArray

F32 = NDArray[np.float32]

COLOUR_FEATURES = ("RG", "GR", "BY", "YB")
"""The colour-opponency maps computed at each level, after intensity ("I")."""

BINOMIAL_5 = np.array([1.0, 4.0, 6.0, 4.0, 1.0]) / 16.0


@dataclass(frozen=True)
class GBVSParams:
    """Every number that defines the default saliency model.

    Parameters
    ----------
    map_size : (rows, cols)
        Size of the activation graph (``n = rows * cols`` nodes) and of the output map.
    levels : tuple of int
        Pyramid levels the feature maps are taken from; the input is
        ``map_size * 2 ** max(levels)``.
    gabor_size, gabor_wavelength, gabor_sigma, gabor_aspect : int, float, float, float
        Gabor pair: kernel side (odd), carrier wavelength (px), envelope σ (px) and
        envelope aspect (across / along the carrier).
    orientations_deg : tuple of float
        Gabor orientations.
    sigma_frac_act, sigma_frac_norm : float
        σ of the distance falloff of the two graphs, as a fraction of the mean map side
        (0.15 and 0.06 in the authors' code).
    log_eps : float
        Offset added to a feature map before the log in the dissimilarity.
    weight_eps : float
        Added to every dissimilarity so a constant map gives a well-defined chain.
    colour_floor : float
        Lower bound of the ``max(r, g, b)`` divisor of the colour maps (dark pixels
        have no reliable colour).
    channel_weights : (3,) tuple of float
        Weights of the intensity, colour and orientation channels.
    norm_iters : int
        How many times the normalisation chain is applied (``num_norm_iters`` in the
        authors' code); each pass moves mass from diffuse maps onto isolated peaks.
    border_reflect : float
        Weight of the mirror images in the distance falloff (:func:`falloff`): 1 makes
        the graph favour no place; 0 is the authors' open graph, which has a centre bias.
    """

    map_size: tuple[int, int] = (15, 24)
    levels: tuple[int, ...] = (1, 2, 3)
    gabor_size: int = 7
    gabor_wavelength: float = 4.0
    gabor_sigma: float = 1.6
    gabor_aspect: float = 0.75
    orientations_deg: tuple[float, ...] = (0.0, 45.0, 90.0, 135.0)
    sigma_frac_act: float = 0.15
    sigma_frac_norm: float = 0.06
    log_eps: float = 0.2
    weight_eps: float = 1e-3
    colour_floor: float = 0.1
    channel_weights: tuple[float, float, float] = (1.0, 1.0, 1.0)
    norm_iters: int = 2
    border_reflect: float = 1.0

    @property
    def input_size(self) -> tuple[int, int]:
        """(rows, cols) of the model input."""
        f = 2 ** max(self.levels)
        return self.map_size[0] * f, self.map_size[1] * f

    @property
    def n_nodes(self) -> int:
        """Number of nodes of each graph."""
        return self.map_size[0] * self.map_size[1]

    @property
    def n_maps(self) -> int:
        """Number of feature maps (features per level × levels)."""
        return len(self.feature_names) * len(self.levels)

    @property
    def feature_names(self) -> tuple[str, ...]:
        """Names of the maps computed at each level, in order: "I", colour, "O<deg>"."""
        return ("I", *COLOUR_FEATURES, *(f"O{d:g}" for d in self.orientations_deg))


@dataclass(frozen=True)
class Constants:
    """Constant arrays derived from :class:`GBVSParams` (shared with the ONNX builder).

    Attributes
    ----------
    blur : (5, 5) float32
        Separable binomial kernel of the pyramid.
    gabor : (2 * k, g, g) float32
        Even kernels for every orientation, then odd kernels in the same order.
    f_act, f_norm : (n, n) float32
        Gaussian distance falloff of the activation and normalisation graphs.
    act_bias : (n,) float32
        ``weight_eps * F_act.sum(axis=1)``, the ε part of the activation degrees.
    combine : (1, n_maps) float32
        Weight of each feature map in the final sum.
    """

    blur: F32
    gabor: F32
    f_act: F32
    f_norm: F32
    act_bias: F32
    combine: F32


def gabor_pair(params: GBVSParams) -> F32:
    """Quadrature Gabor kernels, shape ``(2 * n_orientations, size, size)``.

    Even kernels are made zero-mean; every kernel is scaled to unit L1 norm.
    """
    half = params.gabor_size // 2
    y, x = np.mgrid[-half : half + 1, -half : half + 1].astype(np.float64)
    even, odd = [], []
    for deg in params.orientations_deg:
        t = np.deg2rad(deg)
        along = x * np.cos(t) + y * np.sin(t)
        across = -x * np.sin(t) + y * np.cos(t)
        r2 = along**2 + (params.gabor_aspect * across) ** 2
        env = np.exp(-r2 / (2 * params.gabor_sigma**2))
        phase = 2 * np.pi * along / params.gabor_wavelength
        e = env * np.cos(phase)
        e -= e.mean()
        o = env * np.sin(phase)
        even.append(e / np.abs(e).sum())
        odd.append(o / np.abs(o).sum())
    return np.stack(even + odd).astype(np.float32)


def _falloff_1d(size: int, sigma: float, reflect: float) -> NDArray[np.float64]:
    """Gaussian of the index distance along one axis, plus ``reflect`` times the same
    Gaussian of the target's mirror images about the borders."""
    i = np.arange(size, dtype=np.float64)[:, None]
    j = np.arange(size, dtype=np.float64)[None, :]
    f = np.exp(-((i - j) ** 2) / (2 * sigma**2))
    if reflect:
        for im in (-1 - j, 2 * size - 1 - j):
            f = f + reflect * np.exp(-((i - im) ** 2) / (2 * sigma**2))
    return f


def falloff_factors(
    map_size: tuple[int, int], sigma_frac: float, reflect: float = 0.0
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The two factors of :func:`falloff`: ``(rows, rows)`` and ``(cols, cols)``, symmetric.

    The Gaussian of the grid distance is the product of a Gaussian along the rows and
    one along the columns, so ``falloff = kron(f_rows, f_cols)``, and for maps ``A``
    ``(m, rows, cols)``, ``A.reshape(m, -1) @ falloff`` is ``f_rows @ A @ f_cols``
    reshaped (what the ONNX graph computes: ~25x fewer multiplications at 24x15).
    """
    rows, cols = map_size
    sigma = sigma_frac * (rows + cols) / 2.0
    return _falloff_1d(rows, sigma, reflect), _falloff_1d(cols, sigma, reflect)


def falloff(map_size: tuple[int, int], sigma_frac: float, reflect: float = 0.0) -> F32:
    """Gaussian of the grid distance between nodes, shape ``(n, n)``, symmetric.

    σ is ``sigma_frac`` times the mean side of the map, in nodes. Nodes are numbered
    row-major. ``reflect`` in [0, 1] adds the mirror images of the nodes about the
    borders: 0 is the authors' open graph (border nodes have fewer neighbours, which
    makes a centre bias), 1 a fully reflecting border (no place favoured).
    """
    f = np.kron(*falloff_factors(map_size, sigma_frac, reflect))
    return np.asarray(f, dtype=np.float32)


def _channel(feature: str) -> int:
    """0 intensity, 1 colour, 2 orientation."""
    return 0 if feature == "I" else 1 if feature in COLOUR_FEATURES else 2


def map_weights(params: GBVSParams) -> F32:
    """Weight of each feature map in the final sum, shape ``(1, n_maps)``.

    A channel's maps share its weight equally; the weights sum to 1.
    """
    channel = [_channel(f) for f in params.feature_names] * len(params.levels)
    counts = np.bincount(channel, minlength=3)
    cw = np.asarray(params.channel_weights, dtype=np.float64)
    w = np.array([cw[c] / counts[c] for c in channel]) / cw.sum()
    return np.asarray(w[None, :], dtype=np.float32)


def constants(params: GBVSParams) -> Constants:
    """Every constant array the model needs, computed once from ``params``."""
    f_act = falloff(params.map_size, params.sigma_frac_act, params.border_reflect)
    return Constants(
        blur=np.outer(BINOMIAL_5, BINOMIAL_5).astype(np.float32),
        gabor=gabor_pair(params),
        f_act=f_act,
        f_norm=falloff(params.map_size, params.sigma_frac_norm, params.border_reflect),
        act_bias=(np.float32(params.weight_eps) * f_act.sum(axis=1)).astype(np.float32),
        combine=map_weights(params),
    )


def correlate_valid(image: F32, kernels: F32, stride: int = 1) -> F32:
    """Correlate each of ``c`` planes with ``k`` kernels, no padding.

    Parameters
    ----------
    image : (c, h, w) float32
    kernels : (k, s, s) float32
    stride : int

    Returns
    -------
    (c, k, (h - s) // stride + 1, (w - s) // stride + 1) float32
    """
    s = kernels.shape[-1]
    win = sliding_window_view(image, (s, s), axis=(1, 2))[:, ::stride, ::stride]
    return np.asarray(np.einsum("chwij,kij->ckhw", win, kernels), dtype=np.float32)


def reflect_pad(image: F32, pad: int) -> F32:
    """Reflect-pad the last two axes of a ``(c, h, w)`` array by ``pad`` on each side."""
    return np.pad(image, ((0, 0), (pad, pad), (pad, pad)), mode="reflect")


def pyr_down(image: F32, const: Constants) -> F32:
    """Blur with the binomial kernel and subsample by 2: ``(c, h, w) -> (c, h/2, w/2)``."""
    return correlate_valid(reflect_pad(image, 2), const.blur[None], stride=2)[:, 0]


def level_features(rgb: F32, params: GBVSParams, const: Constants) -> F32:
    """The feature maps of one pyramid level (nine by default).

    Parameters
    ----------
    rgb : (3, h, w) float32
        One pyramid level of the input.

    Returns
    -------
    (len(params.feature_names), h, w) float32
        In the order of ``params.feature_names``.
    """
    r, g, b = rgb[0], rgb[1], rgb[2]
    intensity = (r + g + b) / np.float32(3.0)
    denom = np.maximum(np.max(rgb, axis=0), np.float32(params.colour_floor))
    y = np.minimum(r, g)
    pairs = ((r, g), (g, r), (b, y), (y, b))
    colour = [np.maximum(p - q, np.float32(0.0)) / denom for p, q in pairs]
    pad = params.gabor_size // 2
    resp = correlate_valid(reflect_pad(intensity[None], pad), const.gabor)[0]
    k = len(params.orientations_deg)
    energy = np.sqrt(resp[:k] * resp[:k] + resp[k:] * resp[k:])
    return np.concatenate([intensity[None], np.stack(colour), energy]).astype(np.float32)


def avg_pool(maps: F32, factor: int) -> F32:
    """Mean over ``factor × factor`` blocks: ``(c, h, w) -> (c, h/f, w/f)``."""
    if factor == 1:
        return maps
    c, h, w = maps.shape
    blocks = maps.reshape(c, h // factor, factor, w // factor, factor)
    return np.asarray(blocks.mean(axis=(2, 4), dtype=np.float32), dtype=np.float32)


def feature_maps(rgb: F32, params: GBVSParams, const: Constants) -> F32:
    """All feature maps at the graph size, shape ``(n_maps, n)``.

    Parameters
    ----------
    rgb : (3, H, W) float32
        RGB in [0, 1] at ``params.input_size``.
    """
    top = max(params.levels)
    level = rgb
    out = []
    for k in range(1, top + 1):
        level = pyr_down(level, const)
        if k in params.levels:
            out.append(avg_pool(level_features(level, params, const), 2 ** (top - k)))
    maps = np.concatenate(out)
    return maps.reshape(maps.shape[0], -1)


def activation(maps: F32, params: GBVSParams, const: Constants) -> F32:
    """Equilibrium of the dissimilarity chain over each map, ``(m, n) -> (m, n)``.

    The weights ``(|Δ log| + ε) F_act`` are symmetric, so the equilibrium is the
    normalised weighted degree.
    """
    x = np.log(maps + np.float32(params.log_eps))
    diff = np.abs(x[:, :, None] - x[:, None, :])
    degree = (diff * const.f_act[None]).sum(axis=2, dtype=np.float32) + const.act_bias
    return np.asarray(degree / degree.sum(axis=1, keepdims=True), dtype=np.float32)


def normalisation(act: F32, const: Constants) -> F32:
    """Equilibrium of the chain with weights ``A_j F_norm(i, j)``, ``(m, n) -> (m, n)``.

    Detailed balance holds with ``π_i ∝ A_i (A F_norm)_i``.
    """
    q = act * (act @ const.f_norm)
    return np.asarray(q / q.sum(axis=1, keepdims=True), dtype=np.float32)


def saliency(rgb: F32, params: GBVSParams | None = None) -> F32:
    """The GBVS saliency map of an RGB image, the reference for the ONNX model.

    Parameters
    ----------
    rgb : (3, H, W) float32
        RGB in [0, 1] at ``params.input_size``.
    params : GBVSParams, optional
        Defaults to ``GBVSParams()``.

    Returns
    -------
    (rows, cols) float32
        At ``params.map_size``; its maximum is 1.
    """
    params = params or GBVSParams()
    if rgb.shape != (3, *params.input_size):
        raise ValueError(f"expected (3, {params.input_size}) input, got {rgb.shape}")
    const = constants(params)
    norm = activation(feature_maps(rgb, params, const), params, const)
    for _ in range(params.norm_iters):
        norm = normalisation(norm, const)
    total = (const.combine @ norm).reshape(1, *params.map_size)
    blurred = correlate_valid(reflect_pad(total, 2), const.blur[None])[0, 0]
    return np.asarray(blurred / blurred.max(), dtype=np.float32)


def transition_matrix(weights: NDArray[np.floating]) -> NDArray[np.float64]:
    """Row-normalise edge weights ``(n, n)`` into a Markov transition matrix."""
    w = np.asarray(weights, dtype=np.float64)
    return np.asarray(w / w.sum(axis=1, keepdims=True), dtype=np.float64)


def power_iteration(transition: NDArray[np.floating], iterations: int) -> NDArray[np.float64]:
    """Equilibrium ``π = π P`` by ``iterations`` steps from the uniform distribution."""
    p = np.asarray(transition, dtype=np.float64)
    pi = np.full(p.shape[0], 1.0 / p.shape[0])
    for _ in range(iterations):
        pi = pi @ p
    return pi
