"""How configurations stored by older versions of shapedb read today.

The one place that knows earlier layouts: :class:`~shapedb.config.core.Config` and
:class:`~shapedb.config.core.PartConfig` hand every stored dict to :func:`upgrade_config`
/ :func:`upgrade_part_config` and build today's objects from what comes back. The
functions work on plain dicts (they import nothing of shapedb) and never change their
argument.

Store configuration layouts (``Config.to_dict()``):

* **1** (no ``layout`` key): ``{"mdbd": {...}, "kernel": {...}}``, the kernel section
  flat: the Eq. 1-3 fields and ``method``, plus ``descriptor`` (the descriptor's
  version), ``view_cells``, ``reconstruct`` and ``reconstruct_depth`` (the sparse-cloud
  policy), each added over time.
* **2**: ``{"layout": 2, "mdbd", "kernel", "descriptor": {"version"}, "cloud"}``.
* **3**: layout 2 plus ``"rerank"`` (how a search re-ranks, ``RerankConfig``); a store of
  an earlier layout searched without a re-ranking stage (:data:`SECTIONS_ADDED`).
* **4**: layout 3 plus ``"light_field"`` and ``"lf_fusion"`` (``LightFieldConfig``, and
  the stage's fusion numbers: the light fields a store with the ``"lightfield"`` scorer
  keeps per record, and that scorer's fusion); a store of an earlier layout kept no light
  fields and reads both sections at today's defaults for the product (64 px, 3 light
  fields, silhouettes only).
* **5**: layout 4 plus ``"field_vector"`` (``FieldVectorConfig``: the depth buffers and
  spherical harmonics of the field's inside a store keeps per record); a store of an
  earlier layout kept none (``enabled`` False), and its ``lf_fusion`` section, stored or
  not, reads the field vector's fusion fields off (weights 0, no field candidates).
* **6**: layout 5 without ``"lf_fusion"`` and with ``"rerank"`` holding ``scorer`` alone:
  the stage's numbers are constants of the code (``query.search.tuning``), not options.
  An older store's ``lf_fusion`` and its other ``rerank`` fields are dropped: it searches
  with today's stage. A store of the retired ``"adaptive"`` scorer (an opt-in that lost on
  some set) reads ``"none"``: its stored vectors, ranked by the descriptor alone.
* **7**: layout 6 plus ``"surface_words"`` (``SurfaceWordsConfig``: the bag of local
  surface features a store keeps per record); a store of an earlier layout kept none
  (``enabled`` False).
* **8**: layout 7 plus ``surface_words.view_words`` (the view words a store keeps per record,
  :mod:`shapedb.signature.view_words`); a store of an earlier layout kept none (False).

Part-index configuration layouts (``PartConfig.to_dict()``):

* **1** (no ``layout`` key): flat ``hops, n_r, t, w, la, lb, lam`` and, added later,
  ``size``, ``centre``, ``contact_tol_cells``.
* **2**: ``{"layout": 2, "hops", "kernel": {...}, "size", "centre", "contact_tol_cells"}``.

A field a stored section predates takes the value that reproduces what built the store
(:data:`ADDED`, :data:`STORED_ADDED`, :data:`PART_ADDED`); a section not stored at all takes
today's defaults (the upgraded dict leaves it out), but for :data:`ADDED`'s values. Layout 4
stores wrote ``lf_fusion`` before its fields ``pool`` and ``contrast_floor``: such a section
read ``pool`` 0 and no floor (the gate it searched with) until layout 6 dropped the section.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

__all__ = [
    "LAYOUT",
    "PART_LAYOUT",
    "ADDED",
    "STORED_ADDED",
    "SECTIONS_ADDED",
    "DROPPED",
    "RETIRED_SCORERS",
    "PART_ADDED",
    "upgrade_config",
    "upgrade_part_config",
    "part_fingerprint_fields",
    "mdbd_fingerprint_fields",
    "MDBD_UNHASHED",
]

#: The layout :meth:`Config.to_dict` writes.
LAYOUT = 8
#: The layout :meth:`PartConfig.to_dict` writes.
PART_LAYOUT = 2

#: Per section of a store configuration, fields added after stores were first written,
#: and the value a stored section without the field was built with.
ADDED: dict[str, dict[str, Any]] = {
    # before tie_rule, the packing took the first tied cell (C order); before
    # sheet_cells, sheets and flat meshes were never thickened (they failed); before
    # sheet_rule, only whole models were (sheets beside a solid had no inside)
    "mdbd": {"tie_rule": "first", "sheet_cells": 0.0, "sheet_rule": "whole"},
    # before method, the only feature was the paper's Eq. 1 vector
    "kernel": {"method": "paper"},
    # before versions, the descriptor was version 1
    "descriptor": {"version": 1},
    # before each field: no sparse views, no reconstructions, Poisson depth 8
    "cloud": {"view_cells": 0.0, "reconstruct": False, "reconstruct_depth": 8},
    # before the section: no re-ranking stage
    "rerank": {"scorer": "none"},
    # before the section no light fields were stored: the product's light fields (a
    # stored section without n_balls: STORED_ADDED); before the fills, silhouettes were
    # the plain union of the discs
    "light_field": {
        "n_fields": 3,
        "resolution": 64,
        "depth_weight": 0.0,
        "edges": False,
        "dilate_px": 0.0,
        "close_px": 0,
        "n_balls": 2048,
        "source": "balls",
        "centre": "volume",
        "framing": "sphere",
    },
    "field_vector": {"enabled": False},
    "surface_words": {"enabled": False, "view_words": False},
}

#: Fields added to a section after stores first wrote that section, and the value that
#: reproduces what a stored section without them did. Unlike :data:`ADDED`, only a
#: stored section takes them: a section the layout predates keeps today's defaults.
STORED_ADDED: dict[str, dict[str, Any]] = {
    # before n_balls, the light fields were those of the decomposition's balls; before
    # source, always of balls; before centre, the field was seen about its volume centroid;
    # before framing, every view spanned the unit disc about that centre
    "light_field": {"n_balls": 0, "source": "balls", "centre": "volume", "framing": "sphere"},
    # before view_words, no view words were kept
    "surface_words": {"view_words": False},
}

#: Sections added to the store configuration, by the first layout that writes them:
#: a configuration of an earlier layout gets the section with the values of
#: :data:`ADDED` (what its store did), never today's defaults.
SECTIONS_ADDED: dict[str, int] = {
    "rerank": 3,
    "light_field": 4,
    "field_vector": 5,
    "surface_words": 7,
}

#: Sections and fields layout 6 no longer stores: the stage's numbers, now constants.
DROPPED: dict[str, tuple[str, ...]] = {
    "lf_fusion": (),  # the whole section
    "rerank": ("candidates", "neighbours", "power", "weight", "block", "ratio"),
}
#: Scorers a store may have been written with that read as another today.
RETIRED_SCORERS: dict[str, str] = {"adaptive": "none"}

#: Decomposition fields added after ``Config.fingerprint`` was first stored, and the
#: value at which the fingerprint leaves them out, so that stores written before each
#: field keep the fingerprint their rows carry.
MDBD_UNHASHED: dict[str, Any] = {"sheet_cells": 0.0, "sheet_rule": "whole"}

#: Part-index configuration fields added after part indexes were first written, and
#: the values that reproduce what those indexes hold (the paper's Eq. 1 vector alone
#: on the decomposition's own contact graph).
PART_ADDED: dict[str, Any] = {"size": 0.0, "centre": 0.0, "contact_tol_cells": 0.0}

_KERNEL_FIELDS = ("n_r", "t", "w", "la", "lb", "lam", "method")
_CLOUD_FIELDS = ("view_cells", "reconstruct", "reconstruct_depth")


def upgrade_config(data: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """A stored store configuration of any layout as today's sections.

    Parameters
    ----------
    data : mapping
        What ``Config.to_dict()`` of some version wrote (parsed JSON).

    Returns
    -------
    dict
        ``{section: {field: value}}`` for the sections ``mdbd``, ``kernel``,
        ``descriptor``, ``cloud``, ``rerank``, ``light_field``, ``lf_fusion``,
        ``field_vector``, ``surface_words`` that ``data`` stores (without ``layout``),
        and the sections its layout predates (:data:`SECTIONS_ADDED`); fields a stored
        section predates are filled in from :data:`ADDED` and :data:`STORED_ADDED`. Unknown keys are
        passed on, for the caller to refuse.
    """
    data = dict(data)
    layout = data.pop("layout", 1)
    if layout == 1:
        sections = _layout1_sections(data)
    else:
        sections = {name: dict(section) for name, section in data.items()}
    for name, later in STORED_ADDED.items():
        if isinstance(sections.get(name), dict):
            for key, legacy in later.items():
                sections[name].setdefault(key, legacy)
    for name, first in SECTIONS_ADDED.items():
        if layout < first and name not in sections:
            sections[name] = {}
    for name, section in sections.items():
        if isinstance(section, dict):
            for key, legacy in ADDED.get(name, {}).items():
                section.setdefault(key, legacy)
    return _drop_retired(sections)


def _drop_retired(sections: dict[str, Any]) -> dict[str, Any]:
    """Layout 6: the sections and fields of :data:`DROPPED` left out, retired scorers mapped."""
    for name, keys in DROPPED.items():
        if name not in sections:
            continue
        if not keys:
            sections.pop(name)
        elif isinstance(sections[name], dict):
            for key in keys:
                sections[name].pop(key, None)
    rerank = sections.get("rerank")
    if isinstance(rerank, dict) and rerank.get("scorer") in RETIRED_SCORERS:
        rerank["scorer"] = RETIRED_SCORERS[rerank["scorer"]]
    return sections


def _layout1_sections(data: dict[str, Any]) -> dict[str, Any]:
    """Layout 1: the descriptor version and the cloud policy inside a flat kernel section.

    An empty section counts as not stored.
    """
    sections = {
        name: dict(section) if isinstance(section, Mapping) else section
        for name, section in data.items()
        if section
    }
    kernel = sections.pop("kernel", None)
    if isinstance(kernel, Mapping):
        kernel = dict(kernel)
        sections["descriptor"] = (
            {"version": kernel.pop("descriptor")} if "descriptor" in kernel else {}
        )
        sections["cloud"] = {k: kernel.pop(k) for k in _CLOUD_FIELDS if k in kernel}
        sections["kernel"] = kernel  # what is left: the kernel's own fields, or unknowns
    elif kernel is not None:
        sections["kernel"] = kernel
    return sections


def upgrade_part_config(data: Mapping[str, Any]) -> dict[str, Any]:
    """A stored part-index configuration of any layout in today's layout.

    Returns
    -------
    dict
        ``{"hops", "kernel": {...}, "size", "centre", "contact_tol_cells"}`` (only the
        fields stored, with :data:`PART_ADDED` filled in; without ``layout``). Layout 1
        kernels were always the paper's (``method="paper"``).
    """
    data = dict(data)
    layout = data.pop("layout", 1)
    if layout == 1:
        kernel = {k: data.pop(k) for k in _KERNEL_FIELDS if k in data}
        kernel["method"] = "paper"
        data["kernel"] = kernel
        for key, legacy in PART_ADDED.items():
            data.setdefault(key, legacy)
    return data


def part_fingerprint_fields(data: Mapping[str, Any]) -> dict[str, Any]:
    """The flat dict a part configuration's fingerprint hashes.

    Part-index directories are named by this fingerprint; hashing the fields flat, as
    layout 1 stored them (the kernel's fields beside the part's own, without the
    always-"paper" ``method``), keeps the names of indexes already on disk.

    Parameters
    ----------
    data : mapping
        ``PartConfig`` as a dict of today's layout (``dataclasses.asdict``).
    """
    flat = {k: v for k, v in data.items() if k not in ("kernel", "layout")}
    flat.update({k: v for k, v in dict(data["kernel"]).items() if k != "method"})
    return flat


def mdbd_fingerprint_fields(data: Mapping[str, Any]) -> dict[str, Any]:
    """The dict a store configuration's fingerprint hashes: its ``MDBDConfig`` fields.

    Fields in :data:`MDBD_UNHASHED` are left out at their legacy value, so a store
    written before such a field existed (its rows carry the old fingerprint) keeps it.

    Parameters
    ----------
    data : mapping
        ``MDBDConfig`` as a dict (``dataclasses.asdict``).
    """
    return {k: v for k, v in data.items() if not (k in MDBD_UNHASHED and v == MDBD_UNHASHED[k])}
