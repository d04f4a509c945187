"""A similarity learned on a labelled store: one weight per descriptor block.

The default similarity is unlearned (:mod:`shapedb.signature.descriptor`, scaled once on the
project's validation splits). A store whose shapes carry class labels can fit its own
weighting of the descriptor's blocks, so that the blocks that separate *its* classes
count more; the distance stays a weighted L1, so the faiss index, the exact
re-ranking and the sparse views work unchanged::

    metric = db.fit_metric(label="label")        # LearnedMetric, cross-validated
    hits = db.search("query.stl", metric=metric)
    db.evaluate(metric=metric)
    metric.save("metric.json"); LearnedMetric.load("metric.json")

The fit is neighbourhood components analysis (Goldberger et al., 2004) restricted to
non-negative block weights ``exp(theta_b)``: every labelled shape (and, in a store
with sparse views, every shape's view) queries the others, compared as the search
compares them (a sparse-dense pair by the nearest of own features, views and
reconstructions, :mod:`query.search.engine`); the other shapes are picked with probability
``softmax(-temperature * d / median d)`` and the mean log probability of picking one
of the query's class is maximised, with a penalty
``reg * |theta|^2`` that pulls the weights towards the default; the fitted weights are
then scaled so that shapes of different classes lie as far apart (median) as under the
default, which keeps the similarity ``exp(-lam d)`` calibrated. The strength ``reg``
is chosen by k-fold cross-validation on the mean log margin ``log(d(nearest same
class) / d(nearest other class))`` of held-out queries: a weighting is kept only if
it beats the default's held-out margins by two standard errors (paired over queries),
and among those the most regularised one within one standard error of the best is
chosen. When nothing passes, the metric is the identity and says so (``learned``
False): on a store whose classes the default already separates, fitting is harmless.

What a fit gains on the labelled sets is measured by ``python -m bench.metric``
(``docs/results.md``, "Learned metric").
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import minimize
from scipy.spatial.distance import cdist

from shapedb.config.core import Config
from shapedb.errors import ConfigError, LoadError, QueryError

if TYPE_CHECKING:
    from shapedb.store.handle import StoreHandle

__all__ = ["LearnedMetric", "block_layout", "fit_metric", "fit_store_metric", "as_metric"]

log = logging.getLogger(__name__)

#: Regularisation strengths tried by cross-validation, strongest first.
REGS = (1.0, 0.3, 0.1, 0.03, 0.01, 0.003, 0.001)
#: Softmax sharpness: distances are divided by their median and multiplied by this.
TEMPERATURE = 10.0
#: Shapes used for a fit at most (a class-stratified sample beyond that): the fit
#: holds (queries x shapes x blocks) float64 distances: 128 MB at 2,000 x 1,000 x 8.
MAX_SHAPES = 1000
FORMAT = "shapedb-metric/1"


def block_layout(config: Config) -> tuple[tuple[str, int], ...]:
    """The blocks of a configuration's feature vector: ``((name, length), ...)``.

    Method "mdbd": the blocks of :data:`shapedb.signature.descriptor.LAYOUTS` of its version;
    method "paper": ``p0`` (the representatives' r/r1) and ``walk`` (their walk
    averages), ``n_r`` each.
    """
    if config.kernel.method == "mdbd":
        from shapedb.signature.descriptor import LAYOUTS

        layout = LAYOUTS[config.descriptor.version]
        return tuple((name, int(size)) for name, size, _, _ in layout)
    n_r = int(config.kernel.n_r)
    return (("p0", n_r), ("walk", n_r))


@dataclass(frozen=True)
class LearnedMetric:
    """Block weights on a store's L1 feature distance, fitted on its labels.

    Attributes
    ----------
    blocks : tuple of (str, int)
        Block names and lengths, in feature order (:func:`block_layout`).
    weights : tuple of float
        One multiplier per block (> 0); all ones when ``learned`` is False.
    fingerprint : str
        ``Config.fingerprint`` of the store the features came from; a store with
        another configuration refuses the metric.
    reg : float or None
        The regularisation chosen by cross-validation; None for the identity.
    cv : dict
        Per candidate ``reg`` (key ``"default"`` for the identity): mean held-out log
        margin and its paired standard error against the default (lower is better).
    n_shapes, n_classes : int
        Labelled shapes (and classes) the fit used.
    n_extra : int
        Sparse views of those shapes that were queries too.
    label : str
        The column or metadata key the classes came from.
    """

    blocks: tuple[tuple[str, int], ...]
    weights: tuple[float, ...]
    fingerprint: str
    reg: float | None = None
    cv: dict[str, dict[str, float]] = field(default_factory=dict)
    n_shapes: int = 0
    n_classes: int = 0
    n_extra: int = 0
    label: str = "label"

    def __post_init__(self) -> None:
        w = np.asarray(self.weights, dtype=np.float64)
        if len(w) != len(self.blocks) or not np.all(np.isfinite(w)) or np.any(w <= 0):
            raise ConfigError(
                "needs one positive finite weight per block",
                source=f"weights={self.weights!r}",
            )

    @property
    def learned(self) -> bool:
        """False when cross-validation kept the default (all weights 1)."""
        return self.reg is not None

    @property
    def digest(self) -> str:
        """12 hex digits naming the weighting (fingerprint, blocks and weights)."""
        text = json.dumps([self.fingerprint, [list(b) for b in self.blocks], list(self.weights)])
        return hashlib.sha256(text.encode()).hexdigest()[:12]

    @property
    def dim(self) -> int:
        """Length of the feature vectors it weighs."""
        return sum(n for _, n in self.blocks)

    def dim_weights(self) -> NDArray[np.float64]:
        """(d,) multiplier of every feature dimension."""
        sizes = [n for _, n in self.blocks]
        return np.repeat(np.asarray(self.weights, np.float64), sizes)

    def check(self, config: Any) -> None:
        """Raise ConfigError unless the metric fits a store built with ``config``."""
        if config.fingerprint != self.fingerprint:
            raise ConfigError(
                "the metric was fitted on a store with another configuration "
                f"(fingerprint {self.fingerprint}, this store {config.fingerprint})",
                source="metric",
            )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (what :meth:`save` writes)."""
        out = asdict(self)
        out["blocks"] = [list(b) for b in self.blocks]
        out["weights"] = list(self.weights)
        return {"format": FORMAT, **out}

    @classmethod
    def from_dict(cls, data: dict[str, Any], *, source: str = "metric") -> LearnedMetric:
        """Inverse of :meth:`to_dict`."""
        if not isinstance(data, dict) or data.get("format") != FORMAT:
            raise LoadError(f"not a shapedb metric (expected format {FORMAT})", source=source)
        try:
            return cls(
                blocks=tuple((str(n), int(s)) for n, s in data["blocks"]),
                weights=tuple(float(x) for x in data["weights"]),
                fingerprint=str(data["fingerprint"]),
                reg=None if data.get("reg") is None else float(data["reg"]),
                cv={str(k): dict(v) for k, v in data.get("cv", {}).items()},
                n_shapes=int(data.get("n_shapes", 0)),
                n_classes=int(data.get("n_classes", 0)),
                n_extra=int(data.get("n_extra", 0)),
                label=str(data.get("label", "label")),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise LoadError(f"malformed metric: {exc}", source=source) from exc

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the metric as JSON (atomically: a temporary file, then a rename)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_text(json.dumps(self.to_dict(), indent=1))
        os.replace(tmp, path)
        return path

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> LearnedMetric:
        """Read a metric written by :meth:`save`."""
        try:
            data = json.loads(Path(path).read_text())
        except (OSError, ValueError) as exc:
            raise LoadError(f"cannot read a metric: {exc}", source=os.fspath(path)) from exc
        return cls.from_dict(data, source=os.fspath(path))


def as_metric(metric: Any) -> LearnedMetric | None:
    """None, a :class:`LearnedMetric`, or the path of one saved with :meth:`~LearnedMetric.save`."""
    if metric is None or isinstance(metric, LearnedMetric):
        return metric
    if isinstance(metric, (str, os.PathLike)):
        return LearnedMetric.load(metric)
    raise QueryError(
        "metric must be a LearnedMetric or the path of a saved one",
        source=f"metric={type(metric).__name__}",
    )


# --------------------------------------------------------------------------------------
# Fitting
# --------------------------------------------------------------------------------------


def _block_distances(
    queries: NDArray[np.float64], shapes: NDArray[np.float64], sizes: Sequence[int]
) -> NDArray[np.float64]:
    """(q, n, b): L1 distance of every query to every shape, block by block."""
    out = np.empty((len(queries), len(shapes), len(sizes)))
    lo = 0
    for b, n in enumerate(sizes):
        out[:, :, b] = cdist(queries[:, lo : lo + n], shapes[:, lo : lo + n], "cityblock")
        lo += n
    return out


def _nca_weights(
    blocks: NDArray[np.float64],
    same: NDArray[np.bool_],
    exclude: NDArray[np.bool_],
    reg: float,
    temperature: float,
    alts: tuple[NDArray[np.float64], ...] = (),
) -> NDArray[np.float64]:
    """Block weights maximising the NCA objective; see the module docstring.

    ``blocks`` (q, n, b) per-block distances, ``same`` (q, n) same class, ``exclude``
    (q, n) pairs left out (a query against itself or its own shape); ``alts``, each
    like ``blocks``, other ways of comparing each pair (views, reconstructions): a
    pair is as far apart as the smallest of the weighted sums.
    """
    total = _pair_distances(blocks, alts, np.ones(blocks.shape[-1]))
    scale = temperature / max(float(np.median(total[~exclude])), 1e-12)
    same = same & ~exclude
    counted = same.any(1)
    if not counted.any():
        return np.ones(blocks.shape[-1])
    a = blocks[counted] * scale
    others = [alt[counted] * scale for alt in alts]
    s, ex = same[counted], exclude[counted]
    m = len(a)

    def objective(theta: NDArray[np.float64]) -> tuple[float, NDArray[np.float64]]:
        w = np.exp(theta)
        d = a @ w
        active = a
        for b in others:  # the gradient follows the nearest comparison
            db = b @ w
            active = np.where((db < d)[..., None], b, active)
            d = np.minimum(d, db)
        logits = np.where(ex, -np.inf, -d)
        logits -= logits.max(1, keepdims=True)
        p = np.exp(logits)
        p /= p.sum(1, keepdims=True)
        ps = np.maximum((p * s).sum(1), 1e-300)
        loss = -np.log(ps).sum() / m + reg * float(theta @ theta)
        g_d = (p * s / ps[:, None] - p) / m  # d loss / d distance
        grad = np.einsum("ij,ijk->k", g_d, active) * w + 2 * reg * theta
        return loss, grad

    res = minimize(
        objective, np.zeros(a.shape[-1]), jac=True, method="L-BFGS-B", options={"maxiter": 500}
    )
    return np.exp(np.clip(res.x, -20, 20))


def _pair_distances(
    blocks: NDArray[np.float64], alts: tuple[NDArray[np.float64], ...], w: NDArray[np.float64]
) -> NDArray[np.float64]:
    """(q, n) weighted distances: the smallest of ``blocks @ w`` and each ``alt @ w``."""
    d = blocks @ w
    for alt in alts:
        d = np.minimum(d, alt @ w)
    return d


def _log_margins(
    blocks: NDArray[np.float64],
    w: NDArray[np.float64],
    same: NDArray[np.bool_],
    exclude: NDArray[np.bool_],
    alts: tuple[NDArray[np.float64], ...] = (),
) -> NDArray[np.float64]:
    """log(d(nearest same class) / d(nearest other class)) of each query (NaN if undefined)."""
    d = np.where(exclude, np.inf, _pair_distances(blocks, alts, w))
    near = np.where(same, d, np.inf).min(1)
    far = np.where(~same, d, np.inf).min(1)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.log(np.maximum(near, 1e-12) / np.maximum(far, 1e-12))
    out[~(np.isfinite(near) & np.isfinite(far))] = np.nan
    return out


def _sample_by_class(labels: NDArray[Any], size: int, rng: np.random.Generator) -> NDArray[np.intp]:
    """Sorted indices of about ``size`` rows, each class in proportion (two at least)."""
    picks = []
    for c in np.unique(labels):
        idx = np.flatnonzero(labels == c)
        want = max(2, round(len(idx) * size / len(labels)))
        picks.append(rng.choice(idx, want, replace=False) if len(idx) > want else idx)
    return np.sort(np.concatenate(picks))


def _folds(labels: NDArray[Any], k: int, rng: np.random.Generator) -> NDArray[np.int64]:
    """Class-stratified fold number of each shape."""
    fold = np.empty(len(labels), np.int64)
    for c in np.unique(labels):
        idx = np.flatnonzero(labels == c)
        rng.shuffle(idx)
        fold[idx] = (np.arange(len(idx)) + int(rng.integers(k))) % k
    return fold


def fit_metric(
    features: ArrayLike,
    labels: ArrayLike,
    *,
    blocks: Sequence[tuple[str, int]],
    views: ArrayLike | None = None,
    sparse: ArrayLike | None = None,
    fingerprint: str = "",
    regs: Sequence[float] = REGS,
    temperature: float = TEMPERATURE,
    folds: int = 3,
    max_shapes: int = MAX_SHAPES,
    seed: int = 0,
    label: str = "label",
) -> LearnedMetric:
    """Fit block weights on labelled feature vectors, regularisation cross-validated.

    Every shape queries the others. With ``views`` the pairs follow a views store's
    rule (:mod:`query.search.engine`): a sparse-dense pair is as far apart as the nearest
    of the own features and either side's second feature (view or reconstruction)
    against the other's own, other pairs compare their own features; and each dense shape's view is one more
    (sparse) query, so that the weights also learn what a sparse sample of a surface
    keeps. A query never counts its own shape.

    Parameters
    ----------
    features : (n, d) float
        Feature vectors as the distance weighs them (stored features times the
        kernel's Eq. 2 weights).
    labels : (n,)
        Class of each row.
    blocks : sequence of (name, length)
        The vector's blocks (:func:`block_layout`); one weight is fitted per block.
    views : (n, d) float, optional
        Each shape's second feature: a dense shape's sparse view, a sparse cloud's
        reconstruction (its own feature where it has none).
    sparse : (n,) bool, optional
        Shapes that are themselves sparse samples (compared by their views).
    fingerprint : str
        Configuration fingerprint recorded in the metric.
    regs : sequence of float
        Regularisation strengths to try.
    temperature : float
        Softmax sharpness, in units of the median distance.
    folds : int
        Cross-validation folds (class-stratified, by shape).
    max_shapes : int
        Shapes used at most; a larger store is sampled, stratified by class.
    seed : int
        Seed of the folds and of the sample.
    label : str
        Recorded in the metric.

    Returns
    -------
    LearnedMetric
    """
    sizes = [int(n) for _, n in blocks]
    x, y, v, sp = _checked_inputs(features, labels, views, sparse, sizes, label=label)
    if folds < 2:
        raise ConfigError("must be at least 2", source=f"folds={folds}")
    rng = np.random.default_rng(seed)
    if len(x) > max_shapes:
        keep = _sample_by_class(y, max_shapes, rng)
        x, v, y, sp = x[keep], v[keep], y[keep], sp[keep]
    pairs = _pairs(x, v, y, sp, sizes)
    chosen, cv = _cross_validate(pairs, y, rng, folds=folds, regs=regs, temperature=temperature)
    weights = _final_weights(pairs, chosen, temperature)
    n_classes = int(len(np.unique(y)))
    log.info("fit_metric: %d shapes, %d classes, %d view queries; reg %s, weights %s",
             len(x), n_classes, pairs.n_extra, chosen, np.round(weights, 3).tolist())  # fmt: skip
    return LearnedMetric(
        blocks=tuple((str(name), int(s)) for name, s in blocks),
        weights=tuple(float(w) for w in weights), fingerprint=fingerprint, reg=chosen, cv=cv,
        n_shapes=len(x), n_classes=n_classes, n_extra=pairs.n_extra, label=label,
    )  # fmt: skip


def _checked_inputs(
    features: ArrayLike,
    labels: ArrayLike,
    views: ArrayLike | None,
    sparse: ArrayLike | None,
    sizes: Sequence[int],
    *,
    label: str,
) -> tuple[NDArray[np.float64], NDArray[Any], NDArray[np.float64], NDArray[np.bool_]]:
    """Features (n, d), labels (n,), views (n, d) and sparse flags (n,) as arrays.

    Raises :class:`QueryError` on shapes that do not match the blocks, non-finite
    entries, or fewer than two classes of two shapes or more.
    """
    x = np.asarray(features, dtype=np.float64)
    y = np.asarray(labels, dtype=object)
    if x.ndim != 2 or x.shape[1] != sum(sizes) or len(y) != len(x):
        raise QueryError(
            f"expected ({len(y)}, {sum(sizes)}) features and one label per row",
            source=f"features of shape {x.shape}",
        )
    v = x if views is None else np.asarray(views, dtype=np.float64)
    if v.shape != x.shape:
        raise QueryError(f"views must have the features' shape {x.shape}", source="views")
    sp = np.zeros(len(x), bool) if sparse is None else np.asarray(sparse, dtype=bool)
    if sp.shape != (len(x),):
        raise QueryError(f"sparse must be ({len(x)},) booleans", source="sparse")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(v))):
        raise QueryError("features have NaN or inf entries", source="features")
    classes, counts = np.unique(y, return_counts=True)
    if len(classes) < 2 or (counts >= 2).sum() < 2:
        raise QueryError(
            "a metric needs at least two classes with two or more shapes each",
            source=f"label={label!r}",
        )
    return x, y, v, sp


