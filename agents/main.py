"""The main job: simulate the default convoy and chart its path and energy.

Run with ``python -m agents.main [--out DIR] [--n-trailers N] [--seconds T]``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from dynamics import ConvoyParams, body_poses, energy, simulate


def simulate_and_plot(n_trailers: int, seconds: float, out: Path) -> Path:
    """Let the default convoy coast with an oscillating mass; write a chart of path and energy."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    params = ConvoyParams(n_trailers=n_trailers)
    z0 = np.zeros(params.n_trailers + 5)
    z0[0], z0[1] = 1.0, 0.3
    z0[2 : 2 + n_trailers] = 0.4 * (-1.0) ** np.arange(n_trailers)
    dt = 0.02
    coast = simulate(params, z0, dt, int(seconds / dt), substeps=2)
    n = params.n_trailers
    xs, ys, _ = body_poses(
        params.l, coast.z[:, n + 2], coast.z[:, n + 3], coast.z[:, n + 4], coast.z[:, 2 : 2 + n]
    )
    fig, (ax_path, ax_energy) = plt.subplots(1, 2, figsize=(11, 4.5))
    for body in range(n + 1):
        ax_path.plot(
            xs[:, body], ys[:, body], lw=1.2, label="cart" if body == 0 else f"trailer {body}"
        )
    ax_path.set_aspect("equal")
    ax_path.set_xlabel("x [m]")
    ax_path.set_ylabel("y [m]")
    ax_path.set_title(f"Coasting convoy, n = {n} (a = {params.a} > 0: it straightens)")
    ax_path.legend(fontsize=8)
    e = energy(params, coast.z[:, : n + 2], coast.s, coast.s_dot)
    ax_energy.plot(coast.t, (e - e[0]) / e[0])
    ax_energy.set_xlabel("t [s]")
    ax_energy.set_ylabel("(E - E0) / E0")
    ax_energy.set_title("Relative energy error (RK4, h = 0.01 s)")
    fig.tight_layout()
    out.mkdir(parents=True, exist_ok=True)
    path = out / "convoy_path_energy.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    print(
        f"simulated {seconds:g} s of n = {n}: "
        f"max |dE/E0| = {np.max(np.abs(e - e[0]) / e[0]):.2e}; wrote {path}"
    )
    return path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m agents.main", description=__doc__)
    parser.add_argument(
        "--out", type=Path, default=Path("out"), help="output folder (default: out)"
    )
    parser.add_argument("--n-trailers", type=int, default=2, help="number of trailers (default: 2)")
    parser.add_argument("--seconds", type=float, default=20.0, help="simulated time (default: 20)")
    args = parser.parse_args(argv)
    if args.n_trailers < 0:
        parser.error(f"--n-trailers must be >= 0, got {args.n_trailers}")
    if not args.seconds > 0:
        parser.error(f"--seconds must be > 0, got {args.seconds}")
    simulate_and_plot(args.n_trailers, args.seconds, args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
