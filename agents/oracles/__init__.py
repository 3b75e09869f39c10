"""Oracles with the exact model and state: the sampling planner, the linear feasibility
screen, and the certification of a scene's ceiling built from both."""
