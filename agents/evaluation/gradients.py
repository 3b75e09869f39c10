"""The exact model's policy gradients against the horizon and n: their size, their spread,
and where they explode (the program: :mod:`agents.commands.gradients`).

A first-order learner (short-horizon backpropagation through the model, SHAC's lineage)
differentiates the return of an H-step rollout with respect to the policy's parameters.
Reversing a convoy is unstable, so how that gradient grows with H (and with n) decides
which horizons such a learner can use. Measured here on the headline scene through the
differentiable twin (:mod:`trailer_env.twin`, float64), for the simplest policy with
parameters: a linear feedback ``a = -K x`` on the regulator's state ``x = (omega,
alpha_1..alpha_n, s, s_dot)``, the rail acceleration clipped to its bound and sent as
the actuator's command (what ``lqr`` sends). Two points of parameter space:

* ``lqr``: K the LQR's gains at each start's speed (a stabilising policy: where a
  learner that starts from the regulator stands);
* ``zero``: K = 0 (the mass held still: the open-loop convoy, where a learner that
  starts from scratch stands).

For every start b the return ``R_b = sum_(t < H) r_t`` (the scene's reward, counted while
the episode runs; the mask that stops it has no gradient) is differentiated with respect
to that start's own copy of K (one backward pass gives every start's gradient g_b).
Reported per (policy, n, H): the median and the 90th percentile of ``|g_b|``, the norm of
the mean gradient, the spread ``sqrt(trace Cov(g_b))`` and the share of starts whose
gradient is not finite or above :data:`EXPLODED` ("exploded"). The starts are Reverse-v1
resets of the tuning seeds. :func:`write_gradients` writes ``gradients.md``,
``gradients.json`` and ``gradients.png`` (the median norm against H, one line per n and
policy) atomically.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import cast

import numpy as np

from agents.artifacts import files
from agents.envs import HEADLINE_ENV_ID
from agents.seeds import TUNING_SEED
from trailer_env.core import ConvoyCore

ENV_ID = HEADLINE_ENV_ID
POLICIES = ("lqr", "zero")
HORIZONS = (1, 2, 4, 8, 16, 32, 64, 128, 256)
OUTPUTS = ("gradients.md", "gradients.json", "gradients.png")
#: A per-start gradient norm above this counts as exploded (returns are O(H) <= 256).
EXPLODED = 1e6


def start_gains(n: int, policy: str, starts: int, seed: int) -> np.ndarray:
    """K (starts, n + 3) of ``policy`` at the starts of seeds ``seed ..``: the LQR's at
    each start's speed, or zeros."""
    if policy not in POLICIES:
        raise ValueError(f"policy must be one of {list(POLICIES)}, got {policy!r}")
    if policy == "zero":
        return np.zeros((starts, n + 3))
    from dynamics.columns import U
    from trailer_env.controllers import LQRController

    core = _reset(n, starts, seed)
    return LQRController(core.settings).gains(core.z[:, U])


def _reset(n: int, starts: int, seed: int) -> ConvoyCore:
    """A batch core of the headline scene reset to the starts of seeds ``seed ..``."""
    from trailer_env.registry import core_class_of
    from trailer_env.settings import settings_from_kwargs
    from trailer_env.vector import seed_generators

    core = core_class_of(ENV_ID)(settings_from_kwargs(n_trailers=n), starts)
    seeds = list(range(seed, seed + starts))
    core.reset_rows(np.arange(starts), seed_generators(seeds, starts, None))
    return core


