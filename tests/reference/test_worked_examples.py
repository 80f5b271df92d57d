"""Acceptance tests: the worked examples of the works the exact references follow,
reproduced exactly by mapassoc.reference.association.

* W. Afzal, "Track Association Problems in AD" (2022), section 5.2, eq. 18-20 and Table 1:
  the association vectors and their object / clutter split;
* the n-object posterior of L. Svensson et al., "Multi-Object Tracking for Automotive
  Systems" (Chalmers University of Technology): the two-object posterior with seven
  associations (weights derived by hand below, independently of the library);
* single-object tracking in clutter, from the same course: one object over two scans
  (checked against a brute-force numerical integration on a grid that uses no Kalman
  formula).
"""

from __future__ import annotations

import itertools
import math
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import multivariate_normal

from mapassoc.errors import InputError, NotPositiveDefiniteError
from mapassoc.models.measurement import LinearMeasurement, RangeBearing
from mapassoc.models.motion import ConstantVelocity, RandomWalk
from mapassoc.reference.association import (
    AssociationRow,
    GaussianMixture,
    association_table,
    enumerate_associations,
    n_object_posterior,
    single_object_sequences,
)

SCALAR_MEASUREMENT_VAR = 0.2  # the n-object posterior and single-object tracking in clutter


def scalar_measurement() -> LinearMeasurement:
    return LinearMeasurement(H=[[1.0]], R=[[SCALAR_MEASUREMENT_VAR]], component_names=["x"])


def normal(z: float, mean: float, var: float) -> float:
    """Scalar Gaussian density written out (no library code)."""
    return math.exp(-((z - mean) ** 2) / (2.0 * var)) / math.sqrt(2.0 * math.pi * var)


# --------------------------------------------------------------------------------------
# Afzal's survey: association vectors and Table 1
# --------------------------------------------------------------------------------------


def test_afzal_table1_two_objects_two_measurements() -> None:
    # (theta, O^1, O^2, C, m^o, m^c) exactly as Table 1 of Afzal's survey.
    table1 = [
        ((0, 0), (None, None), (1, 2), 0, 2),
        ((0, 1), (None, 1), (2,), 1, 1),
        ((0, 2), (None, 2), (1,), 1, 1),
        ((1, 0), (1, None), (2,), 1, 1),
        ((1, 2), (1, 2), (), 2, 0),
        ((2, 0), (2, None), (1,), 1, 1),
        ((2, 1), (2, 1), (), 2, 0),
    ]
    thetas = enumerate_associations(2, 2)
    assert thetas == [row[0] for row in table1]
    for theta, objects, clutter, detected, num_clutter in table1:
        assert association_table(theta, 2) == AssociationRow(
            theta=theta,
            object_measurements=objects,
            clutter_measurements=clutter,
            num_detected=detected,
            num_clutter=num_clutter,
        )


@pytest.mark.parametrize(
    ("n", "m"), [(0, 0), (0, 3), (1, 0), (1, 4), (2, 2), (3, 0), (3, 2), (3, 4), (4, 3), (2, 5)]
)
def test_association_count_and_brute_force_oracle(n: int, m: int) -> None:
    thetas = enumerate_associations(n, m)
    expected_count = sum(math.comb(n, k) * math.perm(m, k) for k in range(min(n, m) + 1))
    assert len(thetas) == expected_count
    # Oracle: filter the full product {0..m}^n, which itertools yields in lexicographic order.
    brute = [
        theta
        for theta in itertools.product(range(m + 1), repeat=n)
        if len([j for j in theta if j]) == len({j for j in theta if j})
    ]
    assert thetas == brute
    for theta in thetas:
        row = association_table(theta, m)
        assert row.num_detected + row.num_clutter == m
        used = [j for j in row.object_measurements if j is not None]
        assert sorted(used + list(row.clutter_measurements)) == list(range(1, m + 1))


@pytest.mark.parametrize(("n", "m"), [(-1, 2), (2, -1), (1.5, 2), (True, 2), (2, "3")])
def test_enumerate_rejects_bad_counts(n: object, m: object) -> None:
    with pytest.raises(InputError):
        enumerate_associations(n, m)  # type: ignore[arg-type]


