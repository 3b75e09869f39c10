"""Start replay: train more often on the starts the policy has failed from.

A scene draws its starts from a fixed distribution, so a start that only a precise policy
saves (Reverse-v1's hardest need most of the rail's stroke) comes up a few times in a
hundred episodes, and a policy that already saves the others learns little more from
reward. :class:`StartReplay` keeps the starts of the training episodes that ended
without success and begins a share of the new episodes from them, as Prioritized Level
Replay (Jiang, Grefenstette and Rocktaeschel, 2021) replays the levels with the most to
learn, here with the episode's failure as the score::

    from trailer_env.sb3 import ConvoySB3VecEnv
    from trailer_env.start_replay import StartReplay

    venv = ConvoySB3VecEnv("trailer_env/Dock-v0", num_envs=64, n_trailers=2)
    venv.set_start_replay(StartReplay(0.25, seed=0))

The scene draws every start as before (each row's generator advances exactly as without
replay); a replayed row then has its drawn start replaced by a recorded one, taken out
of the buffer, and put back if that episode fails again. Replayed starts are the
scene's own (drawn earlier), so the training distribution leans towards the hard ones
without leaving the scene's support; evaluation environments are not touched. Under
drawn physics (``randomize``) a start is the state with the episode's drawn parameters:
a replay meets the same convoy that failed.
"""

from __future__ import annotations

import weakref

import numpy as np

from dynamics.params import bounded_integer, bounded_real
from trailer_env.core import ConvoyCore, StartRecord
from trailer_env.core_protocol import BatchCore

#: Starts kept by default: about a hundred rollouts' failures of a 64-env batch.
DEFAULT_CAPACITY = 4096


