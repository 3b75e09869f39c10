"""The results of the README: every scene's baselines and committed agents, tables and pictures.

Run with ``python -m agents.report [--img docs/img] [--out out/report] [--episodes 100]``.

For every scene and number of trailers that a committed model was trained on it
evaluates the scene's baselines, its oracle (the ``mpc`` planner, where the scene has
one; ``--no-planner`` leaves it out) and every committed model (``agents/models/``,
with its training seeds from ``agents/models/seeds/``) on the same seeded episodes
(seeds 1000 ..), prints one Markdown table per scene with its ceiling line
(:func:`agents.oracles.certify.ceiling_note`; also written to ``<out>/tables.md`` with the
JSON results), and writes the pictures ``agents_curves.png`` (learning curves of all
committed agents), ``agents_margins_reverse_v1_n2.png`` and
``agents_frames_reverse_v1_n2.png`` to ``--img``. A last table sweeps the actuator's
authority (stroke, acceleration bound, mass) under the LQR baseline. With the planner
it takes about three minutes on two cores, about one without.

``--out`` and ``--img`` must be writable folders (no file in the way, no symbolic
link among the files written) and ``--episodes`` at most 100,000: checked before
the first episode. Every file is written atomically.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from agents.artifacts import files
from agents.artifacts.shipped import committed_models
from agents.commands import options as cli
from agents.envs import scene_baselines
from agents.evaluation import plots
from agents.evaluation.pictures import write_pictures
from agents.evaluation.report import HEADLINE, SCENARIOS, authority_table, curve_panel
from agents.evaluation.results import (
    curve_metric,
    default_baselines,
    evaluate_policies,
    results_document,
)
from agents.evaluation.tables import markdown_table
from agents.oracles.certify import ceiling_note
from agents.policies.sb3 import limit_torch_threads
from agents.seeds import TEST_SEED


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    parser = argparse.ArgumentParser(
        prog="python -m agents.report", description=(__doc__ or "").split("\n")[0]
    )
    parser.add_argument("--img", type=Path, default=Path("docs/img"), help="picture folder")
    parser.add_argument("--out", type=Path, default=Path("out/report"), help="tables and JSON")
    cli.add_episodes(parser, 100, "episodes per policy (default 100)")
    parser.add_argument(
        "--no-planner", action="store_true", help="leave the scenes' oracle (mpc) out"
    )
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (bad arguments exit with 2)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    cli.check_out_folder(parser, args.out, files_in=("tables.md", "results.json"))
    cli.check_out_folder(
        parser,
        args.img,
        "--img",
        files_in=("agents_curves.png", "agents_margins.png", "agents_frames.png",
                  "agents_margins_reverse_v1_n2.png", "agents_frames_reverse_v1_n2.png"),
    )  # fmt: skip
    cli.check_seeds(parser, TEST_SEED, args.episodes)
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
                files.refuse_symlink(final)
                path.replace(final)
                print(f"wrote {final}")
    sweep = authority_table(args.episodes)
    sections.append(f"#### LQR on Reverse-v0 as the actuator gets stronger\n\n{sweep}")
    print(sections[-1], flush=True)
    grid = plots.plot_curve_grid(
        [panel for panel in panels if panel[1]], args.img / "agents_curves.png"
    )
    print(f"wrote {grid}")
    files.atomic_write_text(args.out / "tables.md", "\n".join(sections))
    files.write_json(args.out / "results.json", documents)
    print(f"wrote {args.out / 'tables.md'} in {time.perf_counter() - started:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
