"""Oracles with the exact model and state: the sampling planner, iLQR, the linear
feasibility screen and what they know of each scene (certification, built on them, is
:mod:`agents.certification`)."""
