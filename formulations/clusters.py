"""Independent clusters of a packing problem.

Two hypotheses interact only through a shared resource, so the connected components
of the hypothesis-resource graph are independent subproblems.  Because the total K
is the sum of the clusters' k, the best score per K is the max-plus convolution of
the clusters' tables and the total mass per K their sum-product convolution
(:mod:`mapassoc.formulations.cardinality`).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray
from scipy.sparse.csgraph import connected_components

from mapassoc.formulations.packing import PackingProblem

__all__ = ["cluster_hypotheses"]


def cluster_hypotheses(problem: PackingProblem) -> list[NDArray[np.int64]]:
    """Hypothesis indices of each connected component, in order of their smallest index.

    Parameters
    ----------
    problem : PackingProblem

    Returns
    -------
    list of ndarray of int
        Each array sorted ascending; together a partition of ``0..H-1``.
    """
    H = problem.num_hypotheses
    R = problem.num_resources
    if H == 0:
        return []
    incidence = problem.incidence().tocoo()  # (R, H)
    # Bipartite graph: hypothesis h is node h, resource r is node H + r.
    hyp_nodes = incidence.col.astype(np.int64)
    res_nodes = incidence.row.astype(np.int64) + H
    n = H + R
    graph = sp.csr_array((np.ones(len(hyp_nodes)), (hyp_nodes, res_nodes)), shape=(n, n))
    _, labels = connected_components(graph, directed=False)
    hyp_labels = labels[:H]
    order = np.argsort(hyp_labels, kind="stable")
    sorted_labels = hyp_labels[order]
    cuts = np.flatnonzero(np.diff(sorted_labels)) + 1
    groups = np.split(order, cuts)
    groups.sort(key=lambda g: int(g[0]))
    return [g.astype(np.int64) for g in groups]
