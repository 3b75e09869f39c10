"""The results of the README: every scene's baselines and committed agents, tables and pictures.

Run with ``python -m agents.report [--img docs/img] [--out out/report] [--episodes 100]``.

For every scene and number of trailers that a committed model was trained on it
evaluates the scene's baselines, its oracle (the ``mpc`` planner, where the scene has
one; ``--no-planner`` leaves it out) and every committed model (``agents/models/``,
with its training seeds from ``agents/models/seeds/``) on the same seeded episodes
(seeds 1000 ..), prints one Markdown table per scene with its ceiling line
(:func:`agents.certify.ceiling_note`; also written to ``<out>/tables.md`` with the
JSON results), and writes the pictures ``agents_curves.png`` (learning curves of all
committed agents), ``agents_margins_reverse_v1_n2.png`` and
``agents_frames_reverse_v1_n2.png`` to ``--img``. A last table sweeps the actuator's
authority (stroke, acceleration bound, mass) under the LQR baseline. With the planner
it takes about three minutes on two cores, about one without.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from agents import cli, plots
from agents.certify import ceiling_note
from agents.envs import ENV_IDS, scene_baselines, scene_title
from agents.evaluate import (
    TEST_SEED,
    Evaluation,
    baseline_levels,
    committed_models,
    curve_metric,
    default_baselines,
    evaluate_policies,
    learning_curve,
    markdown_table,
    results_document,
    write_pictures,
)
from agents.policies import MODELS_DIR, limit_torch_threads, read_card


def committed_scenarios(directory: Path = MODELS_DIR) -> tuple[tuple[str, int], ...]:
    """(environment id, number of trailers) of every committed model's card, in the scene
    table's order, then by n: the scenarios the README reports."""
    found = set()
    for path in directory.glob("*.zip"):
        card = read_card(path)
        env_id, n = card.get("env_id"), card.get("env_kwargs", {}).get("n_trailers")
        if env_id in ENV_IDS and isinstance(n, int):
            found.add((env_id, n))
    return tuple(sorted(found, key=lambda scenario: (ENV_IDS.index(scenario[0]), scenario[1])))


#: (environment id, number of trailers) of the README's results.
SCENARIOS: tuple[tuple[str, int], ...] = committed_scenarios()
#: The scenario whose margins and frames are drawn.
HEADLINE = ("trailer_env/Reverse-v1", 2)
#: Actuator settings of the authority sweep (ConvoyParams / EnvSettings overrides).
AUTHORITY_SWEEP: tuple[dict[str, float], ...] = (
    {},
    {"s_max": 1.0},
    {"rail_accel_max": 8.0},
    {"s_max": 1.0, "rail_accel_max": 8.0},
    {"mu": 1.0},
)


def authority_table(episodes: int, seed: int = TEST_SEED) -> str:
    """The LQR baseline's safe rate on Reverse-v0 as the actuator gets stronger (Markdown).

    Defaults: mass mu = 0.5, stroke s_max = 0.5 m, acceleration bound 4 m/s^2.
    """
    env_id = "trailer_env/Reverse-v0"
    lines = [
        "| actuator (changes from the defaults) | n = 2 safe | n = 3 safe |",
        "|---|---|---|",
    ]
    for changes in AUTHORITY_SWEEP:
        rates = []
        for n in (2, 3):
            env_kwargs = {"n_trailers": n, **changes}
            (evaluation,) = evaluate_policies(["lqr"], env_id, env_kwargs, episodes, seed)
            rates.append(f"{100 * evaluation.summary['safe_rate']:.0f}%")
        name = ", ".join(f"{key} = {value:g}" for key, value in changes.items()) or "defaults"
        lines.append(f"| {name} | {rates[0]} | {rates[1]} |")
    return "\n".join(lines) + "\n"


def curve_panel(
    env_id: str, n: int, evaluations: list[Evaluation]
) -> tuple[str, dict[str, Path], dict[str, float], str]:
    """One panel of the learning-curve grid: the models' curves and the baselines' levels."""
    metric = curve_metric(env_id)
    curves = {}
    for evaluation in evaluations:
        curve = learning_curve(evaluation)
        if evaluation.card and curve is not None:
            name = str(evaluation.card.get("algo", evaluation.label)).upper()
            if evaluation.card.get("recipe") == "dagger":
                name = "DAgger (PPO policy)"
            curves[name] = curve
    levels = baseline_levels(evaluations, metric)
    return f"{scene_title(env_id)}, n = {n}", curves, levels, metric


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status."""
    parser = argparse.ArgumentParser(
        prog="python -m agents.report", description=(__doc__ or "").split("\n")[0]
    )
    parser.add_argument("--img", type=Path, default=Path("docs/img"), help="picture folder")
    parser.add_argument("--out", type=Path, default=Path("out/report"), help="tables and JSON")
    cli.add_episodes(parser, 100, "episodes per policy (default 100)")
    parser.add_argument(
        "--no-planner", action="store_true", help="leave the scenes' oracle (mpc) out"
    )
    args = parser.parse_args(argv)
    limit_torch_threads()
    started = time.perf_counter()
    args.out.mkdir(parents=True, exist_ok=True)
    sections, documents, panels = [], [], []
    for env_id, n in SCENARIOS:
        env_kwargs = {"n_trailers": n}
        oracles = [] if args.no_planner else list(scene_baselines(env_id, oracles=True))
        oracles = [name for name in oracles if name not in default_baselines(env_id)]
        models = [str(path) for path in committed_models(env_id, n)]
        specs = [*default_baselines(env_id), *oracles, *models]
        evaluations = evaluate_policies(specs, env_id, env_kwargs, args.episodes, TEST_SEED)
        heading = (
            f"{env_id}, n = {n}: {args.episodes} episodes, seeds "
            f"{TEST_SEED}..{TEST_SEED + args.episodes - 1}"
        )
        ceiling = ceiling_note(env_id, n, args.episodes, TEST_SEED)
        table = markdown_table(evaluations, curve_metric(env_id))
        sections.append(f"#### {heading}\n\n{table}\n{ceiling}\n")
        documents.append(
            results_document(evaluations, env_id, env_kwargs, args.episodes, TEST_SEED)
        )
        panels.append(curve_panel(env_id, n, evaluations))
        print(sections[-1], flush=True)
        if (env_id, n) == HEADLINE:
            for path in write_pictures(
                evaluations, env_id, env_kwargs, args.img, TEST_SEED, prefix="agents_"
            ):
                if path.name == "agents_curves.png":
                    path.unlink()  # replaced by the grid of every scenario below
                    continue
                final = path.with_name(path.stem + "_reverse_v1_n2.png")
                path.replace(final)
                print(f"wrote {final}")
    sweep = authority_table(args.episodes)
    sections.append(f"#### LQR on Reverse-v0 as the actuator gets stronger\n\n{sweep}")
    print(sections[-1], flush=True)
    grid = plots.plot_curve_grid(
        [panel for panel in panels if panel[1]], args.img / "agents_curves.png"
    )
    print(f"wrote {grid}")
    (args.out / "tables.md").write_text("\n".join(sections))
    (args.out / "results.json").write_text(json.dumps(documents, indent=2, sort_keys=True) + "\n")
    print(f"wrote {args.out / 'tables.md'} in {time.perf_counter() - started:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