class StartReplay:
    """A buffer of failed starts and the share of new episodes begun from them.

    Args:
        fraction: Chance in (0, 1) that an episode starting while the buffer holds a
            start begins from one of them (drawn uniformly) rather than the scene's draw.
        capacity: Most starts kept, an integer >= 1; once full, a new failure replaces
            a stored start drawn uniformly.
        seed: Seed of the replay's own generator (which rows replay, which start).
        max_replays: A start leaves the buffer for good once this many of its replays
            have failed (an integer >= 1), so that starts the policy never saves, a
            scene's infeasible ones among them, do not fill the buffer; None: a start
            returns after every failure.

    Raises:
        TypeError, ValueError: On a bad argument, naming it.

    A replay serves one batch: the first batch it draws starts for is its own, and
    attaching it to another one (:meth:`check_core`) is refused while that batch lives;
    after it is gone, a batch of the same scene, size and settings may take the buffer
    over (its running episodes' starts are then learnt afresh).
    """

    def __init__(
        self,
        fraction: float,
        capacity: int = DEFAULT_CAPACITY,
        seed: int = 0,
        max_replays: int | None = None,
    ) -> None:
        self.fraction = bounded_real("fraction", fraction, 0.0, 1.0, low_open=True, high_open=True)
        self.capacity = bounded_integer("capacity", capacity, 1, 2**24)
        self.seed = bounded_integer("seed", seed, 0, 2**63 - 1)
        self.max_replays = (
            None if max_replays is None else bounded_integer("max_replays", max_replays, 1, 2**31)
        )
        self._rng = np.random.default_rng(self.seed)
        self._stored: StartRecord | None = None  # capacity rows, the first `size` in use
        self.size = 0
        self._stored_replays = np.zeros(self.capacity, dtype=np.int64)  # failed replays so far
        self._current: StartRecord | None = None  # every row's running episode's start
        self._current_replays = np.zeros(0, dtype=np.int64)
        self._known = np.zeros(0, dtype=bool)
        self._served: weakref.ref[BatchCore] | None = None  # the batch drawn for
        self._layout: tuple[object, ...] | None = None  # its scene, size and state widths
        #: Episodes begun from the buffer, and those of them that succeeded.
        self.replayed = 0
        self.replayed_successes = 0

    @property
    def replaying(self) -> np.ndarray:
        """Bool per row of the batch: its running episode began from the buffer."""
        return self._current_replays > 0

    def check_core(self, core: object) -> None:
        """Refuse a batch whose starts cannot be recorded (mixed counts of trailers) or
        that this replay cannot serve (it serves another batch that still lives, or holds
        starts of another scene, size, state or physics draw), changing nothing.

        Raises:
            ValueError: Naming the reason.
        """
        if not isinstance(core, BatchCore) or len(core.counts) > 1:
            raise ValueError("start replay needs one count of trailers, not a mix")
        served = self._served() if self._served is not None else None
        if served is not None and served is not core:
            raise ValueError(
                "this StartReplay serves another batch; give each batch its own StartReplay"
            )
        layout = _layout(core.row_core(0))
        if self._layout is not None and self._layout != layout:
            raise ValueError(
                f"this StartReplay holds starts of {_describe(self._layout)}, not of "
                f"{_describe(layout)}; give each batch its own StartReplay"
            )

    def attach(self, core: BatchCore) -> None:
        """Serve ``core`` from now on (:meth:`check_core` first; the buffer is kept).

        Raises:
            ValueError: As :meth:`check_core`, changing nothing.
        """
        self.check_core(core)
        if self._served is None or self._served() is not core:
            if self._served is not None:
                self._current = None  # another batch's running episodes are not this one's
            self._served = weakref.ref(core)
            self._layout = _layout(core.row_core(0))

    def detach(self) -> None:
        """Serve no batch any more (the buffer is kept): another batch may attach it."""
        self._served = None
        self._current = None

    def __getstate__(self) -> dict[str, object]:
        """Pickle all but the reference to the batch served (a weak reference); the
        unpickled replay serves the first batch of its layout it draws for, keeping the
        running episodes' starts (the batch pickled with it)."""
        state = self.__dict__.copy()
        state["_served"] = None
        return state

    def episodes_ended(self, rows: np.ndarray, succeeded: np.ndarray) -> None:
        """Keep the starts of the episodes of ``rows`` that ended without success
        (``succeeded``: one bool per row); call it before the rows are reset. Episodes
        that began before the replay was attached are not kept (their start is unknown)."""
        if self._current is None:
            return  # no episode has begun under the replay: no start known
        replayed = self._current_replays[rows] > 0
        self.replayed += int(np.count_nonzero(replayed))
        self.replayed_successes += int(np.count_nonzero(replayed & succeeded))
        keep = ~succeeded & self._known[rows]
        if self.max_replays is not None:
            keep &= self._current_replays[rows] < self.max_replays
        failed = rows[keep]
        if failed.size:
            self._store(_take(self._current, failed), self._current_replays[failed])

    def starts_drawn(self, batch: BatchCore, rows: np.ndarray) -> None:
        """After the scene drew the starts of ``rows``: begin a share of them from the
        buffer instead, and record every row's start.

        Raises:
            ValueError: As :meth:`check_core`, before anything changes.
        """
        if self._served is None or self._served() is not batch:
            self.attach(batch)
        core = batch.row_core(0)  # one count (check_core): the batch's own core
        if self._current is None:
            self._current = core.start_records(np.arange(core.batch_size))
            self._known = np.zeros(core.batch_size, dtype=bool)
            self._current_replays = np.zeros(core.batch_size, dtype=np.int64)
        chosen = self._rng.random(rows.size) < self.fraction
        replay = rows[chosen][: self.size]
        self._current_replays[rows] = 0
        if replay.size:
            picks = self._rng.choice(self.size, size=replay.size, replace=False)
            assert self._stored is not None
            core.restart(replay, _take(self._stored, picks))
            self._current_replays[replay] = self._stored_replays[picks] + 1
            self._remove(picks)
        started = core.start_records(rows)
        self._known[rows] = True
        _put(self._current, rows, started)

    def _store(self, record: StartRecord, replays: np.ndarray) -> None:
        count = record.z.shape[0]
        if self._stored is None:
            self._stored = StartRecord(
                np.zeros((self.capacity, *record.z.shape[1:])),
                np.zeros((self.capacity, *record.act.shape[1:])),
                {key: np.zeros((self.capacity, *v.shape[1:])) for key, v in record.task.items()},
                None
                if record.factors is None
                else np.zeros((self.capacity, *record.factors.shape[1:])),
            )
        free = min(self.capacity - self.size, count)
        slots = np.concatenate(
            [
                np.arange(self.size, self.size + free),
                self._rng.integers(0, self.capacity, count - free),
            ]
        )
        self.size += free
        _put(self._stored, slots, record)
        self._stored_replays[slots] = replays

    def _remove(self, picks: np.ndarray) -> None:
        """Take ``picks`` out of the buffer (the others keep their order)."""
        assert self._stored is not None
        keep = np.ones(self.size, dtype=bool)
        keep[picks] = False
        kept = np.flatnonzero(keep)
        self.size = kept.size
        stored = self._stored
        factors = () if stored.factors is None else (stored.factors,)
        for array in (stored.z, stored.act, self._stored_replays, *stored.task.values(), *factors):
            array[: self.size] = array[kept]


def _layout(core: ConvoyCore) -> tuple[object, ...]:
    """What a batch's start records depend on: scene, batch size, widths, task keys and
    whether it draws its physics."""
    return (
        type(core).__name__,
        core.batch_size,
        core.z.shape[1],
        core.act.shape[1],
        core.task_keys,
        core.randomization is not None,
    )


def _describe(layout: tuple[object, ...]) -> str:
    scene, size, width = layout[:3]
    physics = "drawn" if layout[5] else "fixed"
    return f"{scene} with {size} environments, {width} state columns and {physics} physics"


def _put(target: StartRecord, index: np.ndarray, record: StartRecord) -> None:
    """Write ``record``'s entries into ``target`` at ``index``."""
    target.z[index] = record.z
    target.act[index] = record.act
    for key, values in record.task.items():
        target.task[key][index] = values
    if target.factors is not None and record.factors is not None:
        target.factors[index] = record.factors


def _take(record: StartRecord, index: np.ndarray) -> StartRecord:
    return StartRecord(
        record.z[index],
        record.act[index],
        {key: values[index] for key, values in record.task.items()},
        None if record.factors is None else record.factors[index],
    )
