"""Files for the agents tests: tiny models, shipped-model copies, damaged zips, hostile
pickles; and a command's one-line refusal."""

from __future__ import annotations

import shutil
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from stable_baselines3 import PPO

from agents.artifacts.certificates import Certified
from agents.artifacts.shipped import MODELS_DIR
from agents.envs import make_sb3_env

REVERSE = "trailer_env/Reverse-v0"


def refusal(
    main: Callable[[list[str]], int], argv: list[str], capsys: pytest.CaptureFixture[str]
) -> str:
    """The one ``error:`` line of a command that refuses ``argv`` with exit status 2."""
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    assert exit_info.value.code == 2
    errors = [line for line in capsys.readouterr().err.splitlines() if "error:" in line]
    assert len(errors) == 1
    return errors[0]


class Touch:
    """A pickle that creates a file when it is unpickled (stands for hostile code)."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):  # type: ignore[no-untyped-def]
        return (Path.touch, (self.marker,))


def tiny_model(path: Path, n: int = 1) -> Path:
    """An untrained PPO with an 8-unit network for Reverse-v0 with ``n`` trailers, seed 0."""
    venv = make_sb3_env(REVERSE, 2, {"n_trailers": n}, seed=0)
    PPO("MlpPolicy", venv, policy_kwargs={"net_arch": [8]}, seed=0, device="cpu").save(path)
    return path


def model_copy(folder: Path, stem: str = "ppo_reverse_n2") -> Path:
    """A shipped model, its card and statistics copied to ``folder`` (a file from elsewhere)."""
    folder.mkdir(parents=True, exist_ok=True)
    for suffix in (".zip", ".json", "_vecnormalize.json"):
        shutil.copyfile(MODELS_DIR / f"{stem}{suffix}", folder / f"{stem}{suffix}")
    return folder / f"{stem}.zip"


def rewrite_zip(
    path: Path, replace: dict[str, bytes | None], compression: int = zipfile.ZIP_STORED
) -> None:
    """Rewrite the zip at ``path`` with some entries replaced (None: dropped)."""
    with zipfile.ZipFile(path) as archive:
        entries = {name: archive.read(name) for name in archive.namelist()}
    for name, content in replace.items():
        if content is None:
            entries.pop(name, None)
        else:
            entries[name] = content
    with zipfile.ZipFile(path, "w", compression) as archive:
        for name, content in entries.items():
            archive.writestr(name, content)


def tiny_ppo_hyperparams(
    folder: Path, env_id: str, policy_kwargs: str = "dict(net_arch=[8])"
) -> Path:
    """A ``ppo.yml`` in ``folder`` for ``env_id``: 8 environments, 64-step rollouts, one
    epoch, an 8-unit network (training runs of a few thousand steps in seconds)."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "ppo.yml"
    path.write_text(
        f"{env_id}:\n  n_envs: 8\n  policy: MlpPolicy\n  n_steps: 64\n  batch_size: 256\n"
        f'  n_epochs: 1\n  policy_kwargs: "{policy_kwargs}"\n'
    )
    return path


def fake_certified(
    seeds: list[int],
    env_id: str = "trailer_env/Reverse-v1",
    n: int = 1,
    *,
    status: str = "feasible",
    planner: str | None = None,
) -> Certified:
    """A certificate of ``seeds`` all of ``status`` (feasible ones with a three-step zero
    record), as the sampling planner (``planner`` None) or a named planner writes it; a
    goal scene's is not screened and replays to success."""
    from agents.artifacts.certificates import FEASIBLE, Certificate, CertificateStart
    from trailer_env.objective import Objective
    from trailer_env.registry import core_class_of

    feasible = status == FEASIBLE
    goal = core_class_of(env_id).objective is Objective.GOAL
    replayed = True if feasible else None
    starts = tuple(
        CertificateStart(
            seed=seed,
            status=status,  # type: ignore[arg-type]
            screen_stroke_fraction=None if goal else 0.5,
            planner_safe=feasible,
            planner_length=3,
            replay_success=replayed if goal else None,
            replay_safe=None if goal else replayed,
        )
        for seed in seeds
    )
    document = {
        "env_id": env_id,
        "env_kwargs": {"n_trailers": n},
        "seeds": [min(seeds), max(seeds)],
        "episodes": len(seeds),
        "planner": {
            "name": planner,
            "horizon": 10,
            "iterations": 1,
            "restarts": 0,
            "first_pass_safe": len(seeds) if feasible else 0,
            "first_pass_wall_time_s": 0.0,
            "simulated_steps_per_episode": 0.0,
            "wall_time_s": 0.0,
        },
        "screen": {"applied": False, "wall_time_s": 0.0} if goal else {"wall_time_s": 0.0},
        "feasible": len(seeds) if feasible else 0,
        "not_recoverable": len(seeds) if status == "not recoverable" else 0,
        "open": len(seeds) if status == "open" else 0,
        "ceiling": 1.0 if feasible else 0.0,
        "screen_upper_estimate": 1.0,
        "starts": [start.document(goal) for start in starts],
    }
    if goal:
        document["success"] = "the scene's success, replayed"
    certificate = Certificate.from_json(document)
    actions = {seed: np.zeros((3, 1)) for seed in seeds} if feasible else {}
    return Certified(certificate, actions)