@pytest.mark.parametrize("theta", [(1, 1), (3, 0), (-1, 0), (0.5, 0)])
def test_association_table_rejects_invalid_theta(theta: tuple) -> None:
    with pytest.raises(InputError):
        association_table(theta, 2)


# --------------------------------------------------------------------------------------
# The n-object posterior: two objects, two measurements, seven associations
# --------------------------------------------------------------------------------------

TWO_OBJECT_PRIOR_MEANS = np.array([[-2.5], [2.5]])
TWO_OBJECT_PRIOR_COVS = np.array([[[0.36]], [[0.36]]])
TWO_OBJECT_MEASUREMENTS = np.array([[-1.6], [1.0]])
TWO_OBJECT_CLUTTER = 0.3  # per unit length on [-5, 5] (the worked example's density), not 0.3 / 10


def two_object_posterior(pd: float):
    return n_object_posterior(
        TWO_OBJECT_PRIOR_MEANS,
        TWO_OBJECT_PRIOR_COVS,
        TWO_OBJECT_MEASUREMENTS,
        scalar_measurement(),
        pd,
        TWO_OBJECT_CLUTTER,
    )


def two_object_hand_weights(pd: float) -> dict[tuple[int, int], float]:
    """Unnormalised weights of the n-object posterior, written out term by term."""
    S = 0.36 + 0.2  # innovation variance H P H^T + R = 0.56 for both objects
    assert S == pytest.approx(0.56)
    miss = 1.0 - pd  # (1 - Pd) per missed object
    det = pd / TWO_OBJECT_CLUTTER  # (Pd / lambda) per detected object
    obj1_z1 = normal(-1.6, -2.5, S)
    obj1_z2 = normal(1.0, -2.5, S)
    obj2_z1 = normal(-1.6, 2.5, S)
    obj2_z2 = normal(1.0, 2.5, S)
    return {
        (0, 0): miss * miss,
        (0, 1): miss * det * obj2_z1,
        (0, 2): miss * det * obj2_z2,
        (1, 0): det * obj1_z1 * miss,
        (1, 2): det * obj1_z1 * det * obj2_z2,
        (2, 0): det * obj1_z2 * miss,
        (2, 1): det * obj1_z2 * det * obj2_z1,
    }


@pytest.mark.parametrize("pd", [0.85, 0.95, 0.5])
def test_two_object_example_weights_match_hand_derivation(pd: float) -> None:
    post = two_object_posterior(pd)
    hand = two_object_hand_weights(pd)
    assert list(post.associations) == list(hand)
    total = sum(hand.values())
    expected = np.array([hand[theta] / total for theta in post.associations])
    np.testing.assert_allclose(post.weights, expected, rtol=0, atol=1e-12)
    expected_log = np.array([math.log(hand[theta]) for theta in post.associations])
    np.testing.assert_allclose(post.log_weights, expected_log, rtol=1e-12, atol=1e-12)
    assert post.log_normalizer == pytest.approx(math.log(total), rel=1e-12)
    assert post.weights.sum() == pytest.approx(1.0, abs=1e-14)


def test_two_object_example_statements() -> None:
    # Pd = 0.85: three of seven weights are "more or less zero" (< 0.01): exactly the
    # associations that use the far measurement for some object (object 1 with z2 = 1,
    # object 2 with z1 = -1.6).
    post = two_object_posterior(0.85)
    weights = dict(zip(post.associations, post.weights, strict=True))
    near_zero = {theta for theta, weight in weights.items() if weight < 0.01}
    assert near_zero == {(0, 1), (2, 0), (2, 1)}
    # Pd = 0.95: theta = [1, 2] "almost 0.8" (exact value 0.7719978...), both missed almost 0
    # (0.0104...).
    post = two_object_posterior(0.95)
    assert 0.7 < post.weight_of((1, 2)) < 0.85
    assert post.weight_of((1, 2)) == pytest.approx(0.7719978, abs=1e-7)
    assert post.weight_of((0, 0)) < 0.02
    assert int(np.argmax(post.weights)) == post.associations.index((1, 2))
    # Pd = 0.5: both missed has the largest weight (0.4336...).
    post = two_object_posterior(0.5)
    assert int(np.argmax(post.weights)) == post.associations.index((0, 0))


