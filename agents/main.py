"""The main job: the committed agent against the baselines on Reverse-v0 with two trailers.

Run with ``python -m agents.main [--out DIR] [--episodes K] [--train-steps N] [--retrain
[--overwrite]]``.

1. Load the committed agents for ``trailer_env/Reverse-v0``, n = 2
   (``agents/models/*.zip`` whose card names that scene), or, when there are none
   (or with ``--retrain``), train PPO on a short budget into ``<out>/run``; a run
   already there is replaced only with ``--overwrite``.
2. Evaluate them and the baselines (zero, random, LQR) on K seeded episodes
   (seeds 1000 .. 1000 + K - 1) in one native batch per policy.
3. Print the comparison table and write ``results.json``, ``results.md``,
   ``margins.png``, ``frames.png`` and ``curves.png`` to ``--out`` (default ``out``).

It takes well under a minute with the committed models, a few minutes when it trains.
"""

from __future__ import annotations

import argparse
import json
import shutil
import time
from pathlib import Path

from agents import cli
from agents.envs import env_settings
from agents.evaluate import (
    TEST_SEED,
    committed_models,
    default_baselines,
    evaluate_policies,
    markdown_table,
    results_document,
    write_pictures,
)
from agents.model_files import export_files, model_stem
from agents.policies import limit_torch_threads
from agents.run_folder import export_model

ENV_ID = "trailer_env/Reverse-v0"
N_TRAILERS = 2
#: Budget of the fallback training (steps): about a minute of PPO on two cores.
SHORT_BUDGET = 1_000_000


def short_run_files(out: Path) -> list[Path]:
    """What :func:`train_short` writes under ``out`` and would replace: its run, its export."""
    return [out / "run", *export_files(_short_export(out))]


def _short_export(out: Path) -> Path:
    return out / f"{model_stem('ppo', ENV_ID, N_TRAILERS)}.zip"


def train_short(out: Path, budget: int, seed: int = 0, overwrite: bool = False) -> Path:
    """Train PPO on Reverse-v0 (n = 2) for ``budget`` steps; returns the exported model.

    Raises:
        FileExistsError: If ``out`` already holds such a run (or its export) and
            ``overwrite`` is false.
    """
    from agents.config import TrainConfig, load_hyperparams
    from agents.train import train

    run_dir = out / "run"
    existing = [path for path in short_run_files(out) if path.exists()]
    if existing and not overwrite:
        raise FileExistsError(f"{existing[0]} exists; pass --overwrite to replace it")
    shutil.rmtree(run_dir, ignore_errors=True)
    print(f"no committed agent: training PPO for {budget} steps into {run_dir} ...", flush=True)
    command = ("python", "-m", "agents.main", "--train-steps", str(budget))
    config = TrainConfig.resolve(
        ENV_ID,
        "ppo",
        N_TRAILERS,
        seed,
        load_hyperparams("ppo", ENV_ID),
        timesteps=budget,
        command=command,
    )
    train(config, run_dir, eval_freq=max(budget // 10, 1), progress_bar=False)
    return export_model(run_dir, _short_export(out), overwrite=overwrite)


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status."""
    parser = argparse.ArgumentParser(
        prog="python -m agents.main", description=(__doc__ or "").split("\n")[0]
    )
    parser.add_argument("--out", type=Path, default=Path("out"), help="output folder (default out)")
    cli.add_episodes(parser, 100, "evaluation episodes (default 100)")
    parser.add_argument(
        "--train-steps",
        type=cli.at_least(1),
        default=SHORT_BUDGET,
        help=f"budget when training (default {SHORT_BUDGET})",
    )
    parser.add_argument(
        "--retrain", action="store_true", help="train a fresh agent even if committed ones exist"
    )
    cli.add_overwrite(
        parser, "with --retrain: replace the run (and exported model) already in --out"
    )
    args = parser.parse_args(argv)
    cli.check_out_folder(parser, args.out)
    limit_torch_threads()
    started = time.perf_counter()
    models = [] if args.retrain else committed_models(ENV_ID, N_TRAILERS)
    if not models:
        existing = [path for path in short_run_files(args.out) if path.exists()]
        if existing and not args.overwrite:
            parser.error(
                f"argument --out: {existing[0]} holds an earlier run; pass --overwrite "
                "to replace it, or another --out"
            )
        models = [train_short(args.out, args.train_steps, overwrite=args.overwrite)]
    env_kwargs = {"n_trailers": N_TRAILERS}
    env_settings(env_kwargs)
    specs = [*default_baselines(ENV_ID), *(str(path) for path in models)]
    evaluations = evaluate_policies(specs, ENV_ID, env_kwargs, args.episodes, TEST_SEED)
    args.out.mkdir(parents=True, exist_ok=True)
    document = results_document(evaluations, ENV_ID, env_kwargs, args.episodes, TEST_SEED)
    (args.out / "results.json").write_text(json.dumps(document, indent=2, sort_keys=True) + "\n")
    table = markdown_table(evaluations)
    (args.out / "results.md").write_text(table)
    print(
        f"\n{ENV_ID}, n = {N_TRAILERS}: {args.episodes} episodes, seeds "
        f"{TEST_SEED}..{TEST_SEED + args.episodes - 1}; safe = never in the singular band "
        "(margin < 0.3), never folded, never stopped reversing\n"
    )
    print(table)
    for path in write_pictures(evaluations, ENV_ID, env_kwargs, args.out, TEST_SEED):
        print(f"wrote {path}")
    print(f"done in {time.perf_counter() - started:.0f} s; results in {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
