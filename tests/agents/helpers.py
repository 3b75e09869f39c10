"""Files for the agents tests: tiny models, shipped-model copies, damaged zips, hostile pickles."""

from __future__ import annotations

import shutil
import zipfile
from pathlib import Path

from stable_baselines3 import PPO

from agents.artifacts.shipped import MODELS_DIR
from agents.envs import make_sb3_env

REVERSE = "trailer_env/Reverse-v0"


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
