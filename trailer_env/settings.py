"""Settings shared by every scene: physical parameters, control period, actuator, fidelity.

:class:`EnvSettings` is frozen and validated once; the environments, their batch
core and the controllers all read it. :func:`settings_from_kwargs` turns the
keyword arguments of ``gym.make`` (``n_trailers``, ``dt``, ConvoyParams field
overrides such as ``mu=0.4`` ...) into settings.

Default parameters are :class:`dynamics.ConvoyParams`' own; how its actuator was
sized for the scenes is in docs/physics.md section 9 ("Sizing the actuator").
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import cast

from dynamics import ConvoyParams
from dynamics.params import MAX_TRAILERS, bounded_integer, bounded_real, one_of
from trailer_env.actuator import ACTUATORS, ActionMode, Actuator
from trailer_env.fidelity import MAX_FIXED_SUBSTEPS, Fidelity
from trailer_env.observation import checked_observation
from trailer_env.randomize import PARAMETERS, Randomization, checked_observe_params
from trailer_env.substeps import STABILITY_FRACTION, cart_rate_coefficient, stability_limit

#: The action modes, in the order of :data:`trailer_env.actuator.ACTUATORS`.
ACTION_MODES: tuple[str, ...] = tuple(ACTUATORS)

_PARAM_FIELDS = frozenset(f.name for f in dataclasses.fields(ConvoyParams))

#: Accepted control period dt (s): 10 us to 10 s. Below, float32 observations of
#: rates and the servo's gains (~1 / dt^2) lose meaning; above, one held action spans
#: many of the convoy's time constants.
DT_RANGE = (1e-5, 10.0)
#: Accepted range of rail_accel_max (m/s^2) and servo_bandwidth (rad/s).
RATE_RANGE = (1e-6, 1e6)
#: Speed (m/s) the settings must resolve: every scene starts its convoy at |u| <= 1.5 m/s.
REFERENCE_SPEED = 2.0


#: How an environment made with a range ``n_trailers=(low, high)`` gives each episode its
#: count (:mod:`trailer_env.mixed`): "episode" (default) draws it from the episode's
#: generator, uniformly; "row" fixes it by the batch row, ``low + i mod (high - low + 1)``
#: for row i, so every count gets the same share of a batch's steps however long its
#: episodes last.
TRAILER_DRAWS = ("episode", "row")


#: The longest window of past frames ``history`` takes (:mod:`trailer_env.history`).
MAX_HISTORY = 64


@dataclass(frozen=True)
class EnvSettings:
    """Everything but the task: physics, control period, actuator and safety thresholds.

    Every field follows the input policy of :mod:`dynamics.params`: a wrong type is a
    TypeError, an out-of-range value a ValueError naming the field and its range.
    Besides each field's range, the combination must be integrable: at the
    reference speed ``|u| = 2 m/s`` (:data:`REFERENCE_SPEED`, above every scene's
    starting speed) the convoy's fastest rate ``r = |u| max(1 / l, c_cart)`` (see
    :mod:`trailer_env.substeps`) must be resolved by the fidelity, i.e. ``dt r / k``
    within RK4's stability limit for fixed ``k`` substeps, and within
    :data:`~trailer_env.fidelity.MAX_FIXED_SUBSTEPS` (10,000) substeps of the auto
    rule's safe step otherwise. Settings that would diverge at the first step, or
    take minutes per step, are refused up front.

    Bounded cost: one control step of a batch may take at most
    :data:`~trailer_env.substeps.MAX_STEP_WORK` = 2e8 body-substeps (substeps x
    (n_trailers + 1), summed over the environments; its time: benchmarks/README.md). The batch core
    refuses fixed substeps beyond it when it is built (ValueError), and with
    ``substeps="auto"`` a step whose chosen substeps exceed it raises FloatingPointError,
    naming the speed and the budget, before anything is integrated.

    Attributes:
        params: Physical parameters (``params.n_trailers`` trailers).
        dt: Control period in seconds (the action is held over it), in [1e-5, 10].
        fidelity: Integrator and substep control (:class:`Fidelity`).
        action_mode: "servo" (default: the action is a target position on the rail),
            "accel" (the action is the rail acceleration) or "planar" (2-D target).
        rail_accel_max: Bound on the mass's acceleration along each axis, m/s^2, in
            [1e-6, 1e6]; ``rail_accel_max * dt**2 <= s_max`` so the end-of-rail guard
            can always act.
        servo_bandwidth: Natural frequency of the position servo, rad/s, in [1e-6, 1e6],
            capped at ``0.25 / dt`` for the sampled loop to stay well damped.
        singular_band: The convoy is in the singular band when
            ``singular_margin < singular_band``, in [0, 1).
        fold_angle: Jackknife when any ``|alpha_k| >= fold_angle`` (radians, in (0, pi]).
        randomize: None (default), or per-episode factors on ``params`` and the starting
            speed (:class:`trailer_env.randomize.Randomization`: a dict of ranges such as
            ``{"M": (0.8, 1.2)}`` or a preset name such as ``"mismatch20"``). Every corner
            of the box of parameter factors must give valid parameters and integrable
            settings (the checks above); the ratio bounds of ConvoyParams and the rate
            ``r`` are monotone in each factor but ``a``, so the corners bound them. It
            needs an RK4 integrator ("rk4", "rk4-energy"): "dopri5" shares one parameter
            vector.
        observe_params: Append the episode's parameter factors to the observation
            (``log(value / nominal)`` of M, J0, a, m, J, l, mu: 0 where not randomised,
            and where the nominal value is 0, which a factor leaves 0).
        observation: "flat" (default: the scene's Box) or "trailers" (a Dict whose shapes
            do not depend on n, :mod:`trailer_env.observation`).
        max_trailers: Trailer slots of ``observation="trailers"``, an integer in
            ``n_trailers .. 256`` (default 8); None with "flat" (giving it is a ValueError).
        trailer_draw: How an environment made with a range of ``n_trailers`` gives each
            episode its count (:data:`TRAILER_DRAWS`, :mod:`trailer_env.mixed`); with one
            count there is nothing to draw and it changes nothing.
        history: Past frames (observation, applied action) appended to the observation,
            an integer in 0 .. 64 (:mod:`trailer_env.history`); 0 (default) appends
            none. Needs ``observation="flat"``.

    Each field's ``metadata["keyword"]`` is its one-line meaning as a ``gym.make``
    keyword (:data:`MAKE_KEYWORDS`).
    """

    params: ConvoyParams = field(
        default_factory=ConvoyParams,
        metadata={"keyword": "full physical parameters (dynamics.ConvoyParams), default its own"},
    )
    dt: float = field(default=0.05, metadata={"keyword": "control period, s (0.05)"})
    fidelity: Fidelity = field(
        default_factory=Fidelity,
        metadata={
            "keyword": "integrator and substeps (trailer_env.fidelity.Fidelity, a dict, "
            "an integrator name or a substep count)"
        },
    )
    action_mode: ActionMode = field(
        default="servo", metadata={"keyword": '"servo" (default), "accel" or "planar"'}
    )
    rail_accel_max: float = field(
        default=4.0, metadata={"keyword": "bound on the mass's acceleration, m/s^2 (4)"}
    )
    servo_bandwidth: float = field(
        default=5.0, metadata={"keyword": "the position servo's natural frequency, rad/s (5)"}
    )
    singular_band: float = field(
        default=0.3, metadata={"keyword": "singular margin below which a step is penalised (0.3)"}
    )
    fold_angle: float = field(
        default=math.pi / 2, metadata={"keyword": "hitch angle of a jackknife, rad (pi/2)"}
    )
    randomize: Randomization | None = field(
        default=None,
        metadata={
            "keyword": 'per-episode parameter factors: a dict of ranges or a preset ("mismatch20")'
        },
    )
    observe_params: bool = field(
        default=False, metadata={"keyword": "append the episode's parameter factors (False)"}
    )
    observation: str = field(
        default="flat", metadata={"keyword": '"flat" (a Box, default) or "trailers" (a Dict)'}
    )
    max_trailers: int | None = field(
        default=None, metadata={"keyword": 'trailer slots of observation="trailers" (8)'}
    )
    trailer_draw: str = field(
        default="episode",
        metadata={
            "keyword": 'how a range of n_trailers gives each episode its count: "episode" '
            '(default) or "row"'
        },
    )

    history: int = field(
        default=0,
        metadata={"keyword": "past observations and applied actions appended, 0-64 (0)"},
    )

    def __post_init__(self) -> None:
        if not isinstance(self.params, ConvoyParams):
            raise TypeError(f"params must be a ConvoyParams, got {type(self.params).__name__}")
        slots = checked_observation(self.observation, self.max_trailers, self.params.n_trailers)
        object.__setattr__(self, "max_trailers", slots)
        object.__setattr__(self, "fidelity", Fidelity.coerce(self.fidelity))
        object.__setattr__(self, "dt", bounded_real("dt", self.dt, *DT_RANGE))
        for name in ("rail_accel_max", "servo_bandwidth"):
            object.__setattr__(self, name, bounded_real(name, getattr(self, name), *RATE_RANGE))
        one_of("action_mode", self.action_mode, ACTION_MODES)
        one_of("trailer_draw", self.trailer_draw, TRAILER_DRAWS)
        history = bounded_integer("history", self.history, 0, MAX_HISTORY)
        object.__setattr__(self, "history", history)
        if self.history and self.observation != "flat":
            raise ValueError(
                f"history = {self.history} needs observation='flat', got "
                f"{self.observation!r}: a Dict observation has no place for past frames"
            )
        if self.rail_accel_max * self.dt**2 > self.params.s_max:
            raise ValueError(
                f"rail_accel_max * dt**2 = {self.rail_accel_max * self.dt**2:.4g} exceeds s_max = "
                f"{self.params.s_max}: the end-of-rail guard could not always stop the mass; "
                "lower rail_accel_max or dt"
            )
        band = bounded_real("singular_band", self.singular_band, 0.0, 1.0, high_open=True)
        fold = bounded_real("fold_angle", self.fold_angle, 0.0, math.pi, low_open=True)
        object.__setattr__(self, "singular_band", band)
        object.__setattr__(self, "fold_angle", fold)
        self._check_resolution()
        # Fail now rather than at the first step (e.g. "rk4-energy" with mu > 0).
        self.fidelity.check_params(self.params)
        object.__setattr__(self, "observe_params", checked_observe_params(self.observe_params))
        object.__setattr__(self, "randomize", Randomization.coerce(self.randomize))
        if self.randomize is not None:
            self._check_randomize(self.randomize)

    def _check_randomize(self, randomize: Randomization) -> None:
        """Refuse ranges whose corners give invalid parameters or settings (class docstring)."""
        if any(name in PARAMETERS for name in randomize.names) and not self.fidelity.uses_substeps:
            raise ValueError(
                f"randomize {list(randomize.names)} needs an RK4 fidelity: "
                f"fidelity.integrator {self.fidelity.integrator!r} integrates one parameter "
                "vector for the whole batch"
            )
        for corner in randomize.corners():
            if not corner:
                continue
            values = {name: getattr(self.params, name) * factor for name, factor in corner.items()}
            shown = ", ".join(f"{name} x {factor:g}" for name, factor in corner.items())
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", UserWarning)  # J >= m l^2: allowed
                    params = self.params.replace(**values)
                    dataclasses.replace(self, params=params, randomize=None)
            except ValueError as error:
                raise ValueError(
                    f"randomize: at the corner ({shown}) of the ranges, {error}"
                ) from None

    def _check_resolution(self) -> None:
        """Refuse settings whose integrator cannot resolve the reference speed (class docstring)."""
        params, fidelity = self.params, self.fidelity
        rate = REFERENCE_SPEED * max(
            1.0 / params.l, cart_rate_coefficient(params, self.actuator.planar)
        )
        step = self.dt * rate
        limit = stability_limit(params.n_trailers)
        fixed = fidelity.substeps if isinstance(fidelity.substeps, int) else None
        if fixed is not None and fidelity.uses_substeps:
            if step / fixed > limit:
                raise ValueError(
                    f"fidelity.substeps = {fixed} is unstable with dt = {self.dt:g} and l = "
                    f"{params.l:g}: at |u| = {REFERENCE_SPEED:g} m/s, dt r / substeps = "
                    f"{step / fixed:.3g} exceeds RK4's stability limit {limit:.3g}; use at "
                    f"least {math.ceil(step / limit)} substeps, 'auto', or a smaller dt"
                )
            return
        needed = step / (STABILITY_FRACTION * limit)
        if needed > MAX_FIXED_SUBSTEPS:
            raise ValueError(
                f"dt = {self.dt:g} is too long for l = {params.l:g} (and these parameters): at "
                f"|u| = {REFERENCE_SPEED:g} m/s a control step needs ~{needed:.3g} substeps, more "
                f"than {MAX_FIXED_SUBSTEPS}; use a smaller dt or a longer l"
            )

    @property
    def n_trailers(self) -> int:
        """Number of trailers."""
        return self.params.n_trailers

    @property
    def servo_frequency(self) -> float:
        """The servo's natural frequency actually used, min(servo_bandwidth, 0.25 / dt)."""
        return min(self.servo_bandwidth, 0.25 / self.dt)

    @property
    def rail_speed_max(self) -> float:
        """Largest speed the guard lets the mass reach, 2 sqrt(rail_accel_max s_max).

        The mass must be able to stop within the rail, so v^2 / (2 A) <= 2 s_max.
        Observations divide the mass's velocity by this.
        """
        return 2.0 * math.sqrt(self.rail_accel_max * self.params.s_max)

    @property
    def actuator(self) -> Actuator:
        """The action mode's entry of :data:`trailer_env.actuator.ACTUATORS`."""
        return ACTUATORS[self.action_mode]

    @property
    def action_dim(self) -> int:
        """1, or 2 in planar mode."""
        return self.actuator.action_dim


