"""Which physical parameters matter: the LQR on Reverse-v1 with one parameter scaled.

Run with ``python -m benchmarks.parameter_mismatch [--quick]``.

For n = 2 and 3, each parameter of :class:`dynamics.ConvoyParams` is scaled by 0.8 and
1.2 in turn (``gym.make(..., M=0.8 * M0)``). Recorded per case: the relative change
``|K - K0| / |K0|`` of the reversing gain at ``u = -1 m/s``, and the safe rate of the
LQR with the nominal gains and re-designed for the true parameters, on 100 episodes
(seeds 1000-1099; ``--quick``: 10). Then the presets ``randomize="mismatch10"`` and
``"mismatch20"``: the nominal LQR against ``lqr-adaptive`` (re-designed per episode).

The committed output: ``benchmarks/results/parameter_mismatch.csv``; the table is in
docs/physics.md, section "Parameter mismatch".
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from agents.envs import HEADLINE_ENV_ID
from agents.policies.baselines import AdaptiveLQRPolicy, LQRPolicy
from benchmarks._common import one_thread, parse_command, report_written, write_csv
from trailer_env.benchmark import rollout
from trailer_env.controllers import regulator_gain
from trailer_env.settings import settings_from_kwargs

SCENE = HEADLINE_ENV_ID
SEED = 1000
FACTORS = (0.8, 1.2)
PARAMETERS = ("M", "J0", "a", "m", "J", "l", "mu")


def safe_rate(policy: Any, episodes: int, kwargs: dict[str, Any]) -> float:
    """Share of safe episodes of ``policy`` on Reverse-v1 with env keywords ``kwargs``."""
    return float(rollout(policy, SCENE, episodes, SEED, kwargs).safe.mean())


def cases(n: int, episodes: int) -> list[dict[str, Any]]:
    """One row per scaled parameter and per preset, for ``n`` trailers."""
    nominal = settings_from_kwargs(n_trailers=n)
    gain0 = regulator_gain(nominal, -1.0)
    base = safe_rate(LQRPolicy(nominal), episodes, {"n_trailers": n})
    rows = [dict(n=n, change="none", gain_change=0.0, nominal_gains=base, redesigned=base)]
    for name in PARAMETERS:
        for factor in FACTORS:
            kwargs = {"n_trailers": n, name: getattr(nominal.params, name) * factor}
            changed = settings_from_kwargs(**kwargs)
            gain = regulator_gain(changed, -1.0)
            rows.append(
                dict(
                    n=n,
                    change=f"{name} x {factor}",
                    gain_change=float(np.linalg.norm(gain - gain0) / np.linalg.norm(gain0)),
                    nominal_gains=safe_rate(LQRPolicy(nominal), episodes, kwargs),
                    redesigned=safe_rate(LQRPolicy(changed), episodes, kwargs),
                )
            )
            print(_line(rows[-1]), flush=True)
    for preset in ("mismatch10", "mismatch20"):
        kwargs = {"n_trailers": n, "randomize": preset}
        adaptive = AdaptiveLQRPolicy(settings_from_kwargs(**kwargs))
        rows.append(
            dict(
                n=n,
                change=f"randomize={preset}",
                gain_change=float("nan"),
                nominal_gains=safe_rate(LQRPolicy(nominal), episodes, kwargs),
                redesigned=safe_rate(adaptive, episodes, kwargs),
            )
        )
        print(_line(rows[-1]), flush=True)
    return rows


def _line(row: dict[str, Any]) -> str:
    return (
        f"n={row['n']} {row['change']}: gain change {100 * row['gain_change']:.1f} %, "
        f"safe {100 * row['nominal_gains']:.0f} % (nominal gains), "
        f"{100 * row['redesigned']:.0f} % (re-designed)"
    )


def main(argv: list[str] | None = None) -> None:
    """Run every case and write ``parameter_mismatch.csv``."""
    args = parse_command(
        "python -m benchmarks.parameter_mismatch", __doc__, "10 episodes instead of 100", argv
    )
    start = time.perf_counter()
    episodes = 10 if args.quick else 100
    with one_thread():
        rows = [row for n in (2, 3) for row in cases(n, episodes)]
    write_csv(args.results / "parameter_mismatch.csv", rows)
    report_written(f"{args.results / 'parameter_mismatch.csv'}", start)


if __name__ == "__main__":
    main()
