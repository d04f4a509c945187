"""Benchmarks of shapedb: what a user runs to measure the product (``python -m bench.NAME``).

Each prints a table with its baseline measured in the same run and writes JSON under
``bench/results/``:

- ``retrieval``: the paper's Tables 2 and 3 on real and generated sets, with baselines.
- ``representations``: sparse scans and clouds against meshes; ``--cost``: live query cost.
- ``rerank``: the default re-ranking stage per set, against the descriptor and the mesh LFD.
- ``stability``: transformed copies finding their originals, against D2.
- ``metric``: a similarity learned on a labelled store, on held-out splits.
- ``classify``, ``classify_curves``: graph CNNs on the contact graph; learning curves.
- ``parts``, ``substructure``: part matching; corpus part search latency and recall.
- ``query``: retrieval at scale, faiss with exact re-rank against brute force.
- ``ingest``, ``mdbd``: ingest throughput; seconds per decomposition stage.
- ``concurrency``, ``serve``: readers during writes; ``shapedb serve`` over HTTP.

``bench.common`` holds their shared helpers; ``bench.sets`` the data sets and their
generators; ``bench.support`` the code the benchmarks and the studies share; finished
research is in ``bench.studies``.
"""