@dataclass(frozen=True)
class _Pairs:
    """Per-block distances of every (query, shape) pair of a fit.

    ``bd`` (q, n, b): the queries' own features against the shapes' own;
    ``alts``: the same with either side's second feature where a pair mixes a
    sparse and a dense side (empty when no pair does); ``same`` / ``exclude``
    (q, n): same class / the query's own shape; ``owner`` (q,): the shape each
    query belongs to (every shape, then the views of dense shapes).
    """

    bd: NDArray[np.float64]
    alts: tuple[NDArray[np.float64], ...]
    same: NDArray[np.bool_]
    exclude: NDArray[np.bool_]
    owner: NDArray[np.intp]
    n_extra: int


def _pairs(
    x: NDArray[np.float64],
    v: NDArray[np.float64],
    y: NDArray[Any],
    sp: NDArray[np.bool_],
    sizes: Sequence[int],
) -> _Pairs:
    """The queries (every shape, then the view of every dense shape that has one) and pairs."""
    n = len(x)
    extra = np.flatnonzero(~sp & np.any(v != x, axis=1))
    owner = np.concatenate([np.arange(n), extra])
    q_sparse = np.concatenate([sp, np.ones(len(extra), bool)])
    own = np.concatenate([x, v[extra]])  # the queries' own features, and their second
    second = np.concatenate([v, v[extra]])  # (a view query has none but itself)
    bd = _block_distances(own, x, sizes)  # (q, n, b)
    # a sparse-dense pair: the nearest of own-own and either side's second feature
    # against the other's own feature (query.search.engine)
    one = q_sparse[:, None] != sp[None, :]
    alts: tuple[NDArray[np.float64], ...] = ()
    if one.any():
        alts = tuple(
            np.where(one[:, :, None], _block_distances(a, b, sizes), bd)
            for a, b in ((own, v), (second, x))
        )
    same = y[owner][:, None] == y[None, :]
    exclude = owner[:, None] == np.arange(n)[None, :]
    return _Pairs(bd, alts, same, exclude, owner, len(extra))


