"""The paper's hierarchical random-walk graph kernel (section 3.2.1, Eq. 1-3).

Node attributes are the normalised radii ``p^0 = r / r1`` (as the paper does for
retrieval). They diffuse over the contact graph, ``p^k = A p^(k-1)``, with the
column-stochastic transition matrix :meth:`ContactGraph.transition`. For the
``n_r`` largest balls the walk average is ``P_i = (1/t) sum_{k=1..t} w^k p_i^k``
and the feature vector (Eq. 1) is

    f = [p0_1, ..., p0_nr, P_1, ..., P_nr]          (2 n_r,)

padded with zeros when the graph has fewer than ``n_r`` nodes. Two graphs are at
distance (Eq. 2) ``d = sum_i la^i |p0_i - p0'_i| + sum_i lb^i |P_i - P'_i|`` and
have kernel (Eq. 3) ``k = exp(-lam d)`` in (0, 1]. Since Eq. 2 is a weighted L1
distance, it is the plain L1 distance of ``f * weights(config)``, which is what
a vector index stores.

With ``KernelConfig(method="mdbd")`` (the default) :func:`features` returns
shapedb's own descriptor (:mod:`shapedb.signature.descriptor`, of ``DescriptorConfig.version``)
instead, already scaled so that its plain L1 distance is the distance (:func:`weights`
are ones); Eq. 3 turns it into a similarity the same way.

Every function takes the configuration as a whole :class:`~shapedb.config.core.Config`
(what a store holds: its kernel and its descriptor version) or as a
:class:`~shapedb.config.core.KernelConfig` alone (the descriptor then is today's default
version); ``**options`` override kernel fields or ``descriptor`` by flat name.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from shapedb.config.core import OPTIONS, Config, KernelConfig
from shapedb.errors import ConfigError, InvalidShapeError
from shapedb.mdbd.graph import ContactGraph

__all__ = ["features", "features_batch", "weights", "distance", "kernel"]


_KERNEL_OPTIONS = {name for name, (section, _) in OPTIONS.items() if section == "kernel"}


def _config(config: Config | KernelConfig | None, options: dict[str, Any]) -> Config:
    if config is None:
        cfg = Config()
    elif isinstance(config, KernelConfig):
        cfg = Config(kernel=config)
    elif isinstance(config, Config):
        cfg = config
    else:
        raise ConfigError(f"config must be a Config or KernelConfig, got {type(config).__name__}")
    if not options:
        return cfg
    unknown = set(options) - _KERNEL_OPTIONS - {"descriptor"}
    if unknown:
        raise ConfigError(f"unknown kernel option(s): {sorted(unknown)}")
    return cfg.with_options(**options)


def _graph(x: Any) -> ContactGraph:
    if isinstance(x, ContactGraph):
        return x
    g = getattr(x, "graph", None)  # a Decomposition (avoids importing mdbd here)
    if isinstance(g, ContactGraph):
        return g
    raise InvalidShapeError(f"expected a Decomposition or ContactGraph, got {type(x).__name__}")


def features(
    x: Any, config: Config | KernelConfig | None = None, **options: Any
) -> NDArray[np.float64]:
    """Feature vector of a graph: the paper's Eq. 1, or shapedb's descriptor.

    Parameters
    ----------
    x : Decomposition or ContactGraph
        The graph; nodes are ranked by decreasing radius (stable for ties).
    config : Config or KernelConfig, optional
        Kernel parameters (and descriptor version); ``**options`` override them (e.g.
        ``n_r=10``).

    Returns
    -------
    (Config.dim,) float64
        method "paper": ``[p0_1..p0_nr, P_1..P_nr]`` (2 * n_r), zeros for missing
        nodes; method "mdbd": :func:`shapedb.signature.descriptor.describe` of version
        ``config.descriptor.version``.
    """
    full = _config(config, options)
    cfg = full.kernel
    g = _graph(x)
    if cfg.method == "mdbd":
        from shapedb.signature.descriptor import describe

        return describe(g, full.descriptor.version)
    out = np.zeros(full.dim)
    n = g.n_nodes
    if n == 0:
        return out
    r1 = float(g.radii.max())
    if not r1 > 0:
        raise InvalidShapeError(f"largest radius must be > 0, got {r1}")
    p = g.radii / r1
    rep = np.argsort(-g.radii, kind="stable")[: cfg.n_r]
    A = g.transition()
    acc = np.zeros(n)
    wk = 1.0
    for _ in range(cfg.t):
        p = A @ p
        wk *= cfg.w
        acc += wk * p
    k = len(rep)
    out[:k] = g.radii[rep] / r1
    out[cfg.n_r : cfg.n_r + k] = acc[rep] / cfg.t
    return out


def features_batch(
    xs: Iterable[Any], config: Config | KernelConfig | None = None, **options: Any
) -> NDArray[np.float64]:
    """Stacked :func:`features` of several graphs: (N, Config.dim) float64."""
    cfg = _config(config, options)
    rows = [features(x, cfg) for x in xs]
    return np.stack(rows) if rows else np.zeros((0, cfg.dim))


def weights(config: Config | KernelConfig | None = None, **options: Any) -> NDArray[np.float64]:
    """Eq. 2 weights (2 * n_r,): ``[la^1..la^nr, lb^1..lb^nr]``; ones (Config.dim,) for "mdbd"."""
    full = _config(config, options)
    cfg = full.kernel
    if cfg.method == "mdbd":
        return np.ones(full.dim)
    i = np.arange(1, cfg.n_r + 1, dtype=np.float64)
    return np.concatenate([cfg.la**i, cfg.lb**i])


def _check(f: ArrayLike, name: str, cfg: Config) -> NDArray[np.float64]:
    a = np.asarray(f, dtype=np.float64)
    if a.ndim not in (1, 2) or a.shape[-1] != cfg.dim:
        raise ConfigError(
            f"{name} has shape {a.shape} but this kernel's features have length "
            f"{cfg.dim} (method {cfg.kernel.method!r}); were they computed with another "
            "configuration?"
        )
    return a


def distance(
    fa: ArrayLike, fb: ArrayLike, config: Config | KernelConfig | None = None, **options: Any
) -> NDArray[np.float64] | float:
    """Eq. 2: weighted L1 distance between feature vectors.

    Parameters
    ----------
    fa : (d,) float
        Features of one graph, d = ``Config.dim``.
    fb : (d,) or (m, d) float
        Features of one graph or of m graphs.

    Returns
    -------
    float or (m,) float64
        A float when ``fb`` is one vector.
    """
    cfg = _config(config, options)
    a = _check(fa, "fa", cfg)
    b = _check(fb, "fb", cfg)
    if a.ndim != 1:
        raise ConfigError(f"fa must be one feature vector (d,), got shape {a.shape}")
    d = np.abs(b - a) @ weights(cfg)
    return float(d) if b.ndim == 1 else d


def kernel(
    fa: ArrayLike, fb: ArrayLike, config: Config | KernelConfig | None = None, **options: Any
) -> NDArray[np.float64] | float:
    """Eq. 3: ``exp(-lam * d)``, a similarity in (0, 1]; shapes as in :func:`distance`."""
    cfg = _config(config, options)
    d = distance(fa, fb, cfg)
    lam = cfg.kernel.lam
    return float(np.exp(-lam * d)) if isinstance(d, float) else np.exp(-lam * d)
