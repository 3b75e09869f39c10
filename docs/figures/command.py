"""Draw the thesis's pictures from the project's own ``dynamics``, with the numbers behind them.

The command ``python -m docs.figures [--out DIR] [--quick]``: every picture's ``*_data``
function, then its ``draw_*`` function, with RuntimeWarnings raised as errors so that a
picture is never drawn from numbers that overflowed or divided by zero.
"""

from __future__ import annotations

import argparse
import time
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path

from docs.figures.cart_paths import cart_paths_data, draw_cart_paths
from docs.figures.invariant_circles import draw_invariant_circles, invariant_circles_data
from docs.figures.level_function import draw_level_function, level_function_data
from docs.figures.singular_set import draw_singular_set, singular_set_data
from docs.figures.straight_line import draw_straight_line, straight_line_data
from docs.figures.torus_portrait import draw_torus_portrait, torus_portrait_data


def figure_jobs(quick: bool) -> list[tuple[str, Callable[[], object], Callable[..., None]]]:
    """(file name, data function, drawing function) of every picture."""
    dt = 0.02 if quick else 0.01
    return [
        (
            "thesis_torus_portrait.png",
            lambda: torus_portrait_data(grid_size=25 if quick else 41),
            draw_torus_portrait,
        ),
        ("thesis_straight_line.png", lambda: straight_line_data(dt=dt), draw_straight_line),
        ("thesis_level_function.png", level_function_data, draw_level_function),
        (
            "thesis_invariant_circles.png",
            lambda: invariant_circles_data(grid_size=31 if quick else 61),
            draw_invariant_circles,
        ),
        ("thesis_cart_paths.png", lambda: cart_paths_data(quick), draw_cart_paths),
        ("thesis_singular_set.png", lambda: singular_set_data(quick), draw_singular_set),
    ]


def main(argv: Sequence[str] | None = None) -> list[Path]:
    """Write every picture; return the paths written."""
    parser = argparse.ArgumentParser(
        prog="python -m docs.figures", description=__doc__.split("\n\n")[0]
    )
    parser.add_argument(
        "--out",
        type=Path,
        default=Path("out/figures"),
        help="output folder (default out/figures; docs/img refreshes the committed pictures)",
    )
    parser.add_argument("--quick", action="store_true", help="coarse grids, short runs")
    args = parser.parse_args(argv)

    import matplotlib

    matplotlib.use("Agg")
    args.out.mkdir(parents=True, exist_ok=True)
    written = []
    for name, compute, draw in figure_jobs(args.quick):
        start = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)
            data = compute()
            target = args.out / name
            draw(data, target)
        size_kb = target.stat().st_size / 1024
        print(f"{target}  {size_kb:6.1f} kB  {time.perf_counter() - start:5.1f} s")
        written.append(target)
    return written