def test_two_object_example_components_are_kalman_updates_by_hand() -> None:
    post = two_object_posterior(0.85)
    a = post.associations.index((1, 2))
    gain = 0.36 / 0.56
    var = 0.36 - gain * 0.36  # = 0.36 * 0.2 / 0.56 = 0.128571...
    assert post.means[a, 0, 0] == pytest.approx(-2.5 + gain * (-1.6 + 2.5), abs=1e-12)
    assert post.means[a, 1, 0] == pytest.approx(2.5 + gain * (1.0 - 2.5), abs=1e-12)
    assert post.covariances[a, 0, 0, 0] == pytest.approx(var, abs=1e-12)
    assert post.covariances[a, 1, 0, 0] == pytest.approx(var, abs=1e-12)
    # Missed objects keep their prior.
    b = post.associations.index((0, 0))
    np.testing.assert_array_equal(post.means[b], TWO_OBJECT_PRIOR_MEANS)
    np.testing.assert_array_equal(post.covariances[b], TWO_OBJECT_PRIOR_COVS)


def test_two_object_example_marginal_mixture_is_a_density_with_matching_moments() -> None:
    post = two_object_posterior(0.85)
    grid = np.linspace(-10.0, 10.0, 20001)
    step = grid[1] - grid[0]
    for i in range(2):
        mixture = post.marginal(i)
        density = mixture.pdf(grid)
        assert density.shape == grid.shape
        assert density.sum() * step == pytest.approx(1.0, abs=1e-10)
        grid_mean = (grid * density).sum() * step
        grid_var = ((grid - grid_mean) ** 2 * density).sum() * step
        mean, cov = mixture.merged()
        assert mean.shape == (1,)
        assert cov.shape == (1, 1)
        assert mean[0] == pytest.approx(grid_mean, abs=1e-9)
        assert cov[0, 0] == pytest.approx(grid_var, abs=1e-9)
        # The mixture's components are the per-association components of object i.
        np.testing.assert_array_equal(mixture.means, post.means[:, i])
        assert isinstance(mixture.pdf(-1.6), float)


# --------------------------------------------------------------------------------------
# Single-object tracking in clutter: single object in clutter, two scans
# --------------------------------------------------------------------------------------

CLUTTER_SCANS = [np.array([[-1.3], [1.7]]), np.array([[1.3]])]
CLUTTER_PD = 0.9
CLUTTER_CLUTTER = 0.4  # per unit length on [-4, 4]
CLUTTER_MOTION_VAR = 0.35


def one_object_in_clutter_posterior():
    return single_object_sequences(
        [0.5],
        [[0.2]],
        CLUTTER_SCANS,
        RandomWalk(ndim=1, noise_intensity=CLUTTER_MOTION_VAR),
        scalar_measurement(),
        CLUTTER_PD,
        CLUTTER_CLUTTER,
        dt=1.0,
    )


def test_one_object_in_clutter_example_statements() -> None:
    post = one_object_in_clutter_posterior()
    assert post.sequences == ((0, 0), (0, 1), (1, 0), (1, 1), (2, 0), (2, 1))
    # Most likely: detected at both times, by z = 1.7 at time 1 and z = 1.3 at time 2.
    assert post.sequences[int(np.argmax(post.weights))] == (2, 1)
    # Sequences using z = -1.3 at time 1 are very unlikely (each < 0.01; 0.0069 and 0.0083).
    assert post.weight_of((1, 0)) < 0.01
    assert post.weight_of((1, 1)) < 0.01
    assert post.weights.sum() == pytest.approx(1.0, abs=1e-14)