def returns_and_gradients(
    n: int, gains: np.ndarray, horizons: Sequence[int], seed: int, differentiate: bool = True
) -> dict[int, tuple[np.ndarray, np.ndarray | None]]:
    """For every H of ``horizons``: the returns (starts,) of the H-step rollouts from the
    starts of seeds ``seed ..`` under ``a = -K x`` (K = ``gains`` (starts, n + 3), one row
    per start) and, when ``differentiate``, each start's gradient dR/dK (starts, n + 3)."""
    import torch

    from dynamics.columns import ALPHA, ETA, ETA_DOT, OMEGA
    from trailer_env.twin import TwinParams, TwinState, step

    starts = gains.shape[0]
    core = _reset(n, starts, seed)
    settings = core.settings
    params = TwinParams.from_core(core)
    state = TwinState.from_core(core)
    feedback = torch.tensor(gains, dtype=torch.float64, requires_grad=differentiate)
    accel_max = settings.rail_accel_max
    s_max = settings.params.s_max
    total = torch.zeros(starts, dtype=torch.float64)
    alive = torch.ones(starts, dtype=torch.float64)
    last = max(horizons)
    found: dict[int, tuple[np.ndarray, np.ndarray | None]] = {}
    with torch.set_grad_enabled(differentiate):
        for t in range(1, last + 1):
            z, act = state.z, state.act
            x = torch.cat(
                [z[:, OMEGA : OMEGA + 1], z[:, ALPHA : ALPHA + n], act[:, [ETA, ETA_DOT]]], dim=1
            )
            accel = torch.clamp(-(feedback * x).sum(dim=1), -accel_max, accel_max)
            # The actuator's inverse is plain arithmetic: on tensors it gives a tensor.
            command = cast(
                "torch.Tensor",
                settings.actuator.command_for_accel(
                    accel, act[:, ETA], act[:, ETA_DOT], s_max, accel_max, settings.servo_frequency
                ),
            )
            action = torch.clamp(command, -1.0, 1.0)[:, None]
            state, reward, _, terminated = step(state, action, params)
            total = total + alive * reward
            alive = alive * (~terminated).to(torch.float64)
            if t in horizons:
                gradient = None
                if differentiate:
                    (grad,) = torch.autograd.grad(total.sum(), feedback, retain_graph=t < last)
                    gradient = grad.numpy().copy()
                found[t] = (total.detach().numpy().copy(), gradient)
    return found


def _rollout_gradients(
    n: int, policy: str, horizons: Sequence[int], starts: int, seed: int
) -> dict[int, np.ndarray]:
    """Per-start gradients (starts, n + 3) of the H-step return for every H."""
    gains = start_gains(n, policy, starts, seed)
    found = returns_and_gradients(n, gains, horizons, seed)
    return {h: gradient for h, (_, gradient) in found.items() if gradient is not None}


def statistics(gradients: np.ndarray) -> dict[str, float]:
    """The figures of one cell from per-start gradients (starts, p)."""
    norms = np.linalg.norm(gradients, axis=1)
    finite = np.isfinite(norms)
    kept = gradients[finite & (norms <= EXPLODED)]
    mean = kept.mean(axis=0) if len(kept) else np.full(gradients.shape[1], np.nan)
    spread = float(np.sqrt(np.sum(kept.var(axis=0)))) if len(kept) > 1 else float("nan")
    return {
        "median_norm": float(np.median(norms[finite])) if finite.any() else float("nan"),
        "p90_norm": float(np.percentile(norms[finite], 90)) if finite.any() else float("nan"),
        "mean_gradient_norm": float(np.linalg.norm(mean)),
        "spread": spread,
        "exploded": float(np.mean(~finite | (norms > EXPLODED))),
    }


def measure(
    counts: Sequence[int], horizons: Sequence[int], starts: int, seed: int = TUNING_SEED
) -> dict[str, dict[int, dict[int, dict[str, float]]]]:
    """``{policy: {n: {H: statistics}}}`` for every policy of :data:`POLICIES`."""
    return {
        policy: {
            n: {
                h: statistics(gradient)
                for h, gradient in _rollout_gradients(n, policy, horizons, starts, seed).items()
            }
            for n in counts
        }
        for policy in POLICIES
    }


def _cell(value: float) -> str:
    return "-" if not np.isfinite(value) else f"{value:.3g}"