def _cross_validate(
    pairs: _Pairs,
    y: NDArray[Any],
    rng: np.random.Generator,
    *,
    folds: int,
    regs: Sequence[float],
    temperature: float,
) -> tuple[float | None, dict[str, dict[str, float]]]:
    """The regularisation chosen by class-stratified k-fold cross-validation, and the table.

    Each strength's held-out log margins are compared with the default's (paired over
    queries); a strength passes when it beats the default by two standard errors, and
    the most regularised one within one standard error of the best passing one is
    chosen. None when nothing passes. The table maps "default" and each strength to
    its mean held-out ``margin``, its ``gain`` over the default and that gain's ``se``.
    """
    n_blocks = pairs.bd.shape[2]
    fold = _folds(y, folds, rng)
    qfold = fold[pairs.owner]
    held: dict[float | None, list[NDArray[np.float64]]] = {r: [] for r in (None, *regs)}
    for k in range(folds):
        train = fold != k
        tq = qfold != k
        hq = qfold == k
        sub = pairs.bd[tq][:, train]
        for r in held:
            w = (
                np.ones(n_blocks)
                if r is None
                else _nca_weights(
                    sub,
                    pairs.same[tq][:, train],
                    pairs.exclude[tq][:, train],
                    r,
                    temperature,
                    tuple(alt[tq][:, train] for alt in pairs.alts),
                )
            )
            held[r].append(
                _log_margins(
                    pairs.bd[hq],
                    w,
                    pairs.same[hq],
                    pairs.exclude[hq],
                    tuple(alt[hq] for alt in pairs.alts),
                )
            )
    margins = {r: np.concatenate(m) for r, m in held.items()}
    ok = np.isfinite(margins[None])
    for m in margins.values():
        ok &= np.isfinite(m)
    cv: dict[str, dict[str, float]] = {}
    stats: dict[float, tuple[float, float]] = {}
    for r, m in margins.items():
        diff = m[ok] - margins[None][ok]
        se = float(diff.std(ddof=1) / np.sqrt(len(diff))) if len(diff) > 1 else float("inf")
        cv["default" if r is None else f"{r:g}"] = {
            "margin": float(m[ok].mean()) if ok.any() else float("nan"),
            "gain": float(diff.mean()) if ok.any() else 0.0,
            "se": se,
        }
        if r is not None and ok.any():
            stats[r] = (float(diff.mean()), se)
    passed = [r for r, (gain, se) in stats.items() if gain < -2 * se]
    if not passed:
        return None, cv
    best = min(passed, key=lambda r: stats[r][0])
    within = [r for r in passed if stats[r][0] <= stats[best][0] + stats[best][1]]
    return max(within), cv  # the most regularised of the near-best


