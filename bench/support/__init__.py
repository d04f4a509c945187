"""Code the benchmarks and the studies share; nothing here is a benchmark of its own.

The baselines (:mod:`bench.support.baselines`: D2, spherical harmonics, surface
sampling; :mod:`bench.support.lightfield`: the mesh light field descriptor), the
feature matrices (:mod:`bench.support.features`), cached decompositions
(:mod:`bench.support.cached`), the facade's live cost (:mod:`bench.support.cost`), and
the light field stage's stores and scoring (:mod:`bench.support.stores`, with the
field vectors, packings and field insides they read). :mod:`bench.support.inside_fields`
also fills its cache from the command line (``python -m bench.support.inside_fields``).
"""