def test_one_object_in_clutter_example_matches_brute_force_grid_integration() -> None:
    """Weights, means and variances against numerical integration (no Kalman formula)."""
    num_points = 4001
    grid = np.linspace(-8.0, 8.0, num_points)
    step = grid[1] - grid[0]

    def gauss(x: np.ndarray, mean: float | np.ndarray, var: float) -> np.ndarray:
        return np.exp(-((x - mean) ** 2) / (2.0 * var)) / math.sqrt(2.0 * math.pi * var)

    def likelihood(theta: int, scan: np.ndarray) -> np.ndarray:
        if theta == 0:
            return np.full(num_points, 1.0 - CLUTTER_PD)
        z = float(scan[theta - 1, 0])
        return CLUTTER_PD / CLUTTER_CLUTTER * gauss(z, grid, SCALAR_MEASUREMENT_VAR)

    prior_x1 = gauss(grid, 0.5, 0.2)
    # Transition x2 | x1 ~ N(x1, 0.35) on a uniform grid is a discrete convolution.
    offsets = np.arange(-(num_points - 1), num_points) * step
    kernel = gauss(offsets, 0.0, CLUTTER_MOTION_VAR)
    expected_weight, expected_mean, expected_var = {}, {}, {}
    for theta1 in range(3):
        joint_x1 = prior_x1 * likelihood(theta1, CLUTTER_SCANS[0])
        predicted_x2 = np.convolve(joint_x1, kernel)[num_points - 1 : 2 * num_points - 1] * step
        for theta2 in range(2):
            joint_x2 = predicted_x2 * likelihood(theta2, CLUTTER_SCANS[1])
            mass = joint_x2.sum() * step
            mean = (grid * joint_x2).sum() * step / mass
            expected_weight[(theta1, theta2)] = mass
            expected_mean[(theta1, theta2)] = mean
            expected_var[(theta1, theta2)] = ((grid - mean) ** 2 * joint_x2).sum() * step / mass
    total = sum(expected_weight.values())

    post = one_object_in_clutter_posterior()
    assert set(post.sequences) == set(expected_weight)
    for h, sequence in enumerate(post.sequences):
        assert post.weights[h] == pytest.approx(expected_weight[sequence] / total, abs=1e-9)
        assert post.log_weights[h] == pytest.approx(math.log(expected_weight[sequence]), abs=1e-9)
        assert post.means[h, 0] == pytest.approx(expected_mean[sequence], abs=1e-9)
        assert post.covariances[h, 0, 0] == pytest.approx(expected_var[sequence], abs=1e-9)


def test_one_object_in_clutter_example_handles_empty_scan_and_lexicographic_order() -> None:
    scans = [CLUTTER_SCANS[0], np.empty((0, 1)), CLUTTER_SCANS[1]]
    post = single_object_sequences(
        [0.5],
        [[0.2]],
        scans,
        RandomWalk(ndim=1, noise_intensity=0.35),
        scalar_measurement(),
        CLUTTER_PD,
        CLUTTER_CLUTTER,
    )
    assert list(post.sequences) == sorted(itertools.product(range(3), range(1), range(2)))
    # An empty scan multiplies every weight by (1 - Pd): normalised weights are those of
    # the two-scan problem with the object predicted twice.
    two_step = single_object_sequences(
        [0.5],
        [[0.2]],
        [CLUTTER_SCANS[0], CLUTTER_SCANS[1]],
        RandomWalk(ndim=1, noise_intensity=0.35),
        scalar_measurement(),
        CLUTTER_PD,
        CLUTTER_CLUTTER,
        dt=2.0,
    )
    np.testing.assert_allclose(post.weights, two_step.weights, rtol=0, atol=1e-14)
    np.testing.assert_allclose(
        post.log_weights, two_step.log_weights + math.log(1.0 - CLUTTER_PD), rtol=1e-13
    )


# --------------------------------------------------------------------------------------
# Oracles and invariances
# --------------------------------------------------------------------------------------


def test_one_object_posterior_equals_one_scan_sequence_posterior() -> None:
    measurement = scalar_measurement()
    scan = np.array([[-1.3], [1.7], [0.2]])
    objects = n_object_posterior([[0.5]], [[[0.2]]], scan, measurement, 0.7, 0.4)
    sequences = single_object_sequences(
        [0.5], [[0.2]], [scan], RandomWalk(ndim=1, noise_intensity=1.0), measurement, 0.7, 0.4
    )
    assert objects.associations == sequences.sequences
    np.testing.assert_allclose(objects.log_weights, sequences.log_weights, rtol=1e-14)
    np.testing.assert_allclose(objects.means[:, 0], sequences.means, rtol=1e-14)
    np.testing.assert_allclose(objects.covariances[:, 0], sequences.covariances, rtol=1e-14)


