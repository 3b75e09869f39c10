"""Convoys of different lengths in one environment: ``n_trailers=(low, high)``.

Every scene accepts a range of trailer counts instead of one::

    env = gym.make("trailer_env/Reverse-v1", n_trailers=(1, 3))
    envs = gym.make_vec("trailer_env/Reverse-v1", num_envs=256,
                        vectorization_mode="vector_entry_point", n_trailers=(1, 3))

Every episode draws its n uniformly from ``low .. high`` (both included) from the
environment's own generator, before its start: ``n = low + floor(U * count)`` with
``U = Generator.random()`` and ``count = high - low + 1``; the start is then drawn by
the scene for that n from the same generator. So the vector env still replays single
environments seeded ``s + i`` bit for bit, and each episode of n trailers is exactly an
episode of the scene made with ``n_trailers=n`` whose generator drew one number first.

``trailer_draw="row"`` fixes the count by the batch row instead: row i runs
``n = low + i mod count`` in every episode and its generator draws no count, so row i
is exactly the environment made with ``n_trailers=low + i mod count`` seeded ``s + i``
(a single env is row 0: the count ``low``). Every count then gets the same share of
the batch's steps, however early its episodes end: what training a policy for several
counts needs when the longer convoys fold early and would otherwise get fewer steps.

Observation (float32), padded to ``N = high`` trailers, ``m`` mass features (2 on the
rail, 4 planar) and the scene's ``T`` task features:

====================  =========================================================
index                 value
====================  =========================================================
0, 1                  u, omega (as for one n)
2 .. N+1              sin(alpha_k) for k <= n, 0 beyond
N+2 .. 2N+1           cos(alpha_k) for k <= n, 0 beyond
2N+2 .. 2N+1+m        the mass's features (as for one n)
2N+2+m .. 2N+1+m+T    the scene's task features (as for one n)
2N+2+m+T .. 3N+1+m+T  the trailer mask: 1 for k <= n, 0 beyond
====================  =========================================================

``info["n_trailers"]`` holds each environment's n, and with ``randomize=``
``info["params"]`` its episode's parameters, as for one n
(:meth:`~trailer_env.core.ConvoyCore.params_info`). The batch is one scene core per n
(each as large as the batch; a row is live in the core of its episode's n), so a step
is one compiled call per n present, not one call: the kernels' loops over the trailers
are bounded by one n. Measured cost: benchmarks/README.md. Not supported with a range
(each refused with a ValueError): rendering, and task values in ``reset(options=...)``.
A hand-built state (``set_state``, the ``state`` reset option) starts an episode of the
n its length names: 2 + n entries (u, omega, alpha_1..alpha_n), then the pose's 3 in the
scenes that track it (Heading, Dock), as ``get_state()`` and ``state`` return the
running episode's, so they round-trip.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import TypeGuard

import numpy as np

from dynamics.jit import cached_njit
from dynamics.params import MAX_TRAILERS, bounded_integer
from trailer_env.actuator import first_non_finite_row
from trailer_env.core import ConvoyCore
from trailer_env.core_infos import INFO_FIELDS, Info
from trailer_env.core_protocol import BatchCore
from trailer_env.generators import GeneratorBank
from trailer_env.history import HistoryCore
from trailer_env.observation import ObservationView
from trailer_env.settings import EnvSettings, settings_from_keywords

#: Most trailer counts one environment may mix (one scene core each).
MAX_COUNTS = 8


def is_trailer_range(value: object) -> TypeGuard[tuple[object, ...] | list[object]]:
    """Whether ``n_trailers`` was given as a range (a tuple or list) rather than one count."""
    return isinstance(value, (tuple, list))


def trailer_range(value: object) -> tuple[int, int]:
    """``(low, high)`` from a 2-sequence of integers with 0 <= low < high <= 256 and at
    most :data:`MAX_COUNTS` counts.

    Raises:
        TypeError: If it is not a tuple or list of two integers.
        ValueError: If the bounds are out of range or not increasing.
    """
    if not is_trailer_range(value) or len(value) != 2:
        raise TypeError(f"n_trailers must be an integer or a pair (low, high), got {value!r}")
    low = bounded_integer("n_trailers[0]", value[0], 0, MAX_TRAILERS)
    high = bounded_integer("n_trailers[1]", value[1], 0, MAX_TRAILERS)
    if not low < high:
        raise ValueError(f"n_trailers = ({low}, {high}) needs low < high (one count: an int)")
    if high - low + 1 > MAX_COUNTS:
        raise ValueError(
            f"n_trailers = ({low}, {high}) mixes {high - low + 1} counts, more than "
            f"{MAX_COUNTS} (one scene core each)"
        )
    return low, high


def padded_columns(n: int, top: int, tail: int) -> np.ndarray:
    """Where each entry of an n-trailer observation (``2 + 2n + tail`` entries: ``tail``
    mass and task features) goes in the layout padded to ``top >= n`` trailers, followed
    by the columns of the mask's n ones (int64, ``2 + 3n + tail`` columns)."""
    if not 0 <= n <= top:
        raise ValueError(f"an observation of {n} trailers does not fit a layout of {top}")
    return np.concatenate(
        [
            [0, 1],
            2 + np.arange(n),
            2 + top + np.arange(n),
            2 + 2 * top + np.arange(tail),
            2 + 2 * top + tail + np.arange(n),  # the mask's ones
        ]
    ).astype(np.int64)


