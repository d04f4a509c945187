"""Learning from a labelled store: a similarity metric and shape classifiers.

:func:`fit_store_metric` learns one weight per descriptor block (``db.fit_metric``);
:func:`train_classifier` chooses a classifier on validation among descriptor models and
the paper's graph CNN (``db.train_classifier``); torch is imported only when a graph
model is trained or used.
"""

from __future__ import annotations

from query.learn.classify import ShapeClassifier, train_classifier
from query.learn.metric import LearnedMetric, fit_metric, fit_store_metric

__all__ = [
    "LearnedMetric",
    "fit_metric",
    "fit_store_metric",
    "ShapeClassifier",
    "train_classifier",
]
