"""One interface for the batch cores: a scene's core and a mix of trailer counts both
satisfy BatchCore, build_core returns one, and the core's attributes are declared once."""

from __future__ import annotations

import dataclasses
import inspect

import numpy as np
import pytest

from trailer_env.core import ConvoyCore
from trailer_env.core_base import CoreBase
from trailer_env.core_infos import InfoMixin
from trailer_env.core_physics import PhysicsMixin
from trailer_env.core_protocol import BatchCore
from trailer_env.core_retry import RetryMixin
from trailer_env.kernel_args import KernelArguments
from trailer_env.mixed import MixedCore, build_core
from trailer_env.scenes.reverse_v1 import ReverseV1Core


def _members() -> list[str]:
    return [
        name
        for name, _ in inspect.getmembers(BatchCore)
        if not name.startswith("_") and name not in dir(object)
    ]


def test_both_cores_satisfy_the_protocol_and_build_core_returns_them() -> None:
    settings, single = build_core(ReverseV1Core, {"n_trailers": 2}, 3, False)
    _, mixed = build_core(ReverseV1Core, {"n_trailers": (1, 3), "trailer_draw": "row"}, 3, False)
    assert type(single) is ReverseV1Core and type(mixed) is MixedCore
    assert isinstance(single, BatchCore) and isinstance(mixed, BatchCore)
    assert len(_members()) >= 30
    for core in (single, mixed):
        missing = [name for name in _members() if not hasattr(core, name)]
        assert not missing
    assert single.counts == (2,) and list(single.count_cores()) == [2]
    assert single.trailers.tolist() == [2, 2, 2] and single.row_core(1) is single
    assert mixed.counts == (1, 2, 3) and sorted(mixed.count_cores()) == [1, 2, 3]
    mixed.reset_rows(np.arange(3), [np.random.default_rng(k) for k in range(3)])
    assert mixed.trailers.tolist() == [1, 2, 3]  # "row": row i runs low + i mod 3
    assert mixed.row_core(2) is mixed.count_cores()[3]
    assert settings.n_trailers == 2 and mixed.settings.trailer_draw == "row"


def test_rendering_a_range_is_refused() -> None:
    with pytest.raises(ValueError, match="one number of trailers"):
        build_core(ReverseV1Core, {"n_trailers": (1, 2)}, 1, True)


def test_the_core_attributes_are_declared_once() -> None:
    declared = set(vars(CoreBase)["__annotations__"])
    assert {"z", "obs", "kernel_args", "param_values", "randomization"} <= declared
    for part in (PhysicsMixin, InfoMixin, RetryMixin):
        assert issubclass(part, CoreBase)
        assert not vars(part).get("__annotations__"), part.__name__
    assert not declared & set(vars(ConvoyCore).get("__annotations__", {}))


def test_the_kernel_arguments_are_one_frozen_record_of_the_core_arrays() -> None:
    core = ReverseV1Core(build_core(ReverseV1Core, {}, 2, False)[0], 2)
    args = core.kernel_args
    assert isinstance(args, KernelArguments)
    with pytest.raises(dataclasses.FrozenInstanceError):
        args.config = args.config  # type: ignore[misc]
    assert args.state.z is core.z and args.outputs.obs is core.obs
    assert args.config_tuple == tuple(args.config) and args.state_tuple[0] is core.z
    assert args.observe[2][-1] == np.inf and args.step_observe[2][-1] == 1e12
    source = inspect.getsource(CoreBase.__init__).splitlines()
    assert len(source) < 60
