"""The settings of a SHAC run (:mod:`agents.training.shac`), checked when made."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from agents.envs import HEADLINE_ENV_ID


@dataclass(frozen=True)
class SHACConfig:
    """Settings of a SHAC run.

    Attributes:
        env_id: The scene (one the twin restates, rail actuator).
        n_trailers: Trailers (one count).
        seed: The run's seed (network initialisation, starts, noise).
        iterations: Actor updates (each one window of ``num_envs * horizon`` steps).
        num_envs: Convoys rolled per window.
        horizon: Control steps per window (SHAC's short horizon).
        gamma, lam: Discount and TD(lambda) parameter of the critic's targets.
        actor_lr, critic_lr: Adam step sizes.
        critic_iterations: Critic passes over each window's targets (minibatches of a
            quarter of the window each).
        max_grad_norm: The actor's gradient is clipped to this norm.
        net_arch: Hidden layers of the actor and of the critic.
        log_std_init: The actor's initial log standard deviation (exploration noise).
        eval_every: Iterations between validations (and at the last one).
        validation_episodes: Validation episodes (seeds from VALIDATION_SEED).
        init_from: A PPO ``MlpPolicy`` model (a zip with its JSON statistics, of the
            same hidden layers) whose actor, critic and observation statistics the run
            starts from (a stabilising start, e.g. an imitated policy); None: from scratch.
        critic_warmup: Iterations at the start that fit the critic only (the actor
            waits for values worth bootstrapping from).
        surrogate_weight: Weight of the smooth surrogate of the fold in the learner's
            reward, ``- weight * (omega^2 + sum_k alpha_k^2)`` per step (0: the scene's
            reward alone).
        action_bound_weight: Weight of the pull that keeps the actor's mean action within
            the action's bounds, ``- weight * sum (|mean| - 1)_+^2`` per step in the actor's
            objective (0: none). The twin's straight-through clip passes the gradient of an
            action beyond the bounds as if it moved the mass, so without it the mean
            drifts outward, the policy turns bang-bang and its convoys fold.
        state_gradient_clip: Each convoy's gradient with respect to its state (and to its
            action) is scaled to at most this norm at every step of the backward pass
            (0: not clipped). A row whose gradient is not finite is dropped (zero) in
            either case.
        target_critic: SHAC's target critic: the window bootstraps from a copy of the
            critic that keeps this share of itself after each window's fit (the rest
            is the critic's; 0: no copy, the critic itself).
        anneal: Both step sizes fall linearly to 0 over ``iterations`` (SHAC's schedule).
    """

    env_id: str = HEADLINE_ENV_ID
    n_trailers: int = 2
    seed: int = 0
    iterations: int = 200
    num_envs: int = 64
    horizon: int = 32
    gamma: float = 0.999
    lam: float = 0.95
    actor_lr: float = 1e-4
    critic_lr: float = 1e-3
    critic_iterations: int = 16
    max_grad_norm: float = 1.0
    net_arch: tuple[int, ...] = (64, 64)
    log_std_init: float = -1.5
    eval_every: int = 20
    validation_episodes: int = 64
    init_from: str | None = None
    critic_warmup: int = 0
    surrogate_weight: float = 0.0
    action_bound_weight: float = 0.0
    state_gradient_clip: float = 1.0
    target_critic: float = 0.0
    anneal: bool = False

    def __post_init__(self) -> None:
        integers = {
            "n_trailers": (1, 64),
            "seed": (0, 2**31 - 1),
            "iterations": (1, 1_000_000),
            "num_envs": (2, 4096),
            "horizon": (1, 1024),
            "critic_iterations": (1, 1000),
            "eval_every": (1, 1_000_000),
            "validation_episodes": (1, 10_000),
            "critic_warmup": (0, 1_000_000),
        }
        for name, (low, high) in integers.items():
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int):
                raise TypeError(f"{name} must be an int, got {type(value).__name__}")
            if not low <= value <= high:
                raise ValueError(f"{name} must be in [{low}, {high}], got {value}")
        if not isinstance(self.anneal, bool):
            raise TypeError(f"anneal must be a bool, got {type(self.anneal).__name__}")
        if isinstance(self.target_critic, bool) or not isinstance(self.target_critic, (int, float)):
            raise TypeError("target_critic must be a real number")
        if not 0.0 <= self.target_critic < 1.0:
            raise ValueError(f"target_critic must be in [0, 1), got {self.target_critic}")
        for name in ("surrogate_weight", "action_bound_weight", "state_gradient_clip"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise TypeError(f"{name} must be a real number")
            if not (np.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name} must be >= 0, got {value}")
        for name in ("gamma", "lam", "actor_lr", "critic_lr", "max_grad_norm", "log_std_init"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise TypeError(f"{name} must be a real number, got {type(value).__name__}")
            if not np.isfinite(value):
                raise ValueError(f"{name} must be finite, got {value}")
        for name in ("gamma", "lam"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"{name} must be in [0, 1], got {getattr(self, name)}")
        for name in ("actor_lr", "critic_lr", "max_grad_norm"):
            if getattr(self, name) <= 0.0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        if not self.net_arch or not all(
            isinstance(width, int) and not isinstance(width, bool) and 1 <= width <= 4096
            for width in self.net_arch
        ):
            raise ValueError(f"net_arch must be widths in [1, 4096], got {self.net_arch!r}")
        if self.init_from is not None and not isinstance(self.init_from, str):
            raise TypeError(f"init_from must be a path, got {type(self.init_from).__name__}")
        from trailer_env.registry import core_class_of
        from trailer_env.twin import SCENES

        core_class = core_class_of(self.env_id)  # ValueError on an unknown id
        if core_class.scene not in SCENES:
            raise ValueError(f"SHAC needs a scene the twin restates {SCENES}, not {self.env_id}")


__all__ = ["SHACConfig"]
