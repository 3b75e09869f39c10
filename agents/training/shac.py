"""SHAC: a first-order learner that backpropagates short rollouts through the exact model.

Short-Horizon Actor-Critic (Xu et al., ICLR 2022, "Accelerated Policy Learning with Parallel
Differentiable Simulation"): every iteration, ``num_envs`` convoys are rolled ``horizon``
control steps through the differentiable twin (:mod:`trailer_env.twin`, float64, the
kernel's step restated), the actor's action reparameterised (``mean + std * noise``), and
the actor takes one Adam step on the gradient of

    - mean over convoys of [ sum_t gamma^t r_t + gamma^k V(s_k) ] / horizon

(``k`` the window's last step, or the step an episode was cut by the time limit; 0 after
a fold or a stop), back through the rollout's every step, the actuator and the integrator.
The critic then regresses on TD(lambda) targets of the same window (detached). Why SHAC
and not plain backpropagation through the whole episode (APG, BPTT): reversing a convoy
is unstable, and the gradient of an H-step return grows geometrically with H when the
policy does not stabilise it (``python -m agents.gradients``: 1e4-fold from H = 8 to 64
with one trailer, 1e5-fold with eight); the critic cuts the window so the horizon stays
where that gradient is usable. AHAC (Georgiev et al. 2024) adapts the window to the
contact stiffness of the model; this model has no contact, so a fixed window is kept.

The smooth surrogates. Termination (a fold, the convoy slowing to the minimum speed) is
a step function: it passes no gradient (the twin's rule), and a convoy that ends is
replaced by a new start that carries none either; its bootstrap value is 0, so the
critic's value is what carries the fold's penalty back into the actor's gradient. The
reward's own terms are smooth where they count (the hitch angles' cosines, the turning
rate below 1 rad/s); its band and fold penalties are indicators (no gradient).

Two surrogates the gradient needs, both optional in the sense that the forward values are
the kernel's: the twin's ``straight_through`` (always on here: the servo saturates within
8 % of the rail of its target, where the exact gradient with respect to the action is
zero, so the clips pass the gradient as if they did not clip), and ``surrogate_weight``,
a smooth stand-in for the fold (``- weight * (omega^2 + sum alpha_k^2)`` per step, off by
default). A third is an actor regulariser, not a model surrogate: ``action_bound_weight``
pulls the mean action back within its bounds (off by default), where the straight-through
clip passes the return's gradient as if the mass moved.

Two guards keep a step finite. Each convoy's gradient with respect to its state and its
action is scaled to at most ``state_gradient_clip`` at every step of the backward pass,
and a row whose gradient is not finite is dropped (``evaluations.csv`` counts them):
without them one convoy near the fold sent the actor's gradient to 1e19, whose float32
norm overflowed, and every later step was skipped.

Status: experimental. With one trailer, from scratch, its exact gradient is the return's
slope (:func:`gradient_agreement`: a step of 1e-3 along it moves a 32-step window's return
by what it predicts, to 2 %) and it learns to hold convoys, then loses them: its three
seeds peak at 95, 88 and 80 % of the validation starts after about 1,200 windows and
collapse to 0 % within 350 more (the kept peaks keep 96, 82 and 73 % of the test
starts). ``evaluations.csv`` shows why: the same actor acting with its noise, as in the
windows it learns from (``sampled_safe_rate``), holds 2-45 % at the peaks, so the return
it climbs and the values its critic fits are mostly a folding policy's, and each fall
comes with the mean action drifting past the bounds (``saturated_share`` 0.47-0.85
after it), where the straight-through clip lets nothing hold it back. Started from
``dagger_reverse_v1_n4`` (validation 92 %) it lowers that policy whatever the step
size, discount, window and fold surrogate tried, and there the gradient is not the
return's slope: it is 5e7 (7e3 without the straight-through clips)
where a step of 1e-3 along it moves the return by under 1e-3.
``tests/agents/training/test_shac.py`` measures both.

The model is SB3's PPO ``MlpPolicy`` (the actor is its Gaussian policy, the critic its value
network) with observation statistics frozen from 16 steps of uniform random actions from
the first starts (so the rail's columns have their real spread: from the zero action
they sat at the variance floor and the gradient stopped predicting the return), saved
as JSON: it loads and
evaluates like any PPO model (``agents.evaluate``), and its card names the recipe
``shac``. Starts are drawn from the scene's own reset, seeded from
:data:`agents.seeds.TRAINING_SEED` on; validation plays the validation seeds. The run
folder gets ``config.json``, ``evaluations.csv`` (one row per validation),
``best_model.zip`` and ``final_model.zip`` with their cards and statistics. No resume: a
run is sized to minutes (a cut run is started again).
"""