def pad_observations(obs: np.ndarray, n: int, top: int) -> np.ndarray:
    """Observations (B, 2 + 2n + tail) of a scene made with ``n_trailers=n`` in the
    layout of ``n_trailers=(low, top)`` (float32): what MixedCore observes for the same
    state of an n-trailer episode.

    Raises:
        ValueError: If ``n > top`` (the padded layout holds at most ``top`` trailers).
    """
    batch = np.atleast_2d(np.asarray(obs, dtype=np.float32))
    tail = batch.shape[1] - (2 + 2 * n)
    if tail < 0:
        raise ValueError(f"observations of width {batch.shape[1]} hold fewer than {n} trailers")
    columns = padded_columns(n, top, tail)
    out = np.zeros((batch.shape[0], 2 + 3 * top + tail), dtype=np.float32)
    out[:, columns[: batch.shape[1]]] = batch
    out[:, columns[batch.shape[1] :]] = 1.0
    return out


def pad_window_observations(
    obs: np.ndarray, n: int, top: int, history: int, action_dim: int
) -> np.ndarray:
    """:func:`pad_observations` of observations with a window of ``history`` past frames
    (:mod:`trailer_env.history`): each frame's observation padded, its action kept, as
    the env made with ``n_trailers=(low, top)`` and the same ``history`` observes it.

    Raises:
        ValueError: As :func:`pad_observations`, or if the width is not a window's.
    """
    batch = np.atleast_2d(np.asarray(obs, dtype=np.float32))
    width, frames = batch.shape[1] - history * action_dim, history + 1
    if width % frames:
        raise ValueError(
            f"observations of width {batch.shape[1]} are not windows of {history} past "
            f"frames with {action_dim} action entries each"
        )
    d = width // frames
    parts = [pad_observations(batch[:, :d], n, top)]
    for start in range(d, batch.shape[1], d + action_dim):
        parts += [pad_observations(batch[:, start : start + d], n, top)]
        parts += [batch[:, start + d : start + d + action_dim]]
    return np.concatenate(parts, axis=1)


@cached_njit()
def draw_counts(
    generators: Sequence[np.random.Generator],
    picks: np.ndarray,
    low: int,
    count: int,
    out: np.ndarray,
) -> None:
    """``out[j] = low + floor(U * count)``, U drawn from ``generators[picks[j]]``."""
    for j in range(picks.size):
        out[j] = low + math.floor(generators[picks[j]].random() * count)


