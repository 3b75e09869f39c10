"""Seeded batched rollouts, the safety metrics, the comparison tables and the pictures."""
