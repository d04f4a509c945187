"""The public result types of the :class:`~query.database.Database` facade, in one place.

Every operation of the facade returns one of these (or an Arrow table): small frozen
dataclasses with ``to_dict()`` for JSON. They are defined here, in the core, so that the
facade can name them; the stages that build them (``ingest``, ``query``) import them from
here and re-export them where they were defined before.

* :class:`IngestReport`: what ``db.ingest`` did.
* :class:`StoreInfo`: what ``db.info`` summarises (a JSON-ready dict).
* :class:`Hit`: one shape found by ``db.search``.
* :class:`PartMatch`: one part found by ``db.match``.
* :class:`RetrievalScores`: what ``db.evaluate`` measured.
* :class:`Classification`: the class ``db.classify`` predicts.

Two results carry behaviour that lives downstream (a learned similarity, a trained
network); the facade types them by what a caller may rely on:

* :class:`Metric`: what ``db.fit_metric`` returns (``query.learn.metric.LearnedMetric``).
* :class:`Classifier`: what ``db.train_classifier`` returns
  (``query.learn.classify.ShapeClassifier``).

The type aliases :data:`ShapeRef`, :data:`SearchQuery`, :data:`PartQuery`,
:data:`ModelInput` and :data:`IngestInputs` name what the facade's methods accept.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, TypeAlias, TypedDict, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from shapedb.errors import require

if TYPE_CHECKING:
    from shapedb.geometry.base import Geometry
    from shapedb.mdbd.decomposition import Decomposition
    from shapedb.mdbd.graph import ContactGraph
    from shapedb.store.schema import ShapeRecord

__all__ = [
    "jsonable",
    "IngestReport",
    "StoreInfo",
    "FailureInfo",
    "Hit",
    "PartMatch",
    "RetrievalScores",
    "Classification",
    "Metric",
    "Classifier",
    "MEASURES",
    "ShapeRef",
    "SearchQuery",
    "PartQuery",
    "ModelInput",
    "IngestInputs",
]

#: The PSB measures of :class:`RetrievalScores`, in table order.
MEASURES = ("nn", "first_tier", "second_tier", "e_measure", "dcg")

#: A shape: a stored id (int) or name (str), a model file, or an in-memory shape.
ShapeRef: TypeAlias = "int | str | os.PathLike[str] | Geometry | Decomposition | ShapeRecord"
#: What ``db.search`` looks for: a shape, or a feature vector (d,) of the store's kind.
SearchQuery: TypeAlias = "ShapeRef | NDArray[np.floating[Any]] | Sequence[float]"
#: What ``db.match`` takes a part of: a shape, or a contact graph.
PartQuery: TypeAlias = "ShapeRef | ContactGraph"
#: One input of ``db.ingest``: a file or folder, a shape, ``(name, shape)`` or
#: ``(name, label, shape)``.
ModelInput: TypeAlias = (
    "str | os.PathLike[str] | Geometry | tuple[str, Geometry] | tuple[str, str | None, Geometry]"
)
#: The inputs of ``db.ingest``: one input, several, or ``{name: shape}``.
IngestInputs: TypeAlias = "ModelInput | Iterable[ModelInput] | Mapping[str, Geometry]"


@dataclass(frozen=True)
class IngestReport:
    """What an ingest did, with one outcome for every input it was given.

    Attributes
    ----------
    ingested : tuple[int, ...]
        Ids of the shapes added, in input order.
    skipped : tuple[str, ...]
        Inputs left unchanged: their content is already stored (by an earlier run, or
        by an identical input of this run), in input order.
    failed : tuple[tuple[str, str], ...]
        ``(input, reason)`` of every input that could not be ingested, in input order;
        identical failing files each appear.
    seconds : float
        Wall time.
    notes : tuple[tuple[str, str], ...]
        ``(input, note)`` of inputs stored with a caveat, e.g. a mesh file with
        vertices and no faces, stored as a point cloud.
    ignored : tuple[tuple[str, str], ...]
        ``(path, why)`` of what walking a folder left out: hidden files and folders,
        companion files (textures, materials...), files of no supported type.
    outcomes : tuple[tuple[str, str, str], ...]
        ``(input, outcome, detail)`` for every input, in input order, then every
        ignored path: ``outcome`` is one of :data:`OUTCOMES`; ``detail`` is the id
        (stored), why (unchanged, ignored) or the reason (failed).
    labels_matched : int or None
        Inputs that took their label from the labels given, or None without labels.

    Every path in a report is valid text: bytes of a file name that are not UTF-8
    appear as ``\\xNN`` escapes.
    """

    OUTCOMES = ("stored", "unchanged", "failed", "ignored")

    ingested: tuple[int, ...] = ()
    skipped: tuple[str, ...] = ()
    failed: tuple[tuple[str, str], ...] = ()
    seconds: float = 0.0
    notes: tuple[tuple[str, str], ...] = ()
    ignored: tuple[tuple[str, str], ...] = ()
    outcomes: tuple[tuple[str, str, str], ...] = ()
    labels_matched: int | None = None

    @property
    def unchanged(self) -> tuple[str, ...]:
        """Inputs whose content is already stored (the same as :attr:`skipped`)."""
        return self.skipped

    def counts(self) -> dict[str, int]:
        """How many inputs ended in each outcome: ``{"stored": n, "unchanged": n, ...}``."""
        out = dict.fromkeys(self.OUTCOMES, 0)
        for _, outcome, _ in self.outcomes:
            out[outcome] += 1
        return out

    def to_dict(self) -> dict[str, Any]:
        """``{"ingested": n, "skipped": n, "failed": [{"path", "error"}], "notes": [...]}``."""
        return {
            "ingested": len(self.ingested),
            "skipped": len(self.skipped),
            "failed": [{"path": p, "error": e} for p, e in self.failed],
            "notes": [{"path": p, "note": n} for p, n in self.notes],
        }

    def __repr__(self) -> str:
        ignored = f", ignored={len(self.ignored)}" if self.ignored else ""
        return (
            f"IngestReport(ingested={len(self.ingested)}, skipped={len(self.skipped)}, "
            f"failed={len(self.failed)}{ignored}, seconds={self.seconds:.1f})"
        )


class FailureInfo(TypedDict):
    """One input that could not be ingested: its path and ``"<error type>: <message>"``."""

    path: str
    error: str


class StoreInfo(TypedDict):
    """Summary of a store (``db.info()``), JSON-ready.

    Keys
    ----
    shapes : int
        Number of shapes.
    labels : dict[str, int]
        Each label and its count (unlabelled shapes are not counted), sorted by label.
    failures : list of FailureInfo
        Every input that failed, as it stands now.
    config : dict
        The store's configuration, ``Config.to_dict()``.
    """

    shapes: int
    labels: dict[str, int]
    failures: list[FailureInfo]
    config: dict[str, Any]


@dataclass(frozen=True)
class Hit:
    """One search result.

    Attributes
    ----------
    id : int
        Stored shape id.
    name : str
        Stored shape name.
    label : str or None
        Class label, if any.
    similarity : float
        Whole path: the Eq. 3 kernel value ``exp(-lam * distance)``, in (0, 1]. Partial
        path: how much of the query the shape holds, in (0, 1]
        (:mod:`query.parts.partial`). View path: ``exp(-distance / VIEW_UNIT)``
        (:mod:`query.search.view_search`).
    distance : float
        Whole path: the Eq. 2 weighted L1 distance between the query's and the shape's
        features. Partial path: ``-log(similarity) / lam`` with the part kernel's ``lam``.
        View path: the L1 distance of the scan's silhouette features to the shape's
        nearest view.
    path : str
        The search that found it: ``"whole"`` (the whole-shape features),
        ``"partial"`` (the query's parts against the store's part index) or ``"view"``
        (a one-sided scan's silhouette against the stored light fields' views).
    """

    id: int
    name: str
    label: str | None
    similarity: float
    distance: float
    path: str = "whole"

    def to_dict(self) -> dict[str, Any]:
        """``{"id", "name", "label", "similarity", "distance", "path"}``, JSON-ready."""
        return asdict(self)


@dataclass(frozen=True)
class PartMatch:
    """One matched part.

    Attributes
    ----------
    id : int or None
        Stored shape id of the match (None for an unstored model).
    name : str or None
        Its name.
    label : str or None
        Its class label.
    similarity : float
        Eq. 3, ``exp(-lam * distance)`` of the two part vectors, in (0, 1].
    nodes : tuple of int
        N(u, K) in the matched shape.
    query_nodes : tuple of int
        N(v, K) in the query (all nodes when the whole query model is the part).
    node : int
        Centre u of the matched neighbourhood.
    query_node : int
        Centre v of the query neighbourhood (-1 for a whole-model query).
    distance : float
        Part distance: Eq. 2 plus the size/centre blocks (weighted L1).
    """

    id: int | None
    name: str | None
    label: str | None
    similarity: float
    nodes: tuple[int, ...]
    query_nodes: tuple[int, ...]
    node: int = -1
    query_node: int = -1
    distance: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict: ``{"id", "name", "label", "similarity", "nodes", ...}``."""
        d = asdict(self)
        d["nodes"], d["query_nodes"] = list(self.nodes), list(self.query_nodes)
        return d