def markdown(
    found: dict[str, dict[int, dict[int, dict[str, float]]]], starts: int, seed: int
) -> str:
    """One table per policy: the median per-start norm (the exploded share beside it
    where any start exploded), rows n, columns H."""
    lines = []
    for policy, by_n in found.items():
        horizons = sorted(next(iter(by_n.values())))
        lines.append(f"**{policy}**: median |dR/dK| over {starts} starts (exploded share)\n")
        lines.append("| n | " + " | ".join(f"H = {h}" for h in horizons) + " |")
        lines.append("|---|" + "---|" * len(horizons))
        for n, by_h in by_n.items():
            cells = []
            for h in horizons:
                cell = by_h[h]
                text = _cell(cell["median_norm"])
                if cell["exploded"] > 0:
                    text += f" ({cell['exploded']:.0%})"
                cells.append(text)
            lines.append(f"| {n} | " + " | ".join(cells) + " |")
        lines.append("")
    lines.append(
        f"Reverse-v1 starts of seeds {seed}-{seed + starts - 1}, the twin in float64, "
        "H control steps of 0.05 s; `python -m agents.gradients` wrote it."
    )
    return "\n".join(lines) + "\n"


def draw(found: dict[str, dict[int, dict[int, dict[str, float]]]], out: Path) -> Path:
    """The median norm against H, one panel per policy, one line per n (log-log),
    written atomically."""
    from agents.evaluation.plots import PAGE_DPI, PAGE_WIDTH_PX, _pyplot, save_page_figure

    plt = _pyplot()
    fig, axes = plt.subplots(
        1,
        len(found),
        figsize=(PAGE_WIDTH_PX / PAGE_DPI, 3.4),
        squeeze=False,
        sharey=True,
        layout="constrained",
    )
    for axis, (policy, by_n) in zip(axes[0], found.items(), strict=True):
        for n, by_h in by_n.items():
            horizons = sorted(by_h)
            # A zero median (every start's acceleration saturated: no gradient) is left out
            # of the log axis.
            values = [by_h[h]["median_norm"] for h in horizons]
            shown = [value if value > 0.0 else np.nan for value in values]
            axis.loglog(horizons, shown, marker="o", label=f"n = {n}")
        axis.set_xscale("log", base=2)
        axis.set_xlabel("horizon H (control steps of 0.05 s)")
        axis.set_title(f"policy: {policy}", fontsize=10)
        axis.grid(alpha=0.3, which="both")
    axes[0][0].set_ylabel("median |dR/dK| per start")
    axes[0][-1].legend(fontsize=8)
    return save_page_figure(fig, plt, out)


def write_gradients(
    out: Path, counts: Sequence[int], horizons: Sequence[int], starts: int, seed: int
) -> str:
    """Measure, write :data:`OUTPUTS` into ``out`` atomically and return the table."""
    found = measure(counts, horizons, starts, seed)
    table = markdown(found, starts, seed)
    document = {
        "env_id": ENV_ID,
        "starts": starts,
        "seed": seed,
        "horizons": list(horizons),
        "exploded_above": EXPLODED,
        "by_policy": {
            policy: {str(n): {str(h): cell for h, cell in by_h.items()} for n, by_h in by_n.items()}
            for policy, by_n in found.items()
        },
    }
    out.mkdir(parents=True, exist_ok=True)
    files.atomic_write_text(out / OUTPUTS[0], table)
    files.write_json(out / OUTPUTS[1], document)
    draw(found, out / OUTPUTS[2])
    return table


def redraw(out: Path) -> str:
    """Write the table and the chart again from ``out``'s ``gradients.json`` (checked
    whole first); returns the table."""
    path = out / OUTPUTS[1]
    document = files.read_json(path)
    try:
        starts, seed = int(document["starts"]), int(document["seed"])
        found = {
            str(policy): {
                int(n): {
                    int(h): {str(k): float(v) for k, v in cell.items()} for h, cell in by_h.items()
                }
                for n, by_h in by_n.items()
            }
            for policy, by_n in document["by_policy"].items()
        }
    except (KeyError, TypeError, ValueError, AttributeError) as error:
        raise ValueError(f"{path} is not a gradients document: {error}") from None
    table = markdown(found, starts, seed)
    files.atomic_write_text(out / OUTPUTS[0], table)
    draw(found, out / OUTPUTS[2])
    return table
