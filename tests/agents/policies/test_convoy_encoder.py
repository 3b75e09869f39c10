"""ConvoyEncoder: a policy built on one n acts on any n <= max_trailers; the mask works;
it trains, and its saved models load without unpickling."""

from __future__ import annotations

import base64
import json
import pickle
import zipfile
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch
from stable_baselines3 import PPO

from agents.artifacts.files import UnsafeFileError
from agents.artifacts.sb3_zip import load_sb3, save_model
from agents.policies.convoy_encoder import ConvoyEncoder
from agents.policies.extractors import feature_extractor, feature_extractors
from agents.training.config import parse_policy_kwargs
from tests.agents.helpers import rewrite_zip
from trailer_env.sb3 import ConvoySB3VecEnv

REVERSE = "trailer_env/Reverse-v1"
KWARGS = dict(
    features_extractor_class=ConvoyEncoder,
    features_extractor_kwargs=dict(hidden=16, body_hidden=16),
    net_arch=[16],
)


@pytest.fixture(autouse=True)
def one_thread() -> None:
    torch.set_num_threads(1)


def _model(n_trailers: object = 2, n_steps: int = 64, seed: int = 0) -> PPO:
    venv = ConvoySB3VecEnv(REVERSE, num_envs=4, n_trailers=n_trailers, observation="trailers")
    return PPO(
        "MultiInputPolicy",
        venv,
        n_steps=n_steps,
        batch_size=64,
        n_epochs=1,
        policy_kwargs=KWARGS,
        seed=seed,
        device="cpu",
    )


def _observations(n: int, count: int = 3, seed: int = 0) -> dict[str, np.ndarray]:
    venv = ConvoySB3VecEnv(REVERSE, num_envs=count, n_trailers=n, observation="trailers")
    venv.seed(seed)
    return venv.reset()  # type: ignore[return-value]


def _features(model: PPO, obs: dict[str, np.ndarray]) -> torch.Tensor:
    tensors, _ = model.policy.obs_to_tensor(obs)
    with torch.no_grad():
        return model.policy.extract_features(tensors, model.policy.features_extractor)


def test_a_policy_built_on_two_trailers_acts_on_one_to_six() -> None:
    model = _model(2)
    assert model.policy.features_extractor.features_dim == 32
    for n in range(1, 7):  # n = 3 .. 6 never seen: the same weights, more recurrent steps
        obs = _observations(n)
        assert obs["mask"].sum(axis=1).tolist() == [n] * 3
        actions, _ = model.predict(obs, deterministic=True)
        again, _ = model.predict(obs, deterministic=True)
        assert actions.shape == (3, 1) and actions.dtype == np.float32
        assert np.all(np.isfinite(actions)) and np.all(np.abs(actions) <= 1.0)
        np.testing.assert_array_equal(actions, again)  # deterministic
    # A batch mixing n = 1 .. 6 acts row by row as each n alone does.
    rows = [{key: value[:1] for key, value in _observations(n).items()} for n in range(1, 7)]
    mixed = {key: np.concatenate([row[key] for row in rows]) for key in rows[0]}
    alone = np.concatenate([_features(model, row).numpy() for row in rows])
    np.testing.assert_allclose(_features(model, mixed).numpy(), alone, rtol=1e-6, atol=1e-7)


def test_padded_slots_change_nothing_and_real_trailers_do(rng: np.random.Generator) -> None:
    model = _model(2)
    obs = _observations(2, count=4)
    reference = _features(model, obs)
    noisy = {key: value.copy() for key, value in obs.items()}
    noisy["trailers"][:, 2:] = rng.uniform(-1.0, 1.0, size=noisy["trailers"][:, 2:].shape)
    noisy["trailers"][:, 2:] = noisy["trailers"][:, 2:][:, rng.permutation(6)]
    assert torch.equal(_features(model, noisy), reference)  # exactly: the mask skips them
    swapped = {key: value.copy() for key, value in obs.items()}
    swapped["trailers"][:, [0, 1]] = obs["trailers"][:, [1, 0]]
    changed = (_features(model, swapped) - reference).abs().amax(dim=1)
    assert torch.all(changed > 1e-6)  # the order along the convoy matters
    shorter = {key: value.copy() for key, value in obs.items()}
    shorter["mask"][:, 1] = 0.0  # the second trailer no longer counts
    assert torch.all((_features(model, shorter) - reference).abs().amax(dim=1) > 1e-6)