def test_two_dimensional_posterior_against_scipy_and_information_form() -> None:
    """Three constant-velocity objects, 2-D position measurements: independent oracle."""
    rng = np.random.default_rng(7)
    motion = ConstantVelocity(ndim=2, noise_intensity=1.0)
    measurement = LinearMeasurement.position(motion, noise_std=[0.5, 0.8])
    H, R = measurement.H, measurement.R
    means = rng.normal(scale=2.0, size=(3, 4))
    roots = rng.normal(size=(3, 4, 4))
    covs = roots @ roots.transpose(0, 2, 1) + 0.5 * np.eye(4)
    z = means[:, :2] + rng.normal(scale=1.0, size=(3, 2))
    pd, lam = 0.8, 0.05
    post = n_object_posterior(means, covs, z, measurement, pd, lam)
    assert len(post.associations) == 34
    for a, theta in enumerate(post.associations):
        expected = 0.0
        for i, j in enumerate(theta):
            if j == 0:
                expected += math.log(1.0 - pd)
                np.testing.assert_array_equal(post.means[a, i], means[i])
                continue
            S = H @ covs[i] @ H.T + R
            expected += math.log(pd / lam) + multivariate_normal(H @ means[i], S).logpdf(z[j - 1])
            info = np.linalg.inv(covs[i]) + H.T @ np.linalg.inv(R) @ H
            post_cov = np.linalg.inv(info)
            post_mean = post_cov @ (
                np.linalg.solve(covs[i], means[i]) + H.T @ np.linalg.solve(R, z[j - 1])
            )
            np.testing.assert_allclose(post.means[a, i], post_mean, rtol=1e-9, atol=1e-9)
            np.testing.assert_allclose(post.covariances[a, i], post_cov, rtol=1e-9, atol=1e-10)
        assert post.log_weights[a] == pytest.approx(expected, abs=1e-10)


