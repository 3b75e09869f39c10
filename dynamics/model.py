"""Reduced equations of motion and energy (physics.md sections 3, 4, 5 and 9).

The reduced state is ``z = (u, omega, alpha_1, ..., alpha_n)`` with any leading
batch axes. Wherever a state is accepted, the extended state
``(u, omega, alpha_1..alpha_n, x, y, theta)`` (the pose of the cart's axle
midpoint appended) is accepted too, and the reconstruction equations
``x_dot = u cos(theta), y_dot = u sin(theta), theta_dot = omega`` are then
integrated alongside.

Two actuators are offered. The lateral rail (:func:`rhs`, :func:`energy`) puts
the moving mass at body coordinates ``(xi, eta) = (b, s)``; the planar actuator
(:func:`rhs_planar`, :func:`energy_planar`) prescribes both coordinates.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dynamics import _kernel
from dynamics.columns import ACT_WIDTH, ALPHA, U, x_column
from dynamics.params import ConvoyParams

FloatArray = NDArray[np.float64]


def state_component_name(column: int, n: int) -> str:
    """Name of column ``column`` of a (possibly extended) state with ``n`` trailers."""
    if column < ALPHA:
        return ("u", "omega")[column]
    if column < x_column(n):
        return f"alpha_{column - ALPHA + 1}"
    return ("x", "y", "theta")[column - x_column(n)]


def finite_result(what: str, out: FloatArray, n: int, names: str = "state") -> FloatArray:
    """Return ``out``, or raise FloatingPointError naming its first non-finite component.

    Finite input must not give inf or NaN silently; ``names`` says whether the last
    axis holds state components ("state": u, omega, alpha_k, x, y, theta) or is a
    scalar quantity (anything else, e.g. "energy").
    """
    finite = np.isfinite(out)
    if finite.all():
        return out
    if names == "state" and out.ndim >= 1:
        column = int(np.argmin(finite.reshape(-1, out.shape[-1]).all(axis=0)))
        component = f"its {state_component_name(column, n)} component"
    else:
        component = names
    raise FloatingPointError(
        f"{what} overflowed: {component} is not finite although the input was "
        "(the state or the actuator values are too large)"
    )


def real_array(name: str, value: ArrayLike) -> FloatArray:
    """``value`` as a float64 array (ints are converted); bools, strings, complex numbers
    and objects are a TypeError naming ``name``, a ragged sequence a ValueError."""
    if isinstance(value, np.ndarray):
        array = value
    elif value is None or isinstance(value, (str, bytes, bool, np.bool_)):
        raise TypeError(f"{name} must be real numbers, got {type(value).__name__} {value!r}")
    else:
        try:
            array = np.asarray(value)
        except (TypeError, ValueError) as error:
            raise ValueError(f"{name} must be a regular array of real numbers") from error
    if array.dtype.kind not in "iuf":
        raise TypeError(f"{name} must be real numbers, got dtype {array.dtype}")
    return array.astype(np.float64, copy=False)


def check_state(params: ConvoyParams, z: ArrayLike, name: str = "z") -> tuple[FloatArray, bool]:
    """Validate a (possibly extended) state and say whether it carries a pose.

    Integer states are converted to float64 (a new array; nothing is truncated).

    Returns:
        The state as a float64 array and True when its last axis has length n+5.

    Raises:
        TypeError: If ``params`` is not a ConvoyParams or the state is not made of real
            numbers (bools, strings, complex numbers).
        ValueError: If the last axis has the wrong length or a value is not finite.
    """
    if not isinstance(params, ConvoyParams):
        raise TypeError(f"params must be a ConvoyParams, got {type(params).__name__}")
    array = real_array(name, z)
    n = params.n_trailers
    if array.ndim == 0 or array.shape[-1] not in (n + 2, n + 5):
        raise ValueError(
            f"{name} must have last axis of length n+2 = {n + 2} (u, omega, alpha_1..alpha_{n}) "
            f"or n+5 = {n + 5} (with x, y, theta) for n_trailers = {n}; got shape {array.shape}"
        )
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} contains non-finite values (NaN or inf)")
    return array, array.shape[-1] == n + 5


def planar_actuator(
    batch_shape: tuple[int, ...],
    xi: ArrayLike,
    eta: ArrayLike,
    xi_dot: ArrayLike = 0.0,
    eta_dot: ArrayLike = 0.0,
    xi_ddot: ArrayLike = 0.0,
    eta_ddot: ArrayLike = 0.0,
) -> FloatArray:
    """The mass at body coordinates (xi, eta), broadcast to ``(prod(batch_shape), ACT_WIDTH)``.

    Raises:
        ValueError: If a value does not broadcast to the batch or is not finite.
    """
    return _actuator_columns(
        batch_shape,
        [
            ("xi", xi),
            ("eta", eta),
            ("xi_dot", xi_dot),
            ("eta_dot", eta_dot),
            ("xi_ddot", xi_ddot),
            ("eta_ddot", eta_ddot),
        ],
    )


def _actuator_columns(
    batch_shape: tuple[int, ...], columns: list[tuple[str, ArrayLike]]
) -> FloatArray:
    size = int(np.prod(batch_shape, dtype=np.int64))
    act = np.empty((size, ACT_WIDTH), dtype=np.float64)
    for column, (name, value) in enumerate(columns):  # in the order XI .. ETA_DDOT
        array = real_array(name, value)
        try:
            act[:, column] = np.broadcast_to(array, batch_shape).reshape(size)
        except ValueError:
            raise ValueError(
                f"{name} of shape {array.shape} does not broadcast to the batch shape {batch_shape}"
            ) from None
        if not np.all(np.isfinite(array)):
            raise ValueError(f"{name} contains non-finite values (NaN or inf)")
    return act


def rail_actuator(
    params: ConvoyParams,
    batch_shape: tuple[int, ...],
    s: ArrayLike,
    s_dot: ArrayLike,
    s_ddot: ArrayLike,
) -> FloatArray:
    """The lateral rail as a planar actuator: xi = b fixed, eta = s."""
    return _actuator_columns(
        batch_shape,
        [
            ("b", params.b),
            ("s", s),
            ("xi_dot", 0.0),
            ("s_dot", s_dot),
            ("xi_ddot", 0.0),
            ("s_ddot", s_ddot),
        ],
    )


def _rhs(params: ConvoyParams, z: FloatArray, with_pose: bool, act: FloatArray) -> FloatArray:
    rows = z.reshape(-1, z.shape[-1])
    out = _kernel.rhs_batch(_kernel.pack_params(params), rows, act, params.n_trailers, with_pose)
    return finite_result("rhs", out.reshape(z.shape), params.n_trailers)


def rhs(
    params: ConvoyParams,
    z: ArrayLike,
    s: ArrayLike = 0.0,
    s_dot: ArrayLike = 0.0,
    s_ddot: ArrayLike = 0.0,
) -> FloatArray:
    """Time derivative of the state with the moving mass on the lateral rail.

    Args:
        params: Convoy parameters.
        z: State ``(..., n+2)`` or extended state ``(..., n+5)``.
        s, s_dot, s_ddot: Position, velocity and acceleration of the mass on its
            rail, broadcast against ``z.shape[:-1]``. The rail's range is not
            enforced here (that is the environment's servo's job).

    Returns:
        dz/dt, same shape as ``z``.

    Raises:
        ValueError: If ``z`` has the wrong shape or a value is not finite.
        FloatingPointError: If dz/dt overflows (inf or NaN) although the input is finite,
            naming the component.

    Example:
        >>> p = ConvoyParams(n_trailers=1, mu=0.0)
        >>> rhs(p, [1.0, 0.0, 0.0]).tolist()
        [0.0, 0.0, 0.0]
    """
    array, with_pose = check_state(params, z)
    act = rail_actuator(params, array.shape[:-1], s, s_dot, s_ddot)
    return _rhs(params, array, with_pose, act)


def rhs_planar(
    params: ConvoyParams,
    z: ArrayLike,
    xi: ArrayLike,
    eta: ArrayLike,
    xi_dot: ArrayLike = 0.0,
    eta_dot: ArrayLike = 0.0,
    xi_ddot: ArrayLike = 0.0,
    eta_ddot: ArrayLike = 0.0,
) -> FloatArray:
    """Time derivative with the mass at prescribed body coordinates (xi, eta).

    ``xi`` is measured forward and ``eta`` to the left from the cart's axle
    midpoint; ``params.b`` is ignored.
    """
    array, with_pose = check_state(params, z)
    act = planar_actuator(array.shape[:-1], xi, eta, xi_dot, eta_dot, xi_ddot, eta_ddot)
    return _rhs(params, array, with_pose, act)


def _energy(params: ConvoyParams, z: FloatArray, act: FloatArray) -> FloatArray:
    rows = z.reshape(-1, z.shape[-1])
    out = _kernel.energy_batch(_kernel.pack_params(params), rows, act, params.n_trailers)
    return finite_result("energy", out.reshape(z.shape[:-1]), params.n_trailers, "the energy")


def energy(
    params: ConvoyParams, z: ArrayLike, s: ArrayLike = 0.0, s_dot: ArrayLike = 0.0
) -> FloatArray:
    """Kinetic energy of the convoy and the mass on the rail, shape ``z.shape[:-1]``.

    E = (R u^2 + I0 omega^2 + mu ((u - omega s)^2 + (omega b + s_dot)^2)) / 2;
    with mu = 0 it is the conserved energy of physics.md section 4.
    """
    array, _ = check_state(params, z)
    act = rail_actuator(params, array.shape[:-1], s, s_dot, 0.0)
    return _energy(params, array, act)


def energy_planar(
    params: ConvoyParams,
    z: ArrayLike,
    xi: ArrayLike,
    eta: ArrayLike,
    xi_dot: ArrayLike = 0.0,
    eta_dot: ArrayLike = 0.0,
) -> FloatArray:
    """Kinetic energy with the mass at body coordinates (xi, eta)."""
    array, _ = check_state(params, z)
    act = planar_actuator(array.shape[:-1], xi, eta, xi_dot, eta_dot)
    return _energy(params, array, act)


def inertia_R(params: ConvoyParams, alpha: ArrayLike) -> FloatArray:
    """R(alpha) of physics.md section 4, the convoy's effective mass, shape ``alpha.shape[:-1]``."""
    alpha_array = np.asarray(alpha, dtype=np.float64)
    n = params.n_trailers
    if alpha_array.ndim == 0 or alpha_array.shape[-1] != n:
        raise ValueError(
            f"alpha must have last axis of length n = {n}; got shape {alpha_array.shape}"
        )
    # Energy at u = 1, omega = 0 with the mass switched off is R / 2.
    z = np.zeros((*alpha_array.shape[:-1], n + 2))
    z[..., U] = 1.0
    z[..., ALPHA:] = alpha_array
    if not np.all(np.isfinite(z)):
        raise ValueError("alpha contains non-finite values (NaN or inf)")
    rows = z.reshape(-1, n + 2)
    pv = _kernel.pack_params(params)
    pv[_kernel.P_MU] = 0.0
    out = _kernel.energy_batch(pv, rows, np.zeros((rows.shape[0], ACT_WIDTH)), n)
    return 2.0 * out.reshape(z.shape[:-1])
