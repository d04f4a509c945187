"""Benchmarks of shapedb: retrieval tables, baselines and descriptor prototypes."""
