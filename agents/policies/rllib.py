"""An RLlib run's exported policy as a batched policy (tensors only; pickles only if trusted)."""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from agents.artifacts.rllib_files import POLICY_CARD, POLICY_WEIGHTS, read_rllib_card
from agents.policies.baselines import Policy

if TYPE_CHECKING:
    from ray.rllib.core.rl_module.rl_module import RLModule

#: The RLModule of a policy card that names none (the cards written before it did: PPO's).
DEFAULT_MODULE = (
    "ray.rllib.algorithms.ppo.torch.default_ppo_torch_rl_module:DefaultPPOTorchRLModule"
)


def module_class(path: str) -> type[RLModule]:
    """The RLModule class a policy card names (``"module:Class"``, under ``ray.rllib``).

    Raises:
        ValueError: For a path outside ``ray.rllib``, malformed, missing, or not naming an
            RLModule (a card cannot make the loader import anything else).
    """
    from ray.rllib.core.rl_module.rl_module import RLModule

    module, _, name = str(path).partition(":")
    if not (module.startswith("ray.rllib.") and name.isidentifier()):
        raise ValueError(f"policy card module {path[:120]!r} is not 'ray.rllib.<module>:<Class>'")
    try:
        found = getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError):
        raise ValueError(f"policy card module {path[:120]!r} does not exist") from None
    if not (isinstance(found, type) and issubclass(found, RLModule)):
        raise ValueError(f"policy card module {path[:120]!r} is not an RLModule")
    return found


class RLlibPolicy:
    """A trained RLlib module's deterministic action (the Gaussian's mean), batched.

    Actions are clipped to the action space, as RLlib's module-to-env connector does.
    """

    def __init__(self, module: RLModule, low: np.ndarray, high: np.ndarray) -> None:
        self.module = module
        self.low = low
        self.high = high

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        import torch
        from ray.rllib.core.columns import Columns

        batch = torch.as_tensor(np.atleast_2d(obs), dtype=torch.float32)
        with torch.no_grad():
            output = self.module.forward_inference({Columns.OBS: batch})
        inputs = output[Columns.ACTION_DIST_INPUTS].numpy()
        mean = inputs[:, : self.low.size]
        return np.clip(mean, self.low, self.high).astype(np.float32)


def load_rllib_policy(
    path: Path, observation_space: Any, action_space: Any, trust_pickle: bool = False
) -> Policy:
    """The policy of an RLlib checkpoint folder, built for the given spaces.

    Reads the pickle-free export (:data:`POLICY_WEIGHTS`, :data:`POLICY_CARD`); a
    checkpoint without one (made by RLlib directly) is read through RLlib's pickled
    module files only when ``trust_pickle`` is true.

    Raises:
        ValueError: If the checkpoint does not fit the spaces, has no pickle-free export
            and ``trust_pickle`` is false, or its weights cannot be read.
    """
    import torch
    from ray.rllib.core.rl_module.default_model_config import DefaultModelConfig
    from ray.rllib.core.rl_module.rl_module import RLModule, RLModuleSpec

    low = np.asarray(action_space.low, dtype=np.float32)
    high = np.asarray(action_space.high, dtype=np.float32)
    card = read_rllib_card(path)
    if card.empty:
        if not trust_pickle:
            raise ValueError(
                f"{path} has no pickle-free policy export ({POLICY_CARD}); its RLlib "
                "files are pickles, loaded only with --trust-pickle"
            )
        module_dir = path / "learner_group" / "learner" / "rl_module" / "default_policy"
        return RLlibPolicy(RLModule.from_checkpoint(str(module_dir)), low, high)
    widths = card.rllib_hiddens
    if card.spaces is None or not isinstance(widths, list):
        raise ValueError(f"{path}: malformed {POLICY_CARD} (no spaces or no network widths)")
    try:
        hiddens = [int(width) for width in widths]
    except (TypeError, ValueError) as error:
        raise ValueError(f"{path}: malformed {POLICY_CARD} ({error!r})") from None
    saved_shape = card.spaces.observation_shape
    module_type = module_class(card.module_path or DEFAULT_MODULE)
    if saved_shape != tuple(observation_space.shape):
        raise ValueError(
            f"RLlib policy {path} expects observations of shape {saved_shape}, "
            f"but the environment gives {tuple(observation_space.shape)}"
        )
    module: Any = RLModuleSpec(
        module_class=module_type,
        observation_space=observation_space,
        action_space=action_space,
        model_config=DefaultModelConfig(fcnet_hiddens=hiddens),
        inference_only=True if card.inference_only is None else card.inference_only,
    ).build()
    try:
        state = torch.load(path / POLICY_WEIGHTS, map_location="cpu", weights_only=True)
        module.load_state_dict(state)
    except Exception as error:  # torch raises several types for a damaged file
        raise ValueError(f"cannot read the weights of {path / POLICY_WEIGHTS}: {error}") from None
    module.eval()
    return RLlibPolicy(module, low, high)
