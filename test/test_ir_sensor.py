"""The IR lookup table forward and inverse, its noise and the published range."""
import numpy as np
import pytest

from epuck_ros.ir_sensor import (LookupTable, distance_from_raw, noise_from_distance, noisy_raw, range_from_raw,
                                 raw_from_distance)
from epuck_ros.model import IR_LOOKUP_TABLE as TABLE


def test_raw_value_is_the_table_interpolated_linearly():
    np.testing.assert_allclose(raw_from_distance(TABLE[:, 0], TABLE), TABLE[:, 1])
    assert raw_from_distance(0.025, TABLE) == pytest.approx((383.84 + 234.93) / 2)
    assert raw_from_distance(0.0125, TABLE) == pytest.approx((1465.73 + 601.46) / 2)


def test_distances_beyond_the_table_take_the_end_row():
    assert raw_from_distance(0.5, TABLE) == pytest.approx(67.19)
    assert raw_from_distance(np.inf, TABLE) == pytest.approx(67.19)
    assert noise_from_distance(np.inf, TABLE) == pytest.approx(0.04897)
    assert raw_from_distance(-0.01, TABLE) == pytest.approx(4095.0)


def test_noise_is_the_third_column_interpolated():
    np.testing.assert_allclose(noise_from_distance(TABLE[:, 0], TABLE), TABLE[:, 2])
    assert noise_from_distance(0.065, TABLE) == pytest.approx((0.03065 + 0.04897) / 2)


@pytest.mark.parametrize('raw, distance', [
    (4095.0, 0.0), (1000.0, 0.01269), (300.0, 0.02563), (158.03, 0.04), (120.0, 0.05), (67.19, 0.07),
    (60.0, 0.07195), (0.0, 0.08821),   # below the table: extrapolated like webots_ros2
])
def test_inverse_table_matches_webots_ros2(raw, distance):
    assert distance_from_raw(raw, TABLE) == pytest.approx(distance, abs=5e-6)


def test_inverse_undoes_the_forward_table_inside_it():
    distances = np.linspace(0.0, 0.07, 141)
    np.testing.assert_allclose(distance_from_raw(raw_from_distance(distances, TABLE), TABLE), distances, atol=1e-12)


def test_noise_off_gives_the_exact_table_value():
    distances = np.array([0.01, 0.03, np.inf])
    np.testing.assert_array_equal(noisy_raw(distances, TABLE, None), raw_from_distance(distances, TABLE))


@pytest.mark.parametrize('distance', [0.01, 0.015, 0.05, np.inf])
def test_noise_is_relative_with_the_tables_sigma(distance):
    samples = noisy_raw(np.full(20000, distance), TABLE, np.random.default_rng(7))
    value, sigma = raw_from_distance(distance, TABLE), noise_from_distance(distance, TABLE)
    assert samples.mean() == pytest.approx(value, rel=4 * sigma / np.sqrt(len(samples)))
    assert samples.std() / value == pytest.approx(sigma, rel=0.05)


def test_same_seed_same_noise_and_another_seed_other_noise():
    distances = np.linspace(0.0, 0.08, 8)
    first = noisy_raw(distances, TABLE, np.random.default_rng(42))
    np.testing.assert_array_equal(first, noisy_raw(distances, TABLE, np.random.default_rng(42)))
    assert not np.array_equal(first, noisy_raw(distances, TABLE, np.random.default_rng(43)))


def test_range_is_inf_without_a_hit_and_clipped_to_the_table_with_one():
    raw = np.array([67.19, 5000.0, 30.0, 300.0])
    ranges = range_from_raw(raw, np.array([False, True, True, True]), TABLE)
    assert ranges[0] == np.inf
    assert ranges[1] == 0.0          # above 4095: the inverse goes negative, published as 0
    assert ranges[2] == 0.07         # noise pushed the raw value below the far end: at most max_range
    assert ranges[3] == pytest.approx(0.02563, abs=5e-6)
    assert np.all(range_from_raw(raw, np.zeros(4, dtype=bool), TABLE) == np.inf)


def test_one_robots_readings_on_floats_equal_the_numpy_readings_to_the_bit():
    """LookupTable.read_one (the one-robot path) gives exactly noisy_raw's and range_from_raw's values."""
    table = LookupTable(TABLE)
    distances = np.concatenate([TABLE[:, 0], np.random.default_rng(3).uniform(-0.01, 0.09, 400), [np.inf] * 8])
    for noise in (False, True):
        for start in range(0, len(distances), 8):
            rays = distances[start:start + 8]
            raw = noisy_raw(rays, TABLE, np.random.default_rng(start) if noise else None)
            expected = raw.tolist(), range_from_raw(raw, rays < np.inf, TABLE).tolist()
            normals = np.random.default_rng(start).standard_normal(len(rays)).tolist() if noise else None
            assert table.read_one(None if np.isinf(rays).all() else rays.tolist(), normals, len(rays)) == expected
    assert table.read_one(None, None, 8) == ([TABLE[-1, 1]] * 8, [np.inf] * 8)


def test_ranges_of_raw_values_on_floats_equal_the_numpy_ranges_to_the_bit():
    """LookupTable.ranges_of (what a controller reads from ir_raw every step) is range_from_raw on plain floats."""
    table = LookupTable(TABLE)
    rng = np.random.default_rng(5)
    raws = np.concatenate([TABLE[:, 1], rng.uniform(-10.0, 5000.0, 400), rng.uniform(60.0, 90.0, 400)])
    for seen_above in (TABLE[-1, 1], 77.1):
        expected = range_from_raw(raws, raws > seen_above, TABLE).tolist()
        assert table.ranges_of(raws.tolist(), seen_above) == expected