class MixedCore:
    """A scene's batch of B environments whose episodes draw their number of trailers.

    It offers what the single env, the vector env and the SB3 adapter use of a
    :class:`~trailer_env.core.ConvoyCore` (``step``, ``reset_rows``, ``reset_rows_from``,
    ``obs``, ``reward``, ``terminated``, the infos); each per-n core does the work.

    Args:
        core_class: The scene's core.
        settings: Settings of each count (``{n: settings}``, consecutive counts).
        batch_size: B >= 1.

    How each episode gets its count is the settings' ``trailer_draw``: "episode" (each
    episode draws it) or "row" (row i runs the count ``low + i mod count``); see the
    module's docstring.
    """

    task_keys: tuple[str, ...] = ()

    def __init__(
        self,
        core_class: type[ConvoyCore],
        settings: dict[int, EnvSettings],
        batch_size: int,
    ) -> None:
        self.counts = tuple(sorted(settings))
        self.low, self.n = self.counts[0], self.counts[-1]
        self.settings = settings[self.n]
        self.draw = self.settings.trailer_draw
        self.cores = {n: core_class(settings[n], batch_size) for n in self.counts}
        #: The randomisation every count's core draws (the same for all; None: none).
        self.randomization = self.cores[self.n].randomization
        self.batch_size = batch_size
        self.with_pose = False
        top = self.cores[self.n]
        self.n_common = top.n_common
        self.n_task_features = top.n_task_features
        self.obs_dim = top.obs_dim + self.n
        self.obs = np.zeros((batch_size, self.obs_dim), dtype=np.float32)
        self.trailers = np.full(batch_size, self.low, dtype=np.int64)
        self.reward = np.zeros(batch_size)
        self.terminated = np.zeros(batch_size, dtype=bool)
        self.success = np.zeros(batch_size, dtype=bool)
        flags = ("success", "jackknifed")
        self._fields = {
            name: np.zeros(batch_size, dtype=bool if name in flags else np.float64)
            for _, name in INFO_FIELDS
            if name
        }
        self._fields["success"] = self.success
        self.energy0 = np.zeros(batch_size)
        self._targets = {n: self._target_columns(n) for n in self.counts}
        self._all_rows = np.arange(batch_size, dtype=np.int64)

    def _target_columns(self, n: int) -> np.ndarray:
        """Where each observation entry of an n-trailer core goes in the padded layout."""
        core = self.cores[n]
        return padded_columns(n, self.n, core.obs_dim - (2 + 2 * n))

    def observation_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of one padded observation (the largest count's, and [0, 1] for the mask)."""
        low, high = self.cores[self.n].observation_bounds()
        ones = np.ones(self.n, dtype=np.float32)
        return np.concatenate([low, 0 * ones]), np.concatenate([high, ones])

    def mirror_signs(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The mirror image's signs in the padded layout (see
        :meth:`~trailer_env.core.ConvoyCore.mirror_signs`): the largest count's, then +1
        for the mask. A padded zero keeps its value, so the signs of every count's rows
        are these, whatever n the row's episode drew."""
        signs = self.cores[self.n].mirror_signs()
        if signs is None:
            return None
        observation, action = signs
        return np.concatenate([observation, np.ones(self.n)]), action

    # ------------------------------------------------------------- resets
    @property
    def start_scale(self) -> float:
        """The factor on every count's starting perturbation (:meth:`set_start_scale`)."""
        return self.cores[self.n].start_scale

    def set_start_scale(self, scale: float) -> None:
        """:meth:`~trailer_env.core.ConvoyCore.set_start_scale` for every count's core
        (checked on the first before any changes, so a refusal changes nothing)."""
        first, *others = self.cores.values()
        first.set_start_scale(scale)
        for core in others:
            core.set_start_scale(scale)

    def reset_rows(self, rows: np.ndarray, rngs: Sequence[np.random.Generator]) -> None:
        """New episodes in ``rows``, row ``rows[j]`` drawing its n, then its start, from
        ``rngs[j]``."""
        bank = GeneratorBank(list(rngs))
        self._start(rows, bank, np.arange(len(rows), dtype=np.int64))

    def reset_rows_from(self, rows: np.ndarray, bank: GeneratorBank) -> None:
        """New episodes in ``rows``, row ``i`` drawing from ``bank[i]``."""
        self._start(rows, bank, rows.astype(np.int64, copy=False))

    def _start(self, rows: np.ndarray, bank: GeneratorBank, picks: np.ndarray) -> None:
        if self.draw == "row":
            counts = self.low + rows.astype(np.int64) % len(self.counts)
        else:
            counts = np.empty(rows.size, dtype=np.int64)
            draw_counts(bank.typed, picks, self.low, len(self.counts), counts)
        self.trailers[rows] = counts
        self.obs[rows] = 0.0
        for n, core in self.cores.items():
            chosen = counts == n
            if chosen.any():
                group = rows[chosen]
                core.reset_rows(group, [bank[k] for k in picks[chosen].tolist()])
                self._gather(n, group)
                self.energy0[group] = core.energy0[group]

    # -------------------------------------------------------------- steps
    def step(self, action: np.ndarray, rows: np.ndarray | None = None) -> None:
        """Step ``rows`` (default all), each in the core of its n (see ConvoyCore.step).

        Raises:
            ValueError, FloatingPointError: As :meth:`ConvoyCore.step`; a refused step
                changes nothing, in any count's core: the counts stepped before the one
                that raised are taken back (:meth:`ConvoyCore.undo_step`).
        """
        stepped = self._all_rows if rows is None else rows
        # Refused before any count's core moves (each core checks only its own rows).
        bad = first_non_finite_row(action, stepped)
        if bad >= 0:
            raise ValueError(
                f"action contains non-finite values (NaN or inf), environment {bad}: {action[bad]}"
            )
        trailers = self.trailers[stepped]
        groups = []
        for n, core in self.cores.items():
            group = stepped[trailers == n]
            if group.size:
                groups.append((n, core, group))
        # A core that raises leaves its rows as they were (ConvoyCore.step); those stepped
        # before it are taken back, so each keeps a copy of what a step overwrites (the
        # last count stepped needs none).
        for _, core, _ in groups[:-1]:
            core.save_step()
        done: list[tuple[ConvoyCore, np.ndarray]] = []
        try:
            for _, core, group in groups:
                core.step(action, group)
                done.append((core, group))
        except BaseException:
            for core, group in done:
                core.undo_step(group)
            raise
        for n, _, group in groups:  # only once every count has stepped
            self._gather(n, group)

    def _gather(self, n: int, rows: np.ndarray) -> None:
        core = self.cores[n]
        self.obs[np.ix_(rows, self._targets[n][: core.obs_dim])] = core.obs[rows]
        self.obs[np.ix_(rows, self._targets[n][core.obs_dim :])] = 1.0
        self.reward[rows] = core.reward[rows]
        self.terminated[rows] = core.terminated[rows]
        for name, values in self._fields.items():
            values[rows] = getattr(core, name)[rows]

    # -------------------------------------------------------------- infos
    def _info_arrays(self) -> dict[str, np.ndarray]:
        """The :data:`INFO_FIELDS` of every row as arrays (B,) (copies)."""
        return {
            key: self._fields["energy"] - self.energy0
            if name is None
            else self._fields[name].copy()
            for key, name in INFO_FIELDS
        }

    def info_batch(self) -> Info:
        """:meth:`ConvoyCore.info_batch` of every row (``params`` with ``randomize=``, a
        dict of arrays), and ``n_trailers``."""
        infos: Info = dict(self._info_arrays())
        if self.randomization is not None:
            infos["params"] = self.params_batch()
        infos["n_trailers"] = self.trailers.copy()
        return infos

    def params_batch(self) -> dict[str, np.ndarray]:
        """:meth:`ConvoyCore.params_batch` of every row, each from the core of its n."""
        batch: dict[str, np.ndarray] = {}
        for n, core in self.cores.items():
            live = self.trailers == n
            for name, values in core.params_batch().items():
                batch.setdefault(name, np.empty(self.batch_size))[live] = values[live]
        return batch

    def info_row(self, i: int) -> Info:
        """The info dict of environment ``i`` (Python scalars; ``params`` a dict of them)."""
        return self.info_rows()[i]

    def info_rows(self) -> list[Info]:
        """One info dict per environment (Python scalars; ``params`` a dict of them)."""
        arrays = {**self._info_arrays(), "n_trailers": self.trailers}
        columns = [values.tolist() for values in arrays.values()]
        rows: list[Info] = [
            dict(zip(arrays, values, strict=True)) for values in zip(*columns, strict=True)
        ]
        if self.randomization is not None:
            params = self.params_batch()
            names = list(params)
            entries = zip(*(params[name].tolist() for name in names), strict=True)
            for row, entry in zip(rows, entries, strict=True):
                row["params"] = dict(zip(names, entry, strict=True))
        return rows

    # ------------------------------------------------------ hand-built states
    def count_cores(self) -> dict[int, ConvoyCore]:
        """The scene core of each count."""
        return self.cores

    def row_core(self, i: int) -> ConvoyCore:
        """The core of row ``i``'s running episode (that of its n): its ``z``, ``act`` and
        task values are the row's state."""
        return self.cores[int(self.trailers[i])]

    def _core_for_state(self, z: object) -> ConvoyCore:
        """The core of the count a hand-built state ``z`` is for: the one whose full state
        (as ``get_state`` returns it) has ``z``'s length.

        Raises:
            ValueError: If ``z`` is not a flat vector of such a length.
        """
        shape = np.shape(z)  # type: ignore[call-overload]
        for core in self.cores.values():
            if shape == (core.z.shape[1],):
                return core
        top = self.cores[self.n]
        pose = ", then x, y, theta" if top.z.shape[1] > top.n + 2 else ""
        raise ValueError(
            f"z must be a state of n in {self.low}..{self.n} trailers as get_state() returns "
            f"it (u, omega, alpha_1..alpha_n{pose}), got shape {shape}"
        )

    def check_row_state(self, z: object, s: float = 0.0, s_dot: float = 0.0) -> np.ndarray:
        """:meth:`ConvoyCore.check_row_state` of the count ``z``'s length names."""
        return self._core_for_state(z).check_row_state(z, s, s_dot)

    def check_task(self, task: Mapping[str, object]) -> Info:
        """The scene's task values, checked as every count's core checks them."""
        return self.cores[self.n].check_task(task)

    def set_row_state(
        self, i: int, z: object, *, s: float = 0.0, s_dot: float = 0.0, **task: object
    ) -> None:
        """Start a new episode of row ``i`` in a hand-built state: the episode's n is the
        one ``z``'s length names (:meth:`_core_for_state`), the rest as
        :meth:`ConvoyCore.set_row_state`."""
        core = self._core_for_state(z)
        n = core.n
        core.set_row_state(i, z, s=s, s_dot=s_dot, **task)
        rows = np.array([i], dtype=np.int64)
        self.trailers[i] = n
        self.obs[i] = 0.0
        self._gather(n, rows)
        self.energy0[i] = core.energy0[i]


def mixed_settings(kwargs: Mapping[str, object]) -> dict[int, EnvSettings]:
    """Validated settings of every count of ``kwargs["n_trailers"]`` (a range).

    Raises:
        TypeError, ValueError: As :func:`trailer_range` and
            :func:`trailer_env.settings.settings_from_kwargs`.
    """
    low, high = trailer_range(kwargs["n_trailers"])
    rest = {key: value for key, value in kwargs.items() if key != "n_trailers"}
    if "params" in rest:
        raise ValueError("n_trailers as a range cannot be combined with params (one n each)")
    return {n: settings_from_keywords({"n_trailers": n, **rest}) for n in range(low, high + 1)}


def build_core(
    core_class: type[ConvoyCore], kwargs: Mapping[str, object], batch_size: int, track_pose: bool
) -> tuple[EnvSettings, BatchCore]:
    """The settings and the batch core the keywords ask for: a :class:`MixedCore` when
    ``n_trailers`` is a range, the scene's own core otherwise; in a
    :class:`~trailer_env.history.HistoryCore` with ``history=k``.

    Raises:
        TypeError, ValueError: On bad keywords, naming them; rendering with a range.
    """
    core: BatchCore
    if not is_trailer_range(kwargs.get("n_trailers")):
        settings = settings_from_keywords(kwargs)
        core = core_class(settings, batch_size, track_pose=track_pose)
    else:
        by_count = mixed_settings(kwargs)
        if track_pose:
            raise ValueError("rendering needs one number of trailers, not a range")
        core = MixedCore(core_class, by_count, batch_size)
        settings = core.settings
    if settings.history:
        core = HistoryCore(core, settings.history)
    return settings, core


def observation_view(core: BatchCore) -> ObservationView:
    """How the environments built on ``core`` (by :func:`build_core`) present its
    observations, as its settings' ``observation`` keyword asks
    (:mod:`trailer_env.observation`)."""
    settings = core.settings
    return ObservationView(
        settings.observation,
        settings.max_trailers,
        core.n,
        len(core.counts) > 1,
        core.observation_bounds(),
    )