def settings_from_kwargs(
    n_trailers: int | None = None,
    params: ConvoyParams | None = None,
    dt: float = 0.05,
    fidelity: Fidelity | dict[str, object] | str | int | None = None,
    action_mode: ActionMode = "servo",
    rail_accel_max: float = 4.0,
    servo_bandwidth: float = 5.0,
    singular_band: float = 0.3,
    fold_angle: float = math.pi / 2,
    randomize: Randomization | dict[str, object] | str | None = None,
    observe_params: bool = False,
    observation: str = "flat",
    max_trailers: int | None = None,
    trailer_draw: str = "episode",
    history: int = 0,
    **param_overrides: float,
) -> EnvSettings:
    """Build settings from ``gym.make``-style keyword arguments.

    Args:
        n_trailers: Number of trailers, an integer in [0, 256], default 2 (must agree
            with ``params`` when both are given).
        params: Full parameters; by default ConvoyParams' own.
        dt, fidelity, action_mode, rail_accel_max, servo_bandwidth: See :class:`EnvSettings`.
        singular_band, fold_angle, randomize, observe_params: See :class:`EnvSettings`.
        observation, max_trailers: See :class:`EnvSettings`.
        trailer_draw, history: See :class:`EnvSettings`.
        **param_overrides: ConvoyParams fields, e.g. ``mu=0.4``.

    Raises:
        TypeError: On an unknown keyword (the Python convention, which wrappers such as
            TorchRL's rely on to probe optional keywords) or a value of the wrong type,
            naming it.
        ValueError: On an invalid value, naming it.
    """
    unknown = sorted(set(param_overrides) - _PARAM_FIELDS)
    if unknown:
        # Python's own wording, which wrappers match (TorchRL drops `frameskip` on
        # "unexpected keyword argument 'frameskip'"); every unknown name is listed.
        raise TypeError(
            "; ".join(f"unexpected keyword argument {name!r}" for name in unknown)
            + f"; valid: {', '.join(name for name, _ in MAKE_KEYWORDS)} and the "
            f"ConvoyParams fields {sorted(_PARAM_FIELDS - {'n_trailers'})}"
        )
    count = (
        None if n_trailers is None else bounded_integer("n_trailers", n_trailers, 0, MAX_TRAILERS)
    )
    if params is None:
        base = {"n_trailers": 2 if count is None else count, **param_overrides}
        params = ConvoyParams(**base)  # type: ignore[arg-type]
    elif not isinstance(params, ConvoyParams):
        raise TypeError(f"params must be a ConvoyParams, got {type(params).__name__}")
    else:
        if count is not None and count != params.n_trailers:
            raise ValueError(
                f"n_trailers = {count} disagrees with params.n_trailers = {params.n_trailers}"
            )
        if param_overrides:
            params = params.replace(**param_overrides)
    return EnvSettings(
        params=params,
        dt=dt,
        fidelity=Fidelity.coerce(fidelity),
        action_mode=cast("ActionMode", action_mode),  # EnvSettings validates it
        rail_accel_max=rail_accel_max,
        servo_bandwidth=servo_bandwidth,
        singular_band=singular_band,
        fold_angle=fold_angle,
        randomize=Randomization.coerce(randomize),
        observe_params=observe_params,
        observation=observation,
        max_trailers=max_trailers,
        trailer_draw=trailer_draw,
        history=history,
    )


