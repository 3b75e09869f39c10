"""The results pages: every scene's baselines and committed agents, tables and pictures.

Run with ``python -m agents.report [--out out/report] [--docs docs] [--episodes 100]``.

For every scene and number of trailers that a committed model was trained on it
evaluates the scene's baselines, its oracle (the ``mpc`` planner, where the scene has
one; ``--no-planner`` leaves it out) and every committed model (``agents/models/``,
with its training seeds from ``agents/models/seeds/``) on the same seeded episodes
(seeds 1000 ..), prints one Markdown table per scene with its ceiling line
(:func:`agents.evaluation.ceiling.ceiling_note`), and writes ``<out>/tables.md``,
``<out>/results.json`` and the pictures ``agents_curves.png`` (learning curves of all
committed agents), ``agents_margins_reverse_v1_n2.png`` and
``agents_frames_reverse_v1_n2.png`` to ``<out>/img``, and the leaderboard in pictures
(:mod:`agents.evaluation.leaderboard`): ``agents_leaderboard.png``, every scenario, and
``agents_leaderboard_reverse_v1.png``, the headline scene. A last table sweeps the
actuator's authority (stroke, acceleration bound, mass) under the LQR baseline.

By default it writes nothing that git tracks. ``--docs DIR`` (the site's folder,
``docs``) also writes the tables to ``DIR/generated/results_tables.md``, which the
results page includes, and the pictures to ``DIR/img``. Its time on this machine is in
the docs (Reproduce); progress goes to standard error.

``--out`` and ``--docs`` must be writable folders (no file in the way, no symbolic
link among the files written) and ``--episodes`` at most 100,000: checked before the
first episode. Every file is written atomically.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from agents.artifacts import files
from agents.artifacts.results import ResultsDocument
from agents.artifacts.shipped import models_covering
from agents.commands import options as cli
from agents.evaluation import leaderboard, plots
from agents.evaluation.pictures import write_pictures
from agents.evaluation.report import (
    HEADLINE,
    SCENARIOS,
    CurvePanel,
    authority_table,
    curve_panel,
    report_order,
    scenario_section,
    scenario_slug,
    tables_document,
)
from agents.evaluation.results import (
    default_baselines,
    evaluate_policies,
    results_document,
)
from agents.evaluation.time_to_ceiling import TIME_TO_CEILING_LEGEND, time_to_ceiling_table
from agents.policies.baselines import BASELINES, applicable_baselines
from agents.policies.sb3 import limit_torch_threads
from agents.progress import Progress, duration
from agents.seeds import FRESH_SEED, TEST_SEED

#: The oracles the report evaluates by default: the sampling planner and the replay of the
#: certificate's records (seconds a scenario); iLQR takes minutes a scenario (``--oracle``).
DEFAULT_ORACLES = ("mpc", "mpc-replay")

#: The pictures the report writes (under ``<out>/img`` or ``<docs>/img``).
PICTURES = (
    "agents_curves.png",
    "agents_margins.png",
    "agents_frames.png",
    "agents_margins_reverse_v1_n2.png",
    "agents_frames_reverse_v1_n2.png",
    "agents_leaderboard.png",
    "agents_leaderboard_reverse_v1.png",
)


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    parser = argparse.ArgumentParser(
        prog=cli.program("agents.report"), description=(__doc__ or "").split("\n")[0]
    )
    parser.add_argument(
        "--out",
        type=Path,
        default=Path("out/report"),
        help="tables, JSON and img/ (default out/report)",
    )
    parser.add_argument(
        "--docs",
        type=Path,
        default=None,
        metavar="DIR",
        help="also write the site's generated tables and pictures under DIR (e.g. docs)",
    )
    cli.add_episodes(parser, 100, "episodes per policy (default 100)")
    parser.add_argument("--no-planner", action="store_true", help="leave the scenes' oracles out")
    parser.add_argument(
        "--oracle",
        nargs="+",
        default=list(DEFAULT_ORACLES),
        metavar="NAME",
        help="the oracles to evaluate where they fit the scene (default: "
        f"{' '.join(DEFAULT_ORACLES)}; ilqr costs about 10 s an episode at n = 6)",
    )
    parser.add_argument(
        "--no-fresh",
        action="store_true",
        help=f"leave out the fresh starts (seeds from {FRESH_SEED}): about half the time",
    )
    return parser


def write_leaderboards(documents: list[ResultsDocument], img: Path) -> list[Path]:
    """The leaderboard of every scenario (``agents_leaderboard.png``, the results page's
    first picture) and of the headline scene alone (``agents_leaderboard_reverse_v1.png``,
    the README's), from the report's results documents."""
    panels = leaderboard.ordered(
        [leaderboard.panel_of(document) for document in documents], HEADLINE[0]
    )
    episodes = documents[0].episodes if documents else 0
    seeds = documents[0].seeds if documents else (TEST_SEED, TEST_SEED)
    every = leaderboard.plot_leaderboard(
        panels,
        img / "agents_leaderboard.png",
        title=f"Every scene: {episodes} test episodes each (seeds {seeds[0]}-{seeds[1]}), "
        "the same for every policy",
    )
    headline = [panel for panel in panels if panel.env_id == HEADLINE[0]]
    if not headline:
        return [every]
    return [
        every,
        leaderboard.plot_leaderboard(
            headline, img / "agents_leaderboard_reverse_v1.png", small=True
        ),
    ]


def report_scenario(
    args: argparse.Namespace, env_id: str, n: int, img: Path
) -> tuple[str, ResultsDocument, CurvePanel]:
    """One scenario of the report: its section of the tables (printed), its results
    document (with the fresh starts unless ``--no-fresh``) and its learning-curve panel;
    the headline scenario's margins and frames are written under ``img``."""
    env_kwargs = {"n_trailers": n}
    oracles = [] if args.no_planner else list(applicable_baselines(env_id))
    oracles = [
        name for name in oracles if name not in default_baselines(env_id) and name in args.oracle
    ]
    models = [str(path) for path in models_covering(env_id, n)]
    specs = [*default_baselines(env_id), *oracles, *models]
    evaluations = evaluate_policies(
        specs, env_id, env_kwargs, args.episodes, TEST_SEED, progress=False
    )
    fresh = None
    if not args.no_fresh:
        # Fresh starts check the learned policies and the baselines against
        # over-fitting the test starts; the oracles read the exact state (nothing
        # to over-fit) and the certificate's records exist for the test starts only.
        fresh_specs = [*default_baselines(env_id), *models]
        fresh = evaluate_policies(
            fresh_specs,
            env_id,
            env_kwargs,
            args.episodes,
            FRESH_SEED,
            with_seeds=False,
            progress=False,
        )
    document = results_document(evaluations, env_id, env_kwargs, args.episodes, TEST_SEED)
    slug = scenario_slug(env_id, n)
    leaderboard.plot_leaderboard(
        [leaderboard.panel_of(document)], img / "results" / f"{slug}.png", columns=1
    )
    section = scenario_section(
        env_id, n, evaluations, args.episodes, fresh=fresh, picture=f"img/results/{slug}.png"
    )
    if fresh is not None:
        document = document.replace(
            fresh=results_document(fresh, env_id, env_kwargs, args.episodes, FRESH_SEED)
        )
    print(section, flush=True)
    if (env_id, n) == HEADLINE:
        for path in write_pictures(
            evaluations, env_id, env_kwargs, img, TEST_SEED, prefix="agents_"
        ):
            if path.name == "agents_curves.png":
                path.unlink()  # replaced by the grid of every scenario below
                continue
            final = path.with_name(path.stem + "_reverse_v1_n2.png")
            files.refuse_symlink(final)
            path.replace(final)
            print(f"wrote {final}")
    return section, document, curve_panel(env_id, n, evaluations)


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (bad arguments exit with 2)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    unknown = sorted(set(args.oracle) - set(BASELINES))
    if unknown:
        parser.error(f"argument --oracle: no baseline {', '.join(unknown)}")
    cli.check_out_folder(parser, args.out, files_in=("tables.md", "results.json"))
    if args.docs is not None:
        cli.check_out_folder(parser, args.docs, "--docs")
        cli.check_out_folder(
            parser, args.docs / "generated", "--docs", files_in=("results_tables.md",)
        )
    img = args.out / "img" if args.docs is None else args.docs / "img"
    cli.check_out_folder(parser, img, "--out" if args.docs is None else "--docs", files_in=PICTURES)
    cli.check_seeds(parser, TEST_SEED, args.episodes)
    limit_torch_threads()
    started = time.perf_counter()
    args.out.mkdir(parents=True, exist_ok=True)
    img.mkdir(parents=True, exist_ok=True)
    sections: list[str] = []
    documents: list[ResultsDocument] = []
    panels: list[CurvePanel] = []
    with Progress(len(SCENARIOS) + 1, "report") as bar:
        for env_id, n in report_order(SCENARIOS):
            section, document, panel = report_scenario(args, env_id, n, img)
            sections.append(section)
            documents.append(document)
            panels.append(panel)
            bar.advance(f"{env_id}, n = {n}")
        sweep = authority_table(args.episodes)
        bar.advance("actuator sweep")
    sections.append(f"#### LQR on Reverse-v0 as the actuator gets stronger\n\n{sweep}")
    sections.append(
        f"#### Time to the ceiling\n\n{TIME_TO_CEILING_LEGEND}\n\n"
        f"{time_to_ceiling_table(documents)}"
    )
    print(sections[-1], flush=True)
    grid = plots.plot_curve_grid([panel for panel in panels if panel[1]], img / "agents_curves.png")
    print(f"wrote {grid}")
    for path in write_leaderboards(documents, img):
        print(f"wrote {path}")
    tables = tables_document(sections, [env_id for env_id, _ in SCENARIOS])
    files.atomic_write_text(args.out / "tables.md", tables)
    files.write_json(args.out / "results.json", [document.to_json() for document in documents])
    print(f"wrote {args.out / 'tables.md'} and results.json")
    if args.docs is not None:
        generated = args.docs / "generated"
        generated.mkdir(parents=True, exist_ok=True)
        files.atomic_write_text(generated / "results_tables.md", tables)
        print(f"wrote {generated / 'results_tables.md'}")
    print(f"report done in {duration(time.perf_counter() - started)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
