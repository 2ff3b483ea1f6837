"""The 6-d road-style code of the condition vector: six named structure measures, standardised.

The paper leaves the style code open. We use a fixed, hand-chosen mapping rather than a learned
embedding (e.g. PCA fitted on the training tiles): every component has a name and a unit, a user
can read and set it, it does not change when the training data change, and it needs no data file
in the package. The six measures are ones the five priors do not already cover (hierarchy,
dead ends, how much of the map is built up, block regularity and scale; cycle ratio and the
four-way share were dropped for correlating at |r| >= 0.8 with the dead-end ratio and with
gridness on the training tiles). Each is centred and scaled by its mean and standard deviation
over the v1 training crops, so a code of 0 is a typical real tile and ±1 one deviation.
"""

from __future__ import annotations

import math

import networkx as nx
import numpy as np

from .. import metrics
from ..roadgraph import edge_length, merge_degree2
from .tiles import coverage

STYLE_FEATURES = (
    "arterial_share",    # share of road length that is arterial (motorway, trunk, primary)
    "collector_share",   # share of road length that is collector (secondary, tertiary)
    "dead_end_ratio",    # share of road nodes of degree 1 (metrics.dead_end_ratio)
    "coverage",          # share of 100 m cells within 50 m of a road (tiles.coverage)
    "link_length_cv",    # coefficient of variation of the road lengths between road nodes
    "log_link_length",   # log10 of their mean (m): the block scale
)
STYLE_DIM = len(STYLE_FEATURES)

#: Mean and standard deviation of each feature over the 586 unrotated v1 training crops
#: (``bench/prepare_data.py --calibrate`` prints them).
STYLE_MEAN = np.array([0.126, 0.141, 0.320, 0.664, 0.940, 2.094])
STYLE_STD = np.array([0.114, 0.075, 0.097, 0.119, 0.221, 0.128])
STYLE_CLIP = 4.0


def link_lengths(G: nx.Graph) -> np.ndarray:
    """Lengths (m) of the roads between road nodes: chains through degree-2 nodes joined."""
    H = merge_degree2(G.copy())
    return np.array([edge_length(H, u, v) for u, v in H.edges])


def style_features(G: nx.Graph) -> np.ndarray:
    """The six raw measures named in ``STYLE_FEATURES`` (0 where a measure is undefined)."""
    by_class = {"arterial": 0.0, "collector": 0.0, "local": 0.0}
    for u, v, cls in G.edges(data="road_class"):
        by_class[cls] += edge_length(G, u, v)
    total = sum(by_class.values())
    links = link_lengths(G)
    mean = float(links.mean()) if len(links) else 0.0
    return np.array([
        by_class["arterial"] / total if total else 0.0,
        by_class["collector"] / total if total else 0.0,
        metrics.dead_end_ratio(G),
        coverage(G),
        float(links.std()) / mean if mean > 0 else 0.0,
        math.log10(max(mean, 1.0)),
    ])


def style_code(G: nx.Graph) -> np.ndarray:
    """Standardised style features, clipped to ±4: the first six numbers of c."""
    z = (style_features(G) - STYLE_MEAN) / STYLE_STD
    return np.clip(z, -STYLE_CLIP, STYLE_CLIP).astype(np.float32)
