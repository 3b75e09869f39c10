"""A differentiable twin of the scenes' step: the compiled kernel's control step in torch.

``step(state, action, params) -> (next_state, reward, cost, terminated)`` is the step of
:meth:`trailer_env.core.ConvoyCore.step` with the default integrator ("rk4", auto or
fixed substeps) restated in torch, float64, batched over rows, for any number of
trailers, on whatever device the tensors are on (CPU, CUDA). It is a pure function in the
gymnax style: the state (:class:`TwinState`) holds what the kernel's step reads (the
convoy state ``z``, the mass state ``act``, the scene's task values and step counter) and
the parameters (:class:`TwinParams`) the ConvoyParams, EnvSettings and scene constants.

What it restates, in the kernel's order: the actuator (servo, accel or planar, the rail
guard), the auto substep rule (:mod:`trailer_env.substeps`), RK4 with the mass's exact
quadratic motion and the fold test after every substep, the mass's exact advance and the
rail clamp, the cost (singular band) and the scene's reward, success and termination
(Reverse-v0/v1, Coast-v0, Heading-v0, Dock-v0). tests/trailer_env/test_twin.py holds it
to the kernel at every scene and n = 1..8; that test is what keeps the two statements of
the equations one.

Gradients. Every continuous map is differentiated exactly (autograd through RK4 and the
actuator). Where the kernel branches, the forward value is the kernel's and the gradient
is that of the branch taken: the action's clip to [-1, 1], the servo's acceleration clip
and the rail guard's bounds pass no gradient to what they cut off (a row whose
acceleration the guard set takes the guard's bound's gradient with respect to the
mass's position and velocity); the rail clamp after the step passes the gradient inside
the rail (and at its ends). The substep count is piecewise constant (no gradient: a
change of count is a jump of the order of the integrator's error). Termination, success,
the jackknife flag and the cost are booleans or indicators (no gradient); the rewards'
penalties on them are piecewise constant, and ``min(omega^2, 1)``, ``min(|omega|, 1)``
pass no gradient beyond 1. Nothing here smooths them, except on request:
``TwinParams(straight_through=True)`` passes the gradient through the action's clip and
the acceleration's clip to its bound as if they did not clip (the values unchanged), the
surrogate a learner needs where the servo saturates (:mod:`agents.training.shac`).

Not restated: the divergence retry (a step the kernel redoes with 8 times the substeps
or refuses returns non-finite or huge values here), the work budget, "rk4-energy",
"dopri5", per-row randomised physics under the auto rule (give fixed ``substeps``, or
take the rows' parameters as tensors with the nominal auto rule; the counts may then
differ from the kernel's), and the observation's float32 rounding (see :func:`observe`).

torch is the ``agents`` extra's: importing this package without it raises ImportError.
"""

from __future__ import annotations

try:
    import torch  # noqa: F401  (the extra's check; the submodules import it too)
except ImportError as error:  # pragma: no cover - the extra is installed in the tests
    raise ImportError(
        "trailer_env.twin needs torch: pip install 'trailer-env[agents]' (the agents extra)"
    ) from error

from trailer_env.twin.params import SCENES, TwinParams
from trailer_env.twin.physics import PhysicsResult, field, physics_step
from trailer_env.twin.scenes import TwinState, TwinStep, observe, potential, step

__all__ = [
    "SCENES",
    "PhysicsResult",
    "TwinParams",
    "TwinState",
    "TwinStep",
    "field",
    "observe",
    "physics_step",
    "potential",
    "step",
]
