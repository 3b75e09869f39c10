"""The named columns of the arrays every layer shares: the state ``z`` and the mass state ``act``.

Write ``z[i, OMEGA]``, ``z[:, ALPHA + k]`` (hitch ``k + 1``), ``z[:, theta_column(n)]`` and
``act[i, ETA]``, never the bare numbers: the layout is defined here once.

A state row (``n`` trailers) is ``(u, omega, alpha_1..alpha_n)``, width ``n + 2``,
optionally followed by the pose ``(x, y, theta)`` of the cart's axle midpoint, width
``n + 5`` (``docs/physics.md``):

=================  ======================  ============================================
column             name                    holds
=================  ======================  ============================================
0                  :data:`U`               the cart's forward speed ``u``, m/s
1                  :data:`OMEGA`           the cart's yaw rate ``omega``, rad/s
2 .. n + 1         :data:`ALPHA` + k - 1   the hitch angle ``alpha_k``, rad
n + 2              :func:`x_column`        the pose's ``x``, m
n + 3              :func:`y_column`        the pose's ``y``, m
n + 4              :func:`theta_column`    the pose's heading ``theta``, rad
=================  ======================  ============================================

The mass state ``act`` (shape ``(B, ACT_WIDTH)``) holds the moving mass's body-frame
position, velocity and acceleration, ``xi`` forward and ``eta`` to the left of the
cart's axle midpoint. The lateral rail is ``xi = b`` fixed and ``eta = s``: its
position, speed and acceleration are the :data:`ETA`, :data:`ETA_DOT` and
:data:`ETA_DDOT` columns.

In numba, module-level integers are compile-time constants and the column functions
(:func:`numba.extending.register_jitable`, inlined) fold to the same integer sums: the
names cost nothing in compiled code.
"""

from __future__ import annotations

from numba.extending import register_jitable

#: State column of the cart's forward speed ``u``.
U = 0
#: State column of the cart's yaw rate ``omega``.
OMEGA = 1
#: State column of the first hitch angle ``alpha_1``; ``alpha_k`` is at ``ALPHA + k - 1``.
ALPHA = 2

#: ``act`` column of the mass's forward body coordinate ``xi``.
XI = 0
#: ``act`` column of the mass's lateral body coordinate ``eta`` (the rail's ``s``).
ETA = 1
#: ``act`` column of ``xi_dot``.
XI_DOT = 2
#: ``act`` column of ``eta_dot`` (the rail's ``s_dot``).
ETA_DOT = 3
#: ``act`` column of ``xi_ddot`` (held over an integration call).
XI_DDOT = 4
#: ``act`` column of ``eta_ddot`` (the rail's ``s_ddot``, held over an integration call).
ETA_DDOT = 5
#: Number of ``act`` columns.
ACT_WIDTH = 6


@register_jitable(inline="always")
def x_column(n: int) -> int:
    """State column of the pose's ``x`` with ``n`` trailers (the first after the hitches)."""
    return ALPHA + n


@register_jitable(inline="always")
def y_column(n: int) -> int:
    """State column of the pose's ``y`` with ``n`` trailers."""
    return ALPHA + n + 1


@register_jitable(inline="always")
def theta_column(n: int) -> int:
    """State column of the pose's heading ``theta`` with ``n`` trailers (the last)."""
    return ALPHA + n + 2