def settings_from_keywords(keywords: Mapping[str, object]) -> EnvSettings:
    """:func:`settings_from_kwargs` of keywords as ``gym.make`` passes them on (untyped:
    each is checked there, a wrong type being a TypeError naming it).

    Raises:
        TypeError, ValueError: As :func:`settings_from_kwargs`.
    """
    return settings_from_kwargs(**keywords)  # type: ignore[arg-type]


#: The keywords ``gym.make`` and ``gym.make_vec`` take for every scene, with their one-line
#: meanings: ``n_trailers``, then the fields of :class:`EnvSettings` (their
#: ``metadata["keyword"]``); any :class:`dynamics.ConvoyParams` field is a keyword too.
#: docs/generated/keywords.md is written from it (:func:`keywords_markdown`).
MAKE_KEYWORDS: tuple[tuple[str, str], ...] = (
    ("n_trailers", "number of trailers, 0-256 (2), or a range (low, high) drawn per episode"),
    *((item.name, str(item.metadata["keyword"])) for item in dataclasses.fields(EnvSettings)),
)


def keywords_markdown() -> str:
    """:data:`MAKE_KEYWORDS` as the Markdown table of docs/generated/keywords.md."""
    lines = [
        "<!-- written by `python -m trailer_env --keywords docs/generated/keywords.md` -->",
        "",
        "| keyword | meaning (default) |",
        "|---|---|",
        *(f"| `{name}` | {meaning} |" for name, meaning in MAKE_KEYWORDS),
        "| any `dynamics.ConvoyParams` field | that parameter, e.g. `mu=0.4` |",
    ]
    return "\n".join(lines) + "\n"
