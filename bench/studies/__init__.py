"""Finished research on shapedb: each module is still runnable as ``python -m bench.studies.NAME``.

What each study found, and why its idea was or was not kept, is summarised in
``docs/studies.md``; results are written to ``bench/results/studies/``. Studies may
import the product benchmarks (``bench.retrieval``, ``bench.common``,
``bench.support``, ...), never the other way round.
"""