def test_no_trailer_gives_the_cart_state() -> None:
    model = _model(2)
    obs = _observations(0)
    encoder = model.policy.features_extractor
    tensors, _ = model.policy.obs_to_tensor(obs)
    with torch.no_grad():
        features = encoder(tensors)
        start = encoder.start(tensors["body"])
    assert features.shape == (3, 32)
    assert torch.equal(features[:, :16], start)


def test_a_tiny_ppo_learns_with_the_vector_env_and_mixed_n() -> None:
    model = _model((1, 3), n_steps=64)
    before = [p.detach().clone() for p in model.policy.features_extractor.parameters()]
    model.learn(256)
    assert model.num_timesteps == 256
    after = list(model.policy.features_extractor.parameters())
    assert all(not torch.equal(a, b) for a, b in zip(before, after, strict=True))


def test_the_saved_model_loads_without_unpickling(tmp_path: Path) -> None:
    model = _model(2)
    path = save_model(model, tmp_path / "encoder.zip")
    space = model.observation_space
    obs = _observations(5)
    loaded = load_sb3(path, "ppo", space, model.action_space, extractors=feature_extractors())
    assert isinstance(loaded.policy.features_extractor, ConvoyEncoder)
    expected, _ = model.predict(obs, deterministic=True)
    actions, _ = loaded.predict(obs, deterministic=True)
    np.testing.assert_array_equal(actions, expected)
    # Without the table the class cannot be rebuilt: refused, not unpickled.
    with pytest.raises(UnsafeFileError, match="features_extractor_class"):
        load_sb3(path, "ppo", space, model.action_space)
    # A pickle planted under policy_kwargs is never run: the JSON text is read instead.
    marker = tmp_path / "ran"
    with zipfile.ZipFile(path) as archive:
        data = json.loads(archive.read("data"))
    payload = base64.b64encode(pickle.dumps(_Touch(marker))).decode()
    data["policy_kwargs"][":serialized:"] = payload
    rewrite_zip(path, {"data": json.dumps(data).encode()})
    again = load_sb3(path, "ppo", space, model.action_space, extractors=feature_extractors())
    np.testing.assert_array_equal(again.predict(obs, deterministic=True)[0], expected)
    assert not marker.exists()
    # A class outside the table is refused, naming the entry.
    data["policy_kwargs"]["features_extractor_class"] = "<class 'os.system'>"
    rewrite_zip(path, {"data": json.dumps(data).encode()})
    with pytest.raises(UnsafeFileError, match=r"policy_kwargs\['features_extractor_class'\]"):
        load_sb3(path, "ppo", space, model.action_space, extractors=feature_extractors())


