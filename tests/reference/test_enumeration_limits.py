"""The exact references count what they would enumerate and refuse past ``limit``.

9 objects and 9 measurements (17,572,114 associations) or 20 scans of 5 measurements
(6**20 sequences) once allocated until the memory ran out; they now refuse at once with
the exact count, and a raised ``limit`` enumerates a case just past the default."""

from __future__ import annotations

import itertools
import math
import resource

import numpy as np
import pytest

from mapassoc.errors import MapassocError
from mapassoc.models.measurement import LinearMeasurement
from mapassoc.models.motion import RandomWalk
from mapassoc.reference.association import (
    ENUMERATION_LIMIT,
    association_count,
    enumerate_associations,
    n_object_posterior,
    sequence_count,
    single_object_sequences,
)


def _measurement() -> LinearMeasurement:
    return LinearMeasurement(H=[[1.0]], R=[[0.1]], component_names=["x"])


@pytest.fixture
def capped_memory():  # type: ignore[no-untyped-def]
    """Address space capped near what the process holds, so that any real attempt to
    enumerate fails with MemoryError instead of the refusal tested for."""
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    with open("/proc/self/statm") as f:
        held = int(f.read().split()[0]) * resource.getpagesize()
    resource.setrlimit(resource.RLIMIT_AS, (held + 512 * 2**20, hard))
    yield
    resource.setrlimit(resource.RLIMIT_AS, (soft, hard))


def test_counts_are_exact() -> None:
    for n, m in itertools.product(range(5), range(5)):
        assert association_count(n, m) == len(enumerate_associations(n, m))
    assert association_count(9, 9) == 17_572_114
    big = association_count(60, 60)
    assert isinstance(big, int) and big > 2**256  # no float, no overflow
    assert sequence_count([5] * 20) == 6**20
    assert sequence_count([0, 2, 3]) == 12


def test_n_object_posterior_refuses_nine_by_nine(capped_memory: None) -> None:
    with pytest.raises(MapassocError, match=r"9 objects and 9 measurements.*17,572,114.*limit"):
        n_object_posterior(
            np.zeros((9, 1)),
            np.ones((9, 1, 1)),
            np.linspace(-1.0, 1.0, 9)[:, None],
            _measurement(),
            0.9,
            0.5,
        )


def test_single_object_sequences_refuses_twenty_scans_of_five(capped_memory: None) -> None:
    scans = [np.linspace(-1.0, 1.0, 5)[:, None]] * 20
    with pytest.raises(MapassocError, match=f"20 scans of 5 .*{6**20:,}.*limit"):
        single_object_sequences(
            [0.0], [[1.0]], scans, RandomWalk(ndim=1, noise_intensity=0.1), _measurement(), 0.9, 0.5
        )


def test_a_raised_limit_enumerates() -> None:
    # 6 objects and 6 measurements: 13,327 associations; 7 scans of 1: 128 sequences.
    n = m = 6
    means, covs = np.zeros((n, 1)), np.ones((n, 1, 1))
    z = np.linspace(-1.0, 1.0, m)[:, None]
    with pytest.raises(MapassocError, match="13,327 terms, more than limit=100"):
        n_object_posterior(means, covs, z, _measurement(), 0.9, 0.5, limit=100)
    post = n_object_posterior(means, covs, z, _measurement(), 0.9, 0.5, limit=13_327)
    assert len(post.associations) == association_count(n, m) == 13_327
    assert math.isclose(float(post.weights.sum()), 1.0)
    scans = [np.array([[0.1]])] * 7
    motion = RandomWalk(ndim=1, noise_intensity=0.1)
    with pytest.raises(MapassocError, match="128 terms, more than limit=127"):
        single_object_sequences([0.0], [[1.0]], scans, motion, _measurement(), 0.9, 0.5, limit=127)
    sequences = single_object_sequences(
        [0.0], [[1.0]], scans, motion, _measurement(), 0.9, 0.5, limit=128
    )
    assert len(sequences.sequences) == 128
    assert ENUMERATION_LIMIT >= 128


@pytest.mark.parametrize("limit", [0, 1.5, True, "10"])
def test_a_bad_limit_is_named(limit: object) -> None:
    with pytest.raises(MapassocError, match="limit"):
        enumerate_associations(2, 2, limit=limit)  # type: ignore[arg-type]