def _final_weights(pairs: _Pairs, chosen: float | None, temperature: float) -> NDArray[np.float64]:
    """Block weights fitted on all pairs at strength ``chosen`` (ones when None).

    Scaled so that shapes of different classes lie as far apart (median) as under
    the default, which keeps the similarity ``exp(-lam d)`` calibrated.
    """
    n_blocks = pairs.bd.shape[2]
    weights = np.ones(n_blocks)
    if chosen is None:
        return weights
    weights = _nca_weights(pairs.bd, pairs.same, pairs.exclude, chosen, temperature, pairs.alts)
    other = ~pairs.same & ~pairs.exclude
    before = _pair_distances(pairs.bd, pairs.alts, np.ones(n_blocks))[other]
    after = _pair_distances(pairs.bd, pairs.alts, weights)[other]
    weights *= np.median(before) / max(np.median(after), 1e-300)
    return weights


def fit_store_metric(db: StoreHandle, *, label: str = "label", **options: Any) -> LearnedMetric:
    """``db.fit_metric``: :func:`fit_metric` on a store's labelled shapes.

    In a store with sparse views (``CloudConfig.view_cells``) the pairs follow the
    search's rule and each dense shape's view is one more query (see
    :func:`fit_metric`). A store with more than ``max_shapes`` labelled shapes is
    sampled by class before any feature is read. ``options`` go to :func:`fit_metric`
    (``regs``, ``temperature``, ``folds``, ``max_shapes``, ``seed``).
    """
    from query.learn.labels import stored_labels
    from shapedb.signature.kernel import weights as kernel_weights

    ids, labels = stored_labels(db, label)
    keep = np.array([v is not None for v in labels], bool)
    ids, labels = ids[keep], labels[keep]
    max_shapes = int(options.get("max_shapes", MAX_SHAPES))
    if len(ids) > max_shapes:
        pick = _sample_by_class(labels, max_shapes, np.random.default_rng(options.get("seed", 0)))
        ids, labels = ids[pick], labels[pick]
    config = db.config
    views_kept = bool(config.cloud.view_cells)
    columns = ["id", "feature", "view_feature"] if views_kept else ["id", "feature"]
    table = db.store.shapes(columns, ids=ids.tolist())
    found = table.column("id").to_numpy()
    pos = np.searchsorted(ids, found)  # a commit may have deleted some meanwhile
    labels = labels[pos]
    w = np.asarray(kernel_weights(config), np.float64)
    feats = np.asarray(table.column("feature").to_pylist(), np.float64).reshape(len(found), -1)
    views = sparse = None
    if views_kept:
        own = table.column("feature").to_pylist()
        views = (
            np.asarray(
                [
                    o if v is None else v
                    for o, v in zip(own, table.column("view_feature").to_pylist(), strict=True)
                ],
                np.float64,
            ).reshape(len(found), -1)
            * w
        )
        sparse = np.isin(found, db.store.sparse_ids())
    return fit_metric(
        feats * w,
        labels,
        blocks=block_layout(config),
        views=views,
        sparse=sparse,
        fingerprint=config.fingerprint,
        label=label,
        **options,
    )
