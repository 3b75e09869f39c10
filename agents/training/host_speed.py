"""The speed of the machine a run trains on, recorded on its card.

A wall time means little without the machine it was measured on: the same PPO recipe
can take twice as long on a slower or busier host. So every training command
(``agents.train``, ``agents.imitate``, ``agents.shac``; RLlib's on its driver) measures,
when the run starts, a short fixed benchmark under the run's own thread settings and
records it on the run's card as :class:`~agents.artifacts.cards.HostSpeed`:

- ``env_steps_per_s``: environment steps per second of ``trailer_env/Reverse-v1`` with
  three trailers, a native batch of :data:`BATCH` environments stepped with seeded
  uniform actions through the SB3 adapter (:data:`ENV_STEPS` steps after a warm-up that
  compiles and loads the kernels);
- ``ppo_update_s``: the seconds of one PPO update (``PPO.train`` with SB3's defaults: 10
  epochs over a rollout of :data:`ROLLOUT` samples in minibatches of 64, the 64 x 64
  network) on a rollout collected beforehand;
- the CPUs, torch's threads and the load average (1 minute) when it ran.

About a second on a 2-core machine. :data:`BENCHMARK` names the benchmark: two records
compare only when it is the same. ``python -m agents.host_speed`` prints this machine's.
"""

from __future__ import annotations

import os
import random
import time

import gymnasium as gym
import numpy as np

from agents.artifacts.cards import HostSpeed

#: The benchmark's name (changed whenever what it measures changes).
BENCHMARK = "reverse_v1_n3_batch8_ppo2048"
#: Environments in the stepped batch, and steps timed (after :data:`WARMUP_STEPS`).
BATCH = 8
ENV_STEPS = 65_536
WARMUP_STEPS = 64
#: The timed PPO update: SB3's defaults (epochs over a rollout of ``n_steps * BATCH``
#: samples, minibatches of 64).
ROLLOUT = 2048
EPOCHS = 10


def measure_host_speed(seed: int = 0) -> HostSpeed:
    """Run the fixed benchmark (see the module docstring) on this machine, now.

    Args:
        seed: Seeds the environments, the actions and the network (the timings do not
            depend on it beyond noise).
    """
    import torch

    # PPO seeds the global generators: the run's own draws must not depend on whether
    # (or with which seed) the benchmark ran.
    python_state, numpy_state = random.getstate(), np.random.get_state()  # noqa: NPY002
    try:
        with torch.random.fork_rng(devices=[]):
            return _measure(seed)
    finally:
        random.setstate(python_state)
        np.random.set_state(numpy_state)  # noqa: NPY002


def _measure(seed: int) -> HostSpeed:
    import torch
    from stable_baselines3 import PPO

    from agents.envs import make_sb3_env

    venv = make_sb3_env("trailer_env/Reverse-v1", BATCH, {"n_trailers": 3}, seed=seed)
    try:
        generator = np.random.default_rng(seed)
        space = venv.action_space
        assert isinstance(space, gym.spaces.Box)
        low, high = space.low, space.high
        shape = (BATCH, *space.shape)
        venv.reset()
        for _ in range(WARMUP_STEPS):
            venv.step(generator.uniform(low, high, size=shape))
        actions = generator.uniform(low, high, size=(ENV_STEPS // BATCH, *shape))
        started = time.perf_counter()
        for batch_actions in actions:
            venv.step(batch_actions)
        env_steps_per_s = ENV_STEPS / (time.perf_counter() - started)

        model = PPO(
            "MlpPolicy",
            venv,
            n_steps=ROLLOUT // BATCH,
            batch_size=64,
            n_epochs=EPOCHS,
            seed=seed,
            device="cpu",
            verbose=0,
        )
        _, callback = model._setup_learn(ROLLOUT, callback=None, progress_bar=False)
        callback.on_training_start(locals(), globals())
        assert model.env is not None
        model.collect_rollouts(model.env, callback, model.rollout_buffer, model.n_steps)
        started = time.perf_counter()
        model.train()
        ppo_update_s = time.perf_counter() - started
    finally:
        venv.close()
    return HostSpeed(
        benchmark=BENCHMARK,
        env_steps_per_s=round(env_steps_per_s, 1),
        ppo_update_s=round(ppo_update_s, 4),
        cpus=os.cpu_count() or 1,
        torch_threads=torch.get_num_threads(),
        load_average=round(os.getloadavg()[0], 2),
    )