@settings(max_examples=60, deadline=None)
@given(
    data=st.data(),
    n=st.integers(min_value=1, max_value=3),
    m=st.integers(min_value=0, max_value=4),
    pd=st.floats(min_value=0.05, max_value=0.99),
)
def test_permuting_measurements_permutes_associations(
    data: st.DataObject, n: int, m: int, pd: float
) -> None:
    coords = st.floats(min_value=-4.0, max_value=4.0, allow_nan=False)
    means = np.array(data.draw(st.lists(st.tuples(coords, coords), min_size=n, max_size=n)))
    z = np.array(data.draw(st.lists(st.tuples(coords, coords), min_size=m, max_size=m)))
    z = z.reshape(m, 2)
    perm = data.draw(st.permutations(range(m)))
    measurement = LinearMeasurement(H=np.eye(2), R=np.diag([0.3, 0.5]), component_names=["x", "y"])
    covs = np.broadcast_to(np.array([[1.0, 0.3], [0.3, 0.8]]), (n, 2, 2))
    original = n_object_posterior(means, covs, z, measurement, pd, 0.1)
    permuted = n_object_posterior(means, covs, z[list(perm)], measurement, pd, 0.1)
    assert original.weights.sum() == pytest.approx(1.0, abs=1e-12)
    # Measurement j (1-based) of the original scan is measurement new_index[j] after permuting.
    new_index = {0: 0} | {original_j + 1: k + 1 for k, original_j in enumerate(perm)}
    for a, theta in enumerate(original.associations):
        b = permuted.associations.index(tuple(new_index[j] for j in theta))
        assert permuted.weights[b] == pytest.approx(original.weights[a], rel=1e-9, abs=1e-300)
        np.testing.assert_allclose(permuted.means[b], original.means[a], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(
        np.sort(permuted.weights), np.sort(original.weights), rtol=1e-9, atol=1e-300
    )


def test_detection_probability_one_gives_missed_associations_weight_exactly_zero() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        post = two_object_posterior(1.0)
        sequences = single_object_sequences(
            [0.5],
            [[0.2]],
            CLUTTER_SCANS,
            RandomWalk(ndim=1, noise_intensity=0.35),
            scalar_measurement(),
            1.0,
            CLUTTER_CLUTTER,
        )
    for theta, weight, log_weight in zip(
        post.associations, post.weights, post.log_weights, strict=True
    ):
        if 0 in theta:
            assert weight == 0.0
            assert log_weight == -math.inf
        else:
            assert weight > 0.0
    assert post.weights.sum() == pytest.approx(1.0, abs=1e-14)
    for sequence, weight in zip(sequences.sequences, sequences.weights, strict=True):
        assert (weight == 0.0) == (0 in sequence)
    # Hand check: with no misses the weights are proportional to the two products of
    # Gaussian likelihoods.
    hand = two_object_hand_weights(1.0)
    assert post.weight_of((1, 2)) == pytest.approx(
        hand[(1, 2)] / (hand[(1, 2)] + hand[(2, 1)]), abs=1e-12
    )


def test_gaussian_mixture_pdf_and_merge_by_hand() -> None:
    mixture = GaussianMixture(
        weights=np.array([0.25, 0.75]),
        means=np.array([[0.0], [2.0]]),
        covariances=np.array([[[1.0]], [[0.5]]]),
    )
    x = 0.7
    assert mixture.pdf(x) == pytest.approx(
        0.25 * normal(x, 0.0, 1.0) + 0.75 * normal(x, 2.0, 0.5), rel=1e-14
    )
    mean, cov = mixture.merged()
    assert mean[0] == pytest.approx(1.5)
    assert cov[0, 0] == pytest.approx(0.25 * (1.0 + 1.5**2) + 0.75 * (0.5 + 0.5**2))
    plane = GaussianMixture(
        weights=np.array([1.0]),
        means=np.array([[1.0, -1.0]]),
        covariances=np.array([[[2.0, 0.5], [0.5, 1.0]]]),
    )
    points = np.array([[0.0, 0.0], [1.0, -1.0], [3.0, 2.0]])
    expected = multivariate_normal([1.0, -1.0], [[2.0, 0.5], [0.5, 1.0]]).pdf(points)
    np.testing.assert_allclose(plane.pdf(points), expected, rtol=1e-12)
    with pytest.raises(InputError):
        plane.pdf([1.0, 2.0, 3.0])
    with pytest.raises(InputError):
        GaussianMixture(
            weights=np.array([0.5, 0.4]), means=np.zeros((2, 1)), covariances=np.ones((2, 1, 1))
        )


# --------------------------------------------------------------------------------------
# Bad inputs
# --------------------------------------------------------------------------------------


def _n_object_call(**overrides: object) -> None:
    arguments: dict[str, object] = {
        "prior_means": TWO_OBJECT_PRIOR_MEANS,
        "prior_covs": TWO_OBJECT_PRIOR_COVS,
        "measurements": TWO_OBJECT_MEASUREMENTS,
        "measurement_model": scalar_measurement(),
        "detection_probability": 0.85,
        "clutter_intensity": 0.3,
    }
    arguments.update(overrides)
    n_object_posterior(**arguments)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("overrides", "error", "message"),
    [
        ({"detection_probability": -0.1}, InputError, "detection_probability"),
        ({"detection_probability": 0.0}, InputError, "detection_probability"),
        ({"detection_probability": 1.5}, InputError, "detection_probability"),
        ({"clutter_intensity": 0.0}, InputError, "clutter_intensity"),
        ({"clutter_intensity": -0.3}, InputError, "clutter_intensity"),
        ({"prior_covs": np.array([[[0.36]], [[-0.36]]])}, NotPositiveDefiniteError, "prior_covs"),
        ({"prior_means": np.array([-2.5, 2.5])}, InputError, "prior_means"),
        ({"prior_covs": np.array([[[0.36]]])}, InputError, "prior_covs"),
        ({"measurements": np.array([-1.6, 1.0])}, InputError, "measurements"),
        ({"measurements": np.array([[-1.6, 0.0]])}, InputError, "measurements"),
        ({"measurements": np.array([[np.nan]])}, InputError, "measurements"),
        ({"measurement_model": "linear"}, InputError, "measurement_model"),
        (
            {
                "measurement_model": LinearMeasurement(
                    H=[[1.0, 0.0]], R=[[0.2]], component_names=["x"]
                )
            },
            InputError,
            "measurement_model",
        ),
        # Pd = 1 and more objects than measurements: every association has a miss.
        (
            {"detection_probability": 1.0, "measurements": np.array([[0.0]])},
            InputError,
            "probability 0",
        ),
    ],
)
def test_n_object_posterior_rejects_bad_inputs(
    overrides: dict[str, object], error: type[Exception], message: str
) -> None:
    with pytest.raises(error, match=message):
        _n_object_call(**overrides)


