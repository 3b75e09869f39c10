"""The twin's parameters: ConvoyParams, EnvSettings and the scene's constants, read once."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from trailer_env.core import ConvoyCore
from trailer_env.randomize import apply_params
from trailer_env.settings import EnvSettings, settings_from_keywords

#: The scenes the twin restates (``ConvoyCore.scene``).
SCENES = ("Reverse", "Coast", "Heading", "Dock")

#: The physical fields, which may be per-row tensors (the packed parameters' order).
PHYSICAL = ("M", "J0", "a", "m", "J", "l", "mu")
#: A physical parameter: a number for every row, or a tensor broadcasting over the rows
#: (B,) (per-row physics; a tensor that requires grad gives the gradient in it).
Scalar = float | torch.Tensor


@dataclass(frozen=True)
class TwinParams:
    """Everything :func:`trailer_env.twin.step` reads besides the state and the action.

    Build it with :meth:`from_core` (an existing batch core, e.g. ``env.unwrapped.core``),
    :meth:`from_settings` or :meth:`make` (an env id and ``gym.make``'s keywords); the
    physical fields ``M .. mu`` may then be replaced by tensors (``dataclasses.replace``).

    Attributes:
        scene, version: The scene (:data:`SCENES`) and its version (Reverse-v0 / v1).
        n: Number of trailers. with_pose: whether ``z`` carries the pose (x, y, theta).
        M, J0, a, m, J, l, mu: The packed parameters of :func:`dynamics.jit.pack_params`.
        b, s_max: The rail's offset and half-length (m).
        dt, mode, accel_max, frequency, rail_speed_max: The control period, the action
            mode ("servo", "accel", "planar"), the mass's acceleration bound, the servo's
            frequency (``EnvSettings.servo_frequency``) and the observed speed scale.
        singular_band, fold_angle: The cost's band and the jackknife angle.
        substeps: Fixed substeps, or None for the auto rule with the packed settings
            ``auto`` (:func:`trailer_env.substeps.auto_settings`).
        band_penalty .. min_reverse_speed: The scene's reward constants (its core's).
        straight_through: A surrogate gradient for learners: the action's clip to
            [-1, 1] and the acceleration's clip to [-A, A] keep their values but pass the
            gradient as if they did not clip (the servo saturates within 8 % of the rail
            of its target, so the true gradient of the state with respect to the action is
            zero for most actions). The rail guard's bounds are kept as they are. Off: the
            exact gradient of the branch taken.
    """

    scene: str
    version: int
    n: int
    with_pose: bool
    M: Scalar
    J0: Scalar
    a: Scalar
    m: Scalar
    J: Scalar
    l: Scalar
    mu: Scalar
    b: float
    s_max: float
    dt: float
    mode: str
    accel_max: float
    frequency: float
    rail_speed_max: float
    singular_band: float
    fold_angle: float
    substeps: int | None
    auto: tuple[float, ...]
    band_penalty: float
    fold_penalty: float
    time_penalty: float = 0.0
    success_bonus: float = 0.0
    failure_penalty: float = 0.0
    min_reverse_speed: float = 0.0
    straight_through: bool = False

    @classmethod
    def from_settings(
        cls, settings: EnvSettings, core_class: type[ConvoyCore], *, track_pose: bool = False
    ) -> TwinParams:
        """The twin of ``core_class`` (a scene's core) under ``settings``.

        Raises:
            ValueError: If the scene is not one of :data:`SCENES`, the integrator is not
                "rk4", or the settings randomise the physics (give tensors instead).
        """
        if core_class.scene not in SCENES:
            raise ValueError(f"the twin restates the scenes {SCENES}, not {core_class.scene!r}")
        fidelity = settings.fidelity
        if fidelity.integrator != "rk4":
            raise ValueError(f"the twin restates the 'rk4' integrator, not {fidelity.integrator!r}")
        if settings.randomize is not None:
            raise ValueError(
                "the twin takes per-row physics as tensors in TwinParams, not settings.randomize"
            )
        params = settings.params
        auto = fidelity.auto_settings(
            params,
            settings.dt,
            settings.actuator.planar,
            settings.rail_speed_max + settings.rail_accel_max * settings.dt,
        )
        constants: dict[str, Any] = {
            name: float(getattr(core_class, name))
            for name in (
                "band_penalty",
                "fold_penalty",
                "time_penalty",
                "success_bonus",
                "failure_penalty",
                "min_reverse_speed",
            )
            if hasattr(core_class, name)
        }
        return cls(
            scene=core_class.scene,
            version=core_class.version,
            n=settings.n_trailers,
            with_pose=core_class.uses_pose or track_pose,
            M=params.M,
            J0=params.J0,
            a=params.a,
            m=params.m,
            J=params.J,
            l=params.l,
            mu=params.mu,
            b=params.b,
            s_max=params.s_max,
            dt=settings.dt,
            mode=settings.action_mode,
            accel_max=settings.rail_accel_max,
            frequency=settings.servo_frequency,
            rail_speed_max=settings.rail_speed_max,
            singular_band=settings.singular_band,
            fold_angle=settings.fold_angle,
            substeps=None if fidelity.auto else fidelity.fixed_substeps,
            auto=tuple(float(value) for value in auto),
            **constants,
        )

    @classmethod
    def from_core(cls, core: ConvoyCore) -> TwinParams:
        """The twin of a batch core (``env.unwrapped.core``, a vector env's core)."""
        if not isinstance(core, ConvoyCore):
            raise TypeError(f"core must be a ConvoyCore, got {type(core).__name__}")
        return cls.from_settings(core.settings, type(core), track_pose=core.with_pose)

    @classmethod
    def make(cls, env_id: str, **kwargs: object) -> TwinParams:
        """The twin of ``gym.make(env_id, **kwargs)`` (one count of trailers)."""
        from trailer_env.registry import core_class_of

        return cls.from_settings(settings_from_keywords(kwargs), core_class_of(env_id))

    @property
    def width(self) -> int:
        """Columns of ``z``: n + 2, or n + 5 with the pose."""
        return self.n + (5 if self.with_pose else 2)

    @property
    def action_dim(self) -> int:
        """1, or 2 in planar mode."""
        return 2 if self.mode == "planar" else 1

    def auto_by_row(self, rows: int) -> np.ndarray | None:
        """The auto rule's settings of each of ``rows`` rows (rows, 12) where a physical
        field is a per-row tensor, as the kernel's draws set them
        (:func:`trailer_env.randomize.apply_params`); None where the parameters are shared."""
        values = [getattr(self, name) for name in PHYSICAL]
        if not any(isinstance(value, torch.Tensor) and value.numel() > 1 for value in values):
            return None
        packed = np.column_stack(
            [
                np.broadcast_to(
                    np.asarray(
                        value.detach().cpu().numpy() if isinstance(value, torch.Tensor) else value,
                        dtype=np.float64,
                    ),
                    (rows,),
                )
                for value in values
            ]
        )
        nominal = np.asarray(self.auto, dtype=np.float64)
        auto = np.tile(nominal, (rows, 1))
        scratch = np.empty_like(packed)
        planar = self.mode == "planar"
        indices = np.arange(rows, dtype=np.int64)
        apply_params(indices, packed, scratch, nominal, auto, self.b, self.s_max, planar)
        return auto

    def rows(self, index: torch.Tensor) -> TwinParams:
        """The parameters of the rows ``index`` of the batch: each per-row tensor (B,)
        indexed, the numbers and the tensors that broadcast kept."""
        changes = {}
        for name in PHYSICAL:
            value = getattr(self, name)
            if isinstance(value, torch.Tensor) and value.dim() > 0 and value.shape[0] > 1:
                changes[name] = value[index]
        return self.replace(**changes) if changes else self

    def replace(self, **changes: Any) -> TwinParams:
        """A copy with ``changes`` (e.g. ``mu=torch.tensor(0.5, requires_grad=True)``)."""
        return dataclasses.replace(self, **changes)
