"""The scenes' compiled start draws equal NumPy's draws from the same generator, bit for bit.

The references below are the Python draws the scenes made before their starts were
compiled (every committed test start, table and certificate was drawn by them).
"""

from __future__ import annotations

import numpy as np
import pytest

from dynamics import body_poses
from trailer_env.generators import GeneratorBank
from trailer_env.registry import core_class_of
from trailer_env.scenes import coast, dock, heading, reverse, reverse_v1
from trailer_env.settings import settings_from_kwargs

SEEDS = range(300)


def reverse_reference(rng: np.random.Generator, n: int) -> dict[str, np.ndarray]:
    low = np.array([reverse.SPEED_RANGE[0], -reverse.OMEGA_NOISE] + [-reverse.ANGLE_NOISE] * n)
    span = np.array(
        [reverse.SPEED_RANGE[1] - reverse.SPEED_RANGE[0], 2 * reverse.OMEGA_NOISE]
        + [2 * reverse.ANGLE_NOISE] * n
    )
    start = np.empty(n + 2)
    rng.random(out=start)
    start *= span
    start += low
    start[0] = -start[0]
    return {"z": start}


def reverse_v1_reference(rng: np.random.Generator, n: int) -> dict[str, np.ndarray]:
    z = np.zeros(n + 2)
    z[0] = -rng.uniform(*reverse_v1.SPEED_RANGE)
    direction = rng.standard_normal(n + 1)
    radius = reverse_v1.ReverseV1Core.perturbation_radius(n)
    z[1:] = radius * direction / np.linalg.norm(direction)
    return {"z": z}


def dock_reference(rng: np.random.Generator, n: int) -> dict[str, np.ndarray]:
    z = np.zeros(n + 2)
    z[0] = -rng.uniform(*dock.SPEED_RANGE)
    z[1] = rng.uniform(-dock.OMEGA_NOISE, dock.OMEGA_NOISE)
    z[2:] = rng.uniform(-dock.ANGLE_NOISE, dock.ANGLE_NOISE, n)
    xs, _, _ = body_poses(1.0, 0.0, 0.0, 0.0, z[2:])
    target = np.array(
        [
            xs[-1] - rng.uniform(*dock.DISTANCE_RANGE),
            rng.uniform(-dock.LATERAL_RANGE, dock.LATERAL_RANGE),
            rng.uniform(-dock.HEADING_RANGE, dock.HEADING_RANGE),
        ]
    )
    return {"z": z, "target": target}


def coast_reference(rng: np.random.Generator, n: int) -> dict[str, np.ndarray]:
    z = np.zeros(n + 2)
    while True:
        forward = rng.random() < 0.5
        angles = coast.FORWARD_ANGLE_RANGE if forward else coast.REVERSE_ANGLE_RANGE
        omegas = coast.FORWARD_OMEGA_RANGE if forward else coast.REVERSE_OMEGA_RANGE
        z[0] = (1.0 if forward else -1.0) * rng.uniform(*coast.SPEED_RANGE)
        z[1] = rng.uniform(-omegas, omegas)
        z[2:] = rng.uniform(-angles, angles, n)
        straight = abs(z[1]) < coast.SUCCESS_OMEGA and np.all(np.abs(z[2:]) < coast.SUCCESS_ANGLE)
        if not straight:
            return {"z": z}


def heading_reference(rng: np.random.Generator, n: int) -> dict[str, np.ndarray]:
    z = np.zeros(n + 2)
    z[0] = rng.uniform(*heading.SPEED_RANGE)
    z[1] = rng.uniform(-heading.OMEGA_NOISE, heading.OMEGA_NOISE)
    z[2:] = rng.uniform(-heading.ANGLE_NOISE, heading.ANGLE_NOISE, n)
    sign = 1.0 if rng.random() < 0.5 else -1.0
    return {"z": z, "target_heading": np.array(sign * rng.uniform(*heading.TARGET_RANGE))}


CASES = {
    "trailer_env/Reverse-v0": reverse_reference,
    "trailer_env/Reverse-v1": reverse_v1_reference,
    "trailer_env/Dock-v0": dock_reference,
    "trailer_env/Coast-v0": coast_reference,
    "trailer_env/Heading-v0": heading_reference,
}


@pytest.mark.parametrize("env_id", sorted(CASES))
@pytest.mark.parametrize("n", [0, 1, 2, 3, 5])
def test_compiled_starts_equal_numpy_draws(env_id: str, n: int) -> None:
    core = core_class_of(env_id)(settings_from_kwargs(n_trailers=n), len(SEEDS))
    rows = np.arange(len(SEEDS))
    bank = GeneratorBank([np.random.default_rng(seed) for seed in SEEDS])
    core.reset_rows_from(rows, bank)
    references = [np.random.default_rng(seed) for seed in SEEDS]
    for i, rng in enumerate(references):
        expected = CASES[env_id](rng, n)
        np.testing.assert_array_equal(core.z[i, : n + 2], expected["z"])
        for name, value in expected.items():
            if name != "z":
                np.testing.assert_array_equal(getattr(core, name)[i], value)
        # The compiled draws advanced the Python generator exactly as NumPy's would have.
        assert bank[i].bit_generator.state == rng.bit_generator.state


def test_aligned_and_bank_resets_draw_the_same_starts() -> None:
    settings = settings_from_kwargs(n_trailers=2)
    core_class = core_class_of("trailer_env/Reverse-v1")
    by_bank, aligned = core_class(settings, 8), core_class(settings, 8)
    rows = np.array([6, 1, 3])
    by_bank.reset_rows_from(rows, GeneratorBank([np.random.default_rng(s) for s in range(8)]))
    aligned.reset_rows(rows, [np.random.default_rng(s) for s in (6, 1, 3)])
    np.testing.assert_array_equal(by_bank.z, aligned.z)
    assert np.count_nonzero(by_bank.z[:, 0]) == 3


def test_bank_refuses_what_is_not_a_generator() -> None:
    with pytest.raises(TypeError, match=r"numpy\.random\.Generator"):
        GeneratorBank([np.random.default_rng(0), 3])  # type: ignore[list-item]
    bank = GeneratorBank([np.random.default_rng(0)])
    with pytest.raises(TypeError, match=r"numpy\.random\.Generator"):
        bank[0] = np.random.RandomState(0)  # type: ignore[assignment]
    assert isinstance(bank[0], np.random.Generator)


def test_bank_pickles_and_its_copy_draws_the_same_stream() -> None:
    import pickle

    bank = GeneratorBank([np.random.default_rng(s) for s in range(3)])
    assert len(bank.typed) == 3
    clone = pickle.loads(pickle.dumps(bank))
    core_class = core_class_of("trailer_env/Reverse-v1")
    settings = settings_from_kwargs(n_trailers=1)
    first, second = core_class(settings, 3), core_class(settings, 3)
    first.reset_rows_from(np.arange(3), bank)
    second.reset_rows_from(np.arange(3), clone)
    np.testing.assert_array_equal(first.z, second.z)
    assert np.all(first.z[:, 0] < -0.8)