@dataclass(frozen=True)
class RetrievalScores:
    """PSB measures of a leave-one-out retrieval run.

    Attributes
    ----------
    queries : int
        Number of queries scored (labelled shapes in classes of two or more).
    nn, first_tier, second_tier, e_measure, dcg : float
        Means over the queries.
    per_class : dict[str, dict[str, float]]
        For each class: ``{"queries", "nn", "first_tier", "second_tier",
        "e_measure", "dcg"}``.
    recall : (L,) float64
        Standard recall levels.
    precision : (L,) float64
        Mean interpolated precision at each level.
    per_query : dict[str, (q,) ndarray]
        Row index of each scored query (``"index"``) and its value of each measure.
    """

    queries: int
    nn: float
    first_tier: float
    second_tier: float
    e_measure: float
    dcg: float
    per_class: dict[str, dict[str, float]]
    recall: NDArray[np.float64] = field(repr=False)
    precision: NDArray[np.float64] = field(repr=False)
    per_query: dict[str, NDArray[Any]] = field(repr=False, default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """``{"queries", "nn", "first_tier", "second_tier", "e_measure", "dcg", "per_class"}``."""
        out: dict[str, Any] = {"queries": self.queries}
        out.update({m: float(getattr(self, m)) for m in MEASURES})
        out["per_class"] = {c: dict(v) for c, v in self.per_class.items()}
        return out

    def plot(self, path: str | os.PathLike[str], *, title: str | None = None) -> Path:
        """Save the precision-recall curve as a PNG (matplotlib, Agg backend).

        Raises
        ------
        MissingDependencyError
            When matplotlib is not installed.
        """
        require("matplotlib", extra="plot", feature="the precision-recall plot")
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        fig = Figure(figsize=(5, 4), dpi=120)  # no pyplot: no global backend, thread-safe
        FigureCanvasAgg(fig)
        ax = fig.add_subplot()
        ax.plot(self.recall, self.precision, marker="o")
        ax.set(xlabel="recall", ylabel="precision", xlim=(0, 1), ylim=(0, 1.02))
        ax.set_title(title or f"precision-recall ({self.queries} queries)")
        ax.grid(True, alpha=0.3)
        out = Path(path)
        fig.savefig(out, format="png", bbox_inches="tight")
        return out


@dataclass(frozen=True)
class Classification:
    """The predicted class of one shape.

    Attributes
    ----------
    label : str
        Most probable class.
    probability : float
        Its probability.
    probabilities : dict[str, float]
        Every class and its probability, most probable first.
    source : str or None
        The classified input (path, shape name or id).
    """

    label: str
    probability: float
    probabilities: dict[str, float] = field(default_factory=dict)
    source: str | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-serialisable form (for ``shapedb classify --json``)."""
        return {
            "source": self.source,
            "label": self.label,
            "probability": self.probability,
            "probabilities": self.probabilities,
        }


@runtime_checkable
class Metric(Protocol):
    """A similarity learned on a store's labels (``query.learn.metric.LearnedMetric``).

    Block weights on the store's L1 feature distance; ``db.search``, ``db.sql`` and
    ``db.evaluate`` take it (or the path it was saved to) as ``metric=``.
    """

    @property
    def blocks(self) -> tuple[tuple[str, int], ...]:
        """Block names and lengths, in feature order."""

    @property
    def weights(self) -> tuple[float, ...]:
        """One multiplier per block; all ones when :attr:`learned` is False."""

    @property
    def fingerprint(self) -> str:
        """``Config.fingerprint`` of the store it was fitted on."""

    @property
    def reg(self) -> float | None:
        """The regularisation chosen by cross-validation; None for the identity."""

    @property
    def n_shapes(self) -> int:
        """Labelled shapes the fit used."""

    @property
    def n_classes(self) -> int:
        """Classes among them."""

    @property
    def n_extra(self) -> int:
        """Sparse views of those shapes that were queries too."""

    @property
    def learned(self) -> bool:
        """False for the identity (cross-validation found no gain)."""

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write it as JSON; returns the path."""

    def to_dict(self) -> dict[str, Any]:
        """JSON-serialisable form."""


@runtime_checkable
class Classifier(Protocol):
    """A trained classifier (``query.learn.classify.ShapeClassifier``: k-NN, linear, boosting or a
    graph CNN, chosen on validation)."""

    classes_: list[str]
    test_accuracy_: float

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the model and its settings; returns the path."""


def jsonable(x: Any) -> Any:
    """``x`` with numpy values, paths and dates made JSON-serialisable (non-finite -> null)."""
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, (str, int, float, bool)) or x is None:
        return x
    if hasattr(x, "tolist"):
        return jsonable(x.tolist())
    if hasattr(x, "isoformat"):
        return x.isoformat()
    return str(x)