def test_non_symmetric_prior_covariance_is_rejected() -> None:
    covs = np.array([[[1.0, 0.5], [0.0, 1.0]]])
    measurement = LinearMeasurement(H=np.eye(2), R=np.eye(2), component_names=["x", "y"])
    with pytest.raises(NotPositiveDefiniteError, match="prior_covs"):
        n_object_posterior([[0.0, 0.0]], covs, np.zeros((1, 2)), measurement, 0.9, 0.1)


def test_marginal_rejects_bad_object_index() -> None:
    post = two_object_posterior(0.85)
    for bad in (-1, 2, 0.0):
        with pytest.raises(InputError, match="object index"):
            post.marginal(bad)  # type: ignore[arg-type]
    with pytest.raises(InputError):
        post.weight_of((1, 1))


def _sequences_call(**overrides: object) -> None:
    arguments: dict[str, object] = {
        "prior_mean": [0.5],
        "prior_cov": [[0.2]],
        "scans": CLUTTER_SCANS,
        "motion": RandomWalk(ndim=1, noise_intensity=0.35),
        "measurement_model": scalar_measurement(),
        "detection_probability": 0.9,
        "clutter_intensity": 0.4,
        "dt": 1.0,
    }
    arguments.update(overrides)
    single_object_sequences(**arguments)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("overrides", "error", "message"),
    [
        ({"detection_probability": -0.5}, InputError, "detection_probability"),
        ({"clutter_intensity": 0.0}, InputError, "clutter_intensity"),
        ({"dt": 0.0}, InputError, "dt"),
        ({"prior_cov": [[-0.2]]}, NotPositiveDefiniteError, "prior_cov"),
        ({"prior_mean": 0.5}, InputError, "prior_mean"),
        ({"prior_cov": [[0.2, 0.0]]}, InputError, "prior_cov"),
        ({"scans": []}, InputError, "scans"),
        ({"scans": [np.array([-1.3, 1.7])]}, InputError, r"scans\[0\]"),
        ({"motion": RandomWalk(ndim=2, noise_intensity=0.35)}, InputError, "motion"),
        ({"motion": "random walk"}, InputError, "motion"),
        (
            {"detection_probability": 1.0, "scans": [CLUTTER_SCANS[0], np.empty((0, 1))]},
            InputError,
            "probability 0",
        ),
    ],
)
def test_single_object_sequences_rejects_bad_inputs(
    overrides: dict[str, object], error: type[Exception], message: str
) -> None:
    with pytest.raises(error, match=message):
        _sequences_call(**overrides)


def test_range_bearing_model_uses_wrapped_bearing_residuals() -> None:
    """A detection just across the +-pi bearing cut is near the object, not 2 pi away."""
    sensor = RangeBearing(sensor_position=[0.0, 0.0], range_std=0.2, bearing_std=0.01)
    object_mean = np.array([[-10.0, 0.02]])  # bearing just below +pi
    detection = np.array([[10.0, -math.pi + 0.001]])  # bearing just above -pi
    post = n_object_posterior(object_mean, np.eye(2)[None], detection, sensor, 0.9, 1e-3)
    assert post.weight_of((1,)) > 0.99
    detected = post.associations.index((1,))
    assert np.linalg.norm(post.means[detected, 0] - object_mean[0]) < 0.1
