"""The core's retry of a diverged step: redo the rows with more substeps, or give up.

:class:`RetryMixin` is part of :class:`trailer_env.core.ConvoyCore` (its
``step`` calls these methods; the module docstring of :mod:`trailer_env.core` states the
contract: a step whose result is not finite is redone once with :data:`RETRY_FACTOR`
times the substeps, else every stepped row is put back and FloatingPointError raised).
"""

from __future__ import annotations

import numpy as np

from dynamics.columns import OMEGA, U
from trailer_env.core_base import CoreBase
from trailer_env.kernels import OBS_BOUND
from trailer_env.substeps import GROWTH_LIMIT, MAX_STEP_WORK

#: Substeps used to retry a step whose result was not finite (never seen with "auto").
RETRY_FACTOR = 8


class RetryMixin(CoreBase):
    """The retry and refusal paths of :class:`trailer_env.core.ConvoyCore`'s step."""

    def _refuse_over_budget(self, rows: np.ndarray) -> None:
        """Raise FloatingPointError for a step the auto rule priced over the work budget."""
        counts = self.substeps[rows]
        worst = int(rows[int(np.argmax(counts))])
        work = float(counts.sum()) * (self.n + 1)
        raise FloatingPointError(
            f"the step would take {work:.3g} body-substeps (substeps x {self.n + 1} bodies, "
            f"summed over {rows.size} environment(s)), over the budget of {MAX_STEP_WORK:.3g} "
            f"per control step (trailer_env.substeps.MAX_STEP_WORK): environment {worst} at "
            f"u = {self.z[worst, U]:.4g} m/s, omega = {self.z[worst, OMEGA]:.4g} rad/s needs "
            f"{int(self.substeps[worst])} substeps; nothing was stepped (lower the speed, dt, "
            "the number of environments or of trailers)"
        )

    def _retry_finer(self, action: np.ndarray, stepped: np.ndarray) -> None:
        """Redo the rows whose step produced non-finite (or beyond the divergence bound)
        values with more substeps, or give up.

        Only the failed rows are redone; their substep counts are restored afterwards with
        fixed substeps (the auto rule recomputes them at every step anyway).
        """
        rows = stepped[self.step_outputs.nonfinite[stepped]].astype(np.int64)
        self.z[rows] = self.step_state.z_backup[rows]
        self.act[rows] = self.step_state.act_backup[rows]
        used = self.substeps[rows].copy()
        if float(used.sum()) * RETRY_FACTOR * (self.n + 1) > MAX_STEP_WORK:
            self._give_up(stepped, rows, "non-finite or beyond the divergence bound", retried=False)
        self.substeps[rows] = used * RETRY_FACTOR
        try:
            _, nonfinite, _ = self._physics_step(action, rows, False, outcome=False)
        finally:
            if not self.settings.fidelity.auto:
                self.substeps[rows] = used
        if nonfinite:
            failed = rows[self.step_outputs.nonfinite[rows]]
            values = self.z[failed]
            grew = (
                self.accuracy_exceeded[failed].all()
                and np.isnan(values[:, U]).all()
                and np.all(np.isfinite(values[:, OMEGA:]))
            )
            if np.all(np.isfinite(values)):
                bound = self.step_config.obs_settings[OBS_BOUND]
                cause = f"a value beyond {bound:g} in magnitude"
            elif grew:  # marked by the step kernel (trailer_env.substeps.GROWTH_LIMIT)
                cause = (
                    f"a speed max(|u|, l |omega|) more than {GROWTH_LIMIT:g} times its start's "
                    "while fidelity.max_substeps = "
                    f"{self.settings.fidelity.max_substeps} capped the substeps"
                )
            else:
                cause = "a non-finite value (NaN or inf)"
            shown = f"u = {values[0, U]:.4g} m/s" if np.isfinite(values[0, U]) else ""
            self._give_up(stepped, failed, cause + (f", {shown}" if shown else ""), retried=True)

    def _give_up(
        self, stepped: np.ndarray, failed: np.ndarray, cause: str, *, retried: bool
    ) -> None:
        """Put every stepped row back at its state before the step and raise FloatingPointError."""
        self.z[stepped] = self.step_state.z_backup[stepped]
        self.act[stepped] = self.step_state.act_backup[stepped]
        self.refresh(stepped)
        self._after_restore(stepped)
        how = (
            f"even with {RETRY_FACTOR} times the substeps"
            if retried
            else f"(a retry with {RETRY_FACTOR} times the substeps would exceed the work budget)"
        )
        raise FloatingPointError(
            f"the integration diverged in environment(s) {failed.tolist()[:8]}: the step's "
            f"result holds {cause}, {how}; the state was left at the previous step "
            "(use fidelity='auto', more substeps or a smaller dt)"
        )
