"""The host's speed: the fixed benchmark every training run records on its card."""

from __future__ import annotations

import json
import random

import numpy as np
import pytest
import torch

from agents.artifacts.cards import HostSpeed, ModelCard
from agents.artifacts.records import DocumentError
from agents.commands.host_speed import main
from agents.training.host_speed import BENCHMARK, measure_host_speed

GOOD = {
    "benchmark": BENCHMARK,
    "env_steps_per_s": 231_531.8,
    "ppo_update_s": 0.8067,
    "cpus": 2,
    "torch_threads": 1,
    "load_average": 0.6,
}


def test_the_benchmark_measures_positive_speeds_and_leaves_the_generators_alone() -> None:
    random.seed(5)
    np.random.seed(5)  # noqa: NPY002
    torch.manual_seed(5)
    expected = (random.random(), np.random.random(), torch.rand(1).item())  # noqa: NPY002
    random.seed(5)
    np.random.seed(5)  # noqa: NPY002
    torch.manual_seed(5)
    host = measure_host_speed(seed=3)
    # PPO seeds the global generators; the run that measured must draw as if it had not.
    assert (random.random(), np.random.random(), torch.rand(1).item()) == expected  # noqa: NPY002
    assert host.benchmark == BENCHMARK
    # Tens of thousands of steps per second and well under a minute per update on any
    # machine these tests run on (a 2-core machine: about 2.5e5 and 0.8 s).
    assert host.env_steps_per_s > 1e4 and 0 < host.ppo_update_s < 60
    assert host.cpus >= 1 and host.torch_threads == torch.get_num_threads()
    assert host.load_average >= 0


def test_the_record_reads_back_on_a_card_and_refuses_bad_values() -> None:
    card = ModelCard(algo="ppo", host=HostSpeed(**GOOD))
    again = ModelCard.from_json(json.loads(json.dumps(card.to_json())), "test")
    assert again == card and again.host is not None
    assert again.host.summary() == "231,532 steps/s, PPO update 0.81 s (2 CPUs, load 0.6)"
    for field, value in [
        ("env_steps_per_s", 0.0),
        ("ppo_update_s", -1.0),
        ("cpus", 0),
        ("load_average", float("nan")),
    ]:
        with pytest.raises(DocumentError, match=field if field != "cpus" else "'cpus'"):
            HostSpeed(**{**GOOD, field: value})
    with pytest.raises(DocumentError, match="host"):
        ModelCard.from_json({"host": {**GOOD, "speed": 1}}, "test")


def test_the_command_prints_this_machines_record(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--json"]) == 0
    printed = HostSpeed.from_json(json.loads(capsys.readouterr().out), "stdout")
    assert printed.benchmark == BENCHMARK and printed.torch_threads == 1
    assert main([]) == 0
    assert "steps/s, PPO update" in capsys.readouterr().out