class _Touch:
    """Unpickling it writes a file (proof that a pickle ran)."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self) -> tuple:
        return (Path.write_text, (self.marker, "ran"))


def _encoder(direction: str, seed: int = 0) -> ConvoyEncoder:
    space = ConvoySB3VecEnv(REVERSE, num_envs=1, observation="trailers").observation_space
    torch.manual_seed(seed)
    return ConvoyEncoder(space, hidden=8, body_hidden=4, direction=direction)  # type: ignore[arg-type]


@pytest.mark.parametrize("direction", ["tail_first", "both"])
def test_the_reversed_pass_is_the_recurrence_from_the_last_trailer(direction: str) -> None:
    encoder = _encoder(direction)
    assert encoder.features_dim == {"tail_first": 12, "both": 20}[direction]
    rows = [{key: value[:1] for key, value in _observations(n).items()} for n in (1, 3, 6)]
    mixed = {key: torch.as_tensor(np.concatenate([row[key] for row in rows])) for key in rows[0]}
    with torch.no_grad():
        features = encoder(mixed)
        for i, n in enumerate((1, 3, 6)):
            body = mixed["body"][i : i + 1]
            state = encoder.tail_start(body)
            for k in reversed(range(n)):  # the last trailer first, the cart's neighbour last
                inputs = (mixed["trailers"][i : i + 1, k] - encoder.centre) * 10.0
                state = encoder.tail_cell(inputs, state)
            expected = [state, encoder.body(body)]
            if direction == "both":
                forward = encoder.start(body)
                for k in range(n):
                    inputs = (mixed["trailers"][i : i + 1, k] - encoder.centre) * 10.0
                    forward = encoder.cell(inputs, forward)
                expected.insert(0, forward)
            torch.testing.assert_close(
                features[i : i + 1], torch.cat(expected, dim=1), rtol=1e-6, atol=1e-7
            )


def test_the_default_direction_keeps_the_saved_models_weights() -> None:
    # cart_first draws the same initial weights, with the same names, as before the option.
    encoder = _encoder("cart_first", seed=3)
    assert [name for name, _ in encoder.named_parameters()] == [
        "start.0.weight",
        "start.0.bias",
        "body.0.weight",
        "body.0.bias",
        "cell.weight_ih",
        "cell.weight_hh",
        "cell.bias_ih",
        "cell.bias_hh",
    ]
    torch.manual_seed(3)
    first = torch.nn.Linear(encoder.start[0].in_features, 8)
    torch.testing.assert_close(encoder.start[0].weight, first.weight, rtol=0, atol=0)
    assert encoder.features_dim == 12


def test_a_reversed_encoder_saves_and_loads_its_direction(tmp_path: Path) -> None:
    venv = ConvoySB3VecEnv(REVERSE, num_envs=4, n_trailers=(1, 3), observation="trailers")
    kwargs = {
        **KWARGS,
        "features_extractor_kwargs": dict(hidden=16, body_hidden=16, direction="tail_first"),
    }
    model = PPO(
        "MultiInputPolicy",
        venv,
        n_steps=64,
        batch_size=64,
        policy_kwargs=kwargs,
        seed=0,
        device="cpu",
    )
    path = save_model(model, tmp_path / "tail.zip")
    loaded = load_sb3(
        path, "ppo", model.observation_space, model.action_space, extractors=feature_extractors()
    )
    assert loaded.policy.features_extractor.direction == "tail_first"
    obs = _observations(5)  # an n the model never saw
    np.testing.assert_array_equal(
        loaded.predict(obs, deterministic=True)[0], model.predict(obs, deterministic=True)[0]
    )


def test_policy_kwargs_strings_name_the_encoder() -> None:
    parsed = parse_policy_kwargs(
        "dict(features_extractor_class=ConvoyEncoder, features_extractor_kwargs=dict(hidden=8))"
    )
    assert parsed == {
        "features_extractor_class": ConvoyEncoder,
        "features_extractor_kwargs": {"hidden": 8},
    }
    assert feature_extractor("ConvoyEncoder") is ConvoyEncoder
    with pytest.raises(ValueError, match="unsupported expression in policy_kwargs: 'Evil'"):
        parse_policy_kwargs("dict(features_extractor_class=Evil)")
    with pytest.raises(ValueError, match=r"unknown features extractor 'Evil'; shipped: \['Con"):
        feature_extractor("Evil")


def test_the_encoder_refuses_other_spaces_and_sizes() -> None:
    space = ConvoySB3VecEnv(REVERSE, num_envs=1, observation="trailers").observation_space
    with pytest.raises(TypeError, match="needs the Dict observation"):
        ConvoyEncoder(gym.spaces.Box(-1.0, 1.0, (8,)))  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"hidden must be an integer in 1\.\.4096, got 0"):
        ConvoyEncoder(space, hidden=0)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="trailer_scale must be a positive number"):
        ConvoyEncoder(space, trailer_scale=float("nan"))  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"direction must be one of \('cart_first', 'tail_f"):
        ConvoyEncoder(space, direction="backwards")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="direction must be a str, got int"):
        ConvoyEncoder(space, direction=1)  # type: ignore[arg-type]


def test_agents_train_refuses_the_dict_observation_before_writing(tmp_path: Path) -> None:
    from agents.training.config import Hyperparams, TrainConfig
    from agents.training.sb3 import train

    hp = Hyperparams(policy="MultiInputPolicy", env_kwargs={"observation": "trailers"})
    config = TrainConfig.resolve(REVERSE, "ppo", 2, 0, hp, timesteps=64, n_envs=1)
    with pytest.raises(ValueError, match=r"agents\.train needs the flat observation"):
        train(config, tmp_path / "run", progress_bar=False, verbose=0)
    assert not (tmp_path / "run").exists()