from __future__ import annotations

import copy
import dataclasses
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from agents.seeds import TRAINING_SEED, VALIDATION_SEED
from agents.training.shac_config import SHACConfig

#: Columns of ``evaluations.csv``.
CURVE_FIELDS = (
    "iteration",
    "timesteps",
    "wall_s",
    "safe_rate",
    "mean_return",
    "jackknife_rate",
    "sampled_safe_rate",
    "actor_loss",
    "critic_loss",
    "gradient_norm",
    "dropped_rows",
    "saturated_share",
    "log_std",
)


class _Learner:
    """The actor, the critic, the twin and the convoys of one run."""

    def __init__(self, config: SHACConfig) -> None:
        import torch
        from stable_baselines3 import PPO
        from stable_baselines3.common.vec_env import VecNormalize

        from agents.envs import make_sb3_env
        from trailer_env.registry import core_class_of
        from trailer_env.settings import settings_from_kwargs
        from trailer_env.twin import TwinParams

        self.config = config
        self.torch = torch
        torch.manual_seed(config.seed)
        self.noise = torch.Generator().manual_seed(config.seed)
        venv = make_sb3_env(config.env_id, 1, {"n_trailers": config.n_trailers}, seed=config.seed)
        self.stats = VecNormalize(venv, norm_obs=True, norm_reward=False, training=False)
        self.policy_kwargs: dict[str, object] = {
            "net_arch": list(config.net_arch),
            "log_std_init": config.log_std_init,
        }
        self.model = PPO(
            "MlpPolicy",
            self.stats,
            seed=config.seed,
            device="cpu",
            verbose=0,
            policy_kwargs=self.policy_kwargs,
        )
        policy = self.model.policy
        self.actor_parameters = [
            *policy.mlp_extractor.policy_net.parameters(),
            *policy.action_net.parameters(),
            policy.log_std,
        ]
        self.critic_parameters = [
            *policy.mlp_extractor.value_net.parameters(),
            *policy.value_net.parameters(),
        ]
        self.actor_optimizer = torch.optim.Adam(self.actor_parameters, lr=config.actor_lr)
        self.critic_optimizer = torch.optim.Adam(self.critic_parameters, lr=config.critic_lr)
        self.core_class = core_class_of(config.env_id)
        settings = settings_from_kwargs(n_trailers=config.n_trailers)
        self.core = self.core_class(settings, config.num_envs)
        # The servo's saturation passes no gradient: the learner takes the surrogate.
        self.params = TwinParams.from_core(self.core).replace(straight_through=True)
        self.max_steps = int(self.core_class.max_episode_steps)
        self.next_seed = TRAINING_SEED + config.seed * 1_000_000
        rows = np.arange(config.num_envs)
        self._reset(rows)
        self.state = self._states(rows)
        self.steps = np.zeros(config.num_envs, dtype=np.int64)
        self.simulated_steps = 0
        # Gradients of the last backward pass dropped for not being finite: one per row
        # and step at each of the action, the state and the servo's state.
        self.dropped_rows = 0
        self.iterations = 0
        # The observation statistics as tensors (set from the starts or the model).
        self.obs_mean: Any = None
        self.obs_scale: Any = None
        self.clip = 10.0
        if config.init_from is None:
            self._freeze_statistics()
        else:
            self._start_from(Path(config.init_from))
        # SHAC's target critic, made from the (possibly loaded) critic when asked for.
        self.target: Any = None
        if config.target_critic > 0.0:
            self.target = copy.deepcopy(
                torch.nn.ModuleList([policy.mlp_extractor.value_net, policy.value_net])
            )
            self.target.requires_grad_(False)

    # ----------------------------------------------------------------- convoys
    def _reset(self, rows: np.ndarray) -> None:
        from trailer_env.vector import seed_generators

        seeds = list(range(self.next_seed, self.next_seed + rows.size))
        self.next_seed += rows.size
        self.core.reset_rows(rows, seed_generators(seeds, rows.size, None))

    def _states(self, rows: np.ndarray) -> Any:
        from trailer_env.twin import TwinState

        return TwinState.from_core(self.core, rows)

    def _freeze_statistics(self) -> None:
        """Observation statistics from the starts of a few windows of the zero action (the
        variances floored as DAgger's students' are), then frozen."""
        from agents.training.dagger import freeze_statistics
        from trailer_env.twin import observe, step

        torch = self.torch
        state = self.state
        seen = []
        with torch.no_grad():
            for _ in range(16):
                seen.append(observe(state, self.params).numpy().copy())
                shape = (self.config.num_envs, 1)
                action = 2.0 * torch.rand(shape, generator=self.noise, dtype=torch.float64) - 1.0
                state = step(state, action, self.params)[0]
        freeze_statistics(self.stats, np.concatenate(seen).astype(np.float32))
        self._statistics_tensors()

    def _start_from(self, path: Path) -> None:
        """Take the weights and the statistics of the model at ``path`` (loaded without
        unpickling); its exploration noise is reset to ``log_std_init``."""
        from agents.artifacts.paths import stats_path
        from agents.artifacts.sb3_zip import load_sb3
        from agents.artifacts.stats import read_stats, restore_stats

        torch = self.torch
        own = self.model.policy
        loaded = load_sb3(path, "ppo", own.observation_space, own.action_space)
        theirs = loaded.policy.state_dict()
        mine = own.state_dict()
        shapes = {key: tuple(value.shape) for key, value in theirs.items()}
        if shapes != {key: tuple(value.shape) for key, value in mine.items()}:
            raise ValueError(
                f"init_from: {path}'s network is not this run's (net_arch "
                f"{list(self.config.net_arch)}, a flat MlpPolicy)"
            )
        own.load_state_dict(theirs)
        with torch.no_grad():
            own.log_std.fill_(self.config.log_std_init)
        restore_stats(self.stats, read_stats(stats_path(path)))
        self._statistics_tensors()

    def _statistics_tensors(self) -> None:
        torch = self.torch
        rms = self.stats.obs_rms
        assert not isinstance(rms, dict)  # the flat observation: one array
        self.obs_mean = torch.tensor(rms.mean, dtype=torch.float32)
        self.obs_scale = torch.tensor(np.sqrt(rms.var + self.stats.epsilon), dtype=torch.float32)
        self.clip = float(self.stats.clip_obs)

    # ------------------------------------------------------------------ nets
    def normalized(self, state: Any) -> Any:
        """The actor's and critic's input: the twin's observation, float32, normalised as
        VecNormalize does (clipped)."""
        from trailer_env.twin import observe

        torch = self.torch
        raw = observe(state, self.params).to(torch.float32)
        return torch.clamp((raw - self.obs_mean) / self.obs_scale, -self.clip, self.clip)

    def _features(self, obs: Any) -> Any:
        """The policy's features of ``obs`` (a flat MlpPolicy: one tensor, shared)."""
        return self.model.policy.extract_features(obs)

    def mean_action(self, obs: Any) -> Any:
        policy = self.model.policy
        return policy.action_net(policy.mlp_extractor.forward_actor(self._features(obs)))

    def value(self, obs: Any) -> Any:
        policy = self.model.policy
        latent = policy.mlp_extractor.forward_critic(self._features(obs))
        return policy.value_net(latent)[:, 0]

    def bootstrap_value(self, obs: Any) -> Any:
        """The value the window bootstraps from: the target critic's (``target_critic`` >
        0) or the critic's."""
        if self.target is None:
            return self.value(obs)
        return self.target[1](self.target[0](self._features(obs)))[:, 0]

    def window_return(self, horizon: int) -> Any:
        """The mean discounted return of the actor's mean action over ``horizon`` steps from
        the current convoys (no noise, no critic), counted while each episode runs; a
        tensor that carries the gradient. The convoys are not advanced."""
        from trailer_env.twin.scenes import step_outcome

        torch = self.torch
        state = self.state
        total = torch.zeros(self.config.num_envs, dtype=torch.float64)
        alive = torch.ones(self.config.num_envs, dtype=torch.float64)
        for t in range(horizon):
            action = self.mean_action(self.normalized(state)).to(torch.float64)
            outcome = step_outcome(state, action, self.params)
            total = total + alive * self.config.gamma**t * outcome.reward
            alive = alive * (~outcome.terminated).to(torch.float64)
            state = outcome.state
        return total.mean()

    # ----------------------------------------------------------------- update
    def iterate(self) -> dict[str, float]:
        """One window: the actor's step, then the critic's; returns the iteration's
        figures."""
        from dynamics.columns import ALPHA, OMEGA
        from trailer_env.twin.scenes import step_outcome

        torch, config = self.torch, self.config
        count, horizon, gamma = config.num_envs, config.horizon, config.gamma
        for parameter in self.critic_parameters:
            parameter.requires_grad_(False)
        self.dropped_rows = 0
        state = self.state
        objective = torch.zeros(count, dtype=torch.float64)
        discount = torch.ones(count, dtype=torch.float64)
        observations, rewards, ends, folds, next_values = [], [], [], [], []
        saturated, actions = 0, 0
        for t in range(horizon):
            obs = self.normalized(state)
            mean = self.mean_action(obs)
            noise = torch.randn(mean.shape, generator=self.noise, dtype=mean.dtype)
            action = (mean + self.model.policy.log_std.exp() * noise).double()  # twin-clipped
            if action.requires_grad:
                action.register_hook(self._clip_rows)
            outcome = step_outcome(state, action, self.params)
            if outcome.state.z.requires_grad:
                outcome.state.z.register_hook(self._clip_rows)
                outcome.state.act.register_hook(self._clip_rows)
            z = outcome.state.z
            bend = z[:, OMEGA] ** 2 + (z[:, ALPHA : ALPHA + config.n_trailers] ** 2).sum(dim=1)
            reward = outcome.reward - config.surrogate_weight * bend
            excess = torch.relu(mean.abs() - 1.0).to(torch.float64)
            saturated, actions = saturated + int((excess > 0.0).sum()), actions + excess.numel()
            pull = config.action_bound_weight * (excess**2).sum(dim=1)
            objective = objective + discount * (reward - pull)
            discount = discount * gamma
            self.steps += 1
            terminated = outcome.terminated.numpy().copy()
            truncated = (self.steps >= self.max_steps) & ~terminated
            ended = terminated | truncated
            after = outcome.state
            next_obs = self.normalized(after)
            next_value = self.bootstrap_value(next_obs).to(torch.float64)
            last = t == horizon - 1
            bootstrap = torch.from_numpy(truncated | (last & ~terminated))
            objective = objective + torch.where(bootstrap, discount * next_value, 0.0)
            observations.append(obs.detach())
            rewards.append(reward.detach())
            ends.append(ended)
            folds.append(terminated)
            next_values.append(next_value.detach())
            if ended.any():
                rows = np.flatnonzero(ended)
                self._reset(rows)
                fresh = self._states(rows)
                index = torch.from_numpy(rows)
                after = after._replace(
                    z=after.z.index_put((index,), fresh.z),
                    act=after.act.index_put((index,), fresh.act),
                    task=after.task.index_put((index,), fresh.task),
                    hold=after.hold.index_put((index,), fresh.hold),
                )
                discount = discount.index_put((index,), torch.ones(rows.size, dtype=torch.float64))
                self.steps[rows] = 0
            state = after
        loss = -objective.mean() / horizon
        self.actor_optimizer.zero_grad()
        loss.backward()
        norm = torch.nn.utils.clip_grad_norm_(self.actor_parameters, config.max_grad_norm)
        finite = bool(torch.isfinite(norm))
        if config.anneal:
            left = max(0.0, 1.0 - self.iterations / config.iterations)
            for optimizer, rate in (
                (self.actor_optimizer, config.actor_lr),
                (self.critic_optimizer, config.critic_lr),
            ):
                for group in optimizer.param_groups:
                    group["lr"] = rate * left
        if finite and self.iterations >= config.critic_warmup:
            self.actor_optimizer.step()
        self.iterations += 1
        for parameter in self.critic_parameters:
            parameter.requires_grad_(True)
        self.state = type(state)(*(part.detach() for part in state))
        self.simulated_steps += count * horizon
        critic_loss = self._fit_critic(observations, rewards, ends, folds, next_values)
        if self.target is not None:
            keep = config.target_critic
            with torch.no_grad():
                pairs = zip(self.target.parameters(), self.critic_parameters, strict=True)
                for target, weight in pairs:
                    target.mul_(keep).add_((1.0 - keep) * weight)
        return {
            "actor_loss": float(loss.detach()),
            "critic_loss": critic_loss,
            "gradient_norm": float(norm) if finite else float("nan"),
            "dropped_rows": float(self.dropped_rows),
            "saturated_share": saturated / actions,
            "log_std": float(self.model.policy.log_std.detach().mean()),
            "window_return": float(torch.stack(rewards).sum(0).mean()),
        }

    def _clip_rows(self, gradient: Any) -> Any:
        """The state's gradient, each convoy's row scaled to at most ``state_gradient_clip``."""
        torch = self.torch
        finite = torch.isfinite(gradient).all(dim=1, keepdim=True)
        self.dropped_rows += int((~finite).sum())
        gradient = torch.where(finite, gradient, torch.zeros_like(gradient))
        limit = self.config.state_gradient_clip
        if limit <= 0.0:
            return gradient
        norm = gradient.norm(dim=1, keepdim=True)
        return gradient * torch.clamp(limit / (norm + 1e-12), max=1.0)

    def _fit_critic(
        self,
        observations: list[Any],
        rewards: list[Any],
        ends: list[np.ndarray],
        folds: list[np.ndarray],
        next_values: list[Any],
    ) -> float:
        """TD(lambda) targets of the window (an episode's end restarts them; 0 after a
        fold), then ``critic_iterations`` passes of minibatch regression."""
        torch, config = self.torch, self.config
        gamma, lam = config.gamma, config.lam
        horizon = len(rewards)
        targets = [torch.zeros(0)] * horizon
        follow = torch.zeros(config.num_envs, dtype=torch.float64)
        for t in reversed(range(horizon)):
            value = torch.where(torch.from_numpy(folds[t]), 0.0, next_values[t])
            if t == horizon - 1:
                follow = value
            else:
                follow = torch.where(torch.from_numpy(ends[t]), value, follow)
            targets[t] = rewards[t] + gamma * ((1.0 - lam) * value + lam * follow)
            follow = targets[t]
        inputs = torch.cat(observations)
        wanted = torch.cat(targets).to(torch.float32)
        size = max(1, inputs.shape[0] // 4)
        total = 0.0
        for _ in range(config.critic_iterations):
            order = torch.randperm(inputs.shape[0], generator=self.noise)
            for start in range(0, inputs.shape[0], size):
                batch = order[start : start + size]
                loss = torch.mean((self.value(inputs[batch]) - wanted[batch]) ** 2)
                self.critic_optimizer.zero_grad()
                loss.backward()
                self.critic_optimizer.step()
                total = float(loss.detach())
        return total


@dataclass(frozen=True)
class GradientAgreement:
    """Whether the exact gradient of a window's return is that return's slope.

    Attributes:
        value: The window's mean return (the actor's mean action, no noise, no critic).
        gradient_norm: The norm of its gradient with respect to the actor's mean weights.
        predicted: ``step * gradient_norm``, the change a step of length ``step`` along the
            gradient should make to first order.
        up, down: The changes the steps ``+step`` and ``-step`` along it made.
    """

    value: float
    gradient_norm: float
    predicted: float
    up: float
    down: float

    @property
    def ratio(self) -> float:
        """The realised central slope over the predicted one (1: the gradient is the
        slope; near 0: it is dominated by what a step of that length does not reach)."""
        return (self.up - self.down) / (2.0 * self.predicted) if self.predicted else float("nan")


def gradient_agreement(
    config: SHACConfig, horizon: int, step: float, straight_through: bool = True
) -> GradientAgreement:
    """Differentiate the mean ``horizon``-step return of the run's starting actor (from
    ``config``: its starts, statistics and ``init_from``) through the twin, then step its
    mean weights by ``+-step`` along the normalised gradient and replay: the first-order
    check a learner's step relies on. ``straight_through``: the clips pass the gradient
    as the learner's twin does (True), or the exact gradient of the clipped model (False)."""
    import torch

    if not (isinstance(horizon, int) and 1 <= horizon <= 1024):
        raise ValueError(f"horizon must be an int in [1, 1024], got {horizon!r}")
    if not (np.isfinite(step) and step > 0.0):
        raise ValueError(f"step must be > 0, got {step}")
    learner = _Learner(config)
    learner.params = learner.params.replace(straight_through=bool(straight_through))
    actor = learner.actor_parameters[:-1]  # the mean's weights (log_std plays no part)
    value = learner.window_return(horizon)
    gradient = torch.autograd.grad(value, actor)
    norm = float(torch.cat([part.double().flatten() for part in gradient]).norm())
    changes = []
    with torch.no_grad():
        for sign in (1.0, -1.0):
            for weight, part in zip(actor, gradient, strict=True):
                weight.add_(sign * step * part / norm)
            changes.append(float(learner.window_return(horizon) - value))
            for weight, part in zip(actor, gradient, strict=True):
                weight.sub_(sign * step * part / norm)
    return GradientAgreement(float(value.detach()), norm, step * norm, changes[0], changes[1])


def train_shac(
    config: SHACConfig, run_dir: Path, verbose: int = 1, command: Sequence[str] | None = None
) -> dict[str, object]:
    """Train (see the module); returns the run's record (also its ``config.json``)."""
    from agents.artifacts.cards import card_of, read_model_card, write_card
    from agents.artifacts.curves import append_rows, write_curve
    from agents.artifacts.paths import stats_path
    from agents.artifacts.run_folder import BEST_MODEL, CURVE_FILE, FINAL_MODEL, write_config
    from agents.artifacts.sb3_zip import save_model
    from agents.artifacts.stats import save_stats
    from agents.evaluation.metrics import Summary, rollout, summarize
    from agents.policies.sb3 import ModelPolicy, SampledPolicy
    from agents.progress import Progress
    from agents.training.callbacks import score
    from agents.training.host_speed import measure_host_speed

    started = time.perf_counter()
    learner = _Learner(config)
    run_dir.mkdir(parents=True, exist_ok=True)
    env_kwargs = {"n_trailers": config.n_trailers}
    settings = {
        key: (list(value) if isinstance(value, tuple) else value)
        for key, value in dataclasses.asdict(config).items()
        if key not in ("env_id", "n_trailers", "seed")
    }
    record: dict[str, object] = {
        "algo": "ppo",
        "recipe": "shac",
        "command": list(command or ["python", "-m", "agents.shac", *sys.argv[1:]]),
        "env_id": config.env_id,
        "env_kwargs": env_kwargs,
        "seed": config.seed,
        "hyperparams": {**settings, "policy_kwargs": learner.policy_kwargs},
        "normalize": {"norm_obs": True, "norm_reward": False},
        "policy": "MlpPolicy",
        "training_seed": TRAINING_SEED,
        "budget": config.iterations * config.num_envs * config.horizon,
        "host": measure_host_speed(config.seed).to_json(),
    }
    write_config(run_dir, card_of(record, "of the SHAC run"))
    best: tuple[float, float, float] | None = None
    summary: Mapping[str, object] = {}
    first = True
    with Progress(config.iterations, f"shac {config.env_id}, n = {config.n_trailers}") as bar:
        for iteration in range(config.iterations):
            figures = learner.iterate()
            last = iteration == config.iterations - 1
            if (iteration + 1) % config.eval_every and not last:
                bar.advance(f"return per window {figures['window_return']:.2f}")
                continue
            policy = ModelPolicy(learner.model, learner.stats)
            results = rollout(
                policy, config.env_id, config.validation_episodes, VALIDATION_SEED, env_kwargs
            )
            summary = summarize(results)
            figures_of = Summary.from_json(summary, "of the validation")
            # The same actor acting with its noise, as it does in the windows it learns from.
            sampled = rollout(
                SampledPolicy(policy, config.seed),
                config.env_id,
                config.validation_episodes,
                VALIDATION_SEED,
                env_kwargs,
            )
            sampled_of = Summary.from_json(summarize(sampled), "of the sampled validation")
            row = {
                "iteration": iteration + 1,
                "timesteps": learner.simulated_steps,
                "wall_s": round(time.perf_counter() - started, 1),
                "safe_rate": float(figures_of.safe_rate),
                "mean_return": float(figures_of.mean_return),
                "jackknife_rate": float(figures_of.jackknife_rate),
                "sampled_safe_rate": float(sampled_of.safe_rate),
                **{key: round(figures[key], 6) for key in CURVE_FIELDS[7:]},
            }
            if first:
                write_curve(run_dir / CURVE_FILE, [row], CURVE_FIELDS)
                first = False
            else:
                append_rows(run_dir / CURVE_FILE, [row], CURVE_FIELDS)
            if best is None or score(figures_of) > best:
                best = score(figures_of)
                card = card_of(
                    {
                        **record,
                        "validation": summary,
                        "selected_at_iteration": iteration + 1,
                        "selected_at_timesteps": learner.simulated_steps,
                        "timesteps": learner.simulated_steps,
                    },
                    "of the SHAC run",
                )
                save_stats(learner.stats, stats_path(run_dir / BEST_MODEL))
                write_card(run_dir / BEST_MODEL, card)
                save_model(learner.model, run_dir / BEST_MODEL)
            bar.advance(f"validation safe {row['safe_rate']:.2f}")
            if verbose:
                print(
                    f"iteration {iteration + 1}: validation safe {row['safe_rate']:.2f}, "
                    f"return {row['mean_return']:.1f}, actor loss {figures['actor_loss']:.4f}, "
                    f"critic loss {figures['critic_loss']:.4f}, |g| {figures['gradient_norm']:.3g} "
                    f"({row['wall_s']:.0f} s)",
                    flush=True,
                )
    totals = {
        "timesteps": learner.simulated_steps,
        "wall_time_s": round(time.perf_counter() - started, 1),
        "simulated_steps": learner.simulated_steps,
    }
    record.update(totals)
    save_stats(learner.stats, stats_path(run_dir / FINAL_MODEL))
    write_card(run_dir / FINAL_MODEL, card_of({**record, "validation": summary}, "of the run"))
    save_model(learner.model, run_dir / FINAL_MODEL)
    best_path = run_dir / BEST_MODEL
    write_card(best_path, read_model_card(best_path).replace(**totals))
    write_config(run_dir, card_of(record, "of the SHAC run"))
    return record


__all__ = [
    "CURVE_FIELDS",
    "GradientAgreement",
    "SHACConfig",
    "gradient_agreement",
    "train_shac",
]
