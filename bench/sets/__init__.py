"""The bench's data sets and their generators.

:mod:`bench.sets.datasets` is the registry (``capod``, ``articulated``, ``parts``,
``generic``, ``web``, ``webplus``, ``enclosures``, ``people``, and the splits, clouds and
meshes of each); the generated sets are built by :mod:`bench.sets.generic_shapes`,
:mod:`bench.sets.web_shapes` and :mod:`bench.sets.webplus_shapes` (both assembled by
:mod:`bench.sets.assembly`, their kinds' builders in ``web_*`` and ``webplus_*``),
:mod:`bench.sets.enclosures` (builders in :mod:`bench.sets.enclosure_shapes`),
:mod:`bench.sets.people` (articulated people) from the parts of :mod:`bench.sets.mesh_parts`.
"""
